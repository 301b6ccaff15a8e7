use crate::{Backend, End, Period, Start};

/// Observes a run: metrics, logs, visualisation, progress. Recorders never fail the loop;
/// one that can fail (a file, a viewer) keeps its first error for the caller to collect
/// after the run.
pub trait Recorder<B: Backend, O> {
    /// The backend has started (its first reading) and the task has started on it.
    fn start(&mut self, start: &Start<'_, B>) {
        let _ = start;
    }
    /// One period.
    fn record(&mut self, period: &Period<'_, B, O>);
    /// The run ended (the backend is already in its safe state); `t_s` is the time of
    /// the last completed period.
    fn end(&mut self, end: &End<B::Error>, t_s: f64) {
        let _ = (end, t_s);
    }
}

/// Records nothing.
impl<B: Backend, O> Recorder<B, O> for () {
    fn record(&mut self, _: &Period<'_, B, O>) {}
}

impl<B: Backend, O, R: Recorder<B, O> + ?Sized> Recorder<B, O> for &mut R {
    fn start(&mut self, start: &Start<'_, B>) {
        (**self).start(start);
    }
    fn record(&mut self, period: &Period<'_, B, O>) {
        (**self).record(period);
    }
    fn end(&mut self, end: &End<B::Error>, t_s: f64) {
        (**self).end(end, t_s);
    }
}

/// Records if present: optional outputs (a CSV file, a viewer) without optional closures.
/// Records into each, in order (one recorder per leg, say).
impl<B: Backend, O, R: Recorder<B, O>> Recorder<B, O> for Vec<R> {
    fn start(&mut self, start: &Start<'_, B>) {
        for r in self.iter_mut() {
            r.start(start);
        }
    }
    fn record(&mut self, period: &Period<'_, B, O>) {
        for r in self.iter_mut() {
            r.record(period);
        }
    }
    fn end(&mut self, end: &End<B::Error>, t_s: f64) {
        for r in self.iter_mut() {
            r.end(end, t_s);
        }
    }
}

impl<B: Backend, O, R: Recorder<B, O>> Recorder<B, O> for Option<R> {
    fn start(&mut self, start: &Start<'_, B>) {
        if let Some(r) = self {
            r.start(start);
        }
    }
    fn record(&mut self, period: &Period<'_, B, O>) {
        if let Some(r) = self {
            r.record(period);
        }
    }
    fn end(&mut self, end: &End<B::Error>, t_s: f64) {
        if let Some(r) = self {
            r.end(end, t_s);
        }
    }
}

macro_rules! tuple_recorder {
    ($($name:ident),+) => {
        /// Records into each, in order.
        impl<B: Backend, O, $($name: Recorder<B, O>),+> Recorder<B, O> for ($($name,)+) {
            #[allow(non_snake_case)]
            fn start(&mut self, start: &Start<'_, B>) {
                let ($($name,)+) = self;
                $($name.start(start);)+
            }
            #[allow(non_snake_case)]
            fn record(&mut self, period: &Period<'_, B, O>) {
                let ($($name,)+) = self;
                $($name.record(period);)+
            }
            #[allow(non_snake_case)]
            fn end(&mut self, end: &End<B::Error>, t_s: f64) {
                let ($($name,)+) = self;
                $($name.end(end, t_s);)+
            }
        }
    };
}

tuple_recorder!(R1, R2);
tuple_recorder!(R1, R2, R3);
tuple_recorder!(R1, R2, R3, R4);
tuple_recorder!(R1, R2, R3, R4, R5);

/// A closure called with every period.
pub struct FnRecorder<F>(pub F);

impl<B: Backend, O, F: FnMut(&Period<'_, B, O>)> Recorder<B, O> for FnRecorder<F> {
    fn record(&mut self, period: &Period<'_, B, O>) {
        (self.0)(period);
    }
}
