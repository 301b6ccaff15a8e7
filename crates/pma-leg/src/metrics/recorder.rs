use crate::base::PerLeg;
use crate::control::LegOutput;
use crate::plant::{LegPlant, LegState, SupervisedLeg, TrainerState};
use pma_loop::End;
use pma_loop::Period;
use pma_loop::Recorder;
use pma_loop::Start;

/// One leg's view of the loop's start.
#[derive(Debug, Clone, Copy)]
pub struct LegStart<'a> {
    /// Time of the start (s).
    pub t_s: f64,
    /// The leg's state.
    pub state: &'a LegState,
    /// The pressures the leg's valves held at rest (Pa).
    pub resting: &'a [f64; 4],
    /// The whole trainer's state (the treadmill's, the other legs').
    pub trainer: &'a TrainerState,
}

/// One leg's view of one loop period.
#[derive(Clone, Copy)]
pub struct LegPeriod<'a> {
    /// The leg (0 right, 1 left).
    pub leg: usize,
    /// Time of the reading (s).
    pub t_s: f64,
    /// Time since the previous reading (s).
    pub dt_s: f64,
    /// The leg's state at the reading.
    pub state: &'a LegState,
    /// What the leg's controllers made of it.
    pub output: &'a LegOutput,
    /// The pressures held over the period that just ended (Pa).
    pub held: &'a [f64; 4],
    /// The pressures written for the next period (Pa).
    pub written: &'a [f64; 4],
    /// The whole trainer's state (the treadmill's, the other legs').
    pub trainer: &'a TrainerState,
    /// The plant.
    pub plant: &'a LegPlant,
}

/// A recorder of one leg: the leg's figures are written once, for one leg, and run on
/// each leg of a trainer through [`OnLeg`].
pub trait LegRecorder {
    /// The run has started.
    fn start(&mut self, start: &LegStart<'_>) {
        let _ = start;
    }
    /// One period.
    fn record(&mut self, period: &LegPeriod<'_>);
}

/// Runs a one-leg recorder on leg `leg` of the trainer's loop.
#[derive(Debug, Clone)]
pub struct OnLeg<R> {
    /// The leg it follows.
    pub leg: usize,
    /// The recorder.
    pub inner: R,
}

impl<R> OnLeg<R> {
    /// `inner` on leg `leg`.
    pub fn new(leg: usize, inner: R) -> Self {
        Self { leg, inner }
    }
}

impl<R: LegRecorder> Recorder<SupervisedLeg, PerLeg<LegOutput>> for OnLeg<R> {
    fn start(&mut self, s: &Start<'_, SupervisedLeg>) {
        let (Some(state), Some(resting)) = (s.truth.legs.get(self.leg), s.resting.get(self.leg))
        else {
            return;
        };
        self.inner.start(&LegStart {
            t_s: s.t_s,
            state,
            resting,
            trainer: s.truth,
        });
    }

    fn record(&mut self, p: &Period<'_, SupervisedLeg, PerLeg<LegOutput>>) {
        let leg = self.leg;
        let (Some(state), Some(output), Some(held), Some(written)) = (
            p.truth.legs.get(leg),
            p.output.get(leg),
            p.held.get(leg),
            p.written.get(leg),
        ) else {
            return;
        };
        self.inner.record(&LegPeriod {
            leg,
            t_s: p.t_s,
            dt_s: p.dt_s,
            state,
            output,
            held,
            written,
            trainer: p.truth,
            plant: p.backend.inner(),
        });
    }

    fn end(&mut self, _: &End<<SupervisedLeg as pma_loop::Backend>::Error>, _: f64) {}
}
