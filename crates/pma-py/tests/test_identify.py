"""pma_exo.identify gives what `pma-exo identify --json` prints, on a log of the virtual
rig; bad logs raise the CLI's one-line message."""
import json

import pytest

import pma_exo
from test_cli_figures import assert_same_report
from test_interrupt import assert_interrupted


@pytest.fixture(scope="module")
def excite_log(cli, tmp_path_factory):
    log = tmp_path_factory.mktemp("rig") / "excite.csv"
    code, _, stderr = cli(["rig", "excite", "--duration", "20", "--out", str(log)])
    assert code == 0, stderr
    return log


@pytest.mark.figures
def test_identify_gives_the_cli_figures(cli, excite_log, tmp_path):
    code, stdout, stderr = cli(
        [
            "identify", str(excite_log), "--load-kg", "2.0", "--out", str(tmp_path / "plant.toml"),
            "--json", "--force",
        ]
    )
    assert code == 0, stderr
    theirs = json.loads(stdout)
    theirs.pop("provenance")
    ours = pma_exo.identify(str(excite_log), load_kg=2.0, force=True)
    plant = ours.pop("plant")
    assert_same_report(ours, theirs)
    # The plant file the CLI wrote holds the same numbers (TOML leaves out what is None).
    tomllib = pytest.importorskip("tomllib")
    written = tomllib.loads((tmp_path / "plant.toml").read_text())
    assert_same_report(without_none(plant), written, "plant")


def without_none(v):
    if isinstance(v, dict):
        return {k: without_none(x) for k, x in v.items() if x is not None}
    return v


def test_identify_refuses_bad_logs(cli, tmp_path):
    missing = tmp_path / "no-such-log.csv"
    with pytest.raises(pma_exo.PmaError) as raised:
        pma_exo.identify(str(missing))
    code, _, stderr = cli(["identify", str(missing), "--out", str(tmp_path / "p.toml")])
    assert code != 0
    assert str(raised.value) == stderr.strip().removeprefix("error: ")
    with pytest.raises(pma_exo.PmaError, match="1 to 8"):
        pma_exo.identify([])
    with pytest.raises(pma_exo.PmaError, match="load_kg"):
        pma_exo.identify(str(missing), load_kg=-1.0)


def test_ctrl_c_stops_an_identification(excite_log):
    # The whole identification takes about 5 s here.
    assert_interrupted(lambda: pma_exo.identify(str(excite_log), load_kg=2.0, force=True), within_s=3.0)
