"""``examples/identify.ipynb`` runs top to bottom in a kernel of this very Python, and shows what it says it shows."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _kernel_of_this_python(folder: Path) -> str:
    """A kernelspec that starts this interpreter (a ``python3`` spec found elsewhere might start another)."""
    spec = folder / "kernels" / "servoid-test"
    spec.mkdir(parents=True)
    argv = [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"]
    (spec / "kernel.json").write_text(json.dumps({"argv": argv, "display_name": "servoid test", "language": "python"}))
    return "servoid-test"


def test_the_example_notebook_runs_top_to_bottom(tmp_path, monkeypatch):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    monkeypatch.setenv("JUPYTER_PATH", str(tmp_path))
    nb = nbformat.read(EXAMPLES / "identify.ipynb", as_version=4)
    nb.cells.append(nbformat.v4.new_code_cell("import sys; print(sys.executable)"))
    client = nbclient.NotebookClient(nb, kernel_name=_kernel_of_this_python(tmp_path), timeout=120,
                                     resources={"metadata": {"path": str(EXAMPLES)}})  # fmt: skip
    client.execute()
    outputs = [out for cell in nb.cells if cell.cell_type == "code" for out in cell.outputs]
    assert not [out for out in outputs if out.output_type == "error"]
    assert nb.cells[-1].outputs[0].text.strip() == sys.executable
    data = [out.get("data", {}) for out in outputs]
    # the identification and the comparison show as tables, the three figures as images
    assert sum("<table>" in d.get("text/html", "") for d in data) == 2
    assert sum("image/png" in d for d in data) == 3
    text = "".join(out.get("text", "") for out in outputs)
    assert "TransferFunction" in text and "DC gain" in text
