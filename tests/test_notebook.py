"""``examples/fitting.ipynb`` runs end to end (nbclient, a fresh kernel), so the API it shows
cannot rot: the HTML and text reports, the comparison of the models, the figures of
``result.plot()`` and ``post.corner()`` shown inline, the files it saves. About 40-60 s: a
small table, two fits, a short posterior."""

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
    report = next(h for h in html if "brdffit-fit" in h)  # the FitResult's HTML report
    for part in ("initial", "AIC", "correlation", "rmse_log", "same data only"):
        assert part in report, part
    assert any("brdffit-posterior" in h for h in html)
    # the comparison of the models: a row per model, the metrics and AIC/BIC side by side
    assert any(all(f">{part}<" in h for part in ("ggx", "beckmann", "rmse_log", "aic", "bic"))
               for h in html), "no comparison of the models among the cell outputs"
    text = "".join(o.get("text", "") for o in outputs if o.output_type == "stream")
    assert "[[Variables]]" in text and "[[Correlations]]" in text  # result.report()
    # result.plot() and post.corner() return figures that show inline as the cell's value
    figures = [o for o in outputs
               if o.output_type == "execute_result" and "image/png" in o.get("data", {})]
    assert len(figures) == 2, [o.get("data", {}).keys() for o in outputs]
    sources = "".join(cell.source for cell in nb.cells)
    assert "result" in sources and ".plot()" in sources and ".corner(" in sources
    assert "Image(filename" not in sources  # no detour through files to show a figure
    for name in ("ggx.json", "ggx-posterior.json", "ggx-chain.npz", "figures/ggx-corner.png"):
        assert (tmp_path / name).is_file(), name
    import brdffit

    back = brdffit.FitResult.from_json(tmp_path / "ggx.json")
    assert back.success and back.provenance["input"]["path"].endswith("gold-small.binary")
    assert back.params["alpha"] == pytest.approx(0.12, rel=0.02)
