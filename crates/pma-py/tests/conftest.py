"""Shared fixtures: the CLI binary the bindings are compared with."""
import csv
import io
import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]


def pytest_configure(config):
    config.addinivalue_line(
        "markers",
        "figures: compares the bindings' numbers with the CLI's; the numbers are the Rust "
        "core's, the same on every Python, so CI's second interpreter (3.9, the abi3 "
        "wheel's oldest) skips them with -m 'not figures'",
    )


def _cli_path():
    """The pma-exo binary: $PMA_EXO_CLI, else the release build of the repository."""
    given = os.environ.get("PMA_EXO_CLI")
    if given:
        return pathlib.Path(given)
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    return target / "release" / "pma-exo"


@pytest.fixture(scope="session")
def cli():
    """Runs the CLI: cli(args) -> (returncode, stdout, stderr)."""
    path = _cli_path()
    if not path.is_file():
        if os.environ.get("PMA_EXO_CLI"):
            pytest.fail(f"PMA_EXO_CLI={path} is not a file")
        pytest.skip(f"no CLI at {path}: `cargo build --release` or set PMA_EXO_CLI")

    def run(args):
        p = subprocess.run(
            [str(path), *args], cwd=REPO, capture_output=True, text=True, timeout=600
        )
        return p.returncode, p.stdout, p.stderr

    return run


@pytest.fixture(scope="session")
def cli_run(cli, tmp_path_factory):
    """Runs a CLI command with --json and --csv: (the JSON without provenance, the CSV
    as a dict of float arrays)."""

    def run(args):
        out = tmp_path_factory.mktemp("cli") / "run.csv"
        code, stdout, stderr = cli([*args, "--json", "--csv", str(out)])
        # 4: a treadmill run in which the patient did not walk; 5: a leg in the air that
        # pulled a muscle past its rating; each judged and reported as any.
        assert code in (0, 4, 5), stderr
        report = json.loads(stdout)
        report.pop("provenance")
        text = out.read_text()
        rows = list(csv.reader(io.StringIO("".join(l for l in text.splitlines(True) if not l.startswith("#")))))
        header, values = rows[0], np.array(rows[1:], dtype=float)
        return report, {name: values[:, i] for i, name in enumerate(header)}

    return run


@pytest.fixture(scope="session")
def repo():
    return REPO
