"""The fit's options have one owner: :class:`brdffit.config.FitOptions` and its field metadata.

Every option's default, range, choices, preset key and flag come from there, so the command
line, presets, ``brdffit.fit`` and the advice words agree by construction; a new option is
tested here without editing a list.
"""

import dataclasses

import pytest

import brdffit
from brdffit import config
from brdffit.cli import main
from brdffit.cli._words import FLAG_FOR
from brdffit.config import OPTIONS, FitOptions, load_config
from brdffit.errors import ConfigError
from brdffit.fitting import DEFAULT_SOLVER, FIT_DEFAULTS
from brdffit.fitting.losses import DEFAULT_LOSS

RANGED = [key for key, o in OPTIONS.items() if o.high is not None]
#: A value just outside each ranged option's range.
OUTSIDE = {key: (OPTIONS[key].high + 1 if OPTIONS[key].kind is int else OPTIONS[key].high * 2)
           for key in RANGED}


def test_defaults_and_flags_come_from_the_options():
    assert FIT_DEFAULTS == {k: o.default for k, o in OPTIONS.items() if k != "model"}
    assert FIT_DEFAULTS["loss"] == DEFAULT_LOSS and FIT_DEFAULTS["solver"] == DEFAULT_SOLVER
    for key, option in OPTIONS.items():
        if option.flag:
            assert FLAG_FOR[key] == option.flag
    assert set(FitOptions(**{k: None for k in FIT_DEFAULTS if k not in ("init", "fixed", "bounds")}
                          ).fit_kwargs()) == set()
    fields = {f.name for f in dataclasses.fields(FitOptions)}
    assert set(OPTIONS) <= fields


@pytest.mark.parametrize("key", RANGED)
def test_every_flag_is_checked_by_its_flag_name(key, tmp_path, capsys):
    flag, value = OPTIONS[key].flag, OUTSIDE[key]
    code = main(["fit", str(tmp_path / "missing.csv"), "--model", "ggx", flag, str(value)])
    err = capsys.readouterr().err
    assert code == 2
    assert f"{flag} must be {OPTIONS[key].want}" in err, err  # before the input is read


@pytest.mark.parametrize("key", RANGED)
def test_a_preset_and_the_library_say_the_same_words(key, tmp_path):
    option, value = OPTIONS[key], OUTSIDE[key]
    section = "[solver]\n" if option.table == "solver" else ""
    path = tmp_path / "p.toml"
    path.write_text(f"{section}{option.key or key} = {value}\n")
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert f"'{key}' must be {option.want}" in str(err.value)
    with pytest.raises(ConfigError) as err:
        brdffit.fit("never-read.csv", "ggx", **{key: value})
    assert f"'{key}' must be {option.want}" in str(err.value)


def test_brdffit_fit_checks_its_options_once(monkeypatch, tmp_path):
    import sys

    from test_api import write_sample_list

    path = write_sample_list(tmp_path / "s.csv")
    calls = []
    check = config.check_fit_options

    def counted(options, *args, **kwargs):
        calls.append(dict(options))
        return check(options, *args, **kwargs)

    for name, module in list(sys.modules.items()):  # wherever it was imported
        if name.startswith("brdffit") and getattr(module, "check_fit_options", None) is check:
            monkeypatch.setattr(module, "check_fit_options", counted)
    brdffit.fit(path, "ggx", cutoff=80, max_steps=3, throw=False)
    assert len(calls) == 1, calls


def test_the_posterior_takes_fit_options_and_mcmc_options():
    from brdffit.posterior import McmcOptions
    from brdffit.posterior.sampler import _split_options

    fit, mcmc = _split_options({"cutoff": 80}, McmcOptions(nwalkers=16), {"nsteps": 99,
                                                                          "loss": "cosine"})
    assert (fit.cutoff, fit.loss) == (80, "cosine")
    assert (mcmc.nwalkers, mcmc.nsteps, mcmc.burn) == (16, 99, McmcOptions().burn)
    with pytest.raises(TypeError, match="unknown option.*nwalker"):
        _split_options(None, None, {"nwalker": 8})
