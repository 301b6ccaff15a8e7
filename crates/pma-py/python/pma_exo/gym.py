"""A Gymnasium environment of the exoskeleton leg: ``pma_exo.gym.LegEnv``.

A thin wrapper of :class:`pma_exo.Leg` (``pip install gymnasium``): the agent writes every
muscle's pressure each control period and is rewarded for tracking the scenario's gait.

- **Action**: one value per muscle in ``[-1, 1]``, legs after one another in the order of
  ``Leg.muscles``; ``-1`` is vented, ``1`` the valve's ``pressure_max_pa``. The supervisor
  of ``pma-exo simulate`` still rate-limits the commands (``Leg.limits``).
- **Observation**: per leg the hip and knee angles (rad), their references now (rad) and
  the angles' change over the last period (rad/s), in that order: ``6 * legs`` values,
  bounded: angles and references by the supervisor's encoder windows, rates by the speed
  beyond which the simulation fails (``Leg.limits``).
- **Registered** as ``pma_exo/Leg-v0``: ``gymnasium.make("pma_exo/Leg-v0",
  scenario="gait_treadmill")`` once ``pma_exo.gym`` is imported, or
  ``gymnasium.make("pma_exo.gym:pma_exo/Leg-v0")`` without importing it.
- **Reward**: minus the mean absolute tracking error over the joints (deg), per period.
- **End**: ``terminated`` when the supervisor vents the muscles (an encoder left its
  joint's window; the reward is then ``-fault_penalty``), ``truncated`` after
  ``episode_s`` seconds.

Nothing here simulates: every step is one ``Leg.step()``.
"""
from typing import Any, Dict, Optional, Tuple

import numpy as np

try:
    import gymnasium
    from gymnasium import spaces
except ImportError as e:  # pragma: no cover - the message is the point
    raise ImportError("pma_exo.gym needs gymnasium: pip install gymnasium") from e

from . import Leg, PmaError, SupervisorError


class LegEnv(gymnasium.Env):
    """The leg of ``scenario`` tracking its gait, one control period per step."""

    metadata = {"render_modes": []}

    def __init__(self, scenario: str = "gait_training", episode_s: float = 10.0, fault_penalty: float = 100.0):
        if not (np.isfinite(episode_s) and episode_s > 0.0):
            raise PmaError(f"episode_s = {episode_s} must be a positive number of seconds")
        if not (np.isfinite(fault_penalty) and fault_penalty >= 0.0):
            raise PmaError(f"fault_penalty = {fault_penalty} must be a finite number >= 0")
        self.leg = Leg(scenario)
        self.episode_s = float(episode_s)
        self.fault_penalty = float(fault_penalty)
        self._pressure_max_pa = float(self.leg.limits["pressure_max_pa"])
        n = self.leg.legs
        self.action_space = spaces.Box(-1.0, 1.0, shape=(4 * n,), dtype=np.float64)
        low, high = self._bounds()
        self.observation_space = spaces.Box(low, high, dtype=np.float64)
        self._last = np.zeros((n, 2))

    def _bounds(self) -> Tuple[np.ndarray, np.ndarray]:
        """Each observation's range: the encoders' windows for angles and references, the
        physics' speed bound for rates."""
        limits = self.leg.limits
        windows, v = limits["windows"], float(limits["joint_speed_max_rad_s"])
        low, high = [], []
        for i in range(self.leg.legs):
            side = "" if i == 0 else "left "
            hip, knee = windows[f"{side}hip angle"], windows[f"{side}knee angle"]
            low += [hip[0], knee[0], hip[0], knee[0], -v, -v]
            high += [hip[1], knee[1], hip[1], knee[1], v, v]
        return np.array(low), np.array(high)

    def pressures_pa(self, action: np.ndarray) -> np.ndarray:
        """The commands (Pa, shape ``(legs, 4)``) an action stands for."""
        a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        return (0.5 * (a + 1.0) * self._pressure_max_pa).reshape(self.leg.legs, 4)

    def _observation(self, q: np.ndarray) -> np.ndarray:
        rate = (q - self._last) / self.leg.period
        self._last = q.copy()
        obs = np.concatenate([np.hstack([q[i], self.leg.reference()[i], rate[i]]) for i in range(self.leg.legs)])
        # Within the box: a reading beyond a window has already ended the episode.
        return np.clip(obs, self.observation_space.low, self.observation_space.high)

    def _reward(self, q: np.ndarray) -> float:
        return -float(np.degrees(np.abs(q - self.leg.reference())).mean())

    def reset(self, *, seed: Optional[int] = None, options: Optional[Dict[str, Any]] = None) -> Tuple[np.ndarray, Dict[str, Any]]:
        super().reset(seed=seed)
        q = self.leg.reset()
        self._last = q.copy()
        return self._observation(q), {"t_s": self.leg.time}

    def step(self, action: np.ndarray) -> Tuple[np.ndarray, float, bool, bool, Dict[str, Any]]:
        p = self.pressures_pa(action)
        self.leg.write(p[0] if self.leg.legs == 1 else p)
        try:
            q = self.leg.step()
        except SupervisorError as fault:
            q = self.leg.read()
            info = {"t_s": self.leg.time, "fault": str(fault)}
            return self._observation(q), -self.fault_penalty, True, False, info
        truncated = self.leg.time >= self.episode_s - 0.5 * self.leg.period
        return self._observation(q), self._reward(q), False, truncated, {"t_s": self.leg.time}


gymnasium.register(id="pma_exo/Leg-v0", entry_point="pma_exo.gym:LegEnv")
