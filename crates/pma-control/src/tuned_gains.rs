// Placeholder starting points; replaced by `pma-exo tune` output.
use crate::{NdoSmcGains, PidGains, PsmcGains, StaGains};

pub const PSMC: PsmcGains = PsmcGains {
    kp_pa_per_m: 1.0e7,
    ki_pa_per_m_s: 5.0e7,
    kd_pa_s_per_m: 1.0e5,
    h_s: 0.05,
    force_max_pa: 3.0e5,
    bias_pa: 0.7e5,
    estimator_bandwidth_rad_s: 200.0,
};

pub const NDO_SMC: NdoSmcGains = NdoSmcGains {
    c1_per_s: 100.0,
    c2_per_s2: 100.0,
    k_per_s: 50.0,
    eta_m_s2: 1.0,
    phi_m_s: 0.005,
    kappa_per_s: 15952.0,
    estimator_bandwidth_rad_s: 200.0,
};

pub const STA: StaGains = StaGains {
    c1_per_s: 100.0,
    k1: 5.0,
    k2: 50.0,
    estimator_bandwidth_rad_s: 200.0,
};

pub const PID: PidGains = PidGains {
    kp_pa_per_m: 1.0e7,
    ki_pa_per_m_s: 5.0e7,
    kd_pa_s_per_m: 1.0e5,
    bias_pa: 0.7e5,
    estimator_bandwidth_rad_s: 200.0,
};
