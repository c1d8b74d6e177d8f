"""Options have one owner all the way down: what :class:`brdffit.config.FitOptions` and
:class:`brdffit.posterior.McmcOptions` declare reaches the fit and the sampler, and each range
is checked where the option is used, from Python as from the command line."""

from __future__ import annotations

import dataclasses
import re

import pytest

from brdffit.config import FIT_KEYS
from brdffit.errors import ConfigError
from brdffit.fitting import options as fitting_options
from brdffit.fitting.options import Settings


def test_the_resolved_settings_hold_every_fit_option():
    assert {f.name for f in dataclasses.fields(Settings)} == set(FIT_KEYS)


def test_an_option_without_a_setting_is_an_error_not_dropped(monkeypatch):
    """A new :class:`FitOptions` field that :class:`Settings` lacks fails the first fit instead
    of being dropped on the way to the fitter."""
    monkeypatch.setattr(fitting_options, "FIT_DEFAULTS",
                        {**fitting_options.FIT_DEFAULTS, "new_option": 1})
    with pytest.raises(TypeError, match="new_option"):
        Settings.of({})


def test_settings_pass_every_option_through_and_resolve_the_rest():
    s = Settings.of(fitting_options.fit_options(
        None, cutoff=70.0, multistart=2, precision="float32", weighting="samples"))
    assert (s.cutoff, s.multistart, s.precision, s.weighting) == (70.0, 2, "float32", "samples")
    assert (s.rtol, s.atol) == (1e-6, 1e-6) and s.loss.name == "log" and s.scan is True


@pytest.mark.parametrize("key", ["nwalkers", "nsteps", "burn", "subsample"])
def test_sample_posterior_checks_the_mcmc_ranges_before_reading(key, tmp_path):
    """Each sampler option's range (its :class:`McmcOptions` field) is checked from Python
    too, before the input is read, in the words the command line uses for its flag."""
    from brdffit.posterior import sample_posterior
    from brdffit.posterior.options import MCMC_OPTIONS

    option = MCMC_OPTIONS[key]
    value = option.high + 1
    want = "a sample count" if key == "subsample" else option.want
    with pytest.raises(ConfigError, match=f"'{key}' must be " + re.escape(want)):
        sample_posterior(tmp_path / "never-read.csv", "ggx", **{key: value})


@pytest.mark.parametrize("command, kind, where", [
    ("fit", "RGL material", r"FIG-polar\.png for a {}"),  # the polar figure of such an input
    ("plot", "RGL material", r"polar coordinates, for a {}"),
    ("synth", "sample list", r"direction pairs for a {} output"),  # --samples
    ("synth", "RGL material", r"RGL material format \({},"),
])
def test_help_texts_name_a_kinds_suffixes_from_the_registry(command, kind, where, monkeypatch,
                                                            capsys):
    """A suffix added to :data:`brdffit.io.READERS` for a kind appears wherever a help text
    names that kind's files, not only in the list of every format."""
    from brdffit.cli import main
    from brdffit.io import READERS

    reader = next(entry for entry in READERS.values() if entry[0] == kind)
    suffixes = "/".join([s for s, entry in READERS.items() if entry[0] == kind] + [".toykind"])
    monkeypatch.setitem(READERS, ".toykind", reader)
    assert main([command, "--help"]) == 0
    text = " ".join(re.sub(r"-\n\s*", "-", capsys.readouterr().out).split())  # argparse's wrap
    assert re.search(where.format(re.escape(suffixes)), text), text
