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


@pytest.mark.parametrize("options, error, words", [
    ({"cutoff": 500.0}, ConfigError, r"'cutoff' must be degrees in \(0, 90\]"),
    ({"max_step": 5}, TypeError, "unknown option.*max_step"),
    ({"options": {"multistart": -1}}, ConfigError, "'multistart' must be an integer"),
])
def test_fit_many_checks_its_options_before_any_work(options, error, words, monkeypatch,
                                                     tmp_path):
    """``fit_many`` takes the options as :func:`brdffit.fit` does (a ``FitOptions`` or a
    mapping as ``options``, and keywords) and refuses a wrong one before it starts a cluster,
    instead of a failed row per job."""
    import brdffit
    from brdffit.batch import runner

    def started(*args, **kwargs):
        raise AssertionError("the batch started")

    monkeypatch.setattr(runner, "run_batch", started)
    table = tmp_path / "m.csv"
    table.write_text("theta_i,phi_i,theta_o,phi_o,r,g,b\n10,0,10,180,0.5,0.5,0.5\n")
    with pytest.raises(error, match=words):
        brdffit.fit_many([table], "ggx", **options)


def test_fit_many_hands_the_jobs_a_preset_as_checked_options(monkeypatch, tmp_path):
    import brdffit
    from brdffit.batch import runner
    from brdffit.config import FitOptions

    seen = []
    monkeypatch.setattr(runner, "run_batch", lambda jobs, **kwargs: seen.extend(jobs) or
                        type("Out", (), {"frame": None, "results": None})())
    table = tmp_path / "m.csv"
    table.write_text("theta_i,phi_i,theta_o,phi_o,r,g,b\n10,0,10,180,0.5,0.5,0.5\n")
    brdffit.fit_many([table], "ggx", options=FitOptions(cutoff=70.0, covariance="GN"),
                     max_steps=9)
    assert [job.fit_kwargs for job in seen] == [{"cutoff": 70.0, "covariance": "gn",
                                                "max_steps": 9}]


def test_asking_for_a_model_variant_leaves_the_registry_as_it_was():
    """A variant a factory builds by name (Mitsuba's ``roughconductor`` options) is the same
    object every time and is not added to the registry: what :func:`available_models` lists
    does not depend on what the process asked for before."""
    import brdffit

    before = brdffit.available_models()
    name = "mitsuba-roughconductor-beckmann-aniso-tint"
    assert name not in before
    model = brdffit.get_model(name)
    assert model.name == name and brdffit.get_model(name.upper()) is model
    assert brdffit.available_models() == before
    assert brdffit.get_model("mitsuba-roughconductor") is brdffit.get_model(
        "mitsuba-roughconductor")
