//! A fake libcomedi for the tests: an NI PCI-6052E whose analog outputs are wired back to
//! its analog inputs, the way Comedi's `comedi_test` kernel driver loops AO channel n back
//! to AI channel n. Compiled for the tests only (`#[cfg(test)]` in `mod.rs`), so it is not
//! part of the crate's API.
//!
//! Layout (as `ni_pcimio` reports the board, first five subdevices):
//! - 0: AI, 16 channels, 16 bit, ranges 0-7 = ±10, ±5, ±2.5, ±1, ±0.5, ±0.25, ±0.1,
//!   ±0.05 V and 8-15 = 0..20, 0..10, 0..5, 0..2, 0..1, 0..0.5, 0..0.2, 0..0.1 V;
//! - 1: AO, 2 channels, 16 bit, range 0 = ±10 V, 1 = 0..10 V;
//! - 2: DIO, 8 lines;
//! - 3: unused (the 8255 slot of the M-series layout);
//! - 4: calibration DACs.
//!
//! Physics: an AO channel holds the voltage of its last write (0 V at power-up); AI channel
//! n < 2 digitises AO channel n's voltage, AI channels >= 2 a constant
//! ([`FakeBoard::other_input_volts`]); the converter saturates at 0 and `maxdata`. Every
//! instance opened on one board ([`ComediLib::reopen`]) shares that board, as two
//! `comedi_open` calls on one device node do.

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use super::{
    from_phys, to_phys, ComediError, ComediLib, ConversionDirection, Polynomial, Range, RangeUnit,
    SubdeviceKind,
};

/// comedilib's "Invalid subdevice" (`EINVAL_SUBD`).
const EINVAL_SUBD: i32 = 0x1003;
/// comedilib's "Invalid channel" (`EINVAL_CHAN`).
const EINVAL_CHAN: i32 = 0x1004;

/// The calls a failure can be injected into.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum FakeOp {
    /// `comedi_data_read`.
    Read,
    /// `comedi_data_write`.
    Write,
    /// `comedi_dio_config`.
    DioConfig,
    /// `comedi_dio_write`.
    DioWrite,
}

/// What the board's hardware calibration converter gives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum FakeHardcal {
    /// No polynomial: the linear `comedi_to_phys`/`comedi_from_phys` apply.
    None,
    /// The polynomial comedilib 0.11 computes from the range and `maxdata`.
    Nominal,
    /// These polynomials for every channel and range.
    Fixed {
        /// Code to volts.
        to_physical: Polynomial,
        /// Volts to code.
        from_physical: Polynomial,
    },
}

/// A successful `comedi_data_write`, as recorded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct FakeWrite {
    /// Which opened instance wrote (0 = the first).
    pub instance: u32,
    /// Subdevice.
    pub subdevice: u32,
    /// Channel.
    pub channel: u32,
    /// Range index.
    pub range: u32,
    /// Analog reference.
    pub aref: u32,
    /// The raw code.
    pub code: u32,
}

/// One subdevice of the fake board.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct FakeSubdevice {
    /// Its type.
    pub kind: SubdeviceKind,
    /// Number of channels.
    pub n_channels: u32,
    /// Largest code.
    pub maxdata: u32,
    /// Its ranges (the same for every channel).
    pub ranges: Vec<Range>,
}

/// The state of the fake board, shared by every instance opened on it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct FakeBoard {
    /// `comedi_get_board_name`.
    pub name: String,
    /// The subdevices.
    pub subdevices: Vec<FakeSubdevice>,
    /// The voltage each AO channel drives (and its AI twin reads).
    pub output_volts: Vec<f64>,
    /// What AI channels without an AO twin read (V).
    pub other_input_volts: f64,
    /// Raw codes that AI channels return instead of digitising (index = channel).
    pub forced_codes: Vec<Option<u32>>,
    /// The hardware-calibration converter.
    pub hardcal: FakeHardcal,
    /// Failures for the next matching call: (call, subdevice, channel, errno); each fires once.
    pub failures: Vec<(FakeOp, u32, u32, i32)>,
    /// The errno of the next `reopen`, if it is to fail.
    pub reopen_failure: Option<i32>,
    /// Every successful analog write.
    pub writes: Vec<FakeWrite>,
    /// DIO lines configured as outputs: (subdevice, channel).
    pub dio_outputs: Vec<(u32, u32)>,
    /// Every successful DIO write: (subdevice, channel, high).
    pub dio_writes: Vec<(u32, u32, bool)>,
    /// How many instances have been opened.
    pub instances: u32,
}

impl FakeBoard {
    /// A PCI-6052E with its outputs at 0 V and no hardware-calibration polynomial.
    pub fn pci6052e() -> Self {
        let bipolar = [10.0, 5.0, 2.5, 1.0, 0.5, 0.25, 0.1, 0.05];
        let unipolar = [20.0, 10.0, 5.0, 2.0, 1.0, 0.5, 0.2, 0.1];
        let ai_ranges = bipolar
            .iter()
            .map(|&v| Range::volts(-v, v))
            .chain(unipolar.iter().map(|&v| Range::volts(0.0, v)))
            .collect();
        let subdevices = vec![
            FakeSubdevice {
                kind: SubdeviceKind::AnalogInput,
                n_channels: 16,
                maxdata: 65535,
                ranges: ai_ranges,
            },
            FakeSubdevice {
                kind: SubdeviceKind::AnalogOutput,
                n_channels: 2,
                maxdata: 65535,
                ranges: vec![Range::volts(-10.0, 10.0), Range::volts(0.0, 10.0)],
            },
            FakeSubdevice {
                kind: SubdeviceKind::DigitalIo,
                n_channels: 8,
                maxdata: 1,
                ranges: vec![Range::volts(0.0, 1.0)],
            },
            FakeSubdevice {
                kind: SubdeviceKind::Unused,
                n_channels: 0,
                maxdata: 0,
                ranges: Vec::new(),
            },
            FakeSubdevice {
                kind: SubdeviceKind::Calibration,
                n_channels: 12,
                maxdata: 255,
                ranges: vec![Range {
                    min: 0.0,
                    max: 1.0,
                    unit: RangeUnit::None,
                }],
            },
        ];
        Self {
            name: String::from("pci-6052e"),
            subdevices,
            output_volts: vec![0.0; 2],
            other_input_volts: 1.25,
            forced_codes: vec![None; 16],
            hardcal: FakeHardcal::None,
            failures: Vec::new(),
            reopen_failure: None,
            writes: Vec::new(),
            dio_outputs: Vec::new(),
            dio_writes: Vec::new(),
            instances: 0,
        }
    }

    /// Makes the next `op` on (subdevice, channel) fail with `errno`.
    pub fn fail_next(&mut self, op: FakeOp, subdevice: u32, channel: u32, errno: i32) {
        self.failures.push((op, subdevice, channel, errno));
    }

    /// Takes the injected failure for this call, if any.
    fn take_failure(
        &mut self,
        op: FakeOp,
        subdevice: u32,
        channel: u32,
        call: &'static str,
    ) -> Result<(), ComediError> {
        let position = self
            .failures
            .iter()
            .position(|&(o, s, c, _)| o == op && s == subdevice && c == channel);
        match position {
            Some(index) => Err(error(call, self.failures.remove(index).3)),
            None => Ok(()),
        }
    }

    /// The subdevice, or comedilib's "Invalid subdevice".
    fn subdevice(&self, subdevice: u32, call: &'static str) -> Result<&FakeSubdevice, ComediError> {
        self.subdevices
            .get(subdevice as usize)
            .ok_or_else(|| error(call, EINVAL_SUBD))
    }

    /// The subdevice if the channel exists in it, or comedilib's "Invalid channel".
    fn channel(
        &self,
        subdevice: u32,
        channel: u32,
        call: &'static str,
    ) -> Result<&FakeSubdevice, ComediError> {
        let sub = self.subdevice(subdevice, call)?;
        if channel < sub.n_channels {
            Ok(sub)
        } else {
            Err(error(call, EINVAL_CHAN))
        }
    }

    /// The subdevice if it is of `kind` and has the channel.
    fn typed_channel(
        &self,
        kind: SubdeviceKind,
        subdevice: u32,
        channel: u32,
        call: &'static str,
    ) -> Result<&FakeSubdevice, ComediError> {
        let sub = self.channel(subdevice, channel, call)?;
        if sub.kind == kind {
            Ok(sub)
        } else {
            Err(error(call, libc::EINVAL))
        }
    }

    /// A range, or EINVAL (comedilib returns NULL).
    fn range(
        &self,
        subdevice: u32,
        channel: u32,
        range: u32,
        call: &'static str,
    ) -> Result<Range, ComediError> {
        let sub = self.channel(subdevice, channel, call)?;
        sub.ranges
            .get(range as usize)
            .copied()
            .ok_or_else(|| error(call, libc::EINVAL))
    }

    /// The code an AI channel returns: its forced code, or the voltage it sees digitised.
    fn sample(&self, channel: u32, range: &Range, maxdata: u32) -> u32 {
        if let Some(Some(code)) = self.forced_codes.get(channel as usize) {
            return *code;
        }
        let volts = self
            .output_volts
            .get(channel as usize)
            .copied()
            .unwrap_or(self.other_input_volts);
        from_phys(volts, range, maxdata)
    }
}

/// An opened instance of a [`FakeBoard`].
#[derive(Debug)]
pub(crate) struct FakeLib {
    board: Arc<Mutex<FakeBoard>>,
    instance: u32,
}

impl FakeLib {
    /// The first instance on a new board.
    pub fn new(board: FakeBoard) -> Self {
        Self::attach(Arc::new(Mutex::new(board)))
    }

    /// The first instance on a new PCI-6052E.
    pub fn pci6052e() -> Self {
        Self::new(FakeBoard::pci6052e())
    }

    /// The board, shared with the test that inspects it.
    pub fn shared(&self) -> Arc<Mutex<FakeBoard>> {
        Arc::clone(&self.board)
    }

    /// A new instance on a board.
    fn attach(board: Arc<Mutex<FakeBoard>>) -> Self {
        let instance = {
            let mut state = lock(&board);
            state.instances += 1;
            state.instances - 1
        };
        Self { board, instance }
    }

    /// The board's state.
    fn state(&self) -> MutexGuard<'_, FakeBoard> {
        lock(&self.board)
    }
}

/// Locks the board; a test that panicked with it locked must not hide the others' results.
pub(crate) fn lock(board: &Mutex<FakeBoard>) -> MutexGuard<'_, FakeBoard> {
    board.lock().unwrap_or_else(PoisonError::into_inner)
}

/// A [`ComediError`] with the message `comedi_strerror` gives for `errno`.
fn error(call: &'static str, errno: i32) -> ComediError {
    let message = match errno {
        libc::EIO => "Input/output error",
        libc::ENOENT => "No such file or directory",
        libc::EACCES => "Permission denied",
        libc::EINVAL => "Invalid argument",
        libc::EBUSY => "Device or resource busy",
        libc::ENODEV => "No such device",
        EINVAL_SUBD => "Invalid subdevice",
        EINVAL_CHAN => "Invalid channel",
        _ => "Unknown error",
    };
    ComediError {
        call,
        errno,
        message: message.to_owned(),
    }
}

/// The polynomial comedilib 0.11's `comedi_get_hardcal_converter` computes (`lib/calib.c`).
fn nominal(range: &Range, maxdata: u32, direction: ConversionDirection) -> Polynomial {
    let span = range.max - range.min;
    let maxdata = f64::from(maxdata);
    match direction {
        ConversionDirection::ToPhysical => Polynomial {
            coefficients: [range.min, span / maxdata, 0.0, 0.0],
            expansion_origin: 0.0,
            order: 1,
        },
        ConversionDirection::FromPhysical => Polynomial {
            coefficients: [0.0, maxdata / span, 0.0, 0.0],
            expansion_origin: range.min,
            order: 1,
        },
    }
}

impl ComediLib for FakeLib {
    /// Device nodes `/dev/comedi*` open a new PCI-6052E; anything else does not exist.
    fn open(path: &str) -> Result<Self, ComediError> {
        if path.starts_with("/dev/comedi") {
            Ok(Self::pci6052e())
        } else {
            Err(error("comedi_open", libc::ENOENT))
        }
    }

    fn reopen(&self) -> Result<Self, ComediError> {
        if let Some(errno) = self.state().reopen_failure.take() {
            return Err(error("comedi_open", errno));
        }
        Ok(Self::attach(Arc::clone(&self.board)))
    }

    fn board_name(&self) -> Result<String, ComediError> {
        Ok(self.state().name.clone())
    }

    fn n_subdevices(&self) -> Result<u32, ComediError> {
        let count = self.state().subdevices.len();
        u32::try_from(count).map_err(|_| error("comedi_get_n_subdevices", libc::EINVAL))
    }

    fn subdevice_kind(&self, subdevice: u32) -> Result<SubdeviceKind, ComediError> {
        Ok(self
            .state()
            .subdevice(subdevice, "comedi_get_subdevice_type")?
            .kind)
    }

    fn n_channels(&self, subdevice: u32) -> Result<u32, ComediError> {
        Ok(self
            .state()
            .subdevice(subdevice, "comedi_get_n_channels")?
            .n_channels)
    }

    fn n_ranges(&self, subdevice: u32, channel: u32) -> Result<u32, ComediError> {
        let state = self.state();
        let sub = state.channel(subdevice, channel, "comedi_get_n_ranges")?;
        u32::try_from(sub.ranges.len()).map_err(|_| error("comedi_get_n_ranges", libc::EINVAL))
    }

    fn range(&self, subdevice: u32, channel: u32, range: u32) -> Result<Range, ComediError> {
        self.state()
            .range(subdevice, channel, range, "comedi_get_range")
    }

    fn maxdata(&self, subdevice: u32, channel: u32) -> Result<u32, ComediError> {
        Ok(self
            .state()
            .channel(subdevice, channel, "comedi_get_maxdata")?
            .maxdata)
    }

    fn hardcal(
        &self,
        subdevice: u32,
        channel: u32,
        range: u32,
        direction: ConversionDirection,
    ) -> Option<Polynomial> {
        let state = self.state();
        match state.hardcal {
            FakeHardcal::None => None,
            FakeHardcal::Nominal => {
                let range = state
                    .range(subdevice, channel, range, "comedi_get_hardcal_converter")
                    .ok()?;
                let maxdata = state
                    .channel(subdevice, channel, "comedi_get_hardcal_converter")
                    .ok()?
                    .maxdata;
                Some(nominal(&range, maxdata, direction))
            }
            FakeHardcal::Fixed {
                to_physical,
                from_physical,
            } => Some(match direction {
                ConversionDirection::ToPhysical => to_physical,
                ConversionDirection::FromPhysical => from_physical,
            }),
        }
    }

    fn data_read(
        &mut self,
        subdevice: u32,
        channel: u32,
        range: u32,
        _aref: u32,
    ) -> Result<u32, ComediError> {
        const CALL: &str = "comedi_data_read";
        let mut state = self.state();
        state.take_failure(FakeOp::Read, subdevice, channel, CALL)?;
        let maxdata = state
            .typed_channel(SubdeviceKind::AnalogInput, subdevice, channel, CALL)?
            .maxdata;
        let range = state.range(subdevice, channel, range, CALL)?;
        Ok(state.sample(channel, &range, maxdata))
    }

    fn data_write(
        &mut self,
        subdevice: u32,
        channel: u32,
        range: u32,
        aref: u32,
        code: u32,
    ) -> Result<(), ComediError> {
        const CALL: &str = "comedi_data_write";
        let instance = self.instance;
        let mut state = self.state();
        state.take_failure(FakeOp::Write, subdevice, channel, CALL)?;
        let maxdata = state
            .typed_channel(SubdeviceKind::AnalogOutput, subdevice, channel, CALL)?
            .maxdata;
        let volts_range = state.range(subdevice, channel, range, CALL)?;
        if code > maxdata {
            // The kernel masks codes to the DAC's width; a code above maxdata is a bug here.
            return Err(error(CALL, libc::EINVAL));
        }
        if let Some(volts) = state.output_volts.get_mut(channel as usize) {
            *volts = to_phys(code, &volts_range, maxdata);
        }
        state.writes.push(FakeWrite {
            instance,
            subdevice,
            channel,
            range,
            aref,
            code,
        });
        Ok(())
    }

    fn dio_config_output(&mut self, subdevice: u32, channel: u32) -> Result<(), ComediError> {
        const CALL: &str = "comedi_dio_config";
        let mut state = self.state();
        state.take_failure(FakeOp::DioConfig, subdevice, channel, CALL)?;
        state.typed_channel(SubdeviceKind::DigitalIo, subdevice, channel, CALL)?;
        if !state.dio_outputs.contains(&(subdevice, channel)) {
            state.dio_outputs.push((subdevice, channel));
        }
        Ok(())
    }

    fn dio_write(&mut self, subdevice: u32, channel: u32, high: bool) -> Result<(), ComediError> {
        const CALL: &str = "comedi_dio_write";
        let mut state = self.state();
        state.take_failure(FakeOp::DioWrite, subdevice, channel, CALL)?;
        state.typed_channel(SubdeviceKind::DigitalIo, subdevice, channel, CALL)?;
        state.dio_writes.push((subdevice, channel, high));
        Ok(())
    }
}
