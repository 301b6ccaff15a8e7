// Default gains of the baselines: the firefly tuning of `models/gains/<name>.toml`
// (same optimiser, budget and objective for every controller, APRC-NDO included; the
// commands are in each file's header). A test checks these equal the files.
use crate::{NdoSmcGains, PidGains, PsmcGains, StaGains};

pub const PSMC: PsmcGains = PsmcGains {
    kp_pa_per_m: 1286192747.6098444,
    ki_pa_per_m_s: 43983178051.73864,
    kd_pa_s_per_m: 335831.64398549165,
    h_s: 0.01869055892283388,
    force_max_pa: 245076.9225571409,
    bias_pa: 141473.54873650378,
    estimator_bandwidth_rad_s: 596.8010828980097,
};

pub const NDO_SMC: NdoSmcGains = NdoSmcGains {
    c1_per_s: 1458.0356017113713,
    c2_per_s2: 58579.901826513815,
    k_per_s: 931.5713665188886,
    eta_m_s2: 0.021876454236956337,
    phi_m_s: 0.0020692093111997064,
    kappa_per_s: 132.37347876231325,
    estimator_bandwidth_rad_s: 935.5670444947983,
};

pub const STA: StaGains = StaGains {
    c1_per_s: 2103.4002625745143,
    k1: 64.12346203497844,
    k2: 308.57210343387703,
    estimator_bandwidth_rad_s: 980.2536798327482,
};

pub const PID: PidGains = PidGains {
    kp_pa_per_m: 1138973397.0563126,
    ki_pa_per_m_s: 22123355207.435303,
    kd_pa_s_per_m: 396638.29243750626,
    bias_pa: 199715.38671666742,
    estimator_bandwidth_rad_s: 508.9365034835208,
};
