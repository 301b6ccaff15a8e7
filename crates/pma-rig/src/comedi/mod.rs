//! The Comedi driver: any board Comedi supports on Linux, first of all the NI PCI-6052E of
//! the muscle rig (kernel driver `ni_pcimio`).
//!
//! Three layers:
//! - [`ComediLib`]: the raw library calls, made safe (one instance = one opened device).
//!   `ffi::FfiLib` calls the real libcomedi (feature `comedi`); the tests use a fake
//!   PCI-6052E with its outputs looped back to its inputs (`fake.rs`, compiled for tests
//!   only, so that it never leaks into the public API).
//! - Pure-Rust conversions between codes and volts that mirror comedilib's (`lib/range.c`,
//!   `lib/calib.c`): [`to_phys`], [`from_phys`], [`Polynomial`].
//! - [`ComediDaq`]: the [`Daq`] implementation, which validates the configured channels once
//!   and then converts and transfers without allocating.
//!
//! [`open_comedi`] is the entry point for the application: it opens the real device when the
//! crate is built with the `comedi` feature and explains how to rebuild otherwise.

use std::sync::{Mutex, PoisonError};

use thiserror::Error;

use crate::daq::{AnalogChannel, ChannelName, Daq, DaqError, DigitalLine, Direction, OutputHandle};

#[cfg(test)]
mod fake;
#[cfg(feature = "comedi")]
pub mod ffi;

/// A failed libcomedi call: the call, `comedi_errno()` and `comedi_strerror()`.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("{call}: {message} (errno {errno})")]
pub struct ComediError {
    /// The library function that failed (`comedi_data_read` ...).
    pub call: &'static str,
    /// `comedi_errno()`: a libc errno (`EIO` ...) or one of comedilib's own codes (>= 0x1000).
    pub errno: i32,
    /// `comedi_strerror(errno)`.
    pub message: String,
}

/// What a subdevice is (Comedi's `COMEDI_SUBD_*`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SubdeviceKind {
    /// `COMEDI_SUBD_UNUSED`.
    Unused,
    /// `COMEDI_SUBD_AI`.
    AnalogInput,
    /// `COMEDI_SUBD_AO`.
    AnalogOutput,
    /// `COMEDI_SUBD_DI`.
    DigitalInput,
    /// `COMEDI_SUBD_DO`.
    DigitalOutput,
    /// `COMEDI_SUBD_DIO`.
    DigitalIo,
    /// `COMEDI_SUBD_COUNTER`.
    Counter,
    /// `COMEDI_SUBD_TIMER`.
    Timer,
    /// `COMEDI_SUBD_MEMORY`.
    Memory,
    /// `COMEDI_SUBD_CALIB`.
    Calibration,
    /// `COMEDI_SUBD_PROC`.
    Processor,
    /// `COMEDI_SUBD_SERIAL`.
    Serial,
    /// `COMEDI_SUBD_PWM`.
    Pwm,
    /// A type this crate does not know.
    Other(i32),
}

impl SubdeviceKind {
    /// From Comedi's numeric type (`comedi_get_subdevice_type`).
    pub fn from_comedi(code: i32) -> Self {
        match code {
            0 => Self::Unused,
            1 => Self::AnalogInput,
            2 => Self::AnalogOutput,
            3 => Self::DigitalInput,
            4 => Self::DigitalOutput,
            5 => Self::DigitalIo,
            6 => Self::Counter,
            7 => Self::Timer,
            8 => Self::Memory,
            9 => Self::Calibration,
            10 => Self::Processor,
            11 => Self::Serial,
            12 => Self::Pwm,
            other => Self::Other(other),
        }
    }
}

impl std::fmt::Display for SubdeviceKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let name = match self {
            Self::Unused => "unused",
            Self::AnalogInput => "analog input",
            Self::AnalogOutput => "analog output",
            Self::DigitalInput => "digital input",
            Self::DigitalOutput => "digital output",
            Self::DigitalIo => "digital I/O",
            Self::Counter => "counter",
            Self::Timer => "timer",
            Self::Memory => "memory",
            Self::Calibration => "calibration",
            Self::Processor => "processor",
            Self::Serial => "serial",
            Self::Pwm => "PWM",
            Self::Other(code) => return write!(f, "type {code}"),
        };
        f.write_str(name)
    }
}

/// Physical unit of a range (Comedi's `UNIT_*`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RangeUnit {
    /// `UNIT_volt`.
    Volt,
    /// `UNIT_mA`.
    MilliAmp,
    /// `UNIT_none` (digital lines, raw counts).
    None,
    /// Anything else (`RF_EXTERNAL` ranges, unknown units): the raw `unit` field.
    Other(u32),
}

impl RangeUnit {
    /// From `comedi_range.unit`.
    pub fn from_comedi(unit: u32) -> Self {
        match unit {
            0 => Self::Volt,
            1 => Self::MilliAmp,
            2 => Self::None,
            other => Self::Other(other),
        }
    }
}

impl std::fmt::Display for RangeUnit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Volt => f.write_str("V"),
            Self::MilliAmp => f.write_str("mA"),
            Self::None => f.write_str("no unit"),
            Self::Other(unit) => write!(f, "unit {unit:#x}"),
        }
    }
}

/// A range as `comedi_get_range` reports it: code 0 is `min`, code `maxdata` is `max`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Range {
    /// Physical value of code 0.
    pub min: f64,
    /// Physical value of code `maxdata`.
    pub max: f64,
    /// Unit of `min` and `max`.
    pub unit: RangeUnit,
}

impl Range {
    /// A range in volts.
    pub fn volts(min: f64, max: f64) -> Self {
        Self {
            min,
            max,
            unit: RangeUnit::Volt,
        }
    }
}

/// Which way a calibration polynomial converts (`enum comedi_conversion_direction`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConversionDirection {
    /// Code to physical value (`COMEDI_TO_PHYSICAL` = 0).
    ToPhysical,
    /// Physical value to code (`COMEDI_FROM_PHYSICAL` = 1).
    FromPhysical,
}

/// A calibration polynomial (`comedi_polynomial_t`): `sum c[i] (x - origin)^i`, `i <= order`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Polynomial {
    /// `c[0..=order]` (the rest is ignored).
    pub coefficients: [f64; Polynomial::MAX_COEFFICIENTS],
    /// The expansion origin.
    pub expansion_origin: f64,
    /// The degree, at most 3.
    pub order: u32,
}

impl Polynomial {
    /// `COMEDI_MAX_NUM_POLYNOMIAL_COEFFICIENTS`.
    pub const MAX_COEFFICIENTS: usize = 4;

    /// Evaluates the polynomial the way comedilib's `apply_polynomial` does (same order of
    /// operations, so the same rounding). comedilib asserts `order < 4`; here the terms past
    /// the fourth are simply absent, and the FFI layer refuses such a polynomial anyway.
    pub fn eval(&self, x: f64) -> f64 {
        let terms = (self.order as usize).saturating_add(1);
        let mut value = 0.0;
        let mut term = 1.0;
        for coefficient in self.coefficients.iter().take(terms) {
            value += coefficient * term;
            term *= x - self.expansion_origin;
        }
        value
    }

    /// `comedi_to_physical`: a code to a physical value.
    pub fn to_physical(&self, code: u32) -> f64 {
        self.eval(f64::from(code))
    }

    /// `comedi_from_physical`: a physical value to a code, rounded to nearest with ties to
    /// even (comedilib uses `nearbyint` in the default rounding mode). comedilib then casts
    /// to `lsampl_t` without clamping (undefined for a negative value); here the code is
    /// clamped to `[0, maxdata]` and NaN gives 0, so that no value can wrap around to the
    /// opposite end of the range.
    pub fn from_physical(&self, value: f64, maxdata: u32) -> u32 {
        clamp_code(self.eval(value).round_ties_even(), maxdata)
    }
}

/// `comedi_to_phys` with `COMEDI_OOR_NUMBER`: the linear map from code 0 = `range.min` to
/// code `maxdata` = `range.max`. (comedilib's default, `COMEDI_OOR_NAN`, also returns NaN
/// for the saturated codes; [`is_saturated`] tells those apart.) NaN when `maxdata` is 0,
/// as in comedilib.
pub fn to_phys(code: u32, range: &Range, maxdata: u32) -> f64 {
    if maxdata == 0 {
        return f64::NAN;
    }
    // Same order of operations as comedilib, hence bit-identical results.
    let mut x = f64::from(code);
    x /= f64::from(maxdata);
    x *= range.max - range.min;
    x += range.min;
    x
}

/// `comedi_from_phys`: the inverse of [`to_phys`], rounded to nearest (`floor(s + 0.5)`)
/// and clamped to `[0, maxdata]`. 0 when `maxdata` is 0 (as comedilib) and for NaN (where
/// comedilib's cast is undefined).
pub fn from_phys(value: f64, range: &Range, maxdata: u32) -> u32 {
    if maxdata == 0 {
        return 0;
    }
    let s = (value - range.min) / (range.max - range.min) * f64::from(maxdata);
    clamp_code((s + 0.5).floor(), maxdata)
}

/// Whether a code is at either end of the converter's scale, i.e. the input is out of range
/// (the condition under which comedilib's `COMEDI_OOR_NAN` returns NaN).
pub fn is_saturated(code: u32, maxdata: u32) -> bool {
    code == 0 || code >= maxdata
}

/// A rounded value as a code in `[0, maxdata]` (NaN gives 0).
fn clamp_code(rounded: f64, maxdata: u32) -> u32 {
    if rounded.is_nan() || rounded <= 0.0 {
        0
    } else if rounded >= f64::from(maxdata) {
        maxdata
    } else {
        // In (0, maxdata) and integral: the cast is exact.
        rounded as u32
    }
}

/// The raw library calls, made safe. One instance is one opened device (a `comedi_t *`);
/// dropping it closes the device. Errors carry `comedi_errno()` and its message.
///
/// The queries take `&self` (comedilib answers them from tables read at open); the calls
/// that reach the hardware take `&mut self`.
pub trait ComediLib: Send + Sized {
    /// `comedi_open(path)`.
    fn open(path: &str) -> Result<Self, ComediError>;
    /// Opens the same device a second time: an independent instance (another `comedi_t`,
    /// another file descriptor), usable while this one is busy in another thread.
    fn reopen(&self) -> Result<Self, ComediError>;
    /// `comedi_get_board_name`.
    fn board_name(&self) -> Result<String, ComediError>;
    /// `comedi_get_n_subdevices`.
    fn n_subdevices(&self) -> Result<u32, ComediError>;
    /// `comedi_get_subdevice_type`.
    fn subdevice_kind(&self, subdevice: u32) -> Result<SubdeviceKind, ComediError>;
    /// `comedi_get_n_channels`.
    fn n_channels(&self, subdevice: u32) -> Result<u32, ComediError>;
    /// `comedi_get_n_ranges`.
    fn n_ranges(&self, subdevice: u32, channel: u32) -> Result<u32, ComediError>;
    /// `comedi_get_range`, copied out of the library's tables.
    fn range(&self, subdevice: u32, channel: u32, range: u32) -> Result<Range, ComediError>;
    /// `comedi_get_maxdata` (an error instead of comedilib's 0).
    fn maxdata(&self, subdevice: u32, channel: u32) -> Result<u32, ComediError>;
    /// `comedi_get_hardcal_converter`: the conversion polynomial of a hardware-calibrated
    /// board, `None` when the library gives none.
    fn hardcal(
        &self,
        subdevice: u32,
        channel: u32,
        range: u32,
        direction: ConversionDirection,
    ) -> Option<Polynomial>;
    /// `comedi_data_read`: one raw code.
    fn data_read(
        &mut self,
        subdevice: u32,
        channel: u32,
        range: u32,
        aref: u32,
    ) -> Result<u32, ComediError>;
    /// `comedi_data_write`: one raw code.
    fn data_write(
        &mut self,
        subdevice: u32,
        channel: u32,
        range: u32,
        aref: u32,
        code: u32,
    ) -> Result<(), ComediError>;
    /// `comedi_dio_config(.., COMEDI_OUTPUT)`.
    fn dio_config_output(&mut self, subdevice: u32, channel: u32) -> Result<(), ComediError>;
    /// `comedi_dio_write`.
    fn dio_write(&mut self, subdevice: u32, channel: u32, high: bool) -> Result<(), ComediError>;
}

/// What [`ComediDaq`] keeps per analog channel after validating it: everything a conversion
/// needs, so that a read or write makes exactly one library call.
#[derive(Debug, Clone, Copy, PartialEq)]
struct ChannelCal {
    /// The channel, named (direction, subdevice, channel).
    name: ChannelName,
    /// The range index it was validated with.
    range_index: u32,
    /// The range in volts.
    range: Range,
    /// Largest code.
    maxdata: u32,
    /// The hardware-calibration polynomial for this direction (to volts for an input, from
    /// volts for an output), if the board has one.
    polynomial: Option<Polynomial>,
}

impl ChannelCal {
    /// Whether this entry is for `channel` as an output (`output`) or an input.
    fn matches(&self, channel: &AnalogChannel, output: bool) -> bool {
        (self.name.direction == Direction::AnalogOut) == output
            && self.name.subdevice == channel.subdevice
            && self.name.channel == channel.channel
            && self.range_index == channel.range
    }

    /// A code read from an input, in volts; NaN when saturated (out of range).
    fn code_to_volts(&self, code: u32) -> f64 {
        if is_saturated(code, self.maxdata) {
            return f64::NAN;
        }
        match &self.polynomial {
            Some(polynomial) => polynomial.to_physical(code),
            None => to_phys(code, &self.range, self.maxdata),
        }
    }

    /// A value for an output as a code; NaN or outside the range is an error, because a
    /// silently clamped valve command would hide a controller bug.
    fn volts_to_code(&self, device: &str, volts: f64) -> Result<u32, DaqError> {
        if !(self.range.min..=self.range.max).contains(&volts) {
            return Err(DaqError::OutOfRange {
                device: device.to_owned(),
                channel: self.name,
                volts,
                min_v: self.range.min,
                max_v: self.range.max,
            });
        }
        Ok(match &self.polynomial {
            Some(polynomial) => polynomial.from_physical(volts, self.maxdata),
            None => from_phys(volts, &self.range, self.maxdata),
        })
    }
}

/// A [`Daq`] over Comedi. Build it with [`ComediDaq::open`] (or [`open_comedi`]), then call
/// [`Daq::check`] with the channels of the configuration: it validates them, configures the
/// digital lines as outputs and caches each analog channel's range, `maxdata` and hardware
/// calibration, so that reads and writes allocate nothing. A channel used without having
/// been given to `check` is validated and cached at its first use.
pub struct ComediDaq<L: ComediLib> {
    device: String,
    board: String,
    lib: L,
    analog: Vec<ChannelCal>,
    lines: Vec<DigitalLine>,
}

impl<L: ComediLib> std::fmt::Debug for ComediDaq<L> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ComediDaq")
            .field("device", &self.device)
            .field("board", &self.board)
            .field("analog", &self.analog)
            .field("lines", &self.lines)
            .finish_non_exhaustive()
    }
}

impl<L: ComediLib> ComediDaq<L> {
    /// Opens a device (`/dev/comedi0`). The error says what to do when the device is
    /// missing or not accessible.
    pub fn open(device: &str) -> Result<Self, DaqError> {
        let lib = L::open(device).map_err(|error| open_error(device, &error))?;
        Ok(Self::from_lib(device, lib))
    }

    /// Wraps an already opened library instance.
    pub fn from_lib(device: impl Into<String>, lib: L) -> Self {
        // The board name is only for messages: a board that cannot tell it still works.
        let board = lib
            .board_name()
            .unwrap_or_else(|_| String::from("unknown board"));
        Self {
            device: device.into(),
            board,
            lib,
            analog: Vec::new(),
            lines: Vec::new(),
        }
    }

    /// The board's name as the driver reports it (`pci-6052e`).
    pub fn board(&self) -> &str {
        &self.board
    }

    /// The cached calibration of an analog channel, validating and caching it first if
    /// `check` did not.
    fn calibration(
        &mut self,
        channel: &AnalogChannel,
        output: bool,
    ) -> Result<ChannelCal, DaqError> {
        if let Some(cal) = self.analog.iter().find(|cal| cal.matches(channel, output)) {
            return Ok(*cal);
        }
        let cal = resolve_analog(&self.lib, &self.device, &self.board, channel, output)?;
        self.analog.push(cal);
        Ok(cal)
    }

    /// Validates a digital line and configures it as an output.
    fn configure_line(&mut self, line: &DigitalLine) -> Result<(), DaqError> {
        let name = line.name();
        let probe = Probe {
            lib: &self.lib,
            device: &self.device,
            board: &self.board,
            name,
        };
        probe.subdevice_of_kind(SubdeviceKind::DigitalIo)?;
        probe.channel_exists()?;
        self.lib
            .dio_config_output(line.subdevice, line.channel)
            .map_err(|error| io_error(&self.device, name, "configure as output", &error))
    }
}

impl<L: ComediLib + 'static> Daq for ComediDaq<L> {
    fn device(&self) -> &str {
        &self.device
    }

    fn check(
        &mut self,
        inputs: &[AnalogChannel],
        outputs: &[AnalogChannel],
        lines: &[DigitalLine],
    ) -> Result<(), DaqError> {
        // Built aside and swapped in at the end: a failed check leaves the previous table.
        let mut analog = Vec::with_capacity(inputs.len() + outputs.len());
        let directed = inputs
            .iter()
            .map(|channel| (channel, false))
            .chain(outputs.iter().map(|channel| (channel, true)));
        for (channel, output) in directed {
            analog.push(resolve_analog(
                &self.lib,
                &self.device,
                &self.board,
                channel,
                output,
            )?);
        }
        let mut configured = Vec::with_capacity(lines.len());
        for line in lines {
            self.configure_line(line)?;
            configured.push(*line);
        }
        self.analog = analog;
        self.lines = configured;
        Ok(())
    }

    fn range_v(&mut self, channel: &AnalogChannel, output: bool) -> Result<(f64, f64), DaqError> {
        let cal = self.calibration(channel, output)?;
        Ok((cal.range.min, cal.range.max))
    }

    fn read_analog(&mut self, channel: &AnalogChannel) -> Result<f64, DaqError> {
        let cal = self.calibration(channel, false)?;
        let code = self
            .lib
            .data_read(
                channel.subdevice,
                channel.channel,
                channel.range,
                channel.aref.comedi(),
            )
            .map_err(|error| io_error(&self.device, cal.name, "read", &error))?;
        Ok(cal.code_to_volts(code))
    }

    fn write_analog(&mut self, channel: &AnalogChannel, volts: f64) -> Result<(), DaqError> {
        let cal = self.calibration(channel, true)?;
        write_code(&mut self.lib, &self.device, channel, &cal, volts)
    }

    fn write_digital(&mut self, line: &DigitalLine, high: bool) -> Result<(), DaqError> {
        if !self.lines.contains(line) {
            self.configure_line(line)?;
            self.lines.push(*line);
        }
        self.lib
            .dio_write(line.subdevice, line.channel, high)
            .map_err(|error| io_error(&self.device, line.name(), "write", &error))
    }

    fn output_handle(&self, channel: &AnalogChannel) -> Result<Box<dyn OutputHandle>, DaqError> {
        let lib = self
            .lib
            .reopen()
            .map_err(|error| open_error(&self.device, &error))?;
        // Validated on the new instance: it is the one that will write.
        let cal = resolve_analog(&lib, &self.device, &self.board, channel, true)?;
        Ok(Box::new(ComediOutput {
            device: self.device.clone(),
            channel: *channel,
            cal,
            lib: Mutex::new(lib),
        }))
    }
}

/// Converts and writes one analog output (shared by [`ComediDaq`] and [`ComediOutput`]).
/// Nothing reaches the library when the value is refused.
fn write_code<L: ComediLib>(
    lib: &mut L,
    device: &str,
    channel: &AnalogChannel,
    cal: &ChannelCal,
    volts: f64,
) -> Result<(), DaqError> {
    let code = cal.volts_to_code(device, volts)?;
    lib.data_write(
        channel.subdevice,
        channel.channel,
        channel.range,
        channel.aref.comedi(),
        code,
    )
    .map_err(|error| io_error(device, cal.name, "write", &error))
}

/// One analog output on its own opened instance of the device, for the watchdog and the
/// panic hook. The mutex serialises those two; the control loop never takes it, so a loop
/// blocked inside a call on its own instance does not block a vent.
struct ComediOutput<L: ComediLib> {
    device: String,
    channel: AnalogChannel,
    cal: ChannelCal,
    lib: Mutex<L>,
}

impl<L: ComediLib> OutputHandle for ComediOutput<L> {
    fn write(&self, volts: f64) -> Result<(), DaqError> {
        // A poisoned lock only means that another writer panicked; the instance itself is
        // intact (a write is one library call), and venting must still work from the panic
        // hook, so the poison is ignored.
        let mut lib = self.lib.lock().unwrap_or_else(PoisonError::into_inner);
        write_code(&mut *lib, &self.device, &self.channel, &self.cal, volts)
    }
}

/// The validation of one channel against the board, with its name for the errors.
struct Probe<'a, L> {
    lib: &'a L,
    device: &'a str,
    board: &'a str,
    name: ChannelName,
}

impl<L: ComediLib> Probe<'_, L> {
    /// A `Channel` error about this channel.
    fn error(&self, message: String) -> DaqError {
        DaqError::Channel {
            device: self.device.to_owned(),
            channel: self.name,
            message,
        }
    }

    /// A `Channel` error for a failed query.
    fn query_failed(&self, error: &ComediError) -> DaqError {
        self.error(format!("cannot query the board: {error}"))
    }

    /// The subdevice exists and is of `kind`.
    fn subdevice_of_kind(&self, kind: SubdeviceKind) -> Result<(), DaqError> {
        let subdevice = self.name.subdevice;
        let count = self.lib.n_subdevices().map_err(|e| self.query_failed(&e))?;
        if subdevice >= count {
            return Err(self.error(format!(
                "no subdevice {subdevice}: the board ({}) has {count} (0 to {})",
                self.board,
                count.saturating_sub(1)
            )));
        }
        let actual = self
            .lib
            .subdevice_kind(subdevice)
            .map_err(|e| self.query_failed(&e))?;
        if actual != kind {
            return Err(self.error(format!(
                "subdevice {subdevice} of the board ({}) is of type {actual}, not {kind}",
                self.board
            )));
        }
        Ok(())
    }

    /// The channel exists in its subdevice.
    fn channel_exists(&self) -> Result<(), DaqError> {
        let ChannelName {
            subdevice, channel, ..
        } = self.name;
        let count = self
            .lib
            .n_channels(subdevice)
            .map_err(|e| self.query_failed(&e))?;
        if channel >= count {
            return Err(self.error(format!(
                "no channel {channel}: subdevice {subdevice} has {count} channels (0 to {})",
                count.saturating_sub(1)
            )));
        }
        Ok(())
    }

    /// The range index exists for the channel and is in volts.
    fn range_in_volts(&self, index: u32) -> Result<Range, DaqError> {
        let ChannelName {
            subdevice, channel, ..
        } = self.name;
        let count = self
            .lib
            .n_ranges(subdevice, channel)
            .map_err(|e| self.query_failed(&e))?;
        if index >= count {
            return Err(self.error(format!(
                "no range {index}: the channel has {count} ranges (0 to {})",
                count.saturating_sub(1)
            )));
        }
        let range = self
            .lib
            .range(subdevice, channel, index)
            .map_err(|e| self.query_failed(&e))?;
        if range.unit != RangeUnit::Volt {
            return Err(self.error(format!(
                "range {index} ({}..{} {}) is not in volts",
                range.min, range.max, range.unit
            )));
        }
        Ok(range)
    }
}

/// Validates an analog channel as an output (`output`) or an input (subdevice of the right
/// type, channel, range in volts) and reads what its conversions need.
fn resolve_analog<L: ComediLib>(
    lib: &L,
    device: &str,
    board: &str,
    channel: &AnalogChannel,
    output: bool,
) -> Result<ChannelCal, DaqError> {
    let (name, kind, conversion) = if output {
        (
            channel.output_name(),
            SubdeviceKind::AnalogOutput,
            ConversionDirection::FromPhysical,
        )
    } else {
        (
            channel.input_name(),
            SubdeviceKind::AnalogInput,
            ConversionDirection::ToPhysical,
        )
    };
    let probe = Probe {
        lib,
        device,
        board,
        name,
    };
    probe.subdevice_of_kind(kind)?;
    probe.channel_exists()?;
    let range = probe.range_in_volts(channel.range)?;
    let maxdata = lib
        .maxdata(channel.subdevice, channel.channel)
        .map_err(|e| probe.query_failed(&e))?;
    let polynomial = lib.hardcal(
        channel.subdevice,
        channel.channel,
        channel.range,
        conversion,
    );
    Ok(ChannelCal {
        name,
        range_index: channel.range,
        range,
        maxdata,
        polynomial,
    })
}

/// A failed read or write.
fn io_error(
    device: &str,
    channel: ChannelName,
    operation: &'static str,
    error: &ComediError,
) -> DaqError {
    DaqError::Io {
        device: device.to_owned(),
        channel,
        operation,
        message: error.message.clone(),
    }
}

/// A failed open, with what to do about the usual causes.
fn open_error(device: &str, error: &ComediError) -> DaqError {
    let hint = match error.errno {
        libc::ENOENT => {
            ": no such device. Is the board's kernel driver loaded (`lsmod | grep comedi`, \
             `sudo modprobe ni_pcimio`), and did udev create the node, or does it need \
             `comedi_config`? `ls /dev/comedi*` lists the devices"
        }
        libc::EACCES | libc::EPERM => {
            ": permission denied. Add the user to the device's group, usually `iocard` \
             (`sudo usermod -aG iocard $USER`, then log in again), or run with the needed rights"
        }
        libc::ENODEV | libc::ENXIO => {
            ": the device node exists but no board is attached to it. Attach one with \
             `comedi_config`, e.g. `sudo comedi_config /dev/comedi0 ni_pcimio`"
        }
        _ => "",
    };
    DaqError::Open {
        device: device.to_owned(),
        message: format!("{error}{hint}"),
    }
}

/// The Comedi device at `path` (`/dev/comedi0`) as a [`Daq`], with the real libcomedi.
/// Without the `comedi` feature, an [`DaqError::Unsupported`] that says how to rebuild.
pub fn open_comedi(path: &str) -> Result<Box<dyn Daq>, DaqError> {
    #[cfg(feature = "comedi")]
    {
        Ok(Box::new(ComediDaq::<ffi::FfiLib>::open(path)?))
    }
    #[cfg(not(feature = "comedi"))]
    {
        let _ = path;
        Err(DaqError::Unsupported(String::from(
            "this pma-exo was built without Comedi support: rebuild with \
             `cargo build --release --features comedi` (needs `apt install libcomedi-dev`)",
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::fake::{lock, FakeBoard, FakeHardcal, FakeLib, FakeOp};
    use super::*;
    use crate::daq::Aref;

    const MAXDATA: u32 = 65535;
    const DEVICE: &str = "/dev/comedi0";
    /// One 16-bit LSB of the 0..10 V range.
    const LSB_10V: f64 = 10.0 / 65535.0;

    fn ai(channel: u32, range: u32) -> AnalogChannel {
        AnalogChannel {
            subdevice: 0,
            channel,
            range,
            aref: Aref::Ground,
        }
    }

    fn ao(channel: u32, range: u32) -> AnalogChannel {
        AnalogChannel {
            subdevice: 1,
            channel,
            range,
            aref: Aref::Ground,
        }
    }

    fn line(channel: u32) -> DigitalLine {
        DigitalLine {
            subdevice: 2,
            channel,
        }
    }

    /// A checked daq on a fake PCI-6052E (AI 0 and 1 on 0..10 V, AO 0 on 0..10 V, AO 1 on
    /// ±10 V, DIO line 0), with the fake's board for inspection.
    fn rig_with(board: FakeBoard) -> (ComediDaq<FakeLib>, std::sync::Arc<Mutex<FakeBoard>>) {
        let lib = FakeLib::new(board);
        let shared = lib.shared();
        let mut daq = ComediDaq::from_lib(DEVICE, lib);
        let checked = daq.check(&[ai(0, 9), ai(1, 9)], &[ao(0, 1), ao(1, 0)], &[line(0)]);
        assert_eq!(checked, Ok(()));
        (daq, shared)
    }

    fn rig() -> (ComediDaq<FakeLib>, std::sync::Arc<Mutex<FakeBoard>>) {
        rig_with(FakeBoard::pci6052e())
    }

    /// The `Channel` error of a check with these channels, as (channel, message).
    fn check_error(
        inputs: &[AnalogChannel],
        outputs: &[AnalogChannel],
        lines: &[DigitalLine],
    ) -> (ChannelName, String) {
        let mut daq = ComediDaq::from_lib(DEVICE, FakeLib::pci6052e());
        match daq.check(inputs, outputs, lines) {
            Err(DaqError::Channel {
                device,
                channel,
                message,
            }) => {
                assert_eq!(device, DEVICE);
                (channel, message)
            }
            other => panic!("expected a channel error, got {other:?}"),
        }
    }

    // --- conversions -------------------------------------------------------------------

    #[test]
    fn linear_conversion_at_the_ends_and_midpoint_of_a_unipolar_range() {
        let range = Range::volts(0.0, 10.0);
        assert_eq!(to_phys(0, &range, MAXDATA), 0.0);
        assert_eq!(to_phys(MAXDATA, &range, MAXDATA), 10.0);
        assert!((to_phys(32768, &range, MAXDATA) - 5.0).abs() < LSB_10V);
        assert_eq!(from_phys(0.0, &range, MAXDATA), 0);
        assert_eq!(from_phys(10.0, &range, MAXDATA), MAXDATA);
        // 5 V is code 32767.5: comedilib's floor(s + 0.5) rounds the half up.
        assert_eq!(from_phys(5.0, &range, MAXDATA), 32768);
    }

    #[test]
    fn linear_conversion_at_the_ends_and_midpoint_of_a_bipolar_range() {
        let range = Range::volts(-10.0, 10.0);
        let lsb = 20.0 / 65535.0;
        assert_eq!(to_phys(0, &range, MAXDATA), -10.0);
        assert_eq!(to_phys(MAXDATA, &range, MAXDATA), 10.0);
        assert!(to_phys(32767, &range, MAXDATA) < 0.0);
        assert!(to_phys(32768, &range, MAXDATA) > 0.0);
        assert!(to_phys(32768, &range, MAXDATA) < lsb);
        assert_eq!(from_phys(-10.0, &range, MAXDATA), 0);
        assert_eq!(from_phys(10.0, &range, MAXDATA), MAXDATA);
        assert_eq!(from_phys(0.0, &range, MAXDATA), 32768);
    }

    #[test]
    fn linear_round_trips_are_within_half_an_lsb() {
        for range in [
            Range::volts(0.0, 10.0),
            Range::volts(-10.0, 10.0),
            Range::volts(-0.05, 0.05),
        ] {
            let lsb = (range.max - range.min) / f64::from(MAXDATA);
            for step in 0..=1000 {
                let volts = range.min + (range.max - range.min) * f64::from(step) / 1000.0;
                let code = from_phys(volts, &range, MAXDATA);
                let back = to_phys(code, &range, MAXDATA);
                assert!(
                    (back - volts).abs() <= 0.5 * lsb * (1.0 + 1e-9),
                    "{volts} -> {code} -> {back}"
                );
            }
            for code in [0, 1, 12345, 32767, 32768, 65534, MAXDATA] {
                assert_eq!(
                    from_phys(to_phys(code, &range, MAXDATA), &range, MAXDATA),
                    code
                );
            }
        }
    }

    #[test]
    fn from_phys_clamps_to_the_codes_and_maps_nan_to_zero() {
        let range = Range::volts(0.0, 10.0);
        assert_eq!(from_phys(-0.1, &range, MAXDATA), 0);
        assert_eq!(from_phys(-1e300, &range, MAXDATA), 0);
        assert_eq!(from_phys(10.1, &range, MAXDATA), MAXDATA);
        assert_eq!(from_phys(f64::INFINITY, &range, MAXDATA), MAXDATA);
        assert_eq!(from_phys(f64::NAN, &range, MAXDATA), 0);
        // comedilib's answers for a zero maxdata.
        assert_eq!(from_phys(5.0, &range, 0), 0);
        assert!(to_phys(5, &range, 0).is_nan());
    }

    #[test]
    fn saturation_is_either_end_of_the_scale() {
        assert!(is_saturated(0, MAXDATA));
        assert!(is_saturated(MAXDATA, MAXDATA));
        assert!(!is_saturated(1, MAXDATA));
        assert!(!is_saturated(MAXDATA - 1, MAXDATA));
    }

    #[test]
    fn polynomial_conversion_follows_comedilib() {
        // 0.5 + 2 (x - 1) + 0.25 (x - 1)^2 - 0.125 (x - 1)^3
        let cubic = Polynomial {
            coefficients: [0.5, 2.0, 0.25, -0.125],
            expansion_origin: 1.0,
            order: 3,
        };
        assert_eq!(cubic.eval(1.0), 0.5);
        assert_eq!(cubic.eval(3.0), 0.5 + 4.0 + 1.0 - 1.0);
        assert_eq!(cubic.to_physical(3), 4.5);
        // The order limits the terms used.
        let linear = Polynomial { order: 1, ..cubic };
        assert_eq!(linear.eval(3.0), 4.5);
        // from_physical rounds to nearest, ties to even (nearbyint), and clamps.
        let scale = Polynomial {
            coefficients: [0.0, 1.0, 0.0, 0.0],
            expansion_origin: 0.0,
            order: 1,
        };
        assert_eq!(scale.from_physical(2.5, 10), 2);
        assert_eq!(scale.from_physical(3.5, 10), 4);
        assert_eq!(scale.from_physical(3.4, 10), 3);
        assert_eq!(scale.from_physical(-3.0, 10), 0);
        assert_eq!(scale.from_physical(11.0, 10), 10);
        assert_eq!(scale.from_physical(f64::NAN, 10), 0);
    }

    #[test]
    fn the_nominal_hardcal_polynomials_match_the_linear_conversion() {
        // comedilib 0.11's `comedi_get_hardcal_converter`, for 0..10 V, 16 bit.
        let range = Range::volts(0.0, 10.0);
        let to = Polynomial {
            coefficients: [0.0, 10.0 / 65535.0, 0.0, 0.0],
            expansion_origin: 0.0,
            order: 1,
        };
        let from = Polynomial {
            coefficients: [0.0, 65535.0 / 10.0, 0.0, 0.0],
            expansion_origin: 0.0,
            order: 1,
        };
        for code in [1, 100, 32768, 65534] {
            assert!((to.to_physical(code) - to_phys(code, &range, MAXDATA)).abs() < 1e-12);
            assert_eq!(
                from.from_physical(to_phys(code, &range, MAXDATA), MAXDATA),
                code
            );
        }
    }

    // --- writes ------------------------------------------------------------------------

    #[test]
    fn nan_and_out_of_range_writes_are_refused_and_nothing_is_written() {
        let (mut daq, board) = rig();
        for volts in [f64::NAN, 10.0 + 1e-9, 12.0, -1e-9, -3.0, f64::INFINITY] {
            match daq.write_analog(&ao(0, 1), volts) {
                Err(DaqError::OutOfRange {
                    device,
                    channel,
                    volts: refused,
                    min_v,
                    max_v,
                }) => {
                    assert_eq!(device, DEVICE);
                    assert_eq!(channel, ao(0, 1).output_name());
                    assert!(
                        refused.is_nan() == volts.is_nan() && (volts.is_nan() || refused == volts)
                    );
                    assert_eq!((min_v, max_v), (0.0, 10.0));
                }
                other => panic!("{volts} V: expected OutOfRange, got {other:?}"),
            }
        }
        assert!(lock(&board).writes.is_empty());
        // The error names the channel.
        let message = daq
            .write_analog(&ao(0, 1), 11.0)
            .err()
            .map(|e| e.to_string());
        assert_eq!(
            message.as_deref(),
            Some("DAQ `/dev/comedi0`, analog output 1/0: 11 V is outside the channel's range 0..10 V")
        );
    }

    #[test]
    fn the_range_ends_are_writable() {
        let (mut daq, board) = rig();
        assert_eq!(daq.write_analog(&ao(0, 1), 0.0), Ok(()));
        assert_eq!(daq.write_analog(&ao(0, 1), 10.0), Ok(()));
        assert_eq!(daq.write_analog(&ao(1, 0), -10.0), Ok(()));
        let codes: Vec<u32> = lock(&board).writes.iter().map(|w| w.code).collect();
        assert_eq!(codes, [0, MAXDATA, 0]);
    }

    #[test]
    fn loopback_reads_back_the_written_value_within_one_lsb() {
        for hardcal in [FakeHardcal::None, FakeHardcal::Nominal] {
            let (mut daq, _board) = rig_with(FakeBoard {
                hardcal,
                ..FakeBoard::pci6052e()
            });
            for volts in [0.001, 1.0, 3.3, 5.0, 7.77, 9.999] {
                assert_eq!(daq.write_analog(&ao(0, 1), volts), Ok(()));
                let read = daq.read_analog(&ai(0, 9));
                let read = read.unwrap_or(f64::NAN);
                assert!(
                    (read - volts).abs() <= LSB_10V,
                    "{hardcal:?}: wrote {volts}, read {read}"
                );
            }
        }
    }

    #[test]
    fn a_bipolar_output_loops_back_to_a_bipolar_input() {
        let (mut daq, _board) = rig();
        assert_eq!(daq.write_analog(&ao(1, 0), -4.2), Ok(()));
        let read = daq.read_analog(&ai(1, 0)).unwrap_or(f64::NAN);
        assert!((read + 4.2).abs() <= 20.0 / 65535.0, "{read}");
    }

    #[test]
    fn a_saturated_reading_is_nan() {
        let (mut daq, board) = rig();
        // The full-scale output saturates the 0..10 V input at maxdata, 0 V at code 0.
        assert_eq!(daq.write_analog(&ao(0, 1), 10.0), Ok(()));
        assert!(daq.read_analog(&ai(0, 9)).is_ok_and(f64::is_nan));
        assert_eq!(daq.write_analog(&ao(0, 1), 0.0), Ok(()));
        assert!(daq.read_analog(&ai(0, 9)).is_ok_and(f64::is_nan));
        // So does a code forced at the top, even where a larger range would not saturate.
        lock(&board).forced_codes[1] = Some(MAXDATA);
        assert!(daq.read_analog(&ai(1, 9)).is_ok_and(f64::is_nan));
        lock(&board).forced_codes[1] = Some(MAXDATA - 1);
        assert!(daq
            .read_analog(&ai(1, 9))
            .is_ok_and(|v| (v - (10.0 - LSB_10V)).abs() < 1e-9));
    }

    #[test]
    fn inputs_without_a_loopback_read_the_constant() {
        let (mut daq, board) = rig();
        lock(&board).other_input_volts = 2.5;
        let read = daq.read_analog(&ai(7, 9)).unwrap_or(f64::NAN);
        assert!((read - 2.5).abs() <= LSB_10V, "{read}");
    }

    #[test]
    fn the_hardcal_polynomial_is_used_when_the_board_has_one() {
        // A board whose calibration says: volts = 1 + 0.001 code (an offset and a gain the
        // linear conversion would not apply), code = round(1000 (volts - 1)).
        let polynomials = FakeHardcal::Fixed {
            to_physical: Polynomial {
                coefficients: [1.0, 0.001, 0.0, 0.0],
                expansion_origin: 0.0,
                order: 1,
            },
            from_physical: Polynomial {
                coefficients: [0.0, 1000.0, 0.0, 0.0],
                expansion_origin: 1.0,
                order: 1,
            },
        };
        let (mut daq, board) = rig_with(FakeBoard {
            hardcal: polynomials,
            ..FakeBoard::pci6052e()
        });
        lock(&board).forced_codes[0] = Some(2000);
        assert_eq!(daq.read_analog(&ai(0, 9)), Ok(3.0));
        assert_eq!(daq.write_analog(&ao(0, 1), 4.0), Ok(()));
        assert_eq!(lock(&board).writes.last().map(|w| w.code), Some(3000));
    }

    // --- check ---------------------------------------------------------------------------

    #[test]
    fn check_rejects_a_missing_subdevice() {
        let channel = AnalogChannel {
            subdevice: 9,
            ..ai(0, 9)
        };
        let (name, message) = check_error(&[channel], &[], &[]);
        assert_eq!(name, channel.input_name());
        assert!(message.contains("no subdevice 9"), "{message}");
        assert!(message.contains("has 5"), "{message}");
    }

    #[test]
    fn check_rejects_a_channel_out_of_range() {
        let (name, message) = check_error(&[], &[ao(2, 1)], &[]);
        assert_eq!(name, ao(2, 1).output_name());
        assert!(message.contains("no channel 2"), "{message}");
        assert!(message.contains("2 channels"), "{message}");
        let (name, message) = check_error(&[], &[], &[line(8)]);
        assert_eq!(name, line(8).name());
        assert!(message.contains("no channel 8"), "{message}");
    }

    #[test]
    fn check_rejects_a_range_index_out_of_range() {
        let (name, message) = check_error(&[ai(3, 16)], &[], &[]);
        assert_eq!(name, ai(3, 16).input_name());
        assert!(message.contains("no range 16"), "{message}");
        assert!(message.contains("16 ranges"), "{message}");
    }

    #[test]
    fn check_rejects_a_subdevice_of_the_wrong_type() {
        // The analog input subdevice used as an output.
        let output = AnalogChannel {
            subdevice: 0,
            ..ao(0, 1)
        };
        let (name, message) = check_error(&[], &[output], &[]);
        assert_eq!(name, output.output_name());
        assert!(
            message.contains("is of type analog input, not analog output"),
            "{message}"
        );
        // The analog output subdevice used as an input.
        let input = AnalogChannel {
            subdevice: 1,
            ..ai(0, 1)
        };
        let (name, message) = check_error(&[input], &[], &[]);
        assert_eq!(name, input.input_name());
        assert!(message.contains("not analog input"), "{message}");
        // A calibration subdevice as a digital line.
        let calibration = DigitalLine {
            subdevice: 4,
            channel: 0,
        };
        let (name, message) = check_error(&[], &[], &[calibration]);
        assert_eq!(name, calibration.name());
        assert!(message.contains("calibration"), "{message}");
    }

    #[test]
    fn check_rejects_a_range_that_is_not_in_volts() {
        let mut board = FakeBoard::pci6052e();
        board.subdevices[0].ranges[15].unit = RangeUnit::MilliAmp;
        let mut daq = ComediDaq::from_lib(DEVICE, FakeLib::new(board));
        let result = daq.check(&[ai(0, 15)], &[], &[]);
        assert!(
            matches!(&result, Err(DaqError::Channel { message, .. }) if message.contains("not in volts")),
            "{result:?}"
        );
    }

    #[test]
    fn check_configures_the_digital_lines_as_outputs() {
        let (mut daq, board) = rig();
        assert_eq!(lock(&board).dio_outputs, [(2, 0)]);
        assert_eq!(daq.write_digital(&line(0), true), Ok(()));
        // A line that check did not see is configured at its first use.
        assert_eq!(daq.write_digital(&line(5), false), Ok(()));
        let state = lock(&board);
        assert_eq!(state.dio_outputs, [(2, 0), (2, 5)]);
        assert_eq!(state.dio_writes, [(2, 0, true), (2, 5, false)]);
    }

    #[test]
    fn range_v_reports_the_board_ranges() {
        let (mut daq, _board) = rig();
        assert_eq!(daq.range_v(&ai(0, 9), false), Ok((0.0, 10.0)));
        assert_eq!(daq.range_v(&ao(1, 0), true), Ok((-10.0, 10.0)));
        assert_eq!(daq.range_v(&ai(4, 3), false), Ok((-1.0, 1.0)));
        assert!(matches!(
            daq.range_v(&ai(0, 9), true),
            Err(DaqError::Channel { .. })
        ));
    }

    // --- failures ------------------------------------------------------------------------

    #[test]
    fn an_injected_eio_is_an_io_error_naming_everything() {
        let (mut daq, board) = rig();
        lock(&board).fail_next(FakeOp::Read, 0, 1, libc::EIO);
        let expected = DaqError::Io {
            device: DEVICE.to_owned(),
            channel: ai(1, 9).input_name(),
            operation: "read",
            message: String::from("Input/output error"),
        };
        assert_eq!(daq.read_analog(&ai(1, 9)), Err(expected.clone()));
        assert_eq!(
            expected.to_string(),
            "DAQ `/dev/comedi0`, analog input 0/1: read failed: Input/output error"
        );
        // One failure only; the next read works.
        assert!(daq.read_analog(&ai(1, 9)).is_ok());

        lock(&board).fail_next(FakeOp::Write, 1, 0, libc::EIO);
        assert_eq!(
            daq.write_analog(&ao(0, 1), 1.0),
            Err(DaqError::Io {
                device: DEVICE.to_owned(),
                channel: ao(0, 1).output_name(),
                operation: "write",
                message: String::from("Input/output error"),
            })
        );
        lock(&board).fail_next(FakeOp::DioWrite, 2, 0, libc::EIO);
        assert!(matches!(
            daq.write_digital(&line(0), true),
            Err(DaqError::Io { operation: "write", channel, .. }) if channel == line(0).name()
        ));
    }

    #[test]
    fn a_failed_dio_config_fails_the_check() {
        let mut board = FakeBoard::pci6052e();
        board.fail_next(FakeOp::DioConfig, 2, 3, libc::EBUSY);
        let mut daq = ComediDaq::from_lib(DEVICE, FakeLib::new(board));
        assert_eq!(
            daq.check(&[], &[], &[line(3)]),
            Err(DaqError::Io {
                device: DEVICE.to_owned(),
                channel: line(3).name(),
                operation: "configure as output",
                message: String::from("Device or resource busy"),
            })
        );
    }

    // --- output handle ---------------------------------------------------------------------

    #[test]
    fn the_output_handle_writes_through_its_own_instance() {
        let (daq, board) = rig();
        let handle = match daq.output_handle(&ao(0, 1)) {
            Ok(handle) => handle,
            Err(error) => panic!("no output handle: {error}"),
        };
        assert_eq!(handle.write(2.0), Ok(()));
        assert!(matches!(
            handle.write(-1.0),
            Err(DaqError::OutOfRange { .. })
        ));
        // From another thread too (the watchdog's).
        std::thread::scope(|scope| {
            scope.spawn(|| assert_eq!(handle.write(0.0), Ok(())));
        });
        let state = lock(&board);
        assert_eq!(state.instances, 2);
        let writers: Vec<(u32, u32)> = state.writes.iter().map(|w| (w.instance, w.code)).collect();
        assert_eq!(
            writers,
            [
                (1, from_phys(2.0, &Range::volts(0.0, 10.0), MAXDATA)),
                (1, 0)
            ]
        );
    }

    #[test]
    fn the_output_handle_validates_its_channel_and_reports_a_failed_open() {
        let (daq, board) = rig();
        assert!(matches!(
            daq.output_handle(&ao(5, 1)).err(),
            Some(DaqError::Channel { channel, .. }) if channel == ao(5, 1).output_name()
        ));
        lock(&board).reopen_failure = Some(libc::EACCES);
        match daq.output_handle(&ao(0, 1)).err() {
            Some(DaqError::Open { device, message }) => {
                assert_eq!(device, DEVICE);
                assert!(message.contains("iocard"), "{message}");
            }
            other => panic!("expected an open error, got {other:?}"),
        }
    }

    // --- open ----------------------------------------------------------------------------

    #[test]
    fn open_errors_name_the_device_and_say_what_to_do() {
        match ComediDaq::<FakeLib>::open("/dev/nothing-here").err() {
            Some(DaqError::Open { device, message }) => {
                assert_eq!(device, "/dev/nothing-here");
                assert!(message.contains("No such file or directory"), "{message}");
                assert!(message.contains("kernel driver"), "{message}");
            }
            other => panic!("expected an open error, got {other:?}"),
        }
        let denied = ComediError {
            call: "comedi_open",
            errno: libc::EACCES,
            message: String::from("Permission denied"),
        };
        let error = open_error(DEVICE, &denied).to_string();
        assert!(
            error.starts_with(
                "cannot open DAQ device `/dev/comedi0`: comedi_open: Permission denied"
            ),
            "{error}"
        );
        assert!(error.contains("group, usually `iocard`"), "{error}");
    }

    #[test]
    fn open_gives_the_board_name() {
        let daq = ComediDaq::<FakeLib>::open(DEVICE);
        assert_eq!(daq.as_ref().map(|daq| daq.board()), Ok("pci-6052e"));
        assert_eq!(daq.as_ref().map(|daq| daq.device()), Ok(DEVICE));
    }

    #[cfg(not(feature = "comedi"))]
    #[test]
    fn without_the_feature_open_comedi_says_how_to_rebuild() {
        match open_comedi(DEVICE).err() {
            Some(DaqError::Unsupported(message)) => {
                assert!(message.contains("--features comedi"), "{message}");
                assert!(message.contains("libcomedi-dev"), "{message}");
            }
            other => panic!(
                "expected Unsupported, got {:?}",
                other.map(|e| e.to_string())
            ),
        }
    }
}
