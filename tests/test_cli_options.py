"""``brdffit fit`` exposes the fit's options as flags, and its advice names those flags."""

import json

import pytest

from brdffit import FitResult
from brdffit.cli import main
from brdffit.cli._words import cli_words
from test_api import write_sample_list


@pytest.fixture(scope="module")
def samples_csv(tmp_path_factory):
    return write_sample_list(tmp_path_factory.mktemp("cli-options") / "gold.csv")


def test_solver_flags_reach_the_fit_and_its_provenance(samples_csv, tmp_path, capsys):
    out = tmp_path / "r.json"
    code = main(["fit", str(samples_csv), "--model", "ggx", "--max-steps", "2", "--rtol", "1e-7",
                 "--atol", "1e-9", "--ftol", "1e-10", "--covariance", "gn", "--precision",
                 "float64", "--solver", "lm", "--multistart", "0", "--bound", "alpha=0.01,0.5",
                 "--fix", "f0=0.5", "--out", str(out), "--quiet"])
    captured = capsys.readouterr()
    assert code == 1  # two steps cannot converge from the data-driven start
    assert "Increase `--max-steps`" in captured.err and "`max_steps`" not in captured.err
    assert "Increase `--max-steps`" in captured.out  # the summary's message too
    result = json.loads(out.read_text())
    assert result["steps"] <= 2 and result["covariance"] == "gn"
    opts = result["provenance"]["options"]
    assert opts["max_steps"] == 2 and opts["rtol"] == 1e-7 and opts["atol"] == 1e-9
    assert opts["ftol"] == 1e-10 and opts["bounds"] == {"alpha": [0.01, 0.5]}
    assert result["provenance"]["input"]["path"] == str(samples_csv.resolve())
    assert result["provenance"]["config"] == ["command line"]  # no preset merged in
    df = FitResult.from_json(out).to_dataframe()  # the bounds and the fixed scalars it used
    assert (df.loc[["f0[0]", "f0[1]", "f0[2]"], "status"] == "fixed").all()
    assert df.loc[["f0[0]", "f0[1]", "f0[2]"], "stderr"].isna().all()
    assert df.loc["alpha", "lower"] == 0.01 and df.loc["alpha", "upper"] == 0.5


def test_weighting_flag_reaches_the_fit_and_a_wrong_one_is_a_usage_error(samples_csv, tmp_path,
                                                                         capsys):
    out = tmp_path / "r.json"
    assert main(["fit", str(samples_csv), "--model", "ggx", "--weighting", "samples",
                 "--out", str(out), "--quiet"]) == 0
    assert json.loads(out.read_text())["provenance"]["options"]["weighting"] == "samples"
    capsys.readouterr()
    assert main(["fit", str(samples_csv), "--model", "ggx", "--weighting", "solid"]) == 2
    err = capsys.readouterr().err
    assert "--weighting: invalid choice: 'solid'" in err and "Traceback" not in err


def test_bad_bound_flag_is_a_one_line_usage_error(samples_csv, capsys):
    assert main(["fit", str(samples_csv), "--model", "ggx", "--bound", "alpha=0.5"]) == 2
    assert "--bound 'alpha=0.5': expected NAME=LOWER,UPPER" in capsys.readouterr().err


def test_library_advice_is_reworded_as_flags():
    assert cli_words("Increase `max_steps` or start elsewhere.") == \
        "Increase `--max-steps` or start elsewhere."
    assert cli_words("Try another `init`, `multistart`, or the `log` loss.") == \
        "Try another `--init`, `--multistart`, or `--loss log`."
    assert cli_words("relax `cutoff`/`subsample`.") == "relax `--cutoff`/`--subsample`."
    assert cli_words("pass nsteps >= 900 (or use a smaller subsample to make steps cheaper)") \
        == "pass --steps 900 or more (or use a smaller --mcmc-subsample to make steps cheaper)"
    assert cli_words("Try nwalkers=32") == "Try --walkers 32"
    assert cli_words("nwalkers must be even; got nsteps=10, burn=20") == \
        "--walkers must be even; got --steps=10, --burn 20"


def test_words_a_user_reads(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "300")  # argparse wraps help text at the terminal width
    from brdffit import get_model
    from brdffit.errors import UnknownNameError

    with pytest.raises(UnknownNameError) as err:
        get_model("ggx").param("F0")
    assert str(err.value).startswith("model 'ggx' has no parameter 'F0'; valid choices: ")
    assert str(err.value).endswith("Did you mean 'f0'?")
    assert main(["demo", "--help"]) == 0
    assert "(1% noise)" in capsys.readouterr().out
    assert main(["fit", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "(FIG.png and" not in text and "FIG-slice.png, FIG-peaks.png" in text


def test_demo_names_channels_as_the_summary_does():
    from brdffit.cli.demo import comparison

    class Result:
        params = {"f0": [0.9, 0.6, 0.3]}
        stderr = {"f0": [0.01, 0.01, 0.01]}

    text = comparison(Result(), {"f0": (0.9, 0.6, 0.3)})
    assert "f0[0]" in text and "f0[r]" not in text
