//! The data-acquisition board, in volts: what every rig backend talks to.
use thiserror::Error;

/// Analog reference of a channel (Comedi's `AREF_*`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Aref {
    /// Referenced to analog ground (`AREF_GROUND` = 0).
    #[default]
    Ground,
    /// Referenced to analog common (`AREF_COMMON` = 1).
    Common,
    /// Differential (`AREF_DIFF` = 2).
    Diff,
}

impl Aref {
    /// Comedi's numeric value.
    pub fn comedi(self) -> u32 {
        match self {
            Aref::Ground => 0,
            Aref::Common => 1,
            Aref::Diff => 2,
        }
    }
}

/// An analog channel: subdevice, channel, range index and reference, as Comedi numbers them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnalogChannel {
    /// Subdevice index (PCI-6052E: 0 = AI, 1 = AO).
    pub subdevice: u32,
    /// Channel within the subdevice.
    pub channel: u32,
    /// Range index (PCI-6052E AI: 9 = 0..10 V; AO: 1 = 0..10 V).
    pub range: u32,
    /// Analog reference.
    #[serde(default)]
    pub aref: Aref,
}

/// A digital line: subdevice and channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DigitalLine {
    /// Subdevice index (PCI-6052E: 2 = DIO).
    pub subdevice: u32,
    /// Line within the subdevice.
    pub channel: u32,
}

/// Which way a channel goes (for messages).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// Analog input.
    AnalogIn,
    /// Analog output.
    AnalogOut,
    /// Digital output.
    DigitalOut,
}

impl std::fmt::Display for Direction {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Direction::AnalogIn => "analog input",
            Direction::AnalogOut => "analog output",
            Direction::DigitalOut => "digital output",
        })
    }
}

/// A channel as named in errors: `analog input 0/3`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChannelName {
    /// Direction.
    pub direction: Direction,
    /// Subdevice.
    pub subdevice: u32,
    /// Channel.
    pub channel: u32,
}

impl std::fmt::Display for ChannelName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} {}/{}", self.direction, self.subdevice, self.channel)
    }
}

impl AnalogChannel {
    /// This channel's name as an input.
    pub fn input_name(&self) -> ChannelName {
        ChannelName {
            direction: Direction::AnalogIn,
            subdevice: self.subdevice,
            channel: self.channel,
        }
    }
    /// This channel's name as an output.
    pub fn output_name(&self) -> ChannelName {
        ChannelName {
            direction: Direction::AnalogOut,
            subdevice: self.subdevice,
            channel: self.channel,
        }
    }
}

impl DigitalLine {
    /// This line's name.
    pub fn name(&self) -> ChannelName {
        ChannelName {
            direction: Direction::DigitalOut,
            subdevice: self.subdevice,
            channel: self.channel,
        }
    }
}

/// A DAQ failure, with the device or channel it concerns.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum DaqError {
    /// The device could not be opened.
    #[error("cannot open DAQ device `{device}`: {message}")]
    Open {
        /// Device path.
        device: String,
        /// Why, and what to do.
        message: String,
    },
    /// The board does not have what the configuration asks for.
    #[error("DAQ `{device}`, {channel}: {message}")]
    Channel {
        /// Device path.
        device: String,
        /// Channel.
        channel: ChannelName,
        /// What is wrong (no such subdevice, channel or range, wrong type ...).
        message: String,
    },
    /// A read or write failed.
    #[error("DAQ `{device}`, {channel}: {operation} failed: {message}")]
    Io {
        /// Device path.
        device: String,
        /// Channel.
        channel: ChannelName,
        /// `read`, `write`.
        operation: &'static str,
        /// The driver's message (Comedi's `comedi_strerror`).
        message: String,
    },
    /// A value cannot be written: NaN, or outside the channel's range.
    #[error(
        "DAQ `{device}`, {channel}: {volts} V is outside the channel's range {min_v}..{max_v} V"
    )]
    OutOfRange {
        /// Device path.
        device: String,
        /// Channel.
        channel: ChannelName,
        /// The value.
        volts: f64,
        /// Range minimum (V).
        min_v: f64,
        /// Range maximum (V).
        max_v: f64,
    },
    /// A reading that cannot be true of a working rig (a pressure above the limit the
    /// valve was never asked to exceed, a broken wire).
    #[error("DAQ `{device}`, {channel}: {message}")]
    Implausible {
        /// Device path.
        device: String,
        /// Channel.
        channel: ChannelName,
        /// What was read and why it cannot be.
        message: String,
    },
    /// The process was built without the driver.
    #[error("{0}")]
    Unsupported(String),
}

/// A data-acquisition board in physical units (volts). One implementation per driver
/// (Comedi, the virtual rig, test fakes). Calls happen from the control loop's thread;
/// implementations allocate nothing per call.
pub trait Daq: Send {
    /// Device name or path (for messages and the log header).
    fn device(&self) -> &str;
    /// Checks that the board has these channels and ranges (called once, at configure).
    fn check(
        &mut self,
        inputs: &[AnalogChannel],
        outputs: &[AnalogChannel],
        lines: &[DigitalLine],
    ) -> Result<(), DaqError>;
    /// The range (V) of an analog channel as the board reports it: `(min, max)`.
    fn range_v(&mut self, channel: &AnalogChannel, output: bool) -> Result<(f64, f64), DaqError>;
    /// Reads an analog input (V).
    fn read_analog(&mut self, channel: &AnalogChannel) -> Result<f64, DaqError>;
    /// Writes an analog output (V). A value outside the channel's range is an error, never
    /// silently clamped.
    fn write_analog(&mut self, channel: &AnalogChannel, volts: f64) -> Result<(), DaqError>;
    /// Sets a digital output line.
    fn write_digital(&mut self, line: &DigitalLine, high: bool) -> Result<(), DaqError>;
    /// An independent handle on an analog output (opened beside this one).
    fn output_handle(&self, channel: &AnalogChannel) -> Result<Box<dyn OutputHandle>, DaqError>;
}

/// A second, independent path to one analog output, usable from any thread: the watchdog
/// and the panic hook vent through it while the control loop may be stuck inside a call.
pub trait OutputHandle: Send + Sync {
    /// Writes the output (V).
    fn write(&self, volts: f64) -> Result<(), DaqError>;
}
