/// The loading response of a stance's vertical ground reaction: its peak in the first half
/// of stance and the loading rate, the slope from 20 to 80 % of that peak (the units of
/// the samples, per second).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Loading {
    /// The largest vertical reaction in the first half of stance.
    pub peak: f64,
    /// `0.6 peak` over the time from the first sample at 20 % of the peak to the first at
    /// 80 % (NaN when the reaction does not rise through both).
    pub rate: f64,
}

/// The loading response of `grf`, sampled every `dt_s` from heel strike, over a stance of
/// `stance_s`: the measure the trainer's feet and the adults' curves are both given.
pub fn loading(grf: &[f64], dt_s: f64, stance_s: f64) -> Loading {
    let half = ((0.5 * stance_s / dt_s) as usize).clamp(1, grf.len().max(1));
    let first = &grf[..half.min(grf.len())];
    let peak = first.iter().copied().fold(0.0, f64::max);
    let crossing = |level: f64| first.iter().position(|&f| f >= level);
    let rate = match (crossing(0.2 * peak), crossing(0.8 * peak)) {
        (Some(a), Some(b)) if b > a => 0.6 * peak / ((b - a) as f64 * dt_s),
        _ => f64::NAN,
    };
    Loading { peak, rate }
}
