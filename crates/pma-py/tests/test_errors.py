"""Bad arguments raise pma_exo.PmaError with the CLI's one-line message; never a panic."""
import math

import pytest

import pma_exo


def cli_message(cli, args):
    """The CLI's error line, without its `error: ` prefix."""
    code, _, stderr = cli(args)
    assert code != 0
    line = stderr.strip()
    assert "\n" not in line, line
    return line.removeprefix("error: ")


CASES = [
    (dict(plant="no_such_plant"), ["single", "--plant", "no_such_plant"]),
    (dict(duration=math.nan), ["single", "--duration", "NaN"]),
    (dict(duration=-1.0), ["single", "--duration", "-1"]),
    (dict(duration=0.05), ["single", "--duration", "0.05"]),
    (dict(gains="no/such/gains.toml"), ["single", "--gains", "no/such/gains.toml"]),
    (
        dict(controller="psmc", gains="models/gains/muscle/pid.toml"),
        ["single", "--controller", "psmc", "--gains", "models/gains/muscle/pid.toml"],
    ),
    (dict(plant="models/gains/muscle/pid.toml"), ["single", "--plant", "models/gains/muscle/pid.toml"]),
]


@pytest.mark.parametrize("kwargs,args", CASES, ids=[a[-1] for _, a in CASES])
def test_single_errors_carry_the_cli_message(kwargs, args, cli, repo, monkeypatch):
    monkeypatch.chdir(repo)
    with pytest.raises(pma_exo.PmaError) as raised:
        pma_exo.single(**kwargs)
    assert str(raised.value) == cli_message(cli, args)


LEG_CASES = [
    (lambda: pma_exo.simulate("no_such_scenario"), ["simulate", "no_such_scenario"]),
    (lambda: pma_exo.simulate(duration=1.0), ["simulate", "--duration", "1"]),
    (lambda: pma_exo.simulate(duration=math.inf), ["simulate", "--duration", "inf"]),
    (
        lambda: pma_exo.simulate(mode="impedance", controller="psmc"),
        ["simulate", "--mode", "impedance", "--controller", "psmc"],
    ),
    (lambda: pma_exo.pendulum(knee_deg=120.0), ["pendulum", "--knee-deg", "120"]),
    (lambda: pma_exo.pendulum(duration=700.0), ["pendulum", "--duration", "700"]),
]


@pytest.mark.parametrize("call,args", LEG_CASES, ids=[" ".join(a) for _, a in LEG_CASES])
def test_leg_errors_carry_the_cli_message(call, args, cli):
    with pytest.raises(pma_exo.PmaError) as raised:
        call()
    assert str(raised.value) == cli_message(cli, args)


def test_unknown_names_raise():
    with pytest.raises(pma_exo.PmaError, match="unknown controller"):
        pma_exo.single(controller="lqr")
    with pytest.raises(pma_exo.PmaError, match="unknown mode `stiff`"):
        pma_exo.simulate(mode="stiff")
    with pytest.raises(pma_exo.PmaError, match="unknown reference `square`"):
        pma_exo.single(reference="square")
    with pytest.raises(pma_exo.PmaError, match="unknown spasticity `extreme`"):
        pma_exo.pendulum(spasticity="extreme")


def test_wrong_types_raise_type_errors():
    with pytest.raises(TypeError):
        pma_exo.single(duration="long")
    with pytest.raises(TypeError):
        pma_exo.simulate(scenario=3)


def test_pma_error_is_a_value_error():
    assert issubclass(pma_exo.PmaError, ValueError)
    assert issubclass(pma_exo.SupervisorError, pma_exo.PmaError)
