//! The virtual rig: the `pma-model` muscle, load and valve (the bench of `pma-sim`) behind
//! the [`Daq`] trait, in volts and converter counts, so that calibration, quantisation and
//! every fault path of the real rig run without hardware.
use crate::board::BoardLayout;
use crate::config::{Calibration, ClockMode, RigConfig, VirtualConfig};
use crate::daq::{AnalogChannel, ChannelName, Daq, DaqError, DigitalLine, OutputHandle};
use crate::error::RigError;
use pma_bench::{MuscleBench, PlantConfig};
use pma_model::{PositionSensor, SensorParams};
use std::str::FromStr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// The device name the virtual rig reports.
pub const VIRTUAL_DEVICE: &str = "virtual";

/// Plant step of the real-time virtual rig (s): commands take effect within it.
const REALTIME_STEP_S: f64 = 1e-4;

/// The control period a plant file's `substeps_per_period` is chosen for (s): the
/// paper's 1 ms, as the bench runs it.
const PLANT_FILE_PERIOD_S: f64 = 1e-3;

/// Substeps per lockstep period: the plant file's at 1 ms or shorter periods, more at
/// longer ones so that no step is longer than the plant file's. The trapezoidal rule is
/// A-stable but not L-stable: on the muscle's damping pole (about 3000 1/s at 2 kg) a
/// 2.5 ms step (10 ms / 4) rings, and the simulated load rose 4 mm after a vent, where the
/// muscle only sags.
fn lockstep_substeps(plant_substeps: u32, period_s: f64) -> u32 {
    // The tolerance keeps 3 ms at 12 substeps, not 13, through rounding.
    let needed = (f64::from(plant_substeps) * period_s / PLANT_FILE_PERIOD_S - 1e-9).ceil();
    plant_substeps.max(needed as u32)
}

/// A fault the virtual rig can be told to produce (`--inject FAULT@T`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InjectedFault {
    /// The sensor reads NaN (a broken wire on a board that reports it).
    SensorNan,
    /// The sensor repeats its last value (a frozen converter or driver).
    SensorStuck,
    /// The reading jumps 60 mm (a slipped sensor mount, a broken tendon).
    PositionOut,
    /// The board's reads fail (EIO).
    DaqError,
    /// One read blocks for 0.5 s (a hung driver call): of wall time on a rig that follows
    /// it, of simulated time in lockstep.
    Stall,
    /// The control loop panics (the virtual board panics in a read, standing for any bug
    /// in the loop; it tests the panic path, not a board fault).
    ControllerPanic,
    /// The valve's actual-value output reads the supply pressure, 8 bar (a valve stuck
    /// open); only on a rig with the pressure channel.
    PressureHigh,
}

/// The supply pressure a valve stuck open reports (Pa).
const SUPPLY_PA: f64 = 8.0e5;

/// How long the injected stall hangs a read (s): twice the longest watchdog timeout a
/// configuration may ask for, so that every watchdog trips during it.
const STALL_S: f64 = 2.0 * crate::config::WATCHDOG_MAX_S;

impl InjectedFault {
    /// Every fault, with its command-line name.
    pub const ALL: [(InjectedFault, &'static str); 7] = [
        (InjectedFault::SensorNan, "sensor-nan"),
        (InjectedFault::SensorStuck, "sensor-stuck"),
        (InjectedFault::PositionOut, "position-out"),
        (InjectedFault::DaqError, "daq-error"),
        (InjectedFault::Stall, "stall"),
        (InjectedFault::ControllerPanic, "controller-panic"),
        (InjectedFault::PressureHigh, "pressure-high"),
    ];

    /// Command-line name.
    pub fn name(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(f, _)| *f == self)
            .map_or("?", |(_, n)| n)
    }
}

/// A fault and when (seconds after the virtual rig was configured).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Injection {
    /// Which fault.
    pub fault: InjectedFault,
    /// When (s).
    pub at_s: f64,
}

impl FromStr for Injection {
    type Err = String;
    /// `FAULT@T`, e.g. `sensor-nan@5`.
    fn from_str(s: &str) -> Result<Self, String> {
        let names: Vec<&str> = InjectedFault::ALL.iter().map(|(_, n)| *n).collect();
        let expected = format!(
            "expected FAULT@SECONDS with FAULT one of {}",
            names.join(", ")
        );
        let (name, at) = s
            .split_once('@')
            .ok_or_else(|| format!("`{s}`: {expected}"))?;
        let fault = InjectedFault::ALL
            .iter()
            .find(|(_, n)| *n == name)
            .map(|(f, _)| *f)
            .ok_or_else(|| format!("unknown fault `{name}`: {expected}"))?;
        let at_s: f64 = at
            .parse()
            .ok()
            .filter(|t: &f64| t.is_finite() && *t >= 0.0)
            .ok_or_else(|| format!("`{at}` is not a time in seconds >= 0: {expected}"))?;
        Ok(Self { fault, at_s })
    }
}

/// A converter: range and resolution.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Converter {
    min_v: f64,
    max_v: f64,
    /// Highest code; 0 for a continuous converter.
    maxdata: u64,
}

impl Converter {
    fn new(range: [f64; 2], bits: u32) -> Self {
        Self {
            min_v: range[0],
            max_v: range[1],
            maxdata: if bits == 0 { 0 } else { (1u64 << bits) - 1 },
        }
    }

    /// The value the converter delivers for `volts`, or NaN when it saturates (Comedi's
    /// out-of-range behaviour at code 0 or maxdata).
    fn sample(&self, volts: f64) -> f64 {
        if !(volts > self.min_v && volts < self.max_v) {
            return f64::NAN;
        }
        self.quantise(volts)
    }

    fn quantise(&self, volts: f64) -> f64 {
        if self.maxdata == 0 {
            return volts;
        }
        let span = self.max_v - self.min_v;
        let code = ((volts - self.min_v) / span * self.maxdata as f64)
            .round()
            .clamp(0.0, self.maxdata as f64);
        if code == 0.0 || code == self.maxdata as f64 {
            return f64::NAN;
        }
        self.min_v + code * span / self.maxdata as f64
    }

    fn output(&self, volts: f64) -> Option<f64> {
        if !(volts >= self.min_v && volts <= self.max_v) {
            return None;
        }
        if self.maxdata == 0 {
            return Some(volts);
        }
        let span = self.max_v - self.min_v;
        let code = ((volts - self.min_v) / span * self.maxdata as f64).round();
        Some(self.min_v + code * span / self.maxdata as f64)
    }
}

/// The simulated hardware: plant, valve input, sensor, charge pump.
struct Hardware {
    bench: MuscleBench,
    sensor: PositionSensor,
    calibration: Calibration,
    input: Converter,
    /// The pressure channel's converter, if the rig has one.
    pressure_input: Option<Converter>,
    output: Converter,
    step_s: f64,
    steps_done: u64,
    history: Vec<f64>,
    history_next: usize,
    valve_v: f64,
    pump_toggles: u64,
    pump_level: bool,
    stuck_v: Option<f64>,
    stalled: bool,
}

impl Hardware {
    fn integrate_to(&mut self, steps: u64) {
        while self.steps_done < steps {
            self.bench.advance(self.step_s);
            self.steps_done += 1;
            if !self.history.is_empty() {
                self.history[self.history_next] = self.bench.position();
                self.history_next = (self.history_next + 1) % self.history.len();
            }
        }
    }

    /// The true contraction the sensor sees now (delayed by the latency, if any).
    fn sensed_position(&self) -> f64 {
        if self.history.is_empty() || self.steps_done < self.history.len() as u64 {
            self.bench.position()
        } else {
            self.history[self.history_next]
        }
    }

    /// Sets the valve at `volts` (as the output converter delivers them) at `steps`.
    fn write_valve(
        &mut self,
        channel: &AnalogChannel,
        volts: f64,
        steps: u64,
    ) -> Result<(), DaqError> {
        let range = (self.output.min_v, self.output.max_v);
        let v = self
            .output
            .output(volts)
            .ok_or_else(|| DaqError::OutOfRange {
                device: VIRTUAL_DEVICE.into(),
                channel: channel.output_name(),
                volts,
                min_v: range.0,
                max_v: range.1,
            })?;
        self.integrate_to(steps);
        self.valve_v = v;
        self.bench.command(self.calibration.valve_pa(v));
        Ok(())
    }
}

/// How the virtual rig's time advances.
#[derive(Debug, Clone)]
enum TimeSource {
    /// Counted periods, advanced by [`LockstepClock::tick`].
    Lockstep(Arc<AtomicU64>),
    /// Wall time since creation.
    Wall(Instant),
}

impl TimeSource {
    /// Plant steps of `step_s` that have passed: periods in lockstep, wall time otherwise.
    fn steps(&self, step_s: f64) -> u64 {
        match self {
            TimeSource::Lockstep(c) => c.load(Ordering::Relaxed),
            TimeSource::Wall(t0) => (t0.elapsed().as_secs_f64() / step_s) as u64,
        }
    }
}

/// The lockstep clock of a virtual rig: one tick per control period.
#[derive(Debug, Clone)]
pub struct LockstepClock {
    ticks: Arc<AtomicU64>,
    period_s: f64,
}

impl LockstepClock {
    /// Lets one period pass.
    pub fn tick(&self) {
        self.ticks.fetch_add(1, Ordering::Relaxed);
    }

    /// Simulated time since the rig was configured: the clock a lockstep run's watchdog
    /// measures silence on (wall time says nothing about a simulation's periods).
    pub fn elapsed(&self) -> Duration {
        Duration::from_secs_f64(self.ticks.load(Ordering::Relaxed) as f64 * self.period_s)
    }
}

/// What a test can see of the simulated hardware.
#[derive(Clone)]
pub struct VirtualProbe(Arc<Mutex<Hardware>>);

/// The true state of the simulated rig.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VirtualState {
    /// True contraction (m).
    pub position_m: f64,
    /// Pressure in the muscle (Pa).
    pub pressure_pa: f64,
    /// Valve set point (V).
    pub valve_v: f64,
    /// Times the charge-pump line changed level.
    pub pump_toggles: u64,
}

impl VirtualProbe {
    /// The state now.
    pub fn state(&self) -> VirtualState {
        let hw = lock(&self.0);
        VirtualState {
            position_m: hw.bench.position(),
            pressure_pa: hw.bench.pressure(),
            valve_v: hw.valve_v,
            pump_toggles: hw.pump_toggles,
        }
    }
}

fn lock(m: &Mutex<Hardware>) -> MutexGuard<'_, Hardware> {
    // A panic while the lock was held leaves a consistent plant (every update is a few
    // assignments): keep using it, so that venting still works after a panic.
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// The virtual DAQ.
pub struct VirtualDaq {
    hw: Arc<Mutex<Hardware>>,
    time: TimeSource,
    period_s: f64,
    position: AnalogChannel,
    pressure: Option<AnalogChannel>,
    valve: AnalogChannel,
    pump: Option<DigitalLine>,
    injections: Vec<Injection>,
    board: BoardLayout,
}

/// The simulated board's range at `channel` (V); a configured range must agree with it.
/// The pressure the virtual rig's valve receives for a logged command (Pa): the command
/// through the calibration to volts, through the output converter's code and back. A rig
/// log records the command before the converter; an ideal valve feels the difference
/// (a 15 Pa step of a 16-bit 0-10 V output turns the damping mode of eq. (1), which an
/// identification must then see). `None`: not a virtual rig, or a continuous converter.
pub fn delivered_valve_pa(config: &RigConfig) -> Result<Option<impl Fn(f64) -> f64>, RigError> {
    let Some(v) = config.virtual_rig.as_ref().filter(|v| v.converter_bits > 0) else {
        return Ok(None);
    };
    let range = board_range(
        &BoardLayout::pci6052e(),
        &config.signals.valve,
        true,
        v.output_range_v,
    )?;
    let converter = Converter::new(range, v.converter_bits);
    let calibration = config.calibration;
    Ok(Some(move |command_pa: f64| {
        let volts = calibration.valve_v(command_pa);
        converter
            .output(volts)
            .map_or(command_pa, |v| calibration.valve_pa(v))
    }))
}

fn board_range(
    board: &BoardLayout,
    channel: &AnalogChannel,
    output: bool,
    configured: Option<[f64; 2]>,
) -> Result<[f64; 2], RigError> {
    let (min, max) = board.analog_range_v(VIRTUAL_DEVICE, channel, output)?;
    match configured {
        Some(r) if r != [min, max] => Err(RigError::Field {
            field: if output {
                "virtual.output_range_v"
            } else {
                "virtual.input_range_v"
            },
            message: format!(
                "[{}, {}] V is not the range the simulated {} has at range index {} ({min}..{max} V): drop the field or make it agree",
                r[0], r[1], board.name, channel.range
            ),
        }),
        _ => Ok([min, max]),
    }
}

impl VirtualDaq {
    /// The simulated rig of `config` (its `[virtual]` section), the load hanging at rest on
    /// the vented muscle, with `injections` scheduled.
    pub fn new(config: &RigConfig, injections: &[Injection]) -> Result<Self, RigError> {
        let v: &VirtualConfig = config.virtual_rig.as_ref().ok_or(RigError::Missing {
            field: "virtual",
            why: "the virtual driver needs a [virtual] section",
        })?;
        let mut plant = PlantConfig::load(&v.plant)?;
        // The added mass of the added-mass protocol hangs on the plant's load.
        plant.load.mass_kg += config.load.added_mass_kg;
        let seed = plant.sensor.seed;
        plant.sensor = SensorParams::ideal();
        let (step_s, substeps) = match v.clock {
            ClockMode::Lockstep => (
                config.period_s,
                lockstep_substeps(plant.substeps_per_period, config.period_s),
            ),
            ClockMode::Realtime => (REALTIME_STEP_S, 1),
        };
        let bench = MuscleBench::vented(&plant)?.with_substeps(substeps);
        let sensor = PositionSensor::new(SensorParams {
            noise_rms_m: v.sensor_noise_rms_m,
            seed,
            ..SensorParams::ideal()
        })
        .map_err(|e| RigError::Field {
            field: "virtual.sensor_noise_rms_m",
            message: e.to_string(),
        })?;
        let board = BoardLayout::pci6052e();
        let input_range = board_range(&board, &config.signals.position, false, v.input_range_v)?;
        let output_range = board_range(&board, &config.signals.valve, true, v.output_range_v)?;
        let pressure_input = match &config.signals.pressure {
            Some(c) => Some(Converter::new(
                board_range(&board, c, false, None)?,
                v.converter_bits,
            )),
            None => None,
        };
        let latency_steps = (v.sensor_latency_s / step_s).round() as usize;
        let hw = Hardware {
            bench,
            sensor,
            calibration: config.calibration,
            input: Converter::new(input_range, v.converter_bits),
            pressure_input,
            output: Converter::new(output_range, v.converter_bits),
            step_s,
            steps_done: 0,
            history: vec![0.0; latency_steps],
            history_next: 0,
            valve_v: config.calibration.valve_v(0.0),
            pump_toggles: 0,
            pump_level: false,
            stuck_v: None,
            stalled: false,
        };
        let time = match v.clock {
            ClockMode::Lockstep => TimeSource::Lockstep(Arc::new(AtomicU64::new(0))),
            ClockMode::Realtime => TimeSource::Wall(Instant::now()),
        };
        Ok(Self {
            hw: Arc::new(Mutex::new(hw)),
            time,
            period_s: config.period_s,
            position: config.signals.position,
            pressure: config.signals.pressure,
            valve: config.signals.valve,
            pump: config.signals.charge_pump,
            injections: injections.to_vec(),
            board,
        })
    }

    /// The lockstep clock, if the rig runs in lockstep.
    pub fn lockstep_clock(&self) -> Option<LockstepClock> {
        match &self.time {
            TimeSource::Lockstep(c) => Some(LockstepClock {
                ticks: Arc::clone(c),
                period_s: self.period_s,
            }),
            TimeSource::Wall(_) => None,
        }
    }

    /// A probe on the simulated hardware.
    pub fn probe(&self) -> VirtualProbe {
        VirtualProbe(Arc::clone(&self.hw))
    }

    /// Seconds since the rig was configured (virtual time in lockstep).
    fn now_s(&self) -> f64 {
        match &self.time {
            TimeSource::Lockstep(c) => c.load(Ordering::Relaxed) as f64 * self.period_s,
            TimeSource::Wall(t0) => t0.elapsed().as_secs_f64(),
        }
    }

    fn steps_now(&self, step_s: f64) -> u64 {
        self.time.steps(step_s)
    }

    fn active(&self, fault: InjectedFault) -> bool {
        let now = self.now_s();
        self.injections
            .iter()
            .any(|i| i.fault == fault && now >= i.at_s)
    }

    /// The valve's actual-value output: the pressure in the muscle through the channel's
    /// calibration and converter (the faults are the position sensor's).
    fn read_pressure(&mut self) -> f64 {
        let mut hw = lock(&self.hw);
        let steps = self.steps_now(hw.step_s);
        hw.integrate_to(steps);
        let pressure = if self.active(InjectedFault::PressureHigh) {
            SUPPLY_PA
        } else {
            hw.bench.pressure()
        };
        let volts = hw.calibration.pressure_v(pressure);
        hw.pressure_input.map_or(f64::NAN, |c| c.sample(volts))
    }

    /// A driver call that hangs for `seconds`, without holding the plant, as a hung call
    /// would: the watchdog must be able to vent meanwhile. In lockstep the simulated time
    /// jumps (the run's watchdog follows it); otherwise the wall time passes.
    fn hang(&self, seconds: f64) {
        match &self.time {
            TimeSource::Lockstep(c) => {
                c.fetch_add((seconds / self.period_s).round() as u64, Ordering::Relaxed);
            }
            TimeSource::Wall(_) => std::thread::sleep(Duration::from_secs_f64(seconds)),
        }
    }

    fn wrong_channel(&self, channel: ChannelName) -> DaqError {
        DaqError::Channel {
            device: VIRTUAL_DEVICE.into(),
            channel,
            message: "the virtual rig has no such channel (it has the configured position, pressure, valve and charge-pump signals only)".into(),
        }
    }
}

impl Daq for VirtualDaq {
    fn device(&self) -> &str {
        VIRTUAL_DEVICE
    }

    fn check(
        &mut self,
        inputs: &[AnalogChannel],
        outputs: &[AnalogChannel],
        lines: &[DigitalLine],
    ) -> Result<(), DaqError> {
        for c in inputs {
            self.board.analog_range_v(VIRTUAL_DEVICE, c, false)?;
        }
        for c in outputs {
            self.board.analog_range_v(VIRTUAL_DEVICE, c, true)?;
        }
        for l in lines {
            self.board.digital_line(VIRTUAL_DEVICE, l)?;
        }
        if let Some(c) = inputs
            .iter()
            .find(|c| **c != self.position && Some(**c) != self.pressure)
        {
            return Err(self.wrong_channel(c.input_name()));
        }
        if let Some(c) = outputs.iter().find(|c| **c != self.valve) {
            return Err(self.wrong_channel(c.output_name()));
        }
        if let Some(l) = lines.iter().find(|l| Some(**l) != self.pump) {
            return Err(self.wrong_channel(l.name()));
        }
        Ok(())
    }

    fn range_v(&mut self, channel: &AnalogChannel, output: bool) -> Result<(f64, f64), DaqError> {
        let hw = lock(&self.hw);
        if !output && Some(*channel) == self.pressure {
            if let Some(c) = &hw.pressure_input {
                return Ok((c.min_v, c.max_v));
            }
        }
        match (output, *channel == self.valve, *channel == self.position) {
            (true, true, _) => Ok((hw.output.min_v, hw.output.max_v)),
            (false, _, true) => Ok((hw.input.min_v, hw.input.max_v)),
            (true, _, _) => Err(self.wrong_channel(channel.output_name())),
            (false, _, _) => Err(self.wrong_channel(channel.input_name())),
        }
    }

    fn read_analog(&mut self, channel: &AnalogChannel) -> Result<f64, DaqError> {
        if Some(*channel) == self.pressure {
            return Ok(self.read_pressure());
        }
        if *channel != self.position {
            return Err(self.wrong_channel(channel.input_name()));
        }
        if self.active(InjectedFault::Stall) {
            let first = {
                let mut hw = lock(&self.hw);
                !std::mem::replace(&mut hw.stalled, true)
            };
            if first {
                self.hang(STALL_S);
            }
        }
        if self.active(InjectedFault::ControllerPanic) {
            panic!(
                "injected panic in the control loop at {:.3} s",
                self.now_s()
            );
        }
        if self.active(InjectedFault::DaqError) {
            return Err(DaqError::Io {
                device: VIRTUAL_DEVICE.into(),
                channel: channel.input_name(),
                operation: "read",
                message: "Input/output error (injected)".into(),
            });
        }
        let (nan, stuck, out) = (
            self.active(InjectedFault::SensorNan),
            self.active(InjectedFault::SensorStuck),
            self.active(InjectedFault::PositionOut),
        );
        let mut hw = lock(&self.hw);
        let steps = self.steps_now(hw.step_s);
        hw.integrate_to(steps);
        let sensed = hw.sensed_position();
        let mut x = hw.sensor.measure(sensed);
        if out {
            x += 0.060;
        }
        let volts = hw.input.sample(hw.calibration.position_v(x));
        if stuck {
            return Ok(*hw.stuck_v.get_or_insert(volts));
        }
        Ok(if nan { f64::NAN } else { volts })
    }

    fn write_analog(&mut self, channel: &AnalogChannel, volts: f64) -> Result<(), DaqError> {
        if *channel != self.valve {
            return Err(self.wrong_channel(channel.output_name()));
        }
        let mut hw = lock(&self.hw);
        let steps = self.steps_now(hw.step_s);
        hw.write_valve(channel, volts, steps)
    }

    fn write_digital(&mut self, line: &DigitalLine, high: bool) -> Result<(), DaqError> {
        if Some(*line) != self.pump {
            return Err(self.wrong_channel(line.name()));
        }
        let mut hw = lock(&self.hw);
        if hw.pump_level != high {
            hw.pump_toggles += 1;
        }
        hw.pump_level = high;
        Ok(())
    }

    fn output_handle(&self, channel: &AnalogChannel) -> Result<Box<dyn OutputHandle>, DaqError> {
        if *channel != self.valve {
            return Err(self.wrong_channel(channel.output_name()));
        }
        Ok(Box::new(VirtualOutput {
            hw: Arc::clone(&self.hw),
            time: self.time.clone(),
            channel: *channel,
        }))
    }
}

/// The virtual valve output, for the watchdog and the panic hook.
struct VirtualOutput {
    hw: Arc<Mutex<Hardware>>,
    time: TimeSource,
    channel: AnalogChannel,
}

impl OutputHandle for VirtualOutput {
    fn write(&self, volts: f64) -> Result<(), DaqError> {
        let mut hw = lock(&self.hw);
        let steps = self.time.steps(hw.step_s);
        hw.write_valve(&self.channel, volts, steps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sixteen_bit_converter_quantises_and_saturates_to_nan() {
        let c = Converter::new([0.0, 10.0], 16);
        let lsb = 10.0 / 65535.0;
        let v = c.sample(3.3);
        assert!((v - 3.3).abs() <= lsb / 2.0 + 1e-12);
        assert!(c.sample(0.0).is_nan() && c.sample(10.0).is_nan() && c.sample(-1.0).is_nan());
        assert!(c.sample(f64::NAN).is_nan());
        assert_eq!(c.output(11.0), None);
        assert_eq!(Converter::new([0.0, 10.0], 0).sample(3.3), 3.3);
    }

    #[test]
    fn the_lockstep_plant_step_does_not_grow_with_the_period() {
        assert_eq!(lockstep_substeps(4, 1e-4), 4);
        assert_eq!(lockstep_substeps(4, 1e-3), 4);
        assert_eq!(lockstep_substeps(4, 3e-3), 12);
        assert_eq!(lockstep_substeps(4, 1e-2), 40);
        assert_eq!(lockstep_substeps(1000, 1e-2), 10_000);
    }

    /// The virtual rig of the shipped configuration at `period_s`.
    fn virtual_daq_at(period_s: f64) -> (VirtualDaq, RigConfig) {
        // The frozen-sensor check at its 0.5 s, the rate limit at most half the range a
        // period (the configuration's ranges at this period).
        let text = crate::config::EMBEDDED_VIRTUAL
            .replace("period_s = 0.001", &format!("period_s = {period_s}"))
            .replace("watchdog_periods = 50", "watchdog_periods = 20")
            .replace(
                "sensor_stuck_periods = 500",
                &format!("sensor_stuck_periods = {}", (0.5 / period_s).floor()),
            )
            .replace(
                "pressure_rate_max_pa_per_s = 2.0e8",
                &format!(
                    "pressure_rate_max_pa_per_s = {:e}",
                    2.0e8f64.min(3.0e5 / period_s)
                ),
            );
        let cfg = RigConfig::from_toml_str(&text, "virtual.toml").expect("config");
        (VirtualDaq::new(&cfg, &[]).expect("virtual rig"), cfg)
    }

    /// Regression: at a 10 ms period the lockstep plant took 2.5 ms trapezoidal steps,
    /// which ring on the muscle's damping pole: held at 2.17 bar the simulated load settled
    /// 2.6 mm higher than at 1 ms, and in `rig excite` at 10 ms it rose 10 mm in the 30 ms
    /// after the command fell from 2.17 bar to at most 1 bar, going `position-out` despite
    /// the back-off (at 5 ms too).
    #[test]
    fn the_virtual_muscle_at_a_10_ms_period_moves_as_at_1_ms() {
        let trajectory = |period_s: f64| -> Vec<f64> {
            let (mut daq, cfg) = virtual_daq_at(period_s);
            let clock = daq.lockstep_clock().expect("lockstep");
            let valve = cfg.signals.valve;
            let periods_per_10_ms = (0.01 / period_s).round() as usize;
            let mut run = |pa: f64, seconds: f64| {
                daq.write_analog(&valve, cfg.calibration.valve_v(pa))
                    .expect("write");
                let mut sampled = Vec::new();
                for k in 0..(seconds / period_s).round() as usize {
                    clock.tick();
                    daq.read_analog(&cfg.signals.position).expect("read");
                    if (k + 1) % periods_per_10_ms == 0 {
                        sampled.push(daq.probe().state().position_m);
                    }
                }
                sampled
            };
            let mut held = run(2.1666e5, 3.0);
            held.extend(run(0.0, 0.1));
            held
        };
        let fine = trajectory(1e-3);
        let coarse = trajectory(1e-2);
        assert_eq!(fine.len(), coarse.len());
        // Sample for sample, every 10 ms, held and vented.
        for (a, b) in fine.iter().zip(&coarse) {
            assert!((a - b).abs() < 2e-4, "{a} m at 1 ms against {b} m at 10 ms");
        }
    }

    #[test]
    fn injections_parse_and_name_the_problem() {
        let i: Injection = "sensor-nan@5".parse().unwrap();
        assert_eq!(i.fault, InjectedFault::SensorNan);
        assert_eq!(i.at_s, 5.0);
        assert!("sensor-nan"
            .parse::<Injection>()
            .unwrap_err()
            .contains("FAULT@SECONDS"));
        assert!("smoke@1"
            .parse::<Injection>()
            .unwrap_err()
            .contains("unknown fault `smoke`"));
        assert!("stall@-1"
            .parse::<Injection>()
            .unwrap_err()
            .contains("seconds"));
    }
}
