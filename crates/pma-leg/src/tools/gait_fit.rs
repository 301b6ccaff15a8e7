//! A gait reference made consistent with a trainer's belt.
//!
//! The adults' hip and knee angles were measured against their own pelvis, which rocked,
//! rotated and pitched; replayed rigidly on a trainer whose pelvis does none of that, they
//! move a stance foot back relative to the hip at 0.18-0.70 m/s over a stance at 0.50 m/s
//! (the shipped legs, feet and orthoses; docs/treadmill.md). A foot stuck on the belt
//! cannot follow: the pelvis is thrown back and forth, two stance feet squeeze each other
//! through friction, and the servos that replay the reference pay for it (3.8 N m/kg at
//! the hip).
//!
//! [`fit_gait`] finds the hip curve, within the data's harmonics, along which each stance
//! foot moves back at one constant speed relative to the hip, the belt's: an iterative
//! learning loop on the servo-driven trainer itself (its contacts, passive ankles and
//! harness), which measures where the stance contact runs ahead or behind and changes the
//! hip's rate there by that speed over the lever `dx/d(hip)`, then runs the belt at the
//! stance's mean speed. The knee keeps the data's curve; the swing phase is unchanged but
//! for what the harmonics spread into it.
//!
//! The stance's mean contact speed is not quite the belt a stance foot agrees with: the
//! contact point rolls over heel, sole and toe while the elastic contact sticks, and a belt
//! 1 % faster than the feet shears them back all stance long, a drag the harness then
//! holds (58 N on `gait_treadmill`, 0.6 N m/kg more at the hip; docs/treadmill.md). By
//! default ([`BeltRule::NoHarnessDrag`]) the fit then sets the belt, by secant steps on
//! the fitted stance, where the harness carries no mean fore-aft force: a person walking
//! steadily exchanges no net fore-aft impulse with the belt over a stride.
use crate::base::{invalid, LegError};
use crate::body::Mount;
use crate::gait::{FourierSeries, GaitReference};
use crate::scenario::LoadedScenario;
use crate::sim::build_exo;
use crate::tools::{stride_demand, Demand};

/// What the body's fore-aft speed does over a stride, which the stance feet's speed
/// relative to the hip has to give.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BodySpeed {
    /// Constant: each stance foot moves back at the belt's speed, the pelvis stands still.
    #[default]
    Constant,
    /// Swinging as the adults' does: the pelvis's speed is the integral of the normative
    /// fore-aft ground reaction of both feet (Fukuchi et al. 2018, at the gait's speed)
    /// over the body's mass, the reaction scaled by the share of the weight the belt
    /// carries; zero mean.
    Normative,
}

/// How the belt's speed is chosen for the fitted stance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BeltRule {
    /// The stance contact's mean speed relative to the hip (the rule the hip's fit itself
    /// runs with).
    StanceMean,
    /// Where the harness carries no mean fore-aft force over the measured strides: the
    /// belt neither drags the patient back against the harness nor pushes them forward.
    #[default]
    NoHarnessDrag,
}

/// How a fit runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GaitFitSettings {
    /// Servo-driven runs (each the start-up ramp, one stride and `strides` measured).
    pub iterations: usize,
    /// Share of each measured speed error corrected per iteration (0-1].
    pub gain: f64,
    /// Strides measured per run.
    pub strides: usize,
    /// The body's speed over the stride the stance is fitted to.
    pub body_speed: BodySpeed,
    /// How the belt's speed is set once the hip is fitted.
    pub belt: BeltRule,
}

impl Default for GaitFitSettings {
    fn default() -> Self {
        Self {
            iterations: 15,
            gain: 0.8,
            strides: 3,
            body_speed: BodySpeed::Constant,
            belt: BeltRule::NoHarnessDrag,
        }
    }
}

impl GaitFitSettings {
    /// Range checks, naming the field.
    pub fn validate(&self) -> Result<(), LegError> {
        if !(1..=100).contains(&self.iterations) {
            return Err(invalid(
                "iterations",
                self.iterations as f64,
                "must be 1 to 100",
            ));
        }
        if !(self.gain > 0.0 && self.gain <= 1.0) {
            return Err(invalid("gain", self.gain, "must be in (0, 1]"));
        }
        if !(1..=50).contains(&self.strides) {
            return Err(invalid("strides", self.strides as f64, "must be 1 to 50"));
        }
        Ok(())
    }
}

/// One servo-driven run of a fit.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct GaitFitStep {
    /// 0 for the data's hip as measured.
    pub iteration: usize,
    /// The belt's speed in this run (m/s).
    pub belt_speed_m_s: f64,
    /// RMS over the stance of the contact's speed relative to the hip plus the belt's
    /// (m/s): zero when every stance foot moves with the belt.
    pub contact_speed_error_rms_m_s: f64,
    /// Largest |joint torque| of the servos per kilogram of body mass, hip and knee
    /// (N m/kg; the 10 ms averaged demand `size` takes).
    pub peak_demand_nm_kg: [f64; 2],
    /// The feet's slip per stride, the mean over strides of the worst foot (m).
    pub slip_per_stride_m: f64,
    /// Largest vertical loading peak of a foot over the belt's mean load.
    pub grf_peak_over_belt_load: f64,
    /// The harness's mean fore-aft force on the pelvis over the measured strides (N,
    /// forward positive: the belt drags the patient back).
    pub harness_fore_aft_mean_n: f64,
}

/// A fitted hip correction and the belt speed it walks at.
#[derive(Debug, Clone, PartialEq)]
pub struct GaitFit {
    /// Added to the data's hip (deg over the cycle): `[gait.hip_correction]`.
    pub hip_correction: FourierSeries,
    /// The belt's speed with it (m/s): `[treadmill] speed_m_per_s`.
    pub belt_speed_m_s: f64,
    /// Every run, the data's first.
    pub steps: Vec<GaitFitStep>,
    /// Which run is the result: the least contact speed error.
    pub best: usize,
    /// The runs that set the belt on the kept hip ([`BeltRule::NoHarnessDrag`]; empty
    /// otherwise), numbered from 0; the belt is the one of least |harness force|.
    pub belt_steps: Vec<GaitFitStep>,
}

impl GaitFit {
    /// How far the belt without drag lies from the kept run's stance speed, as a share of
    /// the latter (negative: slower); `None` without a belt search. More than a few
    /// percent says the stance does not move with a belt at all: the harness's force then
    /// comes from feet sliding, not from a belt slightly too fast.
    pub fn belt_off_stance(&self) -> Option<f64> {
        let stance = self.steps.get(self.best)?.belt_speed_m_s;
        (!self.belt_steps.is_empty()).then(|| self.belt_speed_m_s / stance - 1.0)
    }
}

/// A belt without drag further than this share from the stance's speed is reported as a
/// stance that does not walk on the belt (`gait_treadmill`: -0.9 %; the same at 0 %
/// support, which does not walk: -12.5 %).
pub const BELT_OFF_STANCE_WARN: f64 = 0.03;

/// Most secant runs of the belt's search.
const BELT_RUNS: usize = 8;
/// A mean harness force this small (N) ends the belt's search.
const BELT_TOLERANCE_N: f64 = 0.5;
/// The first step's slope of the harness's mean force over the belt's speed (N per m/s):
/// the held pelvis of `gait_treadmill` measured 8,000 (docs/treadmill.md); the secant
/// takes over from the second run.
const DRAG_SLOPE_GUESS_N_S_PER_M: f64 = 8.0e3;
/// Largest change of the belt per run of its search (m/s).
const BELT_STEP_MAX_M_S: f64 = 0.02;

/// Phase bins over a cycle in which the contact's speed is averaged.
const BINS: usize = 200;

/// The hip correction that makes `loaded`'s treadmill stance move with its belt, from the
/// data's hip as measured (a correction the scenario already has is ignored; the belt runs
/// at the reference's speed in the first run). `should_stop` is polled between runs: a
/// stop returns the best so far.
pub fn fit_gait(
    loaded: &LoadedScenario,
    settings: &GaitFitSettings,
    should_stop: impl Fn() -> bool,
) -> Result<GaitFit, LegError> {
    settings.validate()?;
    let Some(treadmill) = &loaded.scenario.treadmill else {
        return Err(no_treadmill(loaded));
    };
    let body_mass_kg = treadmill.body_mass_kg;
    let mut run = loaded.clone();
    // From the data and the reference's own belt speed, whatever the scenario holds, so
    // that a fitted scenario refits to what it holds.
    run.scenario.gait.hip_correction = None;
    if let Some(t) = &mut run.scenario.treadmill {
        t.speed_m_per_s = None;
    }
    let data = run.scenario.gait.reference()?;
    let lever = HipLever::new(&run)?;
    let body = match settings.body_speed {
        BodySpeed::Constant => vec![0.0; BINS],
        BodySpeed::Normative => normative_body_speed(&run, data.stride_period_s())?,
    };
    let mut correction = FourierSeries::default();
    let mut steps = Vec::with_capacity(settings.iterations + 1);
    // The run kept: its index, correction, belt speed and contact speed error.
    let mut kept = (0, correction, f64::NAN, f64::NAN);
    for iteration in 0..=settings.iterations {
        let demand = stride_demand(&run, settings.strides)?;
        let speeds = StanceSpeeds::of(&demand, data.toe_off_phase(), &body);
        let belt = demand
            .treadmill
            .as_ref()
            .map_or(f64::NAN, |t| t.belt_speed_m_s);
        let step = step_figures(iteration, &demand, &speeds, belt, body_mass_kg);
        let error = step.contact_speed_error_rms_m_s;
        if iteration == 0 || error < kept.3 {
            kept = (iteration, correction, belt, error);
        }
        steps.push(step);
        if iteration == settings.iterations || should_stop() {
            break;
        }
        let reference = data.with_hip_correction(&correction);
        let change = speeds.hip_change_deg(&reference, &lever, settings.gain)?;
        correction = correction.plus(&change);
        run.scenario.gait.hip_correction = Some(correction);
        let next = -speeds.mean_stance_m_s;
        if !(next.is_finite() && (0.0..=crate::ground::BELT_SPEED_MAX_M_S).contains(&next)) {
            // A speed the fit computed, not one the file holds: say so, not as a field.
            return Err(LegError::Unsupported {
                name: "fit-gait".into(),
                value: format!("run {iteration}"),
                message: format!(
                    "the stance foot moved at {} m/s, which no belt runs (0 to {} m/s): the fit diverges; lower --gain or give more --strides",
                    pma_model::error::number(-next),
                    crate::ground::BELT_SPEED_MAX_M_S
                ),
            });
        }
        if let Some(t) = &mut run.scenario.treadmill {
            t.speed_m_per_s = Some(next);
        }
    }
    let (best, hip_correction, stance_belt_m_s, _) = kept;
    let mut fit = GaitFit {
        hip_correction,
        belt_speed_m_s: stance_belt_m_s,
        steps,
        best,
        belt_steps: Vec::new(),
    };
    if settings.belt == BeltRule::NoHarnessDrag && !should_stop() {
        run.scenario.gait.hip_correction = Some(hip_correction);
        let search = BeltSearch {
            toe_off: data.toe_off_phase(),
            body: &body,
            strides: settings.strides,
            body_mass_kg,
        };
        fit.belt_steps = search.run(&mut run, stance_belt_m_s, &should_stop)?;
        if let Some(least) = fit.belt_steps.iter().min_by(|a, b| {
            a.harness_fore_aft_mean_n
                .abs()
                .total_cmp(&b.harness_fore_aft_mean_n.abs())
        }) {
            fit.belt_speed_m_s = least.belt_speed_m_s;
        }
    }
    Ok(fit)
}

/// The belt's search on a fitted hip: what its runs measure with.
struct BeltSearch<'a> {
    toe_off: f64,
    body: &'a [f64],
    strides: usize,
    body_mass_kg: f64,
}

impl BeltSearch<'_> {
    /// Secant steps on the harness's mean fore-aft force from `start_m_s`, until it is
    /// within [`BELT_TOLERANCE_N`], [`BELT_RUNS`] ran, the force stops responding to the
    /// belt, or `should_stop`.
    fn run(
        &self,
        run: &mut LoadedScenario,
        start_m_s: f64,
        should_stop: &impl Fn() -> bool,
    ) -> Result<Vec<GaitFitStep>, LegError> {
        let mut steps: Vec<GaitFitStep> = Vec::with_capacity(BELT_RUNS);
        let mut belt = start_m_s;
        for k in 0..BELT_RUNS {
            if let Some(t) = &mut run.scenario.treadmill {
                t.speed_m_per_s = Some(belt);
            }
            let demand = stride_demand(run, self.strides)?;
            let speeds = StanceSpeeds::of(&demand, self.toe_off, self.body);
            let step = step_figures(k, &demand, &speeds, belt, self.body_mass_kg);
            let force = step.harness_fore_aft_mean_n;
            let slope = match steps.last() {
                Some(last) => (force - last.harness_fore_aft_mean_n) / (belt - last.belt_speed_m_s),
                None => DRAG_SLOPE_GUESS_N_S_PER_M,
            };
            steps.push(step);
            // A faster belt drags harder; a force that does not grow with it (a pelvis
            // free to follow the feet) has no root to step to.
            if !force.is_finite()
                || force.abs() < BELT_TOLERANCE_N
                || !(slope.is_finite() && slope > 0.0)
                || should_stop()
            {
                break;
            }
            belt -= (force / slope).clamp(-BELT_STEP_MAX_M_S, BELT_STEP_MAX_M_S);
        }
        Ok(steps)
    }
}

fn no_treadmill(loaded: &LoadedScenario) -> LegError {
    LegError::Parse {
        file: loaded.scenario.name.clone(),
        message: "fitting a gait to a belt needs a treadmill scenario ([treadmill])".into(),
    }
}

fn too_few_bins() -> LegError {
    invalid("bins", BINS as f64, "too few for the harmonics")
}

/// A run's figures.
fn step_figures(
    iteration: usize,
    demand: &Demand,
    speeds: &StanceSpeeds,
    belt_speed_m_s: f64,
    body_mass_kg: f64,
) -> GaitFitStep {
    let peak = |j: usize| {
        let [lo, hi] = demand.torque_range_nm(j);
        lo.abs().max(hi.abs()) / body_mass_kg
    };
    let harness = demand
        .treadmill
        .as_ref()
        .map_or(f64::NAN, |t| t.harness_fore_aft_n.mean);
    let (slip, grf) = demand.treadmill.as_ref().map_or((f64::NAN, f64::NAN), |t| {
        let slip = t
            .feet
            .values()
            .map(|f| f.slip_per_stride_m.mean)
            .fold(0.0, f64::max);
        let grf = t
            .feet
            .values()
            .map(|f| f.peak_grf_bw.max)
            .fold(0.0, f64::max)
            / t.expected_belt_load_bw;
        (slip, grf)
    });
    GaitFitStep {
        iteration,
        belt_speed_m_s,
        contact_speed_error_rms_m_s: speeds.error_rms(belt_speed_m_s),
        peak_demand_nm_kg: [peak(0), peak(1)],
        slip_per_stride_m: slip,
        grf_peak_over_belt_load: grf,
        harness_fore_aft_mean_n: harness,
    }
}

/// The body's fore-aft speed over the cycle (m/s, zero mean, per phase bin) as the adults'
/// swings at the scenario's gait speed: the integral of both feet's normative fore-aft
/// reaction over the body's mass, the reaction scaled by the belt's share of the weight.
fn normative_body_speed(loaded: &LoadedScenario, period_s: f64) -> Result<Vec<f64>, LegError> {
    let Some(speed) = loaded.scenario.gait.speed_m_per_s else {
        return Err(LegError::Missing {
            name: "gait.speed_m_per_s".into(),
            hint: "a normative body speed needs the adults' data (gait.data = \"fukuchi2018\")",
        });
    };
    let norms = crate::gait::AdultNorms::at(speed)?;
    let f = &norms.curves.grf_fore_aft_bw;
    let load = loaded
        .scenario
        .treadmill
        .as_ref()
        .map_or(1.0, |t| 1.0 - t.bws_fraction);
    let at = |phase: f64| {
        let x = phase.rem_euclid(1.0) * (f.len() - 1) as f64;
        let (i, w) = (x.floor() as usize, x.fract());
        f[i.min(f.len() - 1)] * (1.0 - w) + f[(i + 1).min(f.len() - 1)] * w
    };
    let dt = period_s / BINS as f64;
    let force: Vec<f64> = (0..BINS)
        .map(|k| {
            let phase = (k as f64 + 0.5) / BINS as f64;
            at(phase) + at(phase + 0.5)
        })
        .collect();
    // The data's net fore-aft impulse over a stride (the treadmill's, or the averaging's)
    // is taken out: a walker at a steady speed has none.
    let net = force.iter().sum::<f64>() / BINS as f64;
    let mut v = 0.0;
    let mut speeds: Vec<f64> = force
        .iter()
        .map(|f| {
            v += (f - net) * pma_model::GRAVITY_M_S2 * load * dt;
            v
        })
        .collect();
    let mean = speeds.iter().sum::<f64>() / BINS as f64;
    for s in &mut speeds {
        *s -= mean;
    }
    Ok(speeds)
}

/// The stance contact's speed relative to the hip over the cycle, averaged over strides
/// and legs in phase bins.
struct StanceSpeeds {
    /// Mean speed per bin (m/s; NaN where no stance foot was measured).
    per_bin_m_s: Vec<f64>,
    /// Whether a bin lies in the reference's stance and was measured.
    stance: Vec<bool>,
    /// Their mean over the stance bins (m/s, negative: backwards).
    mean_stance_m_s: f64,
    /// The body's speed per bin the stance has to give (m/s, zero mean): the contact's
    /// target is the stance's mean less it.
    body_m_s: Vec<f64>,
}

impl StanceSpeeds {
    fn of(demand: &Demand, toe_off: f64, body_m_s: &[f64]) -> Self {
        let mut sum = vec![0.0; BINS];
        let mut count = vec![0usize; BINS];
        for s in demand
            .samples
            .iter()
            .filter(|s| s.contact_speed_m_s.is_finite())
        {
            let bin = ((s.phase * BINS as f64) as usize).min(BINS - 1);
            sum[bin] += s.contact_speed_m_s;
            count[bin] += 1;
        }
        let per_bin_m_s: Vec<f64> = sum
            .iter()
            .zip(&count)
            .map(|(s, &c)| if c > 0 { s / c as f64 } else { f64::NAN })
            .collect();
        let stance: Vec<bool> = per_bin_m_s
            .iter()
            .enumerate()
            .map(|(k, v)| v.is_finite() && (k as f64 + 0.5) / (BINS as f64) < toe_off)
            .collect();
        let (total, n) = per_bin_m_s
            .iter()
            .zip(&stance)
            .filter(|(_, &st)| st)
            .fold((0.0, 0usize), |(t, n), (v, _)| (t + v, n + 1));
        Self {
            per_bin_m_s,
            stance,
            mean_stance_m_s: if n > 0 { total / n as f64 } else { f64::NAN },
            body_m_s: body_m_s.to_vec(),
        }
    }

    /// RMS of the contact's speed plus the belt's over the stance (m/s).
    fn error_rms(&self, belt_speed_m_s: f64) -> f64 {
        let (sq, n) = self
            .per_bin_m_s
            .iter()
            .zip(&self.stance)
            .zip(&self.body_m_s)
            .filter(|((_, &st), _)| st)
            .fold((0.0, 0usize), |(sq, n), ((v, _), u)| {
                (sq + (v + belt_speed_m_s + u).powi(2), n + 1)
            });
        if n > 0 {
            (sq / n as f64).sqrt()
        } else {
            f64::NAN
        }
    }

    /// The change of the hip (deg over the cycle, as a series) that takes out `gain` of
    /// each stance bin's deviation from the stance's mean speed: the hip's rate changed by
    /// the deviation over the lever, integrated over the stance, the drift it leaves at
    /// toe-off taken out linearly so that the swing keeps its curve.
    fn hip_change_deg(
        &self,
        reference: &GaitReference,
        lever: &HipLever,
        gain: f64,
    ) -> Result<FourierSeries, LegError> {
        let period = reference.stride_period_s();
        let dt = period / BINS as f64;
        let mut change = vec![0.0; BINS];
        let mut angle = 0.0;
        let mut last_stance = 0;
        let bins = self
            .stance
            .iter()
            .zip(&self.per_bin_m_s)
            .zip(change.iter_mut());
        for (k, ((&stance, speed), c)) in bins.enumerate() {
            if !stance {
                continue;
            }
            let phase = (k as f64 + 0.5) / BINS as f64;
            let dx_dhip = lever.at(reference, phase);
            let target = self.mean_stance_m_s - self.body_m_s[k];
            angle -= gain * (speed - target) / dx_dhip * dt;
            *c = angle;
            last_stance = k;
        }
        let drift = change[last_stance];
        for (k, c) in change.iter_mut().enumerate().take(last_stance + 1) {
            *c = (*c - drift * k as f64 / last_stance.max(1) as f64).to_degrees();
        }
        for c in change.iter_mut().skip(last_stance + 1) {
            *c = 0.0;
        }
        FourierSeries::project(&change).ok_or_else(too_few_bins)
    }
}

/// How far a stance foot moves fore-aft per radian of hip flexion (m/rad), from the
/// trainer's sagittal chain.
struct HipLever {
    chain: crate::ground::SagittalChain,
}

impl HipLever {
    fn new(loaded: &LoadedScenario) -> Result<Self, LegError> {
        let exo = build_exo(loaded, Mount::default())?;
        let chain = exo
            .ground()
            .map(|g| g.chain().clone())
            .ok_or_else(|| no_treadmill(loaded))?;
        if chain.spheres.is_empty() {
            return Err(LegError::Parse {
                file: loaded.urdf_source.clone(),
                message: "the foot has no contact spheres".into(),
            });
        }
        Ok(Self { chain })
    }

    /// `dx/d(hip)` of the foot's first sphere at `phase` of `reference` (m/rad; the
    /// spheres of a rigid foot move alike).
    fn at(&self, reference: &GaitReference, phase: f64) -> f64 {
        let t = reference.measured_from_s() + phase * reference.stride_period_s();
        let q = reference.sample(t).angles_rad();
        self.chain.sphere_jacobian(0, q)[0][0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_settings_name_their_field() {
        let bad = [
            (
                GaitFitSettings {
                    iterations: 0,
                    ..Default::default()
                },
                "iterations",
            ),
            (
                GaitFitSettings {
                    gain: f64::NAN,
                    ..Default::default()
                },
                "gain",
            ),
            (
                GaitFitSettings {
                    strides: 0,
                    ..Default::default()
                },
                "strides",
            ),
        ];
        for (s, field) in bad {
            let e = s.validate().expect_err("refused").to_string();
            assert!(e.contains(field), "{e}");
        }
    }

    #[test]
    fn the_normative_body_speed_swings_about_zero_twice_a_stride() {
        let loaded = crate::scenario::Scenario::load("gait_treadmill").expect("embedded");
        let v = normative_body_speed(&loaded, 1.75).expect("adult data");
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        assert!(mean.abs() < 1e-12, "{mean}");
        let (lo, hi) = v
            .iter()
            .fold((f64::MAX, f64::MIN), |(l, h), x| (l.min(*x), h.max(*x)));
        // Both feet's reaction: the swing repeats every half stride.
        let half = BINS / 2;
        for k in 0..half {
            assert!((v[k] - v[k + half]).abs() < 1e-3 * (hi - lo), "{k}");
        }
        // Slow walking at 70 % of the weight: a few centimetres per second.
        assert!((0.005..0.3).contains(&(hi - lo)), "{lo}..{hi}");
    }

    #[test]
    fn an_in_air_scenario_cannot_be_fitted_to_a_belt() {
        let loaded = crate::scenario::Scenario::load("gait_training").expect("embedded");
        let e = fit_gait(&loaded, &GaitFitSettings::default(), || false)
            .expect_err("no treadmill")
            .to_string();
        assert!(e.contains("treadmill"), "{e}");
    }
}
