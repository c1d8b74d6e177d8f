"""The command line, end to end in subprocesses (synth → info → fit → plot) and, for the many
error cases, in-process through ``main(argv)`` (same code path, no JAX start-up per case)."""

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import brdffit
from brdffit.cli import main

ROOT = Path(__file__).resolve().parent.parent
TRUTH = {"diffuse": [0.05, 0.03, 0.01], "f0": [0.9, 0.6, 0.3], "alpha": 0.2}  # a gold: no strong diffuse under a metal F0
MERL_BYTES = 34_992_012


def brdffit_cli(*args, cwd):
    """``python cli.py ARGS`` from the checkout, as a user would run it; stdout piped."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, str(ROOT / "cli.py"), *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, env=env, timeout=600)


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    return tmp_path_factory.mktemp("cli")


@pytest.fixture(scope="module")
def table(workdir):
    params = [f"--param={k}={','.join(map(str, np.atleast_1d(v)))}" for k, v in TRUTH.items()]
    run = brdffit_cli("synth", "--model", "ggx", *params, "-o", "t.binary", cwd=workdir)
    assert run.returncode == 0, run.stderr
    assert "wrote t.binary" in run.stdout
    return workdir / "t.binary"


def test_synth_info_fit_plot_end_to_end(table, workdir):
    assert table.stat().st_size == MERL_BYTES
    info = brdffit_cli("info", table, "--json", cwd=workdir)
    assert info.returncode == 0, info.stderr
    figures = json.loads(info.stdout)
    assert figures["dims"] == [90, 90, 180] and 0.75 < figures["valid_fraction"] < 0.77
    assert figures["peak"]["value"] > 100  # the GGX peak of a shiny material, far above diffuse

    fit = brdffit_cli("fit", table, "--model", "ggx", "--subsample", 4000, "--json",
                      "--out", "r.json", "--table", "fitted.binary", cwd=workdir)
    assert fit.returncode == 0, fit.stderr
    assert fit.stderr == ""  # piped: no progress, no warnings
    result = json.loads(fit.stdout)
    assert result == json.loads((workdir / "r.json").read_text())
    assert result["success"] and result["model_name"] == "ggx"
    for name, true in TRUTH.items():
        np.testing.assert_allclose(result["params"][name], true, rtol=1e-3)
    from data_formats.merl import read_merl

    measured, fitted = read_merl(table), read_merl(workdir / "fitted.binary")
    np.testing.assert_array_equal(fitted.valid, measured.valid)
    np.testing.assert_allclose(fitted.rgb, measured.rgb, rtol=1e-3)  # the same material

    plot = brdffit_cli("plot", table, "--fit", "r.json", "-o", "fig.png", cwd=workdir)
    assert plot.returncode == 0, plot.stderr
    sizes = {}
    for view in ("slice", "peaks", "albedo", "spheres"):
        sizes[view] = _png_size(workdir / f"fig-{view}.png")
    assert sizes["spheres"][0] > sizes["spheres"][1]  # measured | fitted side by side
    assert sizes["slice"][0] > sizes["spheres"][0]  # measured | fitted | log ratio
    assert not list(workdir.glob(".*")), "temporary files were left behind"


def _png_size(path):
    """(width, height) of a valid, readable, non-blank PNG of a readable size."""
    import matplotlib.image

    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG"
    img = matplotlib.image.imread(path)
    h, w = img.shape[:2]
    assert w >= 500 and h >= 300, f"{path}: {w}x{h} is too small to read"
    assert img[..., :3].std() > 0.02, f"{path} is blank"
    return w, h


def test_help_of_every_command(capsys):
    for command in ([], ["fit"], ["info"], ["synth"], ["plot"], ["models"], ["demo"], ["export"],
                    ["render"]):
        assert main([*command, "--help"]) == 0
        out = capsys.readouterr().out
        assert out.startswith("usage: brdffit") and ("--force" in out or not command or
                                                     command[0] in ("info", "models"))
    run = brdffit_cli("--help", cwd=ROOT)  # the thin top-level entry, in a fresh process
    assert run.returncode == 0 and "fit" in run.stdout and "demo" in run.stdout


def test_models_lists_the_registry(capsys):
    assert main(["models"]) == 0
    out = capsys.readouterr().out
    assert all(name in out for name in brdffit.available_models())
    assert main(["models", "ggx", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert [p["name"] for p in d["params"]] == ["diffuse", "f0", "alpha", "grazing"]
    assert d["params"][2]["lower"] == 1e-3 and d["params"][2]["log"] is True


def test_the_program_ends_with_the_commands_code_and_all_its_output(tmp_path):
    """The console script is ``brdffit._program.run``, which calls ``brdffit.cli.run``
    (``os._exit`` after the exit handlers): its piped output
    is the whole of what ``main`` prints in a process that ends the usual way, and its exit
    code is the command's."""
    scripts = (ROOT / "pyproject.toml").read_text()
    assert 'brdffit = "brdffit._program:run"' in scripts
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    usual = subprocess.run(
        [sys.executable, "-c", "import sys; from brdffit.cli import main; sys.exit(main(['models']))"],
        cwd=tmp_path, capture_output=True, text=True, env=env, timeout=600)
    assert usual.returncode == 0 and "ggx" in usual.stdout, usual.stderr
    listed = brdffit_cli("models", cwd=tmp_path)
    assert listed.returncode == 0 and listed.stdout == usual.stdout and listed.stderr == ""
    missing = brdffit_cli("info", tmp_path / "missing.binary", cwd=tmp_path)
    assert missing.returncode == 2 and missing.stderr.count("\n") == 1, missing.stderr


EARLY_SIGNAL = """
import os, sys, time, types

import brdffit._program as program


class Importing(types.ModuleType):
    \"\"\"Stands for brdffit.cli while it is being imported: the signal arrives then.\"\"\"

    def __getattr__(self, name):
        os.kill(os.getpid(), SIGNAL)
        time.sleep(5)
        raise AttributeError(name)


sys.modules["brdffit.cli"] = Importing("brdffit.cli")
program.run()
print("no signal handler ended the start-up")
"""


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_during_start_up_ends_the_program_quietly(tmp_path, sig, code):
    """An interrupt while the command line is still being imported (before its signal watcher
    exists) printed a KeyboardInterrupt traceback; now the program ends with 128 + signal."""
    script = tmp_path / "early.py"
    script.write_text(EARLY_SIGNAL.replace("SIGNAL)", f"{int(sig)})"))
    r = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                       env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=120)
    assert (r.returncode, r.stdout, r.stderr) == (code, "", "")


def test_a_batch_worker_process_ignores_interrupts():
    """multiprocessing's "spawn" children (a local batch's workers) import the program as
    their main module: they ignore SIGINT, which a terminal sends to the whole process group
    (the command stops them itself); a worker interrupted in its imports printed a traceback."""
    probe = ("import signal, sys, types; {setup}; import brdffit._program; "
             "print(signal.getsignal(signal.SIGINT) is signal.SIG_IGN)")
    child = "sys.modules['__mp_main__'] = types.ModuleType('__mp_main__')"  # as spawn runs it
    parent = "import multiprocessing"  # the parent's __mp_main__ is its __main__
    for setup, ignored in ((child, "True"), (parent, "False"), ("pass", "False")):
        r = subprocess.run([sys.executable, "-c", probe.format(setup=setup)], capture_output=True,
                           text=True, env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=120)
        assert r.stdout.strip() == ignored, (setup, r.stderr)


def _fails(capsys, argv, message, code=2):
    """Run ``argv``; expect exit ``code`` and one line on stderr containing ``message``."""
    assert main(argv) == code
    err = capsys.readouterr().err
    assert message in err, err
    assert "Traceback" not in err and err.count("\n") == 1, err
    return err


def test_user_mistakes_are_one_line_and_exit_2(capsys, table, tmp_path):
    t = str(table)
    trunc = tmp_path / "trunc.binary"
    trunc.write_bytes(table.read_bytes()[:5000])
    _fails(capsys, ["info", str(trunc)], "truncated")
    _fails(capsys, ["fit", str(trunc), "--model", "ggx"], "truncated")
    _fails(capsys, ["fit", t, "--model", "ggxx"], "unknown model 'ggxx'; valid choices:")
    _fails(capsys, ["fit", t, "--model", "ggx", "--fix", "alpah=0.1"], "Did you mean 'alpha'?")
    _fails(capsys, ["fit", t, "--model", "ggx", "--init", "f0=1,2"], "give one number or three")
    _fails(capsys, ["synth", "--model", "ggx", "-p", "alpha=7", "-o", str(tmp_path / "x.binary")],
           "outside its bounds")
    _fails(capsys, ["fit", t, "--model", "ggx", "--loss", "cosin"], "unknown loss 'cosin'")
    (tmp_path / "typo.toml").write_text("cutof = 80\n")
    _fails(capsys, ["fit", t, "-c", str(tmp_path / "typo.toml"), "--model", "ggx"],
           "unknown key 'cutof'; valid keys: model, loss, cutoff")
    _fails(capsys, ["fit", t, "--config", "no-such-preset", "--model", "ggx"], "no preset named")
    _fails(capsys, ["fit", str(tmp_path / "t.txt"), "--model", "ggx"], "unknown input format '.txt'")
    _fails(capsys, ["info", str(tmp_path / "absent.binary")], "no such file")
    _fails(capsys, ["fit", t], "no model given")
    (tmp_path / "nan.csv").write_text("theta_i,phi_i,theta_o,phi_o,r,g,b\n10,0,10,180,1,nan,1\n")
    _fails(capsys, ["fit", str(tmp_path / "nan.csv"), "--model", "ggx"],
           "nan.csv: line 2, column 'g': value nan is not finite")
    assert main(["fit", t, "--model", "ggx", "--debug", "--fix", "alpah=0.1"]) == 2
    assert "Traceback" in capsys.readouterr().err  # --debug shows it
    assert main(["fit"]) == 2 and "required: FILE" in capsys.readouterr().err  # argparse usage
    assert sorted(p.name for p in tmp_path.iterdir()) == ["nan.csv", "trunc.binary", "typo.toml"]


def test_nan_in_a_merl_table(capsys, tmp_path):
    header = np.array([2, 2, 2], "<i4").tobytes()
    body = np.ones(24)
    body[5] = np.nan
    (tmp_path / "nan.binary").write_bytes(header + body.astype("<f8").tobytes())
    err = _fails(capsys, ["info", str(tmp_path / "nan.binary")], "nan.binary")
    assert "nan" in err.lower()


def test_existing_outputs_refused_before_any_work(capsys, table, tmp_path):
    out = tmp_path / "r.json"
    out.write_text("keep me")
    # the input does not even exist: the output check comes first, so nothing is read or fitted
    _fails(capsys, ["fit", str(tmp_path / "absent.binary"), "--model", "ggx", "--out", str(out)],
           "r.json: already exists; pass --force to overwrite it")
    (tmp_path / "fig-peaks.png").write_text("keep me too")
    _fails(capsys, ["plot", str(table), "-o", str(tmp_path / "fig.png")],
           "fig-peaks.png: already exists")
    # no abbreviations: `synth --out` is not taken for `--output` (argparse usage error, exit 2)
    assert main(["synth", "--model", "ggx", "-o", str(out.with_suffix(".binary")), "--out", "x"]) == 2
    assert "unrecognized arguments: --out x" in capsys.readouterr().err
    _fails(capsys, ["fit", str(table), "--model", "ggx", "--out", str(tmp_path / "no" / "r.json")],
           "folder")
    assert out.read_text() == "keep me" and (tmp_path / "fig-peaks.png").read_text() == "keep me too"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fig-peaks.png", "r.json"]


def test_sample_list_fit_not_converged_exits_1_and_still_writes(capsys, tmp_path):
    """A sample list through synth and fit; a preset allowing one solver step cannot converge:
    exit 1, the result is written and marked, the preset's loss and the flag's cutoff apply."""
    csv = tmp_path / "s.csv"
    assert main(["synth", "--model", "ggx", "-p", "alpha=0.3", "--samples", "1500", "-o",
                 str(csv), "--quiet"]) == 0
    (tmp_path / "p.toml").write_text('loss = "cosine"\ncutoff = 60\n[solver]\nmax_steps = 1\n')
    code = main(["fit", str(csv), "--model", "ggx", "--config", str(tmp_path / "p.toml"),
                 "--cutoff", "85", "--init", "alpha=0.05", "--out", str(tmp_path / "r.json"),
                 "--quiet"])
    captured = capsys.readouterr()
    assert code == 1, captured.err
    assert "did not converge" in captured.err and "FAILED" in captured.out
    result = json.loads((tmp_path / "r.json").read_text())
    assert result["success"] is False and result["loss"] == "cosine" and result["steps"] <= 1
    assert result["n_cells"] > 1300  # cutoff 85° from the flag, not 60° from the preset


def test_progress_only_on_a_terminal():
    import io

    from brdffit.cli._common import Progress

    class Tty(io.StringIO):
        def isatty(self):
            return True

    piped, tty, quiet = io.StringIO(), Tty(), Tty()
    for stream, p in ((piped, Progress(stream=piped)), (tty, Progress(stream=tty)),
                      (quiet, Progress(quiet=True, stream=quiet))):
        p("setup", {"n_cells": 10})
        p("step", {"step": 1, "cost": 0.5})
        p("done", {"success": True})
    assert piped.getvalue() == "" and quiet.getvalue() == ""
    lines = tty.getvalue().split("\n")
    assert "setup n_cells=10" in lines[0] and "\rstep" not in lines[0]
    assert lines[1].startswith("\r[") and "step step=1 cost=0.5" in lines[1]  # overwritten line
    assert "done success=True" in lines[2]


def test_info_of_a_sample_list(capsys, tmp_path):
    (tmp_path / "s.csv").write_text(
        "theta_i,phi_i,theta_o,phi_o,r,g,b\n10,0,10,180,5,4,3\n40,0,20,90,0.1,0.2,0.3\n"
    )
    assert main(["info", str(tmp_path / "s.csv"), "--json"]) == 0
    figures = json.loads(capsys.readouterr().out)
    assert figures["samples"] == 2 and figures["r_max"] == 5 and figures["peak_rgb"] == [5, 4, 3]
    assert figures["peak_theta_i_deg"] == pytest.approx(10)
    assert main(["info", str(tmp_path / "s.csv")]) == 0
    text = capsys.readouterr().out  # laid out as `info` of a MERL table
    assert text.startswith("sample list 's' (") and "  valid        2 (100.0%)" in text
    assert "  channel      min          median       max\n  R            0.1 " in text


def test_demo_recovers_the_known_material(capsys, tmp_path):
    """The README's main job (on a subsample, to keep the test quick)."""
    from brdffit.cli.demo import TRUTH as DEMO_TRUTH

    outdir = tmp_path / "demo"
    assert main(["demo", "--outdir", str(outdir), "--subsample", "20000", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "recovered against true" in out and "alpha" in out
    result = json.loads((outdir / "result.json").read_text())
    for name, true in DEMO_TRUTH.items():  # 1% noise: close, not exact
        np.testing.assert_allclose(result["params"][name], true, rtol=0.03, atol=2e-3)
    # the first material a user sees is one a renderer can trust, and says so
    assert result["plausibility"]["plausible"], result["plausibility"]
    assert sorted(p.name for p in outdir.iterdir()) == [
        "brdffit-demo.json", "demo-albedo.png", "demo-peaks.png", "demo-slice.png",
        "demo-spheres.png", "result.json"]
    # a second run refuses to overwrite a file it did not write, before doing any work
    (outdir / "result.json").write_text("{}")
    _fails(capsys, ["demo", "--outdir", str(outdir)], "result.json: already exists and is not "
           "what an earlier demo wrote; pass --force")


def test_synth_noise_is_multiplicative_with_the_given_sigma():
    from brdffit.cli.synth import synthesize_samples

    ggx = brdffit.get_model("ggx")
    clean = synthesize_samples(ggx, TRUTH, 20000, seed=4)
    noisy = synthesize_samples(ggx, TRUTH, 20000, noise=0.05, seed=4)
    np.testing.assert_array_equal(noisy.wi, clean.wi)  # same directions for the same seed
    ratio = noisy.rgb / clean.rgb - 1.0
    assert abs(ratio.std() - 0.05) < 0.002 and abs(ratio.mean()) < 0.002
    half = (clean.wi + clean.wo) / np.linalg.norm(clean.wi + clean.wo, axis=-1, keepdims=True)
    assert np.mean(half[:, 2] > np.cos(np.radians(10))) > 0.1  # dense near the peak


def test_several_models_side_by_side_best_first(table, workdir):
    run = brdffit_cli("fit", table, "--model", "beckmann,ggx", "--subsample", 3000,
                      "--out", "several.json", cwd=workdir)
    assert run.returncode == 0, run.stderr
    lines = run.stdout.splitlines()
    head = next(i for i, line in enumerate(lines) if line.lstrip().startswith("rank"))
    assert "rmse_log" in lines[head] and "rmse_cosine" in lines[head]
    first, second = lines[head + 2].split(), lines[head + 3].split()
    assert first[:3] == ["1", "ggx", "yes"] and second[:3] == ["2", "beckmann", "yes"]
    assert float(first[3]) < float(second[3])  # the ggx table is fitted best by ggx
    saved = json.loads((workdir / "several.json").read_text())["results"]
    assert [r["model_name"] for r in saved] == ["ggx", "beckmann"]
    bad = brdffit_cli("fit", table, "--model", "ggx,ggx", cwd=workdir)
    assert bad.returncode == 2 and "distinct model names" in bad.stderr
    plot = brdffit_cli("fit", table, "--model", "ggx,beckmann", "--plot", "x.png", cwd=workdir)
    assert plot.returncode == 2 and "take one model" in plot.stderr
