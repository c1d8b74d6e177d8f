"""Hostile input, round two: staging folders, signals at the edges, render's option ranges.

Every command's outputs go through one staging mechanism (:class:`brdffit.cli._outputs.OutputSet`,
a context manager owning its staging folders), so that no ``.brdffit-*`` folder or temporary
stays behind whatever happens: success, a refusal, a failed write, a signal. A signal gives
either the outputs published and the command's own exit status, or nothing and 130/143.
"""

from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from brdffit.cli import main

ROOT = Path(__file__).resolve().parent.parent


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in Path(folder).iterdir())


def _one_line_error(capsys, code, *needles) -> str:
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


@pytest.fixture
def result_json(tmp_path):
    """A ``mitsuba-roughconductor`` result as ``brdffit fit --out`` writes it (no fit needed)."""
    names = ["alpha", "eta[0]", "eta[1]", "eta[2]", "k[0]", "k[1]", "k[2]"]
    x = [0.2, 0.2, 0.9, 1.1, 3.9, 2.4, 2.2]
    doc = {
        "model_name": "mitsuba-roughconductor",
        "params": {"alpha": 0.2, "eta": [0.2, 0.9, 1.1], "k": [3.9, 2.4, 2.2]},
        "stderr": {"alpha": 1e-4, "eta": [1e-3] * 3, "k": [1e-3] * 3},
        "names": names, "x": x, "cov": np.diag(np.full(7, 1e-8)).tolist(),
        "free": names, "fixed": [], "at_bound": {}, "cost": 1e-6,
        "metrics": {"rel_error": 1e-3, "rmse": 1e-3, "rmse_cosine": 1e-3, "rmse_log": 1e-3},
        "success": True, "status": "successful", "message": "", "steps": 5, "starts": [1e-6],
        "loss": "log", "solver": "lm", "n_cells": 2000, "n_total": 2000,
        "init": {"alpha": 0.1, "eta": [0.2, 0.9, 1.1], "k": [3.9, 2.4, 2.2]},
        "wall_time": 1.0, "timings": {}, "table": "gold", "covariance": "sandwich",
        "optimality": 1e-10, "provenance": {},
    }
    path = tmp_path / "r.json"
    path.write_text(json.dumps(doc))
    return path


# -- 1: staging folders left behind -----------------------------------------------------------
@pytest.mark.parametrize("target, name", [("mitsuba-xml", "e.xml"), ("mitsuba-dict", "e.json"),
                                          ("gltf", "e.gltf")])
def test_export_leaves_only_its_output(capsys, tmp_path, result_json, target, name):
    """Before: a ``.brdffit-XXXXXXXX`` folder beside the output after every export."""
    argv = ["export", str(result_json), "--to", target, "-o", str(tmp_path / name), "-q"]
    if target == "gltf":
        argv.append("--approximate")  # a conductor has no exact glTF counterpart
    assert main(argv) == 0, capsys.readouterr().err
    assert _leftovers(tmp_path) == sorted([name, "r.json"])


def test_render_leaves_only_its_output(capsys, tmp_path, result_json):
    """Before: a ``.brdffit-XXXXXXXX`` folder beside the PNG after every render."""
    pytest.importorskip("mitsuba")
    out = tmp_path / "s.png"
    assert main(["render", str(result_json), "-o", str(out), "--size", "16", "--spp", "2",
                 "-q"]) == 0, capsys.readouterr().err
    assert _leftovers(tmp_path) == ["r.json", "s.png"]


def test_failed_export_leaves_nothing(capsys, tmp_path, result_json, monkeypatch):
    """A write that fails (a full disk) and a refusal: exit 2, one line, nothing left."""
    from brdffit.cli import export

    def full(path, text):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(export, "write_text", full)
    code = main(["export", str(result_json), "--to", "mitsuba-xml", "-o", str(tmp_path / "e.xml")])
    _one_line_error(capsys, code, "e.xml: cannot write it (No space left on device)")
    assert _leftovers(tmp_path) == ["r.json"]
    monkeypatch.undo()
    code = main(["export", str(result_json), "--to", "gltf", "-o", str(tmp_path / "e.gltf")])
    _one_line_error(capsys, code, "--approximate")
    assert _leftovers(tmp_path) == ["r.json"]


def test_an_output_set_owns_its_staging_folder(tmp_path):
    """Checked on creation (nothing made), staged only inside ``with``, removed on the way out
    however the block ends."""
    from brdffit.cli._outputs import OutputError, OutputSet

    outputs = OutputSet([tmp_path / "a.txt"], force=False)
    assert _leftovers(tmp_path) == []  # the writability probe leaves nothing
    with pytest.raises(OutputError, match="inside the OutputSet's with block"):
        outputs.staged(tmp_path / "a.txt")
    with pytest.raises(RuntimeError, match="boom"):
        with OutputSet([tmp_path / "a.txt"], force=False) as outputs:
            outputs.write(tmp_path / "a.txt", lambda p: p.write_text("x"))
            assert len(_leftovers(tmp_path)) == 1  # the staging folder
            raise RuntimeError("boom")
    assert _leftovers(tmp_path) == []
    with OutputSet([tmp_path / "a.txt"], force=False) as outputs:
        outputs.write(tmp_path / "a.txt", lambda p: p.write_text("x"))
        outputs.publish()
    assert _leftovers(tmp_path) == ["a.txt"]


# -- 10: signals at the edges -----------------------------------------------------------------
_CHILD = r"""
import os, sys, time
from pathlib import Path
from brdffit.cli._signals import SignalExit, add_cleanup
from brdffit.cli._outputs import OutputSet

mode, folder = sys.argv[1], Path(sys.argv[2])
say = lambda word: (sys.stdout.write(word + "\n"), sys.stdout.flush())

def figures(base):  # as brdffit.plots._style.save: make the folder, then write the figure
    say("writing")
    time.sleep(0.3)  # drawing; the signal arrives now
    for name in ("slice", "peaks"):
        base.parent.mkdir(parents=True, exist_ok=True)
        (base.parent / f"f-{name}.png").write_bytes(b"x" * 4096)
    base.write_bytes(b"png")

# a clean-up that takes a moment, as demo's removal of its 35 MB temporary table does
add_cleanup(lambda: time.sleep(1.0))
with SignalExit("test"):
    with OutputSet([folder / "r.json", folder / "f.png"], False) as outputs:
        outputs.write(folder / "r.json", lambda p: p.write_text("{}"))
        if mode == "figure":
            outputs.write(folder / "f.png", figures, base=True)
        else:
            outputs.write(folder / "f.png", lambda p: p.write_bytes(b"png"))
        if mode == "publishing":
            import brdffit.cli._outputs as o
            real = o.OutputSet._publish_one
            def slow(self, path):
                real(self, path)
                say("publishing")
                time.sleep(1.0)
            o.OutputSet._publish_one = slow
        outputs.publish()
    say("published")
    time.sleep(1.0)
sys.exit(0)
"""


def _child_with_signal(tmp_path, mode, cue, signum=signal.SIGINT):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    p = subprocess.Popen([sys.executable, "-c", _CHILD, mode, str(tmp_path)], env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    for line in p.stdout:
        if line.strip() == cue:
            p.send_signal(signum)
            break
    out, err = p.communicate(timeout=60)
    return p.returncode, err


def test_a_signal_while_figures_are_written_leaves_nothing(tmp_path):
    """The figure writer re-created the staging folder behind the clean-up (a ``.brdffit-*``
    folder with a partial figure stayed): the clean-up now waits for the writes in flight,
    and a writer that tries to start after it waits until the process has ended."""
    code, err = _child_with_signal(tmp_path, "figure", "writing")
    assert code == 130, err
    assert err.strip().splitlines()[-1] == "brdffit test: interrupted"
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize("cue", ["publishing", "published"])
def test_a_signal_after_publishing_does_not_stop_the_command(tmp_path, cue):
    """Before: every output published and still exit 130. Now the publication is the point of
    no return: the outputs stay and the command ends with its own status."""
    code, err = _child_with_signal(tmp_path, "publishing" if cue == "publishing" else "plain",
                                   cue, signal.SIGTERM)
    assert code == 0, err
    assert "terminated" not in err
    assert _leftovers(tmp_path) == ["f.png", "r.json"]


def test_writes_wait_while_closed_and_go_on_when_opened(tmp_path):
    """The gate of :mod:`data_formats._atomic`: a closed gate holds new writes (the signal
    watcher's clean-up cannot be undone by a writer); nested writes of one thread count once."""
    import threading

    from data_formats import _atomic

    with _atomic.writing(), _atomic.writing():
        assert _atomic._STATE["active"] == 1
    assert _atomic.close_writes(1.0)
    try:
        done = threading.Event()
        t = threading.Thread(target=lambda: (_atomic.atomic_write(tmp_path / "a", lambda f: None),
                                             done.set()), daemon=True)
        t.start()
        assert not done.wait(0.3) and _leftovers(tmp_path) == []
    finally:
        _atomic.open_writes()
    assert done.wait(10) and _leftovers(tmp_path) == ["a"]


def _fit_on_a_terminal(folder, data, cue):
    """``brdffit fit --out --plot --table`` with its progress on a pseudo-terminal; SIGINT as
    soon as ``cue`` appears; returns (exit status, stderr text)."""
    import pty

    master, slave = pty.openpty()
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1"}
    p = subprocess.Popen([sys.executable, str(ROOT / "cli.py"), "fit", str(data), "-m", "ggx",
                          "--out", "r.json", "--plot", "f.png", "--table", "t.binary"],
                         cwd=folder, env=env, stdout=subprocess.DEVNULL, stderr=slave)
    os.close(slave)
    text, sent = "", False
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:
            break
        if not chunk:
            break
        text += chunk.decode(errors="replace")
        if not sent and cue in text:
            p.send_signal(signal.SIGINT)
            sent = True
    os.close(master)
    return p.wait(timeout=120), text


def test_sigint_while_fit_writes_its_figures(tmp_path):
    """The reproducer: SIGINT during ``fit --out --plot --table``, here at the moment the
    figures are being written: exit 130, nothing published, no staging folder left."""
    from brdffit import get_model
    from brdffit.cli.synth import synthesize_samples
    from data_formats.samplelist import write_samples

    data = write_samples(tmp_path / "s.csv",
                         synthesize_samples(get_model("ggx"), {"alpha": 0.2}, 400, seed=3))
    folder = tmp_path / "run"
    folder.mkdir()
    code, err = _fit_on_a_terminal(folder, data, "writing figures")
    assert code == 130, err
    assert "Traceback" not in err
    assert err.strip().splitlines()[-1].strip() == "brdffit fit: interrupted"
    assert _leftovers(folder) == []


# -- 16: render's options have ranges ---------------------------------------------------------
@pytest.mark.parametrize("argv, needle", [
    (["--environment", "inf"], "--environment must be a number in [0, 100]"),
    (["--environment", "nan"], "--environment must be a number in [0, 100]"),
    (["--environment", "-1"], "--environment must be a number in [0, 100]"),
    (["--spp", "1e8"], "--spp must be an integer in [1, 4096], got 100000000"),
    (["--spp", "0"], "--spp must be an integer in [1, 4096]"),
    (["--size", "60000"], "--size must be an integer in [8, 4096], got 60000"),
    (["--size", "-5"], "--size must be an integer in [8, 4096]"),
    (["--size", "32.5"], "--size must be an integer in [8, 4096], got 32.5"),
    (["--size", "4096", "--spp", "4096"], "samples, more than"),
])
def test_render_refuses_options_out_of_range(capsys, tmp_path, result_json, argv, needle):
    """Before: a white PNG and 4,036 Mitsuba warnings (inf), NaN/negative silently 0, no upper
    bound (``--size 60000`` started a 43 GB film)."""
    code = main(["render", str(result_json), "-o", str(tmp_path / "s.png"), *argv])
    _one_line_error(capsys, code, needle)
    assert _leftovers(tmp_path) == ["r.json"]


@pytest.mark.parametrize("options", [dict(environment=float("nan")), dict(environment=-1.0),
                                     dict(size=2), dict(spp=10**8), dict(irradiance=0.0),
                                     dict(light_dir=(0.0, 0.0, 0.0))])
def test_the_render_library_refuses_them_too(options):
    from brdffit.errors import ConfigError
    from brdffit.export.render import sphere_scene

    with pytest.raises(ConfigError):
        sphere_scene({"type": "diffuse"}, **options)


@pytest.mark.parametrize("noise", ["1e300", "11", "inf"])
def test_synth_noise_has_an_upper_bound(capsys, tmp_path, noise):
    """Before: ``--noise 1e300`` wrote a table of values near 1e299, exit 0."""
    code = main(["synth", "--model", "ggx", "--noise", noise, "-o", str(tmp_path / "n.binary")])
    _one_line_error(capsys, code, "--noise", "must be a finite number in [0, 10]")
    assert _leftovers(tmp_path) == []


def test_a_signal_during_the_programs_teardown_keeps_the_commands_status(tmp_path):
    """Before: SIGINT while JAX's exit handler ran (after every output was published) printed
    a ``KeyboardInterrupt`` traceback from ``clear_backends``."""
    child = ("import atexit, os, signal, time\n"
             "from brdffit.cli._signals import finish_on_signal\n"
             "atexit.register(lambda: (os.kill(os.getpid(), signal.SIGINT), time.sleep(2)))\n"
             "finish_on_signal(1)\n")
    p = subprocess.run([sys.executable, "-c", child], env={**os.environ, "PYTHONPATH": str(ROOT)},
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 1 and p.stderr == "", p.stderr
