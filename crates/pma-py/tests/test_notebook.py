"""examples/pma_exo_tour.ipynb runs headless: its code cells in order, in one namespace,
as Jupyter would run them (matplotlib on its Agg backend)."""
import json
import os
import pathlib

import pytest

NOTEBOOK = pathlib.Path(__file__).resolve().parents[3] / "examples" / "pma_exo_tour.ipynb"


def test_the_example_notebook_runs(capsys):
    pytest.importorskip("matplotlib")
    os.environ.setdefault("MPLBACKEND", "Agg")
    cells = json.loads(NOTEBOOK.read_text())["cells"]
    code = [c for c in cells if c["cell_type"] == "code"]
    assert len(code) >= 4
    namespace = {"__name__": "__main__"}
    for i, cell in enumerate(code):
        source = "".join(cell["source"])
        exec(compile(source, f"{NOTEBOOK.name}[{i}]", "exec"), namespace)
    out = capsys.readouterr().out
    assert "hip RMS" in out and "deviation" in out and "RMS error over 2 s" in out
