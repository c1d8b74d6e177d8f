"""The sampler's options have one owner: :class:`brdffit.posterior.options.McmcOptions` and its
field metadata. The ``--mcmc`` flags, their help, their range checks and the flags the advice
names come from there; a new flagged field is tested here without editing a list."""

import dataclasses

import pytest

from brdffit.cli import main
from brdffit.cli._words import FLAG_FOR
from brdffit.config import OPTIONS
from brdffit.posterior import McmcOptions
from brdffit.posterior.defaults import DEFAULT_SUBSAMPLE_CELLS
from brdffit.posterior.options import FLAG_KEYS, FLAG_RANGES, MCMC_OPTIONS

FLAGGED = list(FLAG_KEYS)
RANGED = list(FLAG_RANGES)


def test_every_field_has_its_option_and_default():
    fields = dataclasses.fields(McmcOptions)
    assert [f.name for f in fields] == list(MCMC_OPTIONS)
    made = McmcOptions()
    for f in fields:
        if f.name == "subsample":
            assert (made.subsample.size, made.subsample.method) == (DEFAULT_SUBSAMPLE_CELLS,
                                                                    "stratified")
            assert MCMC_OPTIONS["subsample"].default == DEFAULT_SUBSAMPLE_CELLS
        else:
            assert getattr(made, f.name) == MCMC_OPTIONS[f.name].default


@pytest.mark.parametrize("dest", FLAGGED)
def test_every_flag_comes_from_its_field(dest, capsys):
    option = MCMC_OPTIONS[FLAG_KEYS[dest]]
    assert main(["fit", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert option.flag in text
    assert " ".join(option.help.split()) in text
    if FLAG_KEYS[dest] not in OPTIONS:  # the advice names the flag (subsample is the fit's)
        assert FLAG_FOR[FLAG_KEYS[dest]] == option.flag


@pytest.mark.parametrize("dest", RANGED)
@pytest.mark.parametrize("side", ["below", "above"])
def test_every_ranged_flag_is_checked_by_its_flag_name(dest, side, tmp_path, capsys):
    integer, low, high, _low_in, want = FLAG_RANGES[dest]
    value = low - 1 if side == "below" else high + 1
    flag = MCMC_OPTIONS[FLAG_KEYS[dest]].flag
    argv = ["fit", str(tmp_path / "absent.binary"), "--model", "ggx", "--mcmc", flag, str(value)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"{flag} must be {want}, got {value}" in err
    assert "Traceback" not in err


@pytest.mark.parametrize("dest", FLAGGED)
def test_every_flag_needs_mcmc(dest, tmp_path, capsys):
    option = MCMC_OPTIONS[FLAG_KEYS[dest]]
    value = option.choices[0] if option.choices else str(option.low or 2)
    argv = ["fit", str(tmp_path / "absent.binary"), "--model", "ggx", option.flag, value]
    assert main(argv) == 2
    assert f"{option.flag} only apply to posterior sampling: add --mcmc" in capsys.readouterr().err


# -- the --loss and --solver help lists its registry ---------------------------------------------
HELP_LISTS = [("--loss", "LOSSES"), ("--solver", "SOLVERS")]
#: The words of those help lines around the names.
FRAMING = {"residual", "weighting", "default", "or", "huber"}


def _help_line(flag: str) -> str:
    """The help of ``flag`` in ``brdffit fit --help``, read in a fresh process, which must not
    import JAX to build it."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    code = ("import contextlib, io, sys\nfrom brdffit.cli import main\nout = io.StringIO()\n"
            "with contextlib.redirect_stdout(out):\n    main(['fit', '--help'])\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('jax', 'emcee')))\n"
            "print(out.getvalue())")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                       env={**os.environ, "PYTHONPATH": str(root)})
    assert r.returncode == 0, r.stderr
    heavy, text = r.stdout.split("\n", 1)
    assert heavy == "[]", f"building the help imported {heavy}"
    text = " ".join(text.split())
    start = text.index(f"{flag} {flag[2:].upper()} ") + len(flag) * 2
    return text[start:text.index(" --", start)]


@pytest.mark.parametrize("flag, registry", HELP_LISTS)
def test_the_help_lists_exactly_the_registry(flag, registry):
    import re

    import brdffit.fitting as fitting
    from brdffit.config import OPTIONS

    names = list(getattr(fitting, registry))
    line = _help_line(flag)
    listed = [w for w in re.findall(r"[A-Za-z][\w-]*", line) if w not in FRAMING]
    assert listed == names, line
    default = OPTIONS[flag[2:]].default
    assert f"{default} (default)" in line
    assert {"DEFAULT_LOSS": fitting.DEFAULT_LOSS, "DEFAULT_SOLVER": fitting.DEFAULT_SOLVER}[
        f"DEFAULT_{flag[2:].upper()}"] == default
