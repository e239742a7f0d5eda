"""The example notebook (examples/ks_sweep.ipynb) runs headless, and the files it
is made from agree: it plots with matplotlib and shows the web player."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")
pytest.importorskip("ipykernel")
pytest.importorskip("matplotlib")

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
NOTEBOOK = EXAMPLES / "ks_sweep.ipynb"


def _outputs(nb) -> list[dict]:
    return [out for cell in nb.cells if cell.cell_type == "code" for out in cell.get("outputs", [])]


def test_notebook_is_made_by_its_script(tmp_path):
    """ks_sweep.ipynb is what make_ks_sweep.py writes (edit the script, then run it)"""
    code = ("import importlib.util, sys, nbformat\n"
            f"spec = importlib.util.spec_from_file_location('m', {str(EXAMPLES / 'make_ks_sweep.py')!r})\n"
            "m = importlib.util.module_from_spec(spec); spec.loader.exec_module(m)\n"
            "print(nbformat.writes(m.build()))\n")
    made = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert json.loads(made) == json.loads(NOTEBOOK.read_text(encoding="utf-8"))
    assert not _outputs(nbformat.read(NOTEBOOK, as_version=4)), "the notebook is kept without outputs"


def test_ks_sweep_notebook_runs_headless(tmp_path, monkeypatch):
    """executed in a fresh python3 kernel: no error, a PNG plot and the player's HTML"""
    monkeypatch.setenv("MPLBACKEND", "Agg")  # no window, whatever the notebook asks
    nb = nbformat.read(NOTEBOOK, as_version=4)
    client = nbclient.NotebookClient(nb, kernel_name="python3", timeout=300,
                                     resources={"metadata": {"path": str(tmp_path)}})
    client.execute()  # raises CellExecutionError on an error in a cell
    outputs = _outputs(nb)
    assert not [o for o in outputs if o.output_type == "error"]
    assert not [o for o in outputs if o.output_type == "stream" and o.name == "stderr"
                and "Traceback" in o.text]
    data = [o.get("data", {}) for o in outputs if o.output_type in ("display_data", "execute_result")]
    pngs = [d["image/png"] for d in data if "image/png" in d]
    assert pngs and len(pngs[0]) > 1000  # base64 of the plot
    players = [d["text/html"] for d in data if "clothsim-player" in d.get("text/html", "")]
    assert players, "the last cell shows the web player"
    page = players[0]
    assert page.startswith("<iframe") and "srcdoc=" in page and "clothsim-pos-0" in page
    text = "".join(o.get("text", "") for o in outputs if o.output_type == "stream")
    assert "181 frames of 400 points" in text and "ks = 50,000 N/m" in text
