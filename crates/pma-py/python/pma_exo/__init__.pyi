"""Type stubs of pma_exo (pma-exo's Python bindings)."""
import os
from typing import Any, Dict, List, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

__version__: str

#: Controller names: aprc-ndo, aprc, psmc, ndo-smc, sta, pid.
CONTROLLERS: List[str]
#: Plant presets of the bench: ideal, mismatch, realistic, realistic_known_lag.
PLANTS: List[str]

_Path = Union[str, "os.PathLike[str]"]
#: A run: one 1-D float64 array per CSV column of the CLI (``t_s`` first), one value per
#: control period, and ``"metrics"``: the dict the CLI's ``--json`` prints, without its
#: provenance.
Run = Dict[str, Any]

class PmaError(ValueError):
    """An error of pma-exo; its message is the CLI's one line."""

class SupervisorError(PmaError):
    """The supervisor stopped a run (a reading outside its window, NaN): muscles vented."""

def single(
    plant: str = "ideal",
    controller: Optional[str] = None,
    gains: Optional[_Path] = None,
    reference: str = "sine",
    duration: float = 20.0,
) -> Run:
    """One muscle on the paper's bench under one controller (``pma-exo single``).

    ``plant``: a preset or a plant .toml file; ``controller``: one of ``CONTROLLERS``
    (default: the gain file's, else aprc-ndo); ``gains``: a gain .toml file;
    ``reference``: ``"sine"`` (the paper's 0..30 mm at 0.25 Hz) or ``"chirp"``;
    ``duration``: simulated seconds. Series: ``t_s``, ``reference_m``, ``position_m``,
    ``pressure_cmd_pa``, ``pressure_pa``, ``proxy_m``, ``s_p``, ``s_q``, ``gain_hat``,
    ``disturbance_hat``, ``measured_m``, ``force_n``, ``velocity_estimate_m_s``; metrics:
    ``mae_m``, ``iae_m``, ``rte_percent``, ``rms_m``, ...
    """

def simulate(
    scenario: _Path = "gait_training",
    controller: Optional[str] = None,
    gains: Optional[_Path] = None,
    duration: Optional[float] = None,
    mode: Optional[str] = None,
) -> Run:
    """Gait training on the exoskeleton leg (``pma-exo simulate``).

    ``scenario``: an embedded name (gait_training, gait_realistic, gait_spastic,
    gait_spasms, gait_resistive, gait_treadmill, ...) or a scenario .toml file;
    ``controller``: on every muscle (default: APRC-NDO with the scenario's gains);
    ``gains``: a gain file; ``duration``: simulated seconds (default: the scenario's);
    ``mode``: ``"position"`` or ``"impedance"`` (default: the scenario's ``control.mode``;
    impedance runs no muscle controller, so no ``controller`` with it).
    """

def pendulum(
    scenario: _Path = "gait_training",
    knee_deg: float = 0.0,
    hip_deg: float = 0.0,
    duration: float = 10.0,
    spasticity: Optional[str] = None,
) -> Run:
    """The Wartenberg pendulum test of a scenario's patient (``pma-exo pendulum``).

    ``spasticity``: ``"none"``, ``"mild"``, ``"moderate"`` or ``"severe"`` at hip and knee
    instead of the scenario's. Metrics: ``r2``, ``first_peak_deg``, ``oscillations``, ...
    """

def size(
    scenario: _Path = "gait_treadmill",
    strides: int = 3,
    max_length_m: float = 2.0,
    force_margin: float = 0.4,
    closed_loop_s: float = 60.0,
) -> Dict[str, Any]:
    """The Festo muscles and pulleys a scenario's gait needs (``pma-exo size --json``).

    Stiff joint servos drive the legs along the gait for ``strides`` strides; every DMSP
    size, length and pulley is tried, and the smallest size keeping ``force_margin`` of its
    rating free is recommended, then run for ``closed_loop_s`` under the scenario's
    controller (0: no check) and sized again where the controller takes more of the
    rating. Keys: ``sizing``, ``closed_loop`` (each check; the last one's ``holds`` is the
    verdict), ``against_norms``, ``treadmill``, ``servo_max_error_deg``,
    ``servo_raw_torque_range_nm``.
    """

def identify(
    logs: Union[_Path, Sequence[_Path]],
    load_kg: Optional[float] = None,
    seed: int = 1,
    force: bool = False,
) -> Dict[str, Any]:
    """A plant from rig logs (``pma-exo identify LOG... --json``).

    ``logs``: one log (``rig excite --out``, or any ``rig run`` log) or up to 8 (the
    added-mass protocol's pair); ``load_kg``: the load weighed (default the log's, else
    identified from the added-mass logs); ``seed``: the bootstrap's; ``force``: read logs
    ``rig replay`` would refuse. Returns the figures ``identify --json`` prints and
    ``plant``, the plant file's content (what ``identify --out`` writes). Ctrl-C stops it.
    """

def fit_gait(
    scenario: _Path = "gait_treadmill",
    iterations: int = 15,
    gain: float = 0.8,
    strides: int = 3,
    body_speed: str = "constant",
    belt: str = "no-drag",
) -> Dict[str, Any]:
    """A treadmill scenario's hip made consistent with its belt (``pma-exo fit-gait --json``).

    ``iterations`` servo-driven runs after the data's, ``gain`` of each speed error corrected
    per run, ``strides`` measured per run, ``body_speed`` ``"constant"`` or ``"normative"``,
    ``belt`` ``"no-drag"`` (where the harness carries no mean fore-aft force) or ``"stance"``.
    Keys: ``steps``, ``best``, ``belt_steps``, ``belt_speed_m_s``, ``hip_correction`` (``cos_deg``,
    ``sin_deg``: the scenario's ``[gait.hip_correction]``). Ctrl-C between runs stops it.
    """

def sweep(file: _Path, shard: str = "1/1", threads: Optional[int] = None) -> List[Dict[str, Any]]:
    """A sweep's runs in memory (``pma-exo sweep FILE --shard I/N`` without its directory).

    ``file``: a shipped sweep (``shocks``, ``fig9``, ``monte_carlo``, ``leg_patients``) or a
    sweep .toml file; ``shard`` ``"I/N"`` runs part I of N. One dict per run, in run order,
    as the lines of the CLI's ``runs.jsonl`` (a failed run's has ``failed``):
    ``pandas.DataFrame(pma_exo.sweep(...))`` takes them directly. The runs do not depend on
    ``threads`` (default one per core). Ctrl-C stops it once the runs under way end.
    """

class Bench:
    """One muscle lifting a load, stepped by a controller written in Python.

    Each period: ``x = bench.read()``, ``bench.write(p)``, ``bench.step()``. The rig's
    supervisor clamps and rate-limits commands; a reading outside its window vents the
    muscle and raises ``SupervisorError``; then only ``reset()`` goes on.
    """

    def __init__(self, plant: _Path = "ideal", position: float = 0.0, period: float = 1e-3) -> None:
        """A bench of ``plant`` (preset or .toml), the load at rest at ``position`` (m)."""
    def reset(self) -> float:
        """Back at rest where it started, the clock at 0, a fault cleared; the first reading (m)."""
    def read(self) -> float:
        """The sensor's last reading (m), contraction positive."""
    def write(self, pressure: float) -> float:
        """The pressure command (Pa gauge) for the next period; returns it as applied.

        Raises ``PmaError`` for NaN, infinite or out-of-range pressures.
        """
    def step(self) -> float:
        """One period passes with the command held; returns the new reading (m)."""
    def state(self) -> Dict[str, float]:
        """The true state: ``position_m``, ``velocity_m_s``, ``pressure_pa``, ``force_n``."""
    @property
    def time(self) -> float:
        """Time of the last reading (s)."""
    @property
    def period(self) -> float:
        """The control period (s)."""
    @property
    def command(self) -> float:
        """The last command as the supervisor applied it (Pa)."""
    @property
    def plant(self) -> str:
        """The plant's name."""
    @property
    def limits(self) -> Dict[str, float]:
        """The supervisor's limits (``pressure_max_pa``, ``position_min_m``, ...)."""

class Leg:
    """The exoskeleton leg of a scenario (or the treadmill trainer), stepped from Python.

    Each period: ``q = leg.read()`` (rad, shape ``(legs, 2)``: hip, knee),
    ``leg.write(p)`` (Pa, shape ``(legs, 4)`` in the order of ``leg.muscles``; ``(4,)``
    for one leg), ``leg.step()``. The supervisor of ``pma-exo simulate`` rate-limits the
    commands; an encoder past its joint's window vents and raises ``SupervisorError``.
    """

    def __init__(self, scenario: _Path = "gait_training") -> None:
        """The leg of ``scenario`` (an embedded name or a .toml file), at rest."""
    def reset(self) -> npt.NDArray[np.float64]:
        """Back at rest, the clock at 0, a fault cleared; the first reading."""
    def read(self) -> npt.NDArray[np.float64]:
        """The encoders' last reading (rad), shape ``(legs, 2)``."""
    def cuffs(self) -> npt.NDArray[np.float64]:
        """The cuff torque sensors' last reading (N m, device on limb), shape ``(legs, 2)``."""
    def write(self, pressures: Union[npt.NDArray[np.float64], List[float]]) -> npt.NDArray[np.float64]:
        """Pressure commands (Pa gauge) for the next period; returns them as applied.

        Raises ``TypeError`` for a non-float64 array, ``PmaError`` for a wrong shape or a
        NaN, infinite or out-of-range pressure.
        """
    def step(self) -> npt.NDArray[np.float64]:
        """One period passes with the commands held; returns the new reading."""
    def reference(self, t: Optional[float] = None) -> npt.NDArray[np.float64]:
        """The gait reference (rad) at ``t`` (default: now), shape ``(legs, 2)``."""
    def state(self) -> Dict[str, npt.NDArray[np.float64]]:
        """The true state: ``angle_rad``, ``velocity_rad_s``, ``pressure_pa``, ``force_n``,
        ``interaction_nm``, ``cuff_force_n`` (thigh and shank cuffs, N)."""
    @property
    def time(self) -> float:
        """Time of the last reading (s)."""
    @property
    def period(self) -> float:
        """The control period (s)."""
    @property
    def legs(self) -> int:
        """Number of legs (1, or 2 on a two-legged trainer)."""
    @property
    def muscles(self) -> List[str]:
        """A leg's muscles, in the order of ``write``'s columns."""
    @property
    def command(self) -> npt.NDArray[np.float64]:
        """The last commands as applied (Pa), shape ``(legs, 4)``."""
    @property
    def limits(self) -> Dict[str, Any]:
        """``pressure_max_pa``, ``pressure_rate_max_pa_per_s``, ``windows`` (rad)."""
    @property
    def scenario(self) -> str:
        """The scenario's name."""
