//! Gain tuning.
