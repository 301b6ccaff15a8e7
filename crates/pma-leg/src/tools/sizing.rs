//! Actuator dimensioning: for each joint, the Festo muscle sizes, nominal lengths and
//! pulley radii whose antagonistic pair supplies every torque a stride needs
//! ([`crate::demand`]) while each muscle stays within its rated force, its contraction range
//! and the speeds at which more pressure still pulls harder, at a co-contraction pressure
//! the regulator can hold.
//!
//! For a pulley of radius `r` the joint torque is `r (F_flexor - F_extensor)`; each force is
//! the Festo map's ([`pma_model::festo::FestoMuscle`]) less its damping, affine in its
//! pressure at a given contraction and speed: `F = alpha P - beta` with `alpha = dF/dP > 0`
//! only below the muscle's useful speed. With the pair's mean pressure held at `p_cc` (as
//! the co-contraction regulator does) and the pressures `p_cc +- delta`, every sample fixes
//! `delta`, hence both pressures and forces, which must then lie within `[0, p_max]` and
//! `[0, rated]`. The damping is taken as the inflating one (Table I's larger), the
//! conservative side. Each muscle is pre-contracted by [`PRE_CONTRACTION`] at the end of
//! the range where it is longest (a DMSP must not be stretched beyond its nominal length).
use crate::base::JOINT_NAMES;
use crate::plant::{MuscleGeometry, Side};
use crate::tools::Demand;
use pma_model::festo::{DmspSize, FestoMuscle, REST_LENGTH_RANGE_M};
use pma_model::DampingMode;

/// Contraction of each muscle where it is longest (strain): Festo's pretension limit is
/// 5 % of the nominal length (the notes' FluidSIM library entry); 2 % keeps every cable
/// taut without eating the stroke.
pub const PRE_CONTRACTION: f64 = 0.02;
/// Largest contraction (strain): Festo's maximum of 25 % of the nominal length.
pub const MAX_CONTRACTION: f64 = 0.25;
/// Pulley radii tried (m): 10 to 120 mm every 5 mm.
pub const PULLEY_RADII_M: [f64; 23] = [
    0.010, 0.015, 0.020, 0.025, 0.030, 0.035, 0.040, 0.045, 0.050, 0.055, 0.060, 0.065, 0.070,
    0.075, 0.080, 0.085, 0.090, 0.095, 0.100, 0.105, 0.110, 0.115, 0.120,
];
/// Nominal lengths tried (m): 100 mm to 2 m every 100 mm (up to `size --max-length-m`).
/// Up to 400 mm a muscle fits along the 429 mm thigh; longer ones sit on the trainer's frame
/// and pull the pulley through a cable (a 2 m muscle runs from the frame's top to the hip).
pub const REST_LENGTHS_M: [f64; 20] = [
    0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.6, 1.7, 1.8, 1.9,
    2.0,
];
/// The longest muscle that fits along the 429 mm thigh (m).
pub const THIGH_MUSCLE_MAX_M: f64 = 0.4;
/// Co-contraction pressures tried (Pa): 0.5 to 5 bar every 0.25 bar.
pub const COCONTRACTION_STEP_PA: f64 = 0.25e5;

/// One candidate pair on a joint and what it does over the stride.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PairDesign {
    /// Festo size of both muscles.
    pub size: &'static str,
    /// Nominal length (m).
    pub rest_length_m: f64,
    /// Pulley radius (m).
    pub pulley_radius_m: f64,
    /// Mean pressure of the pair (Pa).
    pub cocontraction_pa: f64,
    /// Largest force of either muscle over its rating.
    pub peak_force_over_rated: f64,
    /// Largest strain of either muscle.
    pub max_strain: f64,
    /// Largest contraction speed over the muscle's useful speed (pressure still helps
    /// below 1).
    pub speed_over_useful: f64,
    /// Smallest distance of either pressure to 0 or the valve's maximum, over the maximum.
    pub pressure_headroom: f64,
    /// The design's margin: the smallest of the force, pressure and speed headrooms (0-1).
    pub margin: f64,
}

/// Why a candidate does not work: the first rule one of the stride's samples breaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Reject {
    /// The range needs more than [`MAX_CONTRACTION`].
    Stroke,
    /// A muscle contracts faster than its useful speed: more pressure would pull less.
    Speed,
    /// A pressure below 0 or above the valve's maximum would be needed.
    Pressure,
    /// A muscle would have to push (go slack while its antagonist pulls too little).
    Slack,
    /// A force above the muscle's rating.
    Rating,
}

impl Reject {
    /// Its name, as in the JSON.
    pub fn as_str(self) -> &'static str {
        match self {
            Reject::Stroke => "stroke",
            Reject::Speed => "speed",
            Reject::Pressure => "pressure",
            Reject::Slack => "slack",
            Reject::Rating => "rating",
        }
    }
}

/// A joint's sizing.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct JointSizing {
    /// `hip` or `knee`.
    pub joint: String,
    /// The stride's joint range (deg), flexion positive.
    pub range_deg: [f64; 2],
    /// Largest extension and flexion torque (N m).
    pub torque_nm: [f64; 2],
    /// Largest |joint speed| (deg/s).
    pub peak_speed_deg_s: f64,
    /// Designs that work, per size: the number of (length, radius, co-contraction)
    /// combinations.
    pub feasible_per_size: Vec<(String, usize)>,
    /// Designs that do not, per size and per the first rule they break.
    pub rejected_per_size: Vec<(String, Vec<(Reject, usize)>)>,
    /// The recommended design, if any works.
    pub recommended: Option<PairDesign>,
    /// The co-contraction pressures (Pa) at which the recommended geometry works, lowest
    /// and highest of those tried (the regulator need not hold it exactly).
    pub recommended_cocontraction_range_pa: Option<[f64; 2]>,
    /// Why the recommendation sits at an edge of the range searched, if it does (the
    /// longest muscle or the largest pulley tried): a longer search could find a better one.
    pub at_edge: Option<String>,
}

/// The sizing of both joints.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Sizing {
    /// Hip, knee.
    pub joints: Vec<JointSizing>,
    /// The co-contraction pressure both recommended pairs work at (Pa), if there is one.
    pub cocontraction_pa: Option<f64>,
    /// The valve's maximum (Pa).
    pub pressure_max_pa: f64,
}

/// What a joint asks, sample by sample: angle (rad), speed (rad/s), torque (N m).
type JointSamples = Vec<(f64, f64, f64)>;

fn joint_samples(demand: &Demand, j: usize) -> JointSamples {
    demand
        .samples
        .iter()
        .map(|s| (s.angle_rad[j], s.velocity_rad_s[j], s.torque_nm[j]))
        .collect()
}

/// What a pair's muscles do over a joint's samples.
struct PairLoad {
    /// Largest force of either muscle (N).
    peak_n: f64,
    /// Smallest distance of either pressure to 0 or the valve's maximum, over the maximum.
    headroom: f64,
    /// Largest contraction speed over the useful speed.
    speed_ratio: f64,
    /// Largest contraction of either muscle (m).
    max_contraction_m: f64,
    /// Lowest and highest pressure asked of either muscle (Pa).
    pressure_range_pa: [f64; 2],
}

/// What a pair of `muscle`s on a pulley of `r` does at mean pressure `p_cc` over the
/// joint's `samples`, the flexor contracted by `c_f` and the extensor by `c_e` at zero
/// angle; the first rule a sample breaks if any (all but the rating, which the caller
/// weighs). Unless `strict`, only [`Reject::Speed`] ends it: the pressures the stride asks
/// are recorded wherever they are, and a muscle asked to push is not a rule (what a built
/// trainer's muscles do is measured, not designed: its controller saturates the valve).
fn pair_load(
    muscle: FestoMuscle,
    r: f64,
    (c_f, c_e): (f64, f64),
    (p_cc, p_max): (f64, f64),
    samples: &JointSamples,
    strict: bool,
) -> Result<PairLoad, Reject> {
    let (b0, b1) = {
        let b = |p: f64| muscle.damping(p, DampingMode::Inflation);
        (b(0.0), (b(1e5) - b(0.0)) / 1e5)
    };
    let mut load = PairLoad {
        peak_n: 0.0,
        headroom: 1.0,
        speed_ratio: 0.0,
        max_contraction_m: f64::NEG_INFINITY,
        pressure_range_pa: [f64::INFINITY, f64::NEG_INFINITY],
    };
    for &(q, qd, tau) in samples {
        // Contraction and its rate of each muscle: the flexor shortens with flexion.
        let muscles = [(c_f + r * q, r * qd), (c_e - r * q, -r * qd)];
        let [(alpha_f, beta_f), (alpha_e, beta_e)] = muscles.map(|(x, v)| {
            let per_pa = muscle.static_force_n(1e5, x) / 1e5;
            (per_pa - b1 * v, b0 * v)
        });
        if alpha_f <= 0.0 || alpha_e <= 0.0 {
            return Err(Reject::Speed);
        }
        for (x, v) in muscles {
            let useful = muscle.useful_speed_m_s(x, DampingMode::Inflation);
            load.speed_ratio = load.speed_ratio.max(v / useful);
            load.max_contraction_m = load.max_contraction_m.max(x);
        }
        let delta = (tau / r - p_cc * (alpha_f - alpha_e) + beta_f - beta_e) / (alpha_f + alpha_e);
        let (p_f, p_e) = (p_cc + delta, p_cc - delta);
        let (f_f, f_e) = (p_f * alpha_f - beta_f, p_e * alpha_e - beta_e);
        if strict && (p_f.min(p_e) < 0.0 || p_f.max(p_e) > p_max) {
            return Err(Reject::Pressure);
        }
        if strict && f_f.min(f_e) < 0.0 {
            return Err(Reject::Slack);
        }
        let [lo, hi] = &mut load.pressure_range_pa;
        *lo = lo.min(p_f.min(p_e));
        *hi = hi.max(p_f.max(p_e));
        load.peak_n = load.peak_n.max(f_f.max(f_e));
        load.headroom = load
            .headroom
            .min(p_f.min(p_e).min(p_max - p_f.max(p_e)) / p_max);
    }
    Ok(load)
}

/// Evaluates a pair of `muscle`s on a pulley of `r` at mean pressure `p_cc` over the
/// joint's `samples` ranging over `[lo, hi]` rad, each muscle [`PRE_CONTRACTION`]
/// contracted at its end of the range; the first rule a sample breaks if any.
fn evaluate(
    muscle: FestoMuscle,
    r: f64,
    (lo, hi): (f64, f64),
    p_cc: f64,
    p_max: f64,
    samples: &JointSamples,
) -> Result<PairDesign, Reject> {
    let l0 = muscle.rest_length_m;
    let pre = PRE_CONTRACTION * l0;
    let max_strain = (pre + r * (hi - lo)) / l0;
    if max_strain > MAX_CONTRACTION {
        return Err(Reject::Stroke);
    }
    let rated = muscle.size.rated_force_n();
    let offsets = (pre - r * lo, pre + r * hi);
    let load = pair_load(muscle, r, offsets, (p_cc, p_max), samples, true)?;
    if load.peak_n > rated {
        return Err(Reject::Rating);
    }
    let (peak, headroom, speed_ratio) = (load.peak_n, load.headroom, load.speed_ratio);
    Ok(PairDesign {
        size: muscle.size.name(),
        rest_length_m: l0,
        pulley_radius_m: r,
        cocontraction_pa: p_cc,
        peak_force_over_rated: peak / rated,
        max_strain,
        speed_over_useful: speed_ratio,
        pressure_headroom: headroom,
        margin: headroom.min(1.0 - peak / rated).min(1.0 - speed_ratio),
    })
}

/// A joint's fitted pair (the scenario's own muscles) against a servo-driven stride.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct FittedPair {
    /// `hip` or `knee`.
    pub joint: String,
    /// The muscles, as the datasheet names them (`Festo DMSP-20, 1.200 m on 110 mm`).
    pub muscles: String,
    /// Largest force of either muscle over its rating, if the pair can drive the stride.
    pub peak_force_over_rated: Option<f64>,
    /// The first rule the pair breaks on the stride besides the rating, the pressure's
    /// range and a push, if one: [`Reject::Speed`].
    pub reject: Option<Reject>,
    /// The lowest and highest pressure the stride asks of either muscle (bar), beyond the
    /// valve's range where the controller would saturate it.
    pub pressure_range_bar: Option<[f64; 2]>,
    /// Largest strain of either muscle, if the pair can drive the stride.
    pub max_strain: Option<f64>,
}

impl FittedPair {
    /// Whether the pair drives the stride within its rating and its stroke.
    pub fn fits(&self) -> bool {
        self.reject.is_none()
            && self.peak_force_over_rated.is_some_and(|f| f <= 1.0)
            && self.max_strain.is_some_and(|s| s <= MAX_CONTRACTION)
    }

    /// Why it does not fit, in words (`None` if it does).
    pub fn why_not(&self) -> Option<String> {
        if self.fits() {
            return None;
        }
        Some(
            match (self.reject, self.peak_force_over_rated, self.max_strain) {
                (Some(r), ..) => format!(
                    "the {}'s muscles ({}) cannot drive the stride ({})",
                    self.joint,
                    self.muscles,
                    r.as_str()
                ),
                (None, Some(f), Some(s)) if f <= 1.0 => format!(
                    "the {}'s muscles ({}) would contract by {:.0} % (at most {:.0} %)",
                    self.joint,
                    self.muscles,
                    100.0 * s,
                    100.0 * MAX_CONTRACTION
                ),
                (None, f, _) => format!(
                    "the {}'s muscles ({}) would pull {} times their rating",
                    self.joint,
                    self.muscles,
                    f.map_or("-".into(), |f| format!("{f:.2}"))
                ),
            },
        )
    }
}

/// Each joint's fitted pair (`muscles`, one leg's geometry: Festo muscles only) against
/// `demand` at mean pressure `p_cc` with a valve of `p_max`; empty where the muscles are
/// not a Festo pair per joint (Table I muscles: no datasheet to rate them against).
pub fn fitted_pairs(
    demand: &Demand,
    muscles: &[MuscleGeometry],
    p_cc: f64,
    p_max: f64,
) -> Vec<FittedPair> {
    let mut out = Vec::new();
    for (j, joint) in JOINT_NAMES.iter().take(2).enumerate() {
        let side = |s: Side| muscles.iter().find(|m| m.joint == *joint && m.side == s);
        let (Some(f), Some(e)) = (side(Side::Flexor), side(Side::Extensor)) else {
            continue;
        };
        let (Ok(Some(muscle)), Ok(Some(other))) = (f.festo(), e.festo()) else {
            continue;
        };
        // The sizing's pairs are alike on one pulley: a mixed pair is not rated here.
        if muscle != other || f.pulley_radius_m != e.pulley_radius_m {
            continue;
        }
        let r = f.pulley_radius_m;
        let offsets = (f.contraction_at_zero_m, e.contraction_at_zero_m);
        let samples = joint_samples(demand, j);
        let load = pair_load(muscle, r, offsets, (p_cc, p_max), &samples, false);
        let l0 = muscle.rest_length_m;
        out.push(FittedPair {
            joint: (*joint).to_owned(),
            muscles: format!(
                "Festo {}, {l0:.3} m on {:.0} mm",
                muscle.size.name().to_uppercase(),
                1e3 * r
            ),
            peak_force_over_rated: load
                .as_ref()
                .ok()
                .map(|l| l.peak_n / muscle.size.rated_force_n()),
            reject: load.as_ref().err().copied(),
            pressure_range_bar: load
                .as_ref()
                .ok()
                .map(|l| l.pressure_range_pa.map(|p| p / 1e5)),
            max_strain: load.ok().map(|l| l.max_contraction_m / l0),
        });
    }
    out
}

/// Every candidate of a joint at mean pressure `p_cc`: what works, and per size why the
/// rest does not.
fn designs_at(
    samples: &JointSamples,
    range: (f64, f64),
    p_cc: f64,
    p_max: f64,
    max_length_m: f64,
) -> Vec<Candidate> {
    let mut out = Vec::new();
    for size in DmspSize::ALL {
        for &l0 in REST_LENGTHS_M.iter().filter(|&&l| l <= max_length_m) {
            let Ok(muscle) = FestoMuscle::new(size, l0) else {
                continue;
            };
            for &r in &PULLEY_RADII_M {
                out.push((size, evaluate(muscle, r, range, p_cc, p_max, samples)));
            }
        }
    }
    out
}

/// A candidate of a size and what became of it.
type Candidate = (DmspSize, Result<PairDesign, Reject>);

fn feasible(c: &[Candidate]) -> Vec<PairDesign> {
    c.iter().filter_map(|(_, r)| r.ok()).collect()
}

/// The co-contraction pressures tried (Pa).
fn cocontraction_grid(p_max: f64) -> impl Iterator<Item = f64> {
    (2..)
        .map(|k| f64::from(k) * COCONTRACTION_STEP_PA)
        .take_while(move |p| *p <= 0.85 * p_max)
}

/// The least margin a recommended design keeps on pressure and speed (0-1): a tenth of the
/// valve's range and of the useful speed, left for what the stride's servos do not show.
pub const MARGIN_MIN: f64 = 0.1;

/// The least margin a recommended design keeps on force (of the rating), by default: the
/// room a controller's own activity takes above the servo-driven stride. Measured on the
/// two-leg trainer: the tuned controllers' peak forces reached 1.27-1.6 times the
/// servo-driven peak (DMSP-40s sized at 0.62 of their rating peaked at 0.79-0.99 under the
/// controllers, NDO-SMC 1.13 on the spastic patient), and with DMSP-20s sized at 0.82-0.89
/// of theirs no tuning of APRC-NDO or NDO-SMC stayed within the rating (best 1.19 and 1.15
/// times it). The shipped DMSP-20s, sized at 0.59 of theirs, peak at 0.40-1.00 of it under
/// the five tuned controllers (APRC-NDO at 0.999: 1.69 times the servo-driven peak).
/// docs/treadmill.md.
pub const FORCE_MARGIN_MIN: f64 = 0.4;

/// Largest force margin a sizing is asked for: a muscle kept at a tenth of its rating.
pub const FORCE_MARGIN_MAX: f64 = 0.9;

/// How much a closed-loop check in which the patient does not walk under the force limit
/// raises the margin of the next sizing (`size`): a tenth of the rating, the closed loop's
/// tolerance ([`crate::tools::CLOSED_LOOP_TOLERANCE`]).
pub const FORCE_MARGIN_STEP: f64 = 0.1;

/// Whether `d` keeps `force_margin` of its rating and [`MARGIN_MIN`] of the valve's range
/// and of its useful speed.
fn keeps(d: &PairDesign, force_margin: f64) -> bool {
    1.0 - d.peak_force_over_rated >= force_margin
        && d.pressure_headroom >= MARGIN_MIN
        && 1.0 - d.speed_over_useful >= MARGIN_MIN
}

/// A size's rank, smallest first.
fn size_rank(d: &PairDesign) -> usize {
    DmspSize::ALL
        .iter()
        .position(|s| s.name() == d.size)
        .unwrap_or(usize::MAX)
}

/// The best design among `designs`: the smallest size with a design keeping
/// `force_margin` and [`MARGIN_MIN`] (see [`keeps`]),
/// and among those the shortest muscle, then the smallest pulley, then the largest margin
/// (a compact actuator, not the longest one allowed); if no size keeps that margin, the
/// largest margin, then the smallest size, then the shortest muscle.
fn best(designs: &[PairDesign], force_margin: f64) -> Option<PairDesign> {
    let keeping = designs.iter().filter(|d| keeps(d, force_margin));
    let compact = keeping.clone().min_by(|a, b| {
        size_rank(a)
            .cmp(&size_rank(b))
            .then(a.rest_length_m.total_cmp(&b.rest_length_m))
            .then(a.pulley_radius_m.total_cmp(&b.pulley_radius_m))
            .then(b.margin.total_cmp(&a.margin))
    });
    compact
        .or_else(|| {
            designs.iter().max_by(|a, b| {
                a.margin
                    .total_cmp(&b.margin)
                    .then(size_rank(b).cmp(&size_rank(a)))
                    .then(b.rest_length_m.total_cmp(&a.rest_length_m))
            })
        })
        .copied()
}

/// Sizes both joints for `demand` with a valve of `p_max` Pa, muscles no longer than
/// `max_length_m`: at each co-contraction pressure the best design of each joint, and the
/// pressure at which the worse of the two is best.
pub fn size_joints(demand: &Demand, p_max: f64, max_length_m: f64, force_margin: f64) -> Sizing {
    let max_length_m = max_length_m.min(REST_LENGTH_RANGE_M.1);
    let per_joint: Vec<(JointSamples, (f64, f64))> = (0..2)
        .map(|j| {
            let s = joint_samples(demand, j);
            let range = s.iter().fold(
                (f64::INFINITY, f64::NEG_INFINITY),
                |(lo, hi), &(q, _, _)| (lo.min(q), hi.max(q)),
            );
            (s, range)
        })
        .collect();
    // For each pressure, every joint's candidates.
    let grid: Vec<(f64, [Vec<Candidate>; 2])> = cocontraction_grid(p_max)
        .map(|p| {
            let d = |j: usize| {
                let (s, range) = &per_joint[j];
                designs_at(s, *range, p, p_max, max_length_m)
            };
            (p, [d(0), d(1)])
        })
        .collect();
    // The pressure at which both joints have a design, both keep the margins if any
    // pressure lets them, the larger of the two sizes is smallest, then the worse margin
    // is largest.
    let common = grid
        .iter()
        .filter_map(|(p, d)| {
            Some((
                *p,
                [
                    best(&feasible(&d[0]), force_margin)?,
                    best(&feasible(&d[1]), force_margin)?,
                ],
            ))
        })
        .max_by(|a, b| {
            let both_keep = |x: &[PairDesign; 2]| x.iter().all(|d| keeps(d, force_margin));
            let worse = |x: &[PairDesign; 2]| x[0].margin.min(x[1].margin);
            let larger = |x: &[PairDesign; 2]| size_rank(&x[0]).max(size_rank(&x[1]));
            both_keep(&a.1)
                .cmp(&both_keep(&b.1))
                .then(larger(&b.1).cmp(&larger(&a.1)))
                .then(worse(&a.1).total_cmp(&worse(&b.1)))
        });
    let joints = (0..2)
        .map(|j| {
            let (_, (lo, hi)) = &per_joint[j];
            let candidates: Vec<Candidate> = grid.iter().flat_map(|(_, d)| d[j].clone()).collect();
            let all = feasible(&candidates);
            let recommended = match &common {
                Some((_, designs)) => Some(designs[j]),
                None => best(&all, force_margin),
            };
            let rejected_per_size = DmspSize::ALL
                .iter()
                .map(|size| {
                    let mut counts: Vec<(Reject, usize)> = Vec::new();
                    for (_, r) in candidates.iter().filter(|(s, _)| s == size) {
                        if let Err(why) = r {
                            match counts.iter_mut().find(|(w, _)| w == why) {
                                Some((_, n)) => *n += 1,
                                None => counts.push((*why, 1)),
                            }
                        }
                    }
                    counts.sort();
                    (size.name().to_owned(), counts)
                })
                .collect();
            let [tmin, tmax] = demand.torque_range_nm(j);
            JointSizing {
                joint: JOINT_NAMES[j].to_owned(),
                range_deg: [lo.to_degrees(), hi.to_degrees()],
                torque_nm: [tmin, tmax],
                peak_speed_deg_s: demand.peak_speed_rad_s(j).to_degrees(),
                feasible_per_size: DmspSize::ALL
                    .iter()
                    .map(|size| {
                        let n = all.iter().filter(|d| d.size == size.name()).count();
                        (size.name().to_owned(), n)
                    })
                    .collect(),
                rejected_per_size,
                at_edge: recommended.and_then(|d| edge_of(&d, max_length_m)),
                recommended,
                recommended_cocontraction_range_pa: recommended.and_then(|d| {
                    let same = all.iter().filter(|o| {
                        o.size == d.size
                            && o.rest_length_m == d.rest_length_m
                            && o.pulley_radius_m == d.pulley_radius_m
                    });
                    same.fold(None, |range: Option<[f64; 2]>, o| {
                        let p = o.cocontraction_pa;
                        Some(range.map_or([p, p], |[lo, hi]| [lo.min(p), hi.max(p)]))
                    })
                }),
            }
        })
        .collect();
    Sizing {
        joints,
        cocontraction_pa: common.map(|(p, _)| p),
        pressure_max_pa: p_max,
    }
}

/// Why `d` sits at an edge of the search (the longest length allowed, the largest pulley):
/// longer muscles contract less and can shorten faster for the same joint motion, larger
/// pulleys give more torque per newton, so the best design may lie beyond.
fn edge_of(d: &PairDesign, max_length_m: f64) -> Option<String> {
    let longest = REST_LENGTHS_M
        .iter()
        .copied()
        .filter(|&l| l <= max_length_m)
        .fold(0.0, f64::max);
    let largest = PULLEY_RADII_M[PULLEY_RADII_M.len() - 1];
    let mut why = Vec::new();
    if (d.rest_length_m - longest).abs() < 1e-9 {
        let further = if longest < REST_LENGTHS_M[REST_LENGTHS_M.len() - 1] {
            " (--max-length-m searches further, up to 2 m)"
        } else {
            " (2 m is as long as the search goes: a DMSP that long pulls through cables from the trainer's frame)"
        };
        why.push(format!(
            "its length is the longest searched ({longest:.1} m): a longer muscle strains less and has more useful speed for the same joint motion{further}"
        ));
    }
    if (d.pulley_radius_m - largest).abs() < 1e-9 {
        why.push(format!(
            "its pulley is the largest searched ({:.0} mm)",
            largest * 1e3
        ));
    }
    (!why.is_empty()).then(|| why.join("; "))
}

/// The muscle geometry of a sizing: a flexor and an extensor per joint with the
/// recommended size, length and pulley, pre-contracted by [`PRE_CONTRACTION`] where each
/// is longest over the stride. `None` if a joint has no design.
pub fn muscle_geometry(sizing: &Sizing) -> Option<Vec<MuscleGeometry>> {
    let mut out = Vec::with_capacity(4);
    for j in &sizing.joints {
        let d = j.recommended?;
        let size = DmspSize::ALL.into_iter().find(|s| s.name() == d.size)?;
        let [lo, hi] = j.range_deg.map(f64::to_radians);
        let (r, l0) = (d.pulley_radius_m, d.rest_length_m);
        let pre = PRE_CONTRACTION * l0;
        // Where the body is drawn (the anchor is only drawn): along the thigh if it fits
        // there, otherwise on the trainer's frame above the hip (the hip's) or the top of
        // the thigh (the knee's, whose cables cross the hip).
        let fits = l0 <= THIGH_MUSCLE_MAX_M;
        let (link, y, z) = match (j.joint.as_str(), fits) {
            ("hip", true) => ("thigh", -0.10, -(0.05 + 0.5 * l0)),
            ("hip", false) => ("pelvis", -0.10, 0.05 + 0.5 * l0),
            (_, true) => ("thigh", 0.0, -(0.40 - 0.5 * l0).max(0.05)),
            (_, false) => ("thigh", 0.0, -0.05),
        };
        for (side, x0) in [(Side::Flexor, pre - r * lo), (Side::Extensor, pre + r * hi)] {
            let front = (side == Side::Flexor) == (j.joint == "hip");
            out.push(MuscleGeometry {
                name: format!(
                    "{}_{}",
                    j.joint,
                    if side == Side::Flexor {
                        "flexor"
                    } else {
                        "extensor"
                    }
                ),
                joint: j.joint.clone(),
                side,
                body_link: link.into(),
                anchor_m: [if front { 0.07 } else { -0.07 }, y, z],
                pulley_radius_m: r,
                contraction_at_zero_m: x0,
                size: Some(size),
                rest_length_m: Some(l0),
            });
        }
    }
    Some(out)
}

/// The muscle geometry file (`muscles.toml` format, see
/// `crates/pma-leg/models/muscles.toml`) of `muscles`, after a `#` header of `header`'s
/// lines.
pub fn muscles_toml(muscles: &[MuscleGeometry], header: &str) -> String {
    let mut out = String::new();
    for line in header.lines() {
        out.push_str("# ");
        out.push_str(line);
        out.push('\n');
    }
    for m in muscles {
        let side = match m.side {
            Side::Flexor => "flexor",
            Side::Extensor => "extensor",
        };
        out.push_str(&format!(
            "\n[[muscles]]\nname = \"{}\"\njoint = \"{}\"\nside = \"{side}\"\nbody_link = \"{}\"\nanchor_m = [{:?}, {:?}, {:?}]\npulley_radius_m = {:?}\ncontraction_at_zero_m = {:?}\n",
            m.name, m.joint, m.body_link, m.anchor_m[0], m.anchor_m[1], m.anchor_m[2],
            m.pulley_radius_m, m.contraction_at_zero_m
        ));
        if let (Some(size), Some(l0)) = (m.size, m.rest_length_m) {
            let name = size.name().to_lowercase();
            out.push_str(&format!("size = \"{name}\"\nrest_length_m = {l0:?}\n"));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tools::DemandSample;

    /// A stride that holds `torque_nm` over `[0, range]` rad at `speed_rad_s`.
    fn samples(range: f64, speed_rad_s: f64, torque_nm: f64) -> JointSamples {
        (0..=100)
            .map(|k| (range * f64::from(k) / 100.0, speed_rad_s, torque_nm))
            .collect()
    }

    /// The largest torque a pair holds still at joint angle `q` in `[lo, hi]`, its mean
    /// pressure at `p_cc`: the flexor at `p_cc + d`, the extensor at `p_cc - d`, `d` as
    /// large as the valve allows.
    fn holdable_torque(m: FestoMuscle, r: f64, (lo, hi): (f64, f64), q: f64, p_cc: f64) -> f64 {
        let pre = PRE_CONTRACTION * m.rest_length_m;
        let d = p_cc.min(6e5 - p_cc);
        r * (m.static_force_n(p_cc + d, pre + r * (q - lo))
            - m.static_force_n(p_cc - d, pre + r * (hi - q)))
    }

    #[test]
    fn a_held_torque_works_up_to_what_the_valve_range_gives_and_no_further() {
        let m = FestoMuscle::new(DmspSize::Dmsp20, 0.3).unwrap();
        let (r, range, p_cc) = (0.03, 0.5, 3e5);
        // The weakest point of the range: the flexor most contracted, at its top.
        let limit = holdable_torque(m, r, (0.0, range), range, p_cc);
        assert!(limit > 10.0, "{limit}");
        let below = evaluate(
            m,
            r,
            (0.0, range),
            p_cc,
            6e5,
            &samples(range, 0.0, 0.99 * limit),
        );
        let d = below.unwrap();
        assert!(
            d.pressure_headroom < 0.01 && d.pressure_headroom >= 0.0,
            "{d:?}"
        );
        let above = evaluate(
            m,
            r,
            (0.0, range),
            p_cc,
            6e5,
            &samples(range, 0.0, 1.01 * limit),
        );
        assert_eq!(above, Err(Reject::Pressure));
    }

    #[test]
    fn each_rule_rejects_what_breaks_it() {
        let m = FestoMuscle::new(DmspSize::Dmsp20, 0.3).unwrap();
        // 1 rad on a 100 mm pulley is a third of the muscle's length.
        assert_eq!(
            evaluate(m, 0.1, (0.0, 1.0), 3e5, 6e5, &samples(1.0, 0.0, 0.0)),
            Err(Reject::Stroke)
        );
        // 6 rad/s on 30 mm is 180 mm/s, beyond a 300 mm DMSP-20's 108 mm/s.
        assert_eq!(
            evaluate(m, 0.03, (0.0, 0.5), 3e5, 6e5, &samples(0.5, 6.0, 0.0)),
            Err(Reject::Speed)
        );
        // Stretched while it pulls hard, the flexor's damping adds to its pull: beyond the
        // 1500 N rating at pressures the valve allows (statically a DMSP-20 gives 1460 N
        // at 6 bar).
        let e = evaluate(m, 0.03, (0.0, 0.5), 4.5e5, 6e5, &vec![(0.0, -1.0, 40.0)]);
        assert_eq!(e, Err(Reject::Rating));
        // Held still at a lower co-contraction, 30 N m is within the rating.
        let still = evaluate(m, 0.03, (0.0, 0.5), 3e5, 6e5, &vec![(0.0, 0.0, 30.0)]);
        assert!(still.is_ok(), "{still:?}");
        let ok = evaluate(m, 0.03, (0.0, 0.5), 3e5, 6e5, &samples(0.5, 0.5, 10.0)).unwrap();
        assert!(ok.margin > 0.0 && ok.speed_over_useful < 1.0, "{ok:?}");
    }

    #[test]
    fn the_recommended_geometry_precontracts_each_muscle_where_it_is_longest() {
        let demand = Demand {
            samples: (0..200)
                .map(|k| {
                    let q = 0.4 * (f64::from(k) * 0.05).sin();
                    DemandSample {
                        t_s: f64::from(k) * 1e-3,
                        leg: 0,
                        phase: 0.0,
                        angle_rad: [q, 0.3 + q],
                        velocity_rad_s: [0.2, 0.2],
                        torque_nm: [20.0 * q, 5.0],
                        grf_n: [f64::NAN; 2],
                        ankle_rad: f64::NAN,
                        pelvis_m: [f64::NAN; 2],
                        slip_m_s: f64::NAN,
                        contact_speed_m_s: f64::NAN,
                    }
                })
                .collect(),
            legs: 1,
            max_error_deg: [0.0; 2],
            raw_torque_range_nm: [[0.0; 2]; 2],
            treadmill: None,
        };
        let sizing = size_joints(&demand, 6e5, 0.4, 0.1);
        let muscles = muscle_geometry(&sizing).expect("a light demand is met");
        assert_eq!(muscles.len(), 4);
        for (m, j) in muscles.iter().zip([0, 0, 1, 1]) {
            let [lo, hi] = sizing.joints[j].range_deg.map(f64::to_radians);
            let longest = match m.side {
                Side::Flexor => m.contraction(lo),
                Side::Extensor => m.contraction(hi),
            };
            let l0 = m.rest_length_m.unwrap();
            assert!((longest - PRE_CONTRACTION * l0).abs() < 1e-12, "{m:?}");
        }
        // Each recommendation keeps its margins (a DMSP-10 could hold the hip's 8 N m, but
        // not with 10 % of the valve's range and useful speed to spare).
        for j in &sizing.joints {
            let d = j.recommended.expect("a design");
            assert!(keeps(&d, 0.1), "{d:?}");
        }
        assert_eq!(muscles[2].size, Some(DmspSize::Dmsp10), "{:?}", muscles[2]);
        // Asked to keep 40 % of the rating free, whatever it recommends keeps it.
        let kept = size_joints(&demand, 6e5, 0.4, FORCE_MARGIN_MIN);
        for j in &kept.joints {
            let d = j.recommended.expect("a design");
            assert!(d.peak_force_over_rated <= 1.0 - FORCE_MARGIN_MIN, "{d:?}");
        }
        // The file it writes parses back to the same muscles, to the bit: a run of the
        // written file is the closed-loop check's run. (Rounded to 1e-5 m, the unsupported
        // trainer's check walked 20 s and its file collapsed at 14.40 s.)
        let text = muscles_toml(&muscles, "test");
        let back = crate::plant::parse_muscles(&text, "sized.toml").unwrap();
        assert_eq!(back, muscles);
    }
}
