"""pma_exo.fit_gait gives what `pma-exo fit-gait --json` prints; bad settings raise the
CLI's one-line message."""
import json

import pytest

import pma_exo
from test_cli_figures import assert_same_report


@pytest.mark.figures
def test_fit_gait_gives_the_cli_figures(cli):
    code, stdout, stderr = cli(["fit-gait", "gait_treadmill", "--iterations", "2", "--strides", "1", "--json"])
    assert code == 0, stderr
    theirs = json.loads(stdout)
    theirs.pop("provenance")
    ours = pma_exo.fit_gait("gait_treadmill", iterations=2, strides=1)
    assert_same_report(ours, theirs)
    # The belt's secant runs end where the harness carries no mean fore-aft force.
    assert ours["belt_steps"], ours
    assert abs(ours["belt_steps"][-1]["harness_fore_aft_mean_n"]) < 0.5, ours["belt_steps"]


def test_fit_gait_refuses_bad_settings(cli):
    with pytest.raises(pma_exo.PmaError) as raised:
        pma_exo.fit_gait(gain=1.5)
    code, _, stderr = cli(["fit-gait", "--gain", "1.5"])
    assert code != 0
    assert str(raised.value) == stderr.strip().removeprefix("error: ")
    with pytest.raises(pma_exo.PmaError, match="body_speed"):
        pma_exo.fit_gait(body_speed="swinging")
    with pytest.raises(pma_exo.PmaError, match="belt"):
        pma_exo.fit_gait(belt="fastest")
    with pytest.raises(pma_exo.PmaError, match="treadmill"):
        pma_exo.fit_gait("gait_training", iterations=1)
