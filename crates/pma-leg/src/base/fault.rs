/// Why the supervisor stopped a leg run (it vented every muscle).
#[derive(Debug, Clone, PartialEq)]
pub struct LegFault {
    /// Short name (`sensor-nan`, `position-out`).
    pub name: &'static str,
    /// Time of the last period that completed (s).
    pub t_s: f64,
    /// What happened, on one line.
    pub message: String,
}
