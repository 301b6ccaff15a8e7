//! Shocks: what the paper's first sentence is about ("unpredictable shocks which lead to
//! the sudden change of desired trajectories and large tracking errors"). A reference that
//! jumps, a load blocked and then released, an impact on the load; and what a controller
//! does through each: overshoot, peak speed, command rate, time at the valve limits,
//! settling time and error integral, measured per event.
use pma_bench::{BenchState, Disturbance, MuscleBench};
use pma_control::MuscleStep;
use pma_control::{JumpReference, Reference, SineReference};
use pma_loop::{Period, Recorder, Start};
use serde::Serialize;

/// The jump reference: 5 mm, 25 mm from [`JUMP_UP_S`], 5 mm again from [`JUMP_DOWN_S`].
pub const JUMP_LOW_M: f64 = 0.005;
/// Its upper level (m).
pub const JUMP_HIGH_M: f64 = 0.025;
/// Up (s).
pub const JUMP_UP_S: f64 = 4.0;
/// Down (s).
pub const JUMP_DOWN_S: f64 = 10.0;
/// The obstacle appears (s): the sine is at 15 mm and rising.
pub const BLOCK_START_S: f64 = 8.0;
/// How long it holds the load (s); it lets go at the sine's top.
pub const BLOCK_S: f64 = 1.0;
/// The impact (s): the sine at 26 mm, rising.
pub const IMPACT_START_S: f64 = 8.5;
/// Its duration (s).
pub const IMPACT_S: f64 = 0.030;
/// Its force (N): about six times the load's weight.
pub const IMPACT_N: f64 = 150.0;
/// How long after an event its figures are taken (s), unless the next event comes first.
pub const WINDOW_S: f64 = 3.0;
/// Within this of the reference the load has settled (m).
pub const SETTLED_M: f64 = 0.5e-3;

/// A reference by name: the paper's `sine`, its `chirp`, or the `jump`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum RefKind {
    /// The paper's sine.
    Sine,
    /// The paper's chirp.
    Chirp,
    /// 5 mm, 25 mm at 4 s, 5 mm at 10 s.
    Jump,
}

impl RefKind {
    /// Every reference, by its name.
    pub const ALL: [(RefKind, &'static str); 3] = [
        (RefKind::Sine, "sine"),
        (RefKind::Chirp, "chirp"),
        (RefKind::Jump, "jump"),
    ];

    /// Name.
    pub fn name(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(k, _)| *k == self)
            .map_or("?", |(_, n)| n)
    }

    /// The trajectory.
    pub fn reference(self) -> Box<dyn Reference> {
        match self {
            RefKind::Sine => Box::new(SineReference::paper()),
            RefKind::Chirp => Box::new(pma_control::ChirpReference::paper()),
            RefKind::Jump => Box::new(JUMP),
        }
    }
}

/// The jump: 5 mm, 25 mm from 4 s, 5 mm again from 10 s.
pub const JUMP: JumpReference = JumpReference {
    low_m: JUMP_LOW_M,
    high_m: JUMP_HIGH_M,
    up_s: JUMP_UP_S,
    down_s: JUMP_DOWN_S,
};

/// What happens to the load besides the reference.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Event {
    /// Nothing.
    None,
    /// An obstacle holds the load for [`BLOCK_S`], then lets go.
    Block,
    /// [`IMPACT_N`] lifting the load for [`IMPACT_S`].
    ImpactUp,
    /// The same pushing it down.
    ImpactDown,
}

impl Event {
    /// Every event, by its name.
    pub const ALL: [(Event, &'static str); 4] = [
        (Event::None, "none"),
        (Event::Block, "block"),
        (Event::ImpactUp, "impact-up"),
        (Event::ImpactDown, "impact-down"),
    ];

    /// Name.
    pub fn name(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(k, _)| *k == self)
            .map_or("?", |(_, n)| n)
    }

    /// The disturbance on the bench.
    pub fn disturbance(self) -> Disturbance {
        match self {
            Event::None => Disturbance::None,
            Event::Block => Disturbance::Obstacle {
                start_s: BLOCK_START_S,
                duration_s: BLOCK_S,
            },
            Event::ImpactUp | Event::ImpactDown => Disturbance::ForcePulse {
                start_s: IMPACT_START_S,
                duration_s: IMPACT_S,
                force_n: if self == Event::ImpactUp {
                    IMPACT_N
                } else {
                    -IMPACT_N
                },
            },
        }
    }
}

/// The instants whose aftermath is measured: the reference's jumps and the event.
pub fn onsets(reference: RefKind, event: Event) -> Vec<(&'static str, f64)> {
    let mut v = Vec::new();
    if reference == RefKind::Jump {
        v.push(("jump up", JUMP_UP_S));
        v.push(("jump down", JUMP_DOWN_S));
    }
    match event {
        Event::None => {}
        Event::Block => v.push(("release", BLOCK_START_S + BLOCK_S)),
        Event::ImpactUp => v.push(("impact up", IMPACT_START_S)),
        Event::ImpactDown => v.push(("impact down", IMPACT_START_S)),
    }
    v.sort_by(|a, b| a.1.total_cmp(&b.1));
    v
}

/// What a controller did after one event.
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct EventMetrics {
    /// The event (`jump up`, `release`, `impact down`, ...).
    pub name: String,
    /// When (s).
    pub t_s: f64,
    /// End of its window (s).
    pub window_end_s: f64,
    /// Largest |x_d - x| in the window (m).
    pub peak_error_m: f64,
    /// How far the load went past the reference against the first excursion, i.e. beyond
    /// where the correction should stop (m, >= 0). The first excursion is the first error
    /// over 0.5 mm after the event: the jump itself, the lag behind the blocked reference,
    /// the push of the impact.
    pub overshoot_m: f64,
    /// Largest |load speed| (m/s).
    pub peak_speed_m_s: f64,
    /// Largest |du/dt| of the pressure command (bar/s).
    pub peak_command_rate_bar_per_s: f64,
    /// Time the command spent at 0 or at the valve's maximum (s).
    pub limit_time_s: f64,
    /// From the event to the last instant the error exceeded 0.5 mm (s); `None` if it still
    /// did at the end of the window.
    pub settling_s: Option<f64>,
    /// Integral of |x_d - x| over the window (m s).
    pub error_integral_m_s: f64,
    /// Largest contact force of the obstacle since the run started (N).
    pub peak_contact_force_n: f64,
}

#[derive(Debug, Clone, Copy)]
struct Window {
    t_s: f64,
    end_s: f64,
    peak_abs: f64,
    direction: f64,
    overshoot: f64,
    peak_speed: f64,
    peak_rate: f64,
    limit_s: f64,
    last_unsettled: Option<f64>,
    integral: f64,
}

/// Measures every onset's window; allocates only when built.
pub struct EventRecorder {
    names: Vec<&'static str>,
    windows: Vec<Window>,
    pressure_max_pa: f64,
    previous_command_pa: f64,
    peak_contact_force_n: f64,
}

impl EventRecorder {
    /// For the onsets of `reference` and `event`, with the valve's maximum.
    pub fn new(reference: RefKind, event: Event, pressure_max_pa: f64) -> Self {
        let list = onsets(reference, event);
        let windows = list
            .iter()
            .enumerate()
            .map(|(i, &(_, t))| {
                let next = list.get(i + 1).map_or(f64::INFINITY, |o| o.1);
                Window {
                    t_s: t,
                    end_s: (t + WINDOW_S).min(next),
                    peak_abs: 0.0,
                    direction: 0.0,
                    overshoot: 0.0,
                    peak_speed: 0.0,
                    peak_rate: 0.0,
                    limit_s: 0.0,
                    last_unsettled: None,
                    integral: 0.0,
                }
            })
            .collect();
        Self {
            names: list.iter().map(|o| o.0).collect(),
            windows,
            pressure_max_pa,
            previous_command_pa: 0.0,
            peak_contact_force_n: 0.0,
        }
    }

    /// The figures of every event.
    pub fn metrics(&self) -> Vec<EventMetrics> {
        self.names
            .iter()
            .zip(&self.windows)
            .map(|(name, w)| EventMetrics {
                name: (*name).to_owned(),
                t_s: w.t_s,
                window_end_s: w.end_s,
                peak_error_m: w.peak_abs,
                overshoot_m: w.overshoot,
                peak_speed_m_s: w.peak_speed,
                peak_command_rate_bar_per_s: w.peak_rate / 1e5,
                limit_time_s: w.limit_s,
                settling_s: match w.last_unsettled {
                    None => Some(0.0),
                    Some(t) if t < w.end_s - 1.5e-3 => Some(t - w.t_s),
                    Some(_) => None,
                },
                error_integral_m_s: w.integral,
                peak_contact_force_n: self.peak_contact_force_n,
            })
            .collect()
    }

    fn push(&mut self, t: f64, dt: f64, e: f64, s: &BenchState, u: f64) {
        let rate = (u - self.previous_command_pa).abs() / dt;
        self.previous_command_pa = u;
        self.peak_contact_force_n = self.peak_contact_force_n.max(s.contact_force_n);
        let at_limit = u <= 0.0 || u >= self.pressure_max_pa;
        for w in self
            .windows
            .iter_mut()
            .filter(|w| t > w.t_s && t <= w.end_s)
        {
            w.peak_abs = w.peak_abs.max(e.abs());
            if w.direction == 0.0 && e.abs() > SETTLED_M {
                w.direction = e.signum();
            }
            // Past the reference, on the other side from the first excursion.
            w.overshoot = w.overshoot.max(-w.direction * e);
            w.peak_speed = w.peak_speed.max(s.velocity_m_s.abs());
            w.peak_rate = w.peak_rate.max(rate);
            if at_limit {
                w.limit_s += dt;
            }
            if e.abs() > SETTLED_M {
                w.last_unsettled = Some(t);
            }
            w.integral += e.abs() * dt;
        }
    }
}

impl Recorder<MuscleBench, MuscleStep> for EventRecorder {
    fn start(&mut self, s: &Start<'_, MuscleBench>) {
        self.previous_command_pa = *s.held;
    }

    fn record(&mut self, p: &Period<'_, MuscleBench, MuscleStep>) {
        let e = p.output.reference.position_m - p.truth.position_m;
        self.push(p.t_s, p.dt_s, e, p.truth, p.output.control.pressure_cmd_pa);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state(v: f64) -> BenchState {
        BenchState {
            position_m: 0.0,
            velocity_m_s: v,
            pressure_pa: 0.0,
            force_n: 0.0,
            contact_force_n: 0.0,
            external_force_n: 0.0,
        }
    }

    #[test]
    fn a_jump_with_overshoot_is_measured_by_hand() {
        let mut r = EventRecorder::new(RefKind::Jump, Event::None, 6e5);
        let dt = 0.1;
        // After the jump up the error is +20 mm, then the load overshoots by 3 mm, then
        // settles inside 0.5 mm from 4.6 s.
        let errors = [0.020, 0.010, -0.003, -0.001, 0.0002, 0.0001];
        for (k, e) in errors.iter().enumerate() {
            let t = JUMP_UP_S + (k + 1) as f64 * dt;
            r.push(t, dt, *e, &state(0.1 * k as f64), 1e5);
        }
        let m = &r.metrics()[0];
        assert_eq!(m.name, "jump up");
        assert_eq!(m.peak_error_m, 0.020);
        assert_eq!(m.overshoot_m, 0.003);
        assert!((m.peak_speed_m_s - 0.5).abs() < 1e-12);
        assert!((m.settling_s.expect("settled") - 0.4).abs() < 1e-9);
        assert!((m.error_integral_m_s - 0.1 * 0.0343).abs() < 1e-12);
        assert_eq!(m.window_end_s, JUMP_UP_S + WINDOW_S);
    }

    #[test]
    fn an_error_that_stays_is_not_settled() {
        let mut r = EventRecorder::new(RefKind::Sine, Event::ImpactDown, 6e5);
        let dt = 1e-3;
        let mut t = IMPACT_START_S;
        while t < IMPACT_START_S + WINDOW_S + 0.5 {
            t += dt;
            r.push(t, dt, 0.002, &state(0.0), 6e5);
        }
        let m = &r.metrics()[0];
        assert_eq!(m.settling_s, None);
        assert!((m.limit_time_s - WINDOW_S).abs() < 2e-3);
    }

    #[test]
    fn onsets_are_ordered_and_windows_stop_at_the_next() {
        let o = onsets(RefKind::Jump, Event::None);
        assert_eq!(o, vec![("jump up", 4.0), ("jump down", 10.0)]);
        assert_eq!(onsets(RefKind::Sine, Event::Block), vec![("release", 9.0)]);
    }
}
