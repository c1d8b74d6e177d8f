"""``examples/fitting.ipynb`` runs end to end (nbclient, a fresh kernel), so the API it shows
cannot rot. About 40-60 s: a small table, three fits, a short posterior."""

import shutil
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

NOTEBOOK = Path(__file__).resolve().parent.parent / "examples" / "fitting.ipynb"


def test_the_example_notebook_runs_and_shows_its_results(tmp_path):
    nb = nbformat.read(NOTEBOOK, as_version=4)
    shutil.copy(NOTEBOOK, tmp_path)
    NotebookClient(nb, timeout=300, kernel_name="python3",
                   resources={"metadata": {"path": str(tmp_path)}}).execute()
    outputs = [o for cell in nb.cells if cell.cell_type == "code" for o in cell.outputs]
    errors = [o for o in outputs if o.output_type == "error"]
    assert not errors, errors
    html = [o["data"]["text/html"] for o in outputs if "text/html" in o.get("data", {})]
    assert any("brdffit-fit" in h for h in html)  # the FitResult's HTML view
    assert any("brdffit-posterior" in h for h in html)
    images = [o for o in outputs if "image/png" in o.get("data", {})]
    assert len(images) >= 5  # four diagnostic figures and the corner plot, inline
    for name in ("ggx.json", "ggx-posterior.json", "ggx-chain.npz", "figures/ggx-corner.png"):
        assert (tmp_path / name).is_file(), name
    import brdffit

    back = brdffit.FitResult.from_json(tmp_path / "ggx.json")
    assert back.success and back.provenance["input"]["path"].endswith("gold-small.binary")
    assert back.params["alpha"] == pytest.approx(0.12, rel=0.02)
