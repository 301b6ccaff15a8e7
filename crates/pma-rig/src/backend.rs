//! The rig as a [`Backend`]: any [`Daq`] behind calibration, with the lifecycle of a
//! ros2_control hardware component: configure (open, check the board, vent, read the
//! sensor; valve not live) -> activate ([`Backend::start`]) -> read / write every period ->
//! deactivate ([`Backend::stop`]: vent).
use crate::config::{Calibration, Limits, RigConfig, Signals};
use crate::daq::{Daq, DaqError};
use crate::error::RigError;
use crate::timing::{Pacer, TimingSummary};
use crate::virtual_daq::LockstepClock;
use pma_control::Measurement;
use pma_loop::{Backend, Started};
use std::time::Duration;

/// How periods pass.
pub enum Pacing {
    /// The virtual rig's plant advances one period per loop period, at once.
    Lockstep(LockstepClock),
    /// Absolute wall-clock deadlines.
    Realtime(Duration),
}

/// Raw telemetry of a period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigTelemetry {
    /// The sensor's voltage at the last read (V).
    pub position_v: f64,
    /// The valve's last set point (V).
    pub valve_v: f64,
    /// The pressure channel's voltage at the last read (V); NaN without the channel.
    pub pressure_v: f64,
    /// The pressure it means (Pa); NaN without the channel.
    pub pressure_pa: f64,
}

/// The rig, configured. See the module documentation for its lifecycle.
pub struct RigBackend {
    daq: Box<dyn Daq>,
    signals: Signals,
    calibration: Calibration,
    period_s: f64,
    output_range_v: (f64, f64),
    vent_v: f64,
    pacing: Pacing,
    pacer: Option<Pacer>,
    pump_level: bool,
    telemetry: RigTelemetry,
    active: bool,
    vented: bool,
    vent_error: Option<DaqError>,
    configure_reading_m: f64,
    /// Highest plausible measured pressure (Pa).
    pressure_fault_pa: f64,
}

/// A measured pressure this far above the pressure limit (as a share of it) is a fault: the
/// valve was never asked for more than the limit, so the valve, its supply regulator or the
/// channel's calibration is wrong. 10 % is well above the VPPM's stated accuracy (about 1 %
/// of full scale, Festo MPA-S info 2017/11, p. 31).
pub const PRESSURE_FAULT_MARGIN: f64 = 0.1;

fn range_error(field: &'static str, what: &str, volts: f64, range: (f64, f64)) -> RigError {
    RigError::Field {
        field,
        message: format!(
            "{what} is {volts} V, outside the channel's range {}..{} V",
            range.0, range.1
        ),
    }
}

impl RigBackend {
    /// Configures the rig: checks that the board has the configured channels and ranges
    /// and that the calibration maps the limits into them, writes the vent value, resets
    /// the charge pump and reads the sensor, which must be inside the position window.
    /// The valve is not live: nothing but the vent value has been written.
    pub fn configure(
        config: &RigConfig,
        mut daq: Box<dyn Daq>,
        pacing: Pacing,
    ) -> Result<Self, RigError> {
        // Nothing reaches the board before the whole configuration is known to be sound.
        config.validate()?;
        let s = config.signals;
        let c = config.calibration;
        let lines: Vec<_> = s.charge_pump.into_iter().collect();
        let inputs: Vec<_> = std::iter::once(s.position).chain(s.pressure).collect();
        daq.check(&inputs, &[s.valve], &lines)?;
        let out = daq.range_v(&s.valve, true)?;
        let inside =
            |v: f64, r: (f64, f64)| v >= r.0 - RANGE_TOLERANCE_V && v <= r.1 + RANGE_TOLERANCE_V;
        let vent_v = c.valve_v(0.0);
        if !inside(vent_v, out) {
            return Err(range_error(
                "calibration.valve_offset_v",
                "the vent value (0 Pa)",
                vent_v,
                out,
            ));
        }
        let max_v = c.valve_v(config.limits.pressure_max_pa);
        if !inside(max_v, out) {
            return Err(range_error(
                "limits.pressure_max_pa",
                "the highest command",
                max_v,
                out,
            ));
        }
        let input = daq.range_v(&s.position, false)?;
        check_window(&config.limits, &c, input)?;
        if let Some(channel) = &s.pressure {
            let range = daq.range_v(channel, false)?;
            check_pressure_span(config.limits.pressure_max_pa, &c, channel, range)?;
        }
        let vent_v = vent_v.clamp(out.0, out.1);
        daq.write_analog(&s.valve, vent_v)?;
        if let Some(line) = &s.charge_pump {
            daq.write_digital(line, false)?;
        }
        let position_v = daq.read_analog(&s.position)?;
        let x = c.position_m(position_v);
        let l = &config.limits;
        if !(x >= l.position_min_m && x <= l.position_max_m) {
            return Err(RigError::Field {
                field: "limits",
                message: format!(
                    "the sensor reads {x} m ({position_v} V), outside the position window {}..{} m: check the sensor, its wiring, its calibration and the mount before going live",
                    l.position_min_m, l.position_max_m
                ),
            });
        }
        let mut rig = Self {
            daq,
            signals: s,
            calibration: c,
            period_s: config.period_s,
            output_range_v: out,
            vent_v,
            pacing,
            pacer: None,
            pump_level: false,
            telemetry: RigTelemetry {
                position_v,
                valve_v: vent_v,
                pressure_v: f64::NAN,
                pressure_pa: f64::NAN,
            },
            active: false,
            vented: true,
            vent_error: None,
            configure_reading_m: x,
            pressure_fault_pa: (1.0 + PRESSURE_FAULT_MARGIN) * config.limits.pressure_max_pa,
        };
        // A pressure channel that reads nonsense or pressure in a vented muscle is found
        // before the valve goes live.
        rig.read_pressure()?;
        Ok(rig)
    }

    /// Reads the pressure channel, if any: a NaN or a pressure above the limit plus
    /// [`PRESSURE_FAULT_MARGIN`] is an error (the loop fails safe on it).
    fn read_pressure(&mut self) -> Result<(), DaqError> {
        let Some(channel) = self.signals.pressure else {
            return Ok(());
        };
        let v = self.daq.read_analog(&channel)?;
        self.telemetry.pressure_v = v;
        let p = self.calibration.pressure_pa(v);
        self.telemetry.pressure_pa = p;
        if p.is_nan() || p > self.pressure_fault_pa {
            return Err(DaqError::Implausible {
                device: self.daq.device().to_owned(),
                channel: channel.input_name(),
                message: format!(
                    "the valve reports {:.3} bar ({v} V), above the {:.3} bar the supervisor allows plus {:.0} %: the valve, its supply or the channel's calibration is wrong (a NaN is a broken wire or a reading outside the range)",
                    p / 1e5,
                    self.pressure_fault_pa / (1.0 + PRESSURE_FAULT_MARGIN) / 1e5,
                    PRESSURE_FAULT_MARGIN * 100.0
                ),
            });
        }
        Ok(())
    }

    /// The reading taken at configure (m).
    pub fn configure_reading_m(&self) -> f64 {
        self.configure_reading_m
    }

    /// The pressure channel's reading at configure (Pa), if the rig has the channel.
    pub fn pressure_reading_pa(&self) -> Option<f64> {
        self.signals.pressure.map(|_| self.telemetry.pressure_pa)
    }

    /// The valve voltage that vents the muscle.
    pub fn vent_v(&self) -> f64 {
        self.vent_v
    }

    /// The device.
    pub fn device(&self) -> &str {
        self.daq.device()
    }

    /// An independent handle on the valve output (for the watchdog and the panic hook).
    pub fn valve_handle(&self) -> Result<Box<dyn crate::daq::OutputHandle>, DaqError> {
        self.daq.output_handle(&self.signals.valve)
    }

    /// Whether the last stop wrote the vent value.
    pub fn vented(&self) -> bool {
        self.vented
    }

    /// Why venting failed, if it did.
    pub fn vent_error(&self) -> Option<&DaqError> {
        self.vent_error.as_ref()
    }

    /// The timing of a real-time run.
    pub fn timing(&self) -> Option<TimingSummary> {
        self.pacer.as_ref().map(Pacer::summary)
    }

    /// The set point of a pressure; a value within rounding of the output's range is
    /// brought onto it (configure checked the limits map into the range).
    fn valve_volts(&self, pressure_pa: f64) -> f64 {
        let v = self.calibration.valve_v(pressure_pa);
        let (lo, hi) = self.output_range_v;
        if v < lo && v >= lo - RANGE_TOLERANCE_V {
            lo
        } else if v > hi && v <= hi + RANGE_TOLERANCE_V {
            hi
        } else {
            v
        }
    }

    fn toggle_charge_pump(&mut self) -> Result<(), DaqError> {
        if let Some(line) = &self.signals.charge_pump {
            self.pump_level = !self.pump_level;
            self.daq.write_digital(line, self.pump_level)?;
        }
        Ok(())
    }
}

/// Volts closer than this to a range's edge count as inside it (V): a window computed
/// through the calibration lands on the edge up to rounding (the documented span of the
/// sensor, -20..130 mm, is -2.2e-16..10 V).
const RANGE_TOLERANCE_V: f64 = 1e-9;

fn check_window(limits: &Limits, c: &Calibration, input: (f64, f64)) -> Result<(), RigError> {
    for (field, x) in [
        ("limits.position_min_m", limits.position_min_m),
        ("limits.position_max_m", limits.position_max_m),
    ] {
        let v = c.position_v(x);
        if !(v >= input.0 - RANGE_TOLERANCE_V && v <= input.1 + RANGE_TOLERANCE_V) {
            return Err(RigError::Field {
                field,
                message: format!(
                    "{x} m is {v:.6} V through the calibration, outside the sensor input's range {}..{} V: the window must be measurable",
                    input.0, input.1
                ),
            });
        }
    }
    Ok(())
}

/// The pressure channel must read every pressure a run can meet without a fault, 0 Pa to
/// the limit plus [`PRESSURE_FAULT_MARGIN`], strictly inside its range: a converter reads
/// NaN at either end, and a run stops on a NaN. Found at configure, this is one line; found
/// by the run, it is a fault as soon as the muscle passes the channel's top.
fn check_pressure_span(
    pressure_max_pa: f64,
    c: &Calibration,
    channel: &crate::daq::AnalogChannel,
    range: (f64, f64),
) -> Result<(), RigError> {
    let highest_pa = (1.0 + PRESSURE_FAULT_MARGIN) * pressure_max_pa;
    let (zero_v, highest_v) = (c.pressure_v(0.0), c.pressure_v(highest_pa));
    let inside = |v: f64| v > range.0 && v < range.1;
    if inside(zero_v) && inside(highest_v) {
        return Ok(());
    }
    Err(RigError::Field {
        field: "signals.pressure",
        message: format!(
            "0..{:.2} bar (limits.pressure_max_pa + {:.0} %, the highest reading a run accepts) is {zero_v:.4}..{highest_v:.4} V through the calibration ({} Pa/V, {} V at 0 Pa), not inside range {} of the channel, {}..{} V, whose ends read NaN: choose a range that holds it, or correct calibration.pressure_pa_per_v and pressure_offset_v",
            highest_pa / 1e5,
            PRESSURE_FAULT_MARGIN * 100.0,
            c.pressure_scale_pa_per_v(),
            c.pressure_zero_v(),
            channel.range,
            range.0,
            range.1
        ),
    })
}

impl Backend for RigBackend {
    type Reading = Measurement;
    type Command = f64;
    type Truth = RigTelemetry;
    type Error = DaqError;

    /// Activates: the valve goes live (still at the vent value), the first reading is
    /// taken and the real-time clock starts.
    fn start(&mut self) -> Result<Started<Measurement, f64>, DaqError> {
        self.active = true;
        self.vented = false;
        let reading = self.read()?;
        if let Pacing::Realtime(period) = self.pacing {
            self.pacer = Some(Pacer::start(period));
        }
        Ok(Started {
            t_s: 0.0,
            reading,
            command: 0.0,
        })
    }

    fn period_s(&self) -> f64 {
        self.period_s
    }

    /// Toggles the charge pump, then lets the period pass.
    fn wait(&mut self) -> Result<u32, DaqError> {
        self.toggle_charge_pump()?;
        match (&self.pacing, self.pacer.as_mut()) {
            (Pacing::Lockstep(clock), _) => {
                clock.tick();
                Ok(1)
            }
            (Pacing::Realtime(_), Some(p)) => Ok(p.wait()),
            (Pacing::Realtime(period), None) => {
                self.pacer = Some(Pacer::start(*period));
                Ok(self.pacer.as_mut().map_or(1, Pacer::wait))
            }
        }
    }

    fn read(&mut self) -> Result<Measurement, DaqError> {
        let v = self.daq.read_analog(&self.signals.position)?;
        self.telemetry.position_v = v;
        self.read_pressure()?;
        Ok(Measurement {
            position_m: self.calibration.position_m(v),
        })
    }

    fn write(&mut self, pressure_pa: &f64) -> Result<f64, DaqError> {
        let v = self.valve_volts(*pressure_pa);
        self.daq.write_analog(&self.signals.valve, v)?;
        self.telemetry.valve_v = v;
        Ok(*pressure_pa)
    }

    fn truth(&self) -> RigTelemetry {
        self.telemetry
    }

    /// Writes the vent value; a failure is kept (see [`RigBackend::vent_error`]).
    fn stop(&mut self) {
        match self.daq.write_analog(&self.signals.valve, self.vent_v) {
            Ok(()) => {
                self.vented = true;
                self.telemetry.valve_v = self.vent_v;
            }
            Err(e) => {
                self.vented = false;
                self.vent_error = Some(e);
            }
        }
        self.active = false;
    }
}

/// A rig dropped while active (a panic unwinding through the loop) vents.
impl Drop for RigBackend {
    fn drop(&mut self) {
        if self.active {
            self.stop();
        }
    }
}
