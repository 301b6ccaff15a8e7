"""pma_exo.gym.LegEnv: a Gymnasium environment that passes Gymnasium's own checker, steps
the same leg as pma_exo.Leg, rewards tracking and ends on a fault."""
import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")
from gymnasium.utils.env_checker import check_env  # noqa: E402

import pma_exo  # noqa: E402
from pma_exo.gym import LegEnv  # noqa: E402


def test_the_environment_passes_gymnasiums_checker():
    check_env(LegEnv(episode_s=0.05), skip_render_check=True)


@pytest.mark.parametrize("scenario", ["gait_training", "gait_treadmill"])
def test_a_step_is_a_step_of_the_leg(scenario):
    env = LegEnv(scenario, episode_s=0.2)
    leg = pma_exo.Leg(scenario)
    obs, _ = env.reset()
    q = leg.reset()
    n = leg.legs
    assert obs.shape == (6 * n,) and env.action_space.shape == (4 * n,)
    rng = np.random.default_rng(7)
    steps, truncated = 0, False
    while not truncated:
        action = rng.uniform(-0.2, 0.2, size=4 * n)
        obs, reward, terminated, truncated, info = env.step(action)
        p = env.pressures_pa(action)
        leg.write(p[0] if n == 1 else p)
        q = leg.step()
        steps += 1
        assert not terminated
        np.testing.assert_array_equal(obs.reshape(n, 6)[:, :2], q)
        assert reward == -np.degrees(np.abs(q - leg.reference())).mean()
        assert info["t_s"] == leg.time
    # 0.2 s of 1 ms periods.
    assert steps == round(0.2 / leg.period)


def test_the_joints_limits_hold_a_leg_driven_to_its_stops():
    # Flexors at full pressure, extensors vented: the URDF's limits stop the joints inside
    # the supervisor's windows, so the episode goes on, at a large tracking error.
    env = LegEnv(episode_s=2.0)
    env.reset()
    truncated = terminated = False
    while not (terminated or truncated):
        _, reward, terminated, truncated, _ = env.step(np.array([1.0, -1.0, 1.0, -1.0]))
    assert truncated and not terminated
    assert reward < -20.0


def test_a_fault_ends_the_episode_with_the_penalty():
    env = LegEnv(episode_s=1.0, fault_penalty=50.0)
    env.reset()

    class Faulting:
        """The leg, whose next step the supervisor ends (the shapes of the real one)."""

        def __init__(self, leg):
            self.leg = leg

        def __getattr__(self, name):
            return getattr(self.leg, name)

        def step(self):
            raise pma_exo.SupervisorError("hip angle 1.5 rad outside -0.85..1.37: muscles vented")

    env.leg = Faulting(env.leg)
    _, reward, terminated, truncated, info = env.step(np.zeros(4))
    assert terminated and not truncated
    assert reward == -50.0 and "outside" in info["fault"]


def test_bad_settings_raise_a_one_line_error():
    with pytest.raises(pma_exo.PmaError, match="episode_s"):
        LegEnv(episode_s=0.0)
    with pytest.raises(pma_exo.PmaError, match="fault_penalty"):
        LegEnv(fault_penalty=float("nan"))
    with pytest.raises(pma_exo.PmaError, match="scenario"):
        LegEnv("no_such_scenario")


def test_the_environment_is_registered_and_its_observations_are_bounded():
    env = gymnasium.make("pma_exo/Leg-v0", scenario="gait_training", episode_s=0.05)
    space = env.observation_space
    assert np.all(np.isfinite(space.low)) and np.all(np.isfinite(space.high))
    obs, _ = env.reset()
    assert space.contains(obs)
    # Without importing the module first, as Gymnasium's "module:id" form does.
    gymnasium.make("pma_exo.gym:pma_exo/Leg-v0", episode_s=0.05).reset()
