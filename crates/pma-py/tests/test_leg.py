"""Leg: a controller written in Python steps the exoskeleton leg behind its supervisor."""
import numpy as np
import pytest

import pma_exo


def joint_pid(leg, periods, kp=1e7, kd=1e5):
    """A PD per joint around the resting co-contraction: flexor up, extensor down."""
    resting = leg.command.copy()
    q = leg.read()
    previous, errors = q.copy(), []
    for k in range(periods):
        e = leg.reference(leg.time + leg.period) - q
        u = kp * e - kd * (q - previous) / leg.period
        previous = q.copy()
        p = resting + np.stack([u[:, 0], -u[:, 0], u[:, 1], -u[:, 1]], axis=1) / 2
        leg.write(np.clip(p, 0.0, leg.limits["pressure_max_pa"]))
        q = leg.step()
        errors.append(np.degrees(np.abs(leg.reference() - q)))
    return np.array(errors)


def test_a_python_pd_tracks_the_gait():
    leg = pma_exo.Leg("gait_training")
    assert leg.legs == 1 and leg.muscles == ["hip_flexor", "hip_extensor", "knee_flexor", "knee_extensor"]
    errors = joint_pid(leg, 4800)
    assert leg.time == pytest.approx(4.8)
    rms = np.sqrt(np.mean(errors[1600:] ** 2, axis=0))
    assert np.all(rms < 3.0), rms


def test_the_cuffs_read_the_torque_the_device_puts_into_the_limb():
    leg = pma_exo.Leg("gait_training")
    joint_pid(leg, 500)
    cuffs = leg.cuffs()
    assert cuffs.shape == (1, 2) and np.all(np.isfinite(cuffs))
    np.testing.assert_allclose(cuffs, leg.state()["interaction_nm"], rtol=1e-12)
    # The PD holds the limb up: the device carries part of its weight at the hip.
    assert abs(cuffs[0, 0]) > 0.1, cuffs
    # The cuff forces give the knee's torque back at the shank cuff, 0.20 m below it.
    forces = leg.state()["cuff_force_n"]
    assert forces.shape == (1, 2) and np.all(np.isfinite(forces))
    np.testing.assert_allclose(-forces[0, 1] * 0.20, cuffs[0, 1], rtol=1e-9)


def test_the_trainer_has_two_legs():
    leg = pma_exo.Leg("gait_treadmill")
    assert leg.legs == 2
    assert leg.read().shape == (2, 2) and leg.command.shape == (2, 4)
    assert leg.cuffs().shape == (2, 2)
    with pytest.raises(pma_exo.PmaError, match=r"shape \(4,\)"):
        leg.write(np.zeros(4))
    leg.write(leg.command)
    assert leg.step().shape == (2, 2)


def test_bad_pressures_raise_and_send_nothing():
    leg = pma_exo.Leg()
    before = leg.command.copy()
    with pytest.raises(pma_exo.PmaError, match=r"shape \(3,\)"):
        leg.write(np.zeros(3))
    with pytest.raises(TypeError, match="float64"):
        leg.write(np.zeros(4, dtype=np.int64))
    with pytest.raises(TypeError):
        leg.write("4 bar")
    with pytest.raises(pma_exo.PmaError, match="hip_extensor"):
        leg.write([1e5, np.nan, 1e5, 1e5])
    with pytest.raises(pma_exo.PmaError, match="knee_flexor"):
        leg.write(np.array([1e5, 1e5, 1e9, 1e5]))
    with pytest.raises(pma_exo.PmaError, match="3 pressures"):
        leg.write([1e5, 1e5, 1e5])
    np.testing.assert_array_equal(leg.command, before)


def test_a_joint_cannot_be_driven_past_its_limits():
    """Hip flexor at full pressure, extensor vented, for 5 s: the hip flexes as far as the
    muscle pulls it (about 50 deg), inside the supervisor's window (else it would vent and
    raise)."""
    leg = pma_exo.Leg()
    p_max = leg.limits["pressure_max_pa"]
    lo, hi = leg.limits["windows"]["hip angle"]
    hips = []
    for _ in range(5000):
        leg.write([p_max, 0.0, leg.command[0, 2], leg.command[0, 3]])
        hips.append(leg.step()[0, 0])
    assert lo <= min(hips) and max(hips) <= hi
    assert max(hips) > 0.5, "the hip flexed"
    leg.reset()
    assert leg.time == 0.0
    np.testing.assert_array_equal(leg.read(), [[0.0, 0.0]])


def test_unknown_scenarios_raise_the_cli_message(cli):
    with pytest.raises(pma_exo.PmaError) as raised:
        pma_exo.Leg("no_such_scenario")
    code, _, stderr = cli(["simulate", "no_such_scenario"])
    assert code == 1 and str(raised.value) == stderr.strip().removeprefix("error: ")
