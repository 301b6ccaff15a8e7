//! A leg run over the gait cycle, for `simulate --plot`'s `strides.png`: every period's
//! joint angles, their references, the tracking errors and, on a treadmill, each foot's
//! vertical ground reaction, binned by the phase of the leg's own gait reference
//! ([`GaitReference::phase`]: 0 % at the reference's initial contact of that leg), 1 % a
//! bin. Each bin keeps the mean over every sample of the strides binned, and the range of
//! the strides' own means in it (a stride's bin holds about 16 samples at 1 kHz). The
//! buffers are sized when the recorder is made: the loop allocates nothing.
use pma_leg::gait::GaitReference;
use pma_leg::{LegError, LegOutput, LegSim, PerLeg, SupervisedLeg};
use pma_loop::{End, Period, Recorder};
use std::ops::Range;

/// Bins of the gait cycle: 1 % each.
pub const BINS: usize = 100;

/// Phase of bin `bin`'s centre (0-1).
pub fn bin_centre(bin: usize) -> f64 {
    (bin as f64 + 0.5) / BINS as f64
}

/// The bin of `phase` (0-1).
fn bin_of(phase: f64) -> usize {
    ((phase * BINS as f64) as usize).min(BINS - 1)
}

/// One channel over the gait cycle.
#[derive(Debug, Clone)]
pub struct CycleCurve {
    count: Vec<u64>,
    sum: Vec<f64>,
    /// The current stride's samples in each bin.
    stride_count: Vec<u32>,
    stride_sum: Vec<f64>,
    /// The lowest and highest stride mean in each bin.
    low: Vec<f64>,
    high: Vec<f64>,
}

impl Default for CycleCurve {
    fn default() -> Self {
        Self {
            count: vec![0; BINS],
            sum: vec![0.0; BINS],
            stride_count: vec![0; BINS],
            stride_sum: vec![0.0; BINS],
            low: vec![f64::INFINITY; BINS],
            high: vec![f64::NEG_INFINITY; BINS],
        }
    }
}

impl CycleCurve {
    fn push(&mut self, bin: usize, value: f64) {
        self.count[bin] += 1;
        self.sum[bin] += value;
        self.stride_count[bin] += 1;
        self.stride_sum[bin] += value;
    }

    /// Folds the current stride's means into the range and starts the next stride.
    fn close_stride(&mut self) {
        for b in 0..BINS {
            if self.stride_count[b] > 0 {
                let mean = self.stride_sum[b] / f64::from(self.stride_count[b]);
                self.low[b] = self.low[b].min(mean);
                self.high[b] = self.high[b].max(mean);
            }
            self.stride_count[b] = 0;
            self.stride_sum[b] = 0.0;
        }
    }

    /// Samples in bin `bin`, over every stride.
    pub fn count(&self, bin: usize) -> u64 {
        self.count[bin]
    }

    /// Whether no sample was binned.
    pub fn is_empty(&self) -> bool {
        self.count.iter().all(|n| *n == 0)
    }

    /// Mean of bin `bin` over every sample of every stride (NaN for an empty bin).
    pub fn mean(&self, bin: usize) -> f64 {
        if self.count[bin] == 0 {
            f64::NAN
        } else {
            self.sum[bin] / self.count[bin] as f64
        }
    }

    /// The lowest and highest of the strides' means in bin `bin` (NaN for an empty bin).
    pub fn range(&self, bin: usize) -> (f64, f64) {
        if self.count[bin] == 0 {
            (f64::NAN, f64::NAN)
        } else {
            (self.low[bin], self.high[bin])
        }
    }
}

/// One leg over its gait cycle (hip, knee, ankle in this order; deg, flexion and
/// dorsiflexion positive).
#[derive(Debug, Clone)]
pub struct LegCycle {
    gait: GaitReference,
    /// Whether the reference has an ankle curve and the leg a passive ankle.
    ankle: bool,
    /// Joint angles (deg).
    pub angle_deg: [CycleCurve; 3],
    /// The reference at the same samples (deg).
    pub reference_deg: [CycleCurve; 3],
    /// Tracking error, reference - angle (deg), of the driven joints (hip, knee).
    pub error_deg: [CycleCurve; 2],
    /// The foot's vertical ground reaction (body weights), on a treadmill.
    pub grf_bw: CycleCurve,
    last_bin: Option<usize>,
}

impl LegCycle {
    /// The leg's gait reference, whose phase bins its samples.
    pub fn gait(&self) -> &GaitReference {
        &self.gait
    }

    /// Whether the ankle is binned (a passive ankle under a reference with an ankle curve).
    pub fn has_ankle(&self) -> bool {
        self.ankle
    }

    fn curves(&mut self) -> impl Iterator<Item = &mut CycleCurve> {
        self.angle_deg
            .iter_mut()
            .chain(&mut self.reference_deg)
            .chain(&mut self.error_deg)
            .chain(std::iter::once(&mut self.grf_bw))
    }

    fn close_stride(&mut self) {
        self.curves().for_each(CycleCurve::close_stride);
    }

    /// One period of this leg: its bin by the reference's phase at `t_s`; a new stride
    /// when the phase wraps.
    fn record(&mut self, t_s: f64, angle_rad: [f64; 3], output: &LegOutput, grf_bw: f64) {
        let bin = bin_of(self.gait.phase(t_s));
        if self.last_bin.is_some_and(|last| bin < last) {
            self.close_stride();
        }
        self.last_bin = Some(bin);
        let reference = [
            output.reference_rad[0],
            output.reference_rad[1],
            // The passive ankle is not driven: its reference is only compared with.
            self.gait.sample(t_s).ankle.angle_rad,
        ];
        let joints = if self.ankle { 3 } else { 2 };
        for j in 0..joints {
            self.angle_deg[j].push(bin, angle_rad[j].to_degrees());
            self.reference_deg[j].push(bin, reference[j].to_degrees());
        }
        for j in 0..2 {
            self.error_deg[j].push(bin, (reference[j] - angle_rad[j]).to_degrees());
        }
        if grf_bw.is_finite() {
            self.grf_bw.push(bin, grf_bw);
        }
    }
}

/// Every leg of a run over its gait cycle: a recorder of the loop.
#[derive(Debug, Clone)]
pub struct GaitCycles {
    legs: Vec<LegCycle>,
    from_s: f64,
    /// The last sample binned (s).
    to_s: f64,
    /// The patient's body weight (N), the unit of the ground reaction; NaN in the air.
    body_weight_n: f64,
}

impl GaitCycles {
    /// Every leg of `sim`, binning the periods after `from_s` (the report's tracking
    /// figures start after the first stride: pass the stride period to bin the same
    /// samples).
    pub fn new(sim: &LegSim, from_s: f64) -> Result<Self, LegError> {
        let sc = sim.scenario();
        let gait = sc.gait.reference()?;
        // Only the adult data has an ankle curve; only a treadmill's leg a passive ankle.
        let ankle = gait.data_speed_m_s().is_some() && sc.treadmill.is_some();
        let legs = (0..sim.leg_count())
            .map(|leg| LegCycle {
                gait: gait.for_leg(leg),
                ankle,
                angle_deg: Default::default(),
                reference_deg: Default::default(),
                error_deg: Default::default(),
                grf_bw: CycleCurve::default(),
                last_bin: None,
            })
            .collect();
        Ok(Self {
            legs,
            from_s,
            to_s: from_s,
            body_weight_n: sc
                .treadmill
                .as_ref()
                .map_or(f64::NAN, |t| t.body_mass_kg * pma_model::GRAVITY_M_S2),
        })
    }

    /// The legs, in leg order (right, left).
    pub fn legs(&self) -> &[LegCycle] {
        &self.legs
    }

    /// The time binned (s): from the start given to the last sample.
    pub fn span_s(&self) -> Range<f64> {
        self.from_s..self.to_s
    }

    /// Strides binned (each leg's: the gait's stride period is every leg's).
    pub fn strides(&self) -> f64 {
        self.legs.first().map_or(0.0, |l| {
            (self.to_s - self.from_s) / l.gait.stride_period_s()
        })
    }
}

impl Recorder<SupervisedLeg, PerLeg<LegOutput>> for GaitCycles {
    fn record(&mut self, p: &Period<'_, SupervisedLeg, PerLeg<LegOutput>>) {
        if p.t_s <= self.from_s {
            return;
        }
        self.to_s = p.t_s;
        for (leg, cycle) in self.legs.iter_mut().enumerate() {
            let (Some(s), Some(o)) = (p.truth.legs.get(leg), p.output.get(leg)) else {
                continue;
            };
            let grf_bw = p
                .truth
                .ground
                .and_then(|g| g.feet.get(leg).map(|f| f.vertical_n / self.body_weight_n))
                .unwrap_or(f64::NAN);
            let angles = [s.angle_rad[0], s.angle_rad[1], s.ankle_rad];
            cycle.record(p.t_s, angles, o, grf_bw);
        }
    }

    /// The last stride, however far it got.
    fn end(&mut self, _: &End<<SupervisedLeg as pma_loop::Backend>::Error>, _: f64) {
        self.legs.iter_mut().for_each(LegCycle::close_stride);
    }
}
