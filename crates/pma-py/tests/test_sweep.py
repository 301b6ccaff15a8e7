"""pma_exo.sweep gives the records `pma-exo sweep` writes to runs.jsonl, shard by shard;
bad arguments raise the CLI's one-line message."""
import json

import pytest

import pma_exo

SWEEP = """name = "tiny"
description = "two controllers, two plants, a short sine"
duration_s = 2.0

[[grid]]
controllers = ["aprc-ndo", "pid"]
gains = ["equal-activity/3"]
references = ["sine"]
events = ["none"]
[grid.plants]
presets = ["mismatch", "realistic"]
"""


@pytest.fixture
def sweep_file(tmp_path):
    path = tmp_path / "tiny.toml"
    path.write_text(SWEEP)
    return path


def cli_records(cli, sweep_file, out, shard):
    code, _, stderr = cli(["sweep", str(sweep_file), "--out", str(out), "--shard", shard])
    assert code == 0, stderr
    lines = (out / "runs.jsonl").read_text().splitlines()
    return sorted((json.loads(l) for l in lines), key=lambda r: r["run"])


@pytest.mark.figures
@pytest.mark.parametrize("shard", ["1/1", "2/3"])
def test_sweep_gives_the_cli_records(cli, sweep_file, tmp_path, shard):
    theirs = cli_records(cli, sweep_file, tmp_path / "out", shard)
    ours = pma_exo.sweep(sweep_file, shard=shard, threads=1)
    assert [r["run"] for r in ours] == [r["run"] for r in theirs]
    assert ours == theirs
    if shard == "1/1":
        assert len(ours) == 4
        assert {r["controller"] for r in ours} == {"aprc-ndo", "pid"}


def test_the_records_do_not_depend_on_the_threads(sweep_file):
    assert pma_exo.sweep(sweep_file, threads=1) == pma_exo.sweep(sweep_file, threads=2)


def test_sweep_refuses_bad_arguments(cli, sweep_file):
    with pytest.raises(pma_exo.PmaError) as raised:
        pma_exo.sweep("no_such_sweep")
    code, _, stderr = cli(["sweep", "no_such_sweep", "--out", "unused"])
    assert code != 0
    assert str(raised.value) == stderr.strip().removeprefix("error: ")
    with pytest.raises(pma_exo.PmaError, match="shard"):
        pma_exo.sweep(sweep_file, shard="3/2")
    with pytest.raises(pma_exo.PmaError, match="threads"):
        pma_exo.sweep(sweep_file, threads=0)
