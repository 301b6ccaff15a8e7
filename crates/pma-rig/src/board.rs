//! What a DAQ board has, as Comedi reports it: subdevices, their type, channels and
//! ranges. The virtual rig checks a configuration against the layout of the board it
//! simulates, as the Comedi driver checks it against the real board's own report, so that
//! a channel the board does not have, an input used as an output or a range index out of
//! bounds fail `rig check` on the virtual rig too.
use crate::comedi::SubdeviceKind;
use crate::daq::{AnalogChannel, ChannelName, DaqError, DigitalLine};

/// One subdevice.
#[derive(Debug, Clone, PartialEq)]
pub struct SubdeviceLayout {
    /// Its type.
    pub kind: SubdeviceKind,
    /// Number of channels (lines).
    pub channels: u32,
    /// Converter resolution (bits; 1 for digital lines).
    pub bits: u32,
    /// Its ranges in volts, by index (the same for every channel).
    pub ranges_v: Vec<(f64, f64)>,
}

/// A board's subdevices, by index.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardLayout {
    /// The board's name (`comedi_get_board_name`).
    pub name: &'static str,
    /// Subdevices, by index.
    pub subdevices: Vec<SubdeviceLayout>,
}

impl BoardLayout {
    /// The NI PCI-6052E as Linux's `ni_pcimio` reports it (first five subdevices): AI (16
    /// channels, 16 bit, ranges 0-7 = +-10 .. +-0.05 V, 8-15 = 0..20 .. 0..0.1 V), AO (2
    /// channels, 16 bit, 0 = +-10 V, 1 = 0..10 V), DIO (8 lines), unused, calibration DACs.
    pub fn pci6052e() -> Self {
        let bipolar = [10.0, 5.0, 2.5, 1.0, 0.5, 0.25, 0.1, 0.05];
        let unipolar = [20.0, 10.0, 5.0, 2.0, 1.0, 0.5, 0.2, 0.1];
        let ai_ranges = bipolar
            .iter()
            .map(|&v| (-v, v))
            .chain(unipolar.iter().map(|&v| (0.0, v)))
            .collect();
        Self {
            name: "pci-6052e",
            subdevices: vec![
                SubdeviceLayout {
                    kind: SubdeviceKind::AnalogInput,
                    channels: 16,
                    bits: 16,
                    ranges_v: ai_ranges,
                },
                SubdeviceLayout {
                    kind: SubdeviceKind::AnalogOutput,
                    channels: 2,
                    bits: 16,
                    ranges_v: vec![(-10.0, 10.0), (0.0, 10.0)],
                },
                SubdeviceLayout {
                    kind: SubdeviceKind::DigitalIo,
                    channels: 8,
                    bits: 1,
                    ranges_v: vec![(0.0, 1.0)],
                },
                SubdeviceLayout {
                    kind: SubdeviceKind::Unused,
                    channels: 0,
                    bits: 0,
                    ranges_v: Vec::new(),
                },
                SubdeviceLayout {
                    kind: SubdeviceKind::Calibration,
                    channels: 12,
                    bits: 8,
                    ranges_v: vec![(0.0, 1.0)],
                },
            ],
        }
    }

    fn subdevice(
        &self,
        device: &str,
        name: ChannelName,
        kind: SubdeviceKind,
    ) -> Result<&SubdeviceLayout, DaqError> {
        let error = |message: String| DaqError::Channel {
            device: device.to_owned(),
            channel: name,
            message,
        };
        let count = self.subdevices.len();
        let sub = self
            .subdevices
            .get(name.subdevice as usize)
            .ok_or_else(|| {
                error(format!(
                    "no subdevice {}: the board ({}) has {count} (0 to {})",
                    name.subdevice,
                    self.name,
                    count.saturating_sub(1)
                ))
            })?;
        if sub.kind != kind {
            return Err(error(format!(
                "subdevice {} of the board ({}) is of type {}, not {kind}",
                name.subdevice, self.name, sub.kind
            )));
        }
        if name.channel >= sub.channels {
            return Err(error(format!(
                "no channel {}: subdevice {} has {} channels (0 to {})",
                name.channel,
                name.subdevice,
                sub.channels,
                sub.channels.saturating_sub(1)
            )));
        }
        Ok(sub)
    }

    /// Checks an analog channel as an input or an output and returns its range (V).
    pub fn analog_range_v(
        &self,
        device: &str,
        channel: &AnalogChannel,
        output: bool,
    ) -> Result<(f64, f64), DaqError> {
        let (name, kind) = if output {
            (channel.output_name(), SubdeviceKind::AnalogOutput)
        } else {
            (channel.input_name(), SubdeviceKind::AnalogInput)
        };
        let sub = self.subdevice(device, name, kind)?;
        sub.ranges_v
            .get(channel.range as usize)
            .copied()
            .ok_or_else(|| DaqError::Channel {
                device: device.to_owned(),
                channel: name,
                message: format!(
                    "no range {}: the channel has {} ranges (0 to {})",
                    channel.range,
                    sub.ranges_v.len(),
                    sub.ranges_v.len().saturating_sub(1)
                ),
            })
    }

    /// Checks a digital output line.
    pub fn digital_line(&self, device: &str, line: &DigitalLine) -> Result<(), DaqError> {
        self.subdevice(device, line.name(), SubdeviceKind::DigitalIo)
            .map(|_| ())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn channel(subdevice: u32, channel: u32, range: u32) -> AnalogChannel {
        AnalogChannel {
            subdevice,
            channel,
            range,
            aref: crate::daq::Aref::Ground,
        }
    }

    #[test]
    fn the_pci6052e_layout_refuses_what_the_board_does_not_have() {
        let b = BoardLayout::pci6052e();
        assert_eq!(
            b.analog_range_v("v", &channel(0, 0, 9), false).unwrap(),
            (0.0, 10.0)
        );
        assert_eq!(
            b.analog_range_v("v", &channel(1, 1, 1), true).unwrap(),
            (0.0, 10.0)
        );
        let msg = |r: Result<(f64, f64), DaqError>| r.unwrap_err().to_string();
        assert!(msg(b.analog_range_v("v", &channel(0, 0, 9), true)).contains("not analog output"));
        assert!(msg(b.analog_range_v("v", &channel(77, 0, 0), false)).contains("no subdevice 77"));
        assert!(msg(b.analog_range_v("v", &channel(0, 99999, 0), false)).contains("no channel"));
        assert!(msg(b.analog_range_v("v", &channel(1, 0, 250), true)).contains("no range 250"));
        let pump_on_valve = DigitalLine {
            subdevice: 1,
            channel: 0,
        };
        assert!(b
            .digital_line("v", &pump_on_valve)
            .unwrap_err()
            .to_string()
            .contains("not digital I/O"));
    }
}
