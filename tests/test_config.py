"""TOML presets: every shipped preset loads and validates; layers merge; mistakes are named."""

import os
import re
import tomllib
from pathlib import Path

import pytest

import brdffit
from brdffit.config import FitOptions, check_fit_options, find_config, load_config, parse_config
from brdffit.errors import ConfigError, UnknownNameError

CONFIGS = Path(__file__).resolve().parent.parent / "configs"
PRESETS = sorted(CONFIGS.glob("*.toml"))


@pytest.mark.parametrize("name", brdffit.available_models())
def test_every_registered_model_has_a_preset(name):
    path = CONFIGS / f"{name}.toml"
    assert path.is_file(), f"configs/{name}.toml is missing: one preset per registered model"
    opts = load_config(path)
    assert opts.model == name
    model = brdffit.get_model(name)
    opts.check_params(model)  # names, shapes and values against the registry
    assert opts.loss and opts.cutoff and opts.solver and opts.ftol and opts.max_steps
    text = path.read_text()
    for pname in model.names:  # every parameter is listed to edit (start value and bounds)
        assert len(re.findall(rf"^(# )?{re.escape(pname)} = ", text, re.M)) >= 2 - (
            pname in opts.fixed), f"{path.name} does not list {pname}"
    listed = text.split("[bounds]", 1)[1] if "[bounds]" in text else ""
    for pname, lo, hi in re.findall(r"^# (\w+) = \[([^,\]]+), ([^\]]+)\]", listed, re.M):
        p = model.param(pname)  # the commented bounds are the declared ones
        assert (float(lo), float(hi)) == (p.lower, p.upper), f"{path.name}: {pname}"


@pytest.mark.parametrize("path", PRESETS, ids=[p.stem for p in PRESETS])
def test_every_preset_loads_and_names_valid_loss_and_solver(path):
    from brdffit.fitting.losses import LOSSES
    from brdffit.fitting.solvers import SOLVERS

    opts = load_config(path)
    assert opts.sources == (str(path),) and opts.description
    assert opts.loss in LOSSES
    assert opts.solver is None or opts.solver in SOLVERS


def test_ngan2005_protocol():
    opts = load_config(CONFIGS / "ngan2005.toml")
    assert (opts.loss, opts.cutoff, opts.model, opts.weighting) == (
        "cosine-in", 80.0, None, "solid-angle")
    text = (CONFIGS / "ngan2005.toml").read_text()
    assert "does not reproduce" in text and "80°" in text


def test_parse_full_layout():
    data = tomllib.loads(
        """
        model = "ggx"
        loss = "log"
        cutoff = 75
        subsample = 1000
        seed = 3
        multistart = 2
        weighting = "samples"
        [solver]
        name = "dogleg"
        rtol = 1e-6
        max_steps = 50
        [init]
        alpha = 0.2
        [fixed]
        f0 = [0.9, 0.6, 0.3]
        [bounds]
        alpha = [0.01, 0.5]
        """
    )
    opts = parse_config(data, "x.toml")
    assert opts.fit_kwargs() == {
        "loss": "log", "solver": "dogleg", "cutoff": 75.0, "subsample": 1000, "seed": 3,
        "multistart": 2, "rtol": 1e-6, "max_steps": 50, "weighting": "samples",
        "init": {"alpha": 0.2},
        "fixed": {"f0": (0.9, 0.6, 0.3)}, "bounds": {"alpha": (0.01, 0.5)},
    }
    assert isinstance(opts.cutoff, float)
    opts.check_params(brdffit.get_model("ggx"))


def test_flags_override_preset_and_free_fixed_parameters():
    preset = FitOptions(model="ggx", loss="log", cutoff=80.0, fixed={"f0": 0.04, "alpha": 0.1},
                        init={"diffuse": 0.3}, sources=("p.toml",))
    flags = FitOptions(loss="cosine", init={"f0": 0.5}, fixed={"diffuse": 0.1})
    out = preset.merged(flags)
    assert (out.model, out.loss, out.cutoff) == ("ggx", "cosine", 80.0)
    assert out.fixed == {"alpha": 0.1, "diffuse": 0.1}  # f0 freed by --init, diffuse fixed
    assert out.init == {"f0": 0.5}
    assert out.sources == ("p.toml",)
    assert FitOptions().merged(FitOptions()).fit_kwargs() == {}


@pytest.mark.parametrize(
    "text, message",
    [
        ("cutof = 80", "unknown key 'cutof'; valid keys: model, loss, cutoff"),
        ("cutof = 80", "Did you mean 'cutoff'?"),
        ('cutoff = "80"', "'cutoff' must be degrees in (0, 90], got str '80'"),
        ("cutoff = 95", "'cutoff' must be degrees in (0, 90], got 95"),
        ("subsample = 1.5", "'subsample' must be a sample count in [1, 16777216] or a fraction in (0, 1], got 1.5"),
        ("seed = true", "'seed' must be an integer in [0, 2^32 - 1], got bool True"),
        ('weighting = "angle"', """'weighting' must be "angles", "samples" or "solid-angle", got 'angle'"""),
        ("model = 3", "'model' must be a model name, got int 3"),
        ("init = 3", "'init' must be a table ([init]), got 3"),
        ("[init]\nalpha = 'x'", "[init] 'alpha' must be a finite number or a list of 3 finite numbers"),
        ("[fixed]\nf0 = [1, 2]", "[fixed] 'f0' must be a finite number or a list of 3 finite numbers"),
        ("[bounds]\nalpha = [0.5, 0.1]", "[bounds] 'alpha' = [0.5, 0.1]: lower must be below upper"),
        ("[bounds]\nalpha = 0.5", "[bounds] 'alpha' must be [lower, upper]"),
        ("[solver]\nrtoll = 1e-6", "[solver] unknown key 'rtoll'; valid keys: name, max_steps, rtol"),
        ("[solver]\nmax_steps = 0", "[solver] 'max_steps' must be an integer in [1, 100000], got 0"),
        ("multistart = 9223372036854775807", "'multistart' must be an integer in [0, 1000]"),
        ("multistart = -1", "'multistart' must be an integer in [0, 1000], got -1"),
        ("seed = -1", "'seed' must be an integer in [0, 2^32 - 1], got -1"),
        ("[solver]\nrtol = 9223372036854775807", "[solver] 'rtol' must be a number in (0, 1]"),
        ("[solver]\natol = nan", "[solver] 'atol' must be a number in (0, 1], got nan"),
        ("subsample = inf", "'subsample' must be a sample count"),
        ("[init]\nalpha = inf", "[init] 'alpha' must be a finite number"),
        ("[bounds]\nalpha = [0.1, inf]", "[bounds] 'alpha' must be [lower, upper] (finite numbers)"),
        ("[init]\nalpha = 0.2\n[fixed]\nalpha = 0.3", "alpha is both in [init] and in [fixed]"),
    ],
)
def test_mistakes_name_the_key_and_the_choices(tmp_path, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text + "\n")
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert message in str(err.value) and str(path) in str(err.value)


def test_parameter_names_and_values_checked_against_the_model():
    ggx = brdffit.get_model("ggx")
    with pytest.raises(UnknownNameError, match="model 'ggx' has no parameter 'alpah'.*alpha"):
        FitOptions(init={"alpah": 0.1}).check_params(ggx)
    with pytest.raises(ConfigError, match=r"\[fixed\] alpha: .*outside its bounds"):
        FitOptions(fixed={"alpha": 5.0}).check_params(ggx)
    with pytest.raises(ConfigError, match=r"\[init\] f0: .*takes shape \(3,\)"):
        FitOptions(init={"f0": (0.1, 0.2)}).check_params(ggx)
    with pytest.raises(ConfigError, match=r"\[bounds\] alpha = \[0.0001, 0.5\] must satisfy"):
        FitOptions(bounds={"alpha": (1e-4, 0.5)}).check_params(ggx)


def test_bare_names_paths_and_bad_files(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # not the checkout: a bare name still finds the checkout's preset
    assert find_config("ggx") == CONFIGS / "ggx.toml"
    (tmp_path / "configs").mkdir()
    (tmp_path / "configs" / "ggx.toml").write_text('loss = "linear"\n')
    assert load_config("ggx").loss == "linear"  # ./configs wins over the checkout
    with pytest.raises(ConfigError, match="no preset named 'nope'.*known presets: .*ggx"):
        load_config("nope")
    with pytest.raises(ConfigError, match="config file 'some/where.toml' not found"):
        load_config("some/where.toml")
    (tmp_path / "broken.toml").write_text("loss = \n")
    with pytest.raises(ConfigError, match="broken.toml: not valid TOML"):
        load_config(tmp_path / "broken.toml")


def test_a_preset_that_is_not_utf8_or_not_a_file_is_one_clear_error(tmp_path):
    path = tmp_path / "latin1.toml"
    path.write_bytes(b'description = "caf\xe9"\n')
    with pytest.raises(ConfigError, match=r"latin1.toml: not valid TOML \(not UTF-8 text"):
        load_config(path)
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    with pytest.raises(ConfigError, match="fifo.toml: is a FIFO"):
        load_config(fifo)  # before the fix: open() blocked forever


def test_bounds_too_narrow_to_fit_are_refused_with_the_escape_hatch():
    ggx = brdffit.get_model("ggx")
    with pytest.raises(ConfigError, match=r"\[bounds\] f0 = \[1e-300, 1e-299\] is narrower.*"
                                          r"\[fixed\] f0"):
        FitOptions(bounds={"f0": (1e-300, 1e-299)}).check_params(ggx)
    FitOptions(bounds={"alpha": (0.01, 0.0101)}).check_params(ggx)  # narrow but fittable


@pytest.mark.parametrize("key, value, message", [
    ("multistart", 100_000_000, "'multistart' must be an integer in [0, 1000], got 100000000"),
    ("multistart", 2.0, "'multistart' must be an integer in [0, 1000], got 2.0"),
    ("max_steps", True, "'max_steps' must be an integer in [1, 100000], got bool True"),
    ("rtol", 9223372036854775807, "'rtol' must be a number in (0, 1]"),
    ("atol", -1e-8, "'atol' must be a number in (0, 1], got -1e-08"),
    ("seed", 2**32, "'seed' must be an integer in [0, 2^32 - 1]"),
    ("subsample", float("inf"), "'subsample' must be a sample count in [1, 16777216]"),
    ("subsample", 0, "'subsample' must be a sample count"),
    ("subsample", 1.5, "or a fraction in (0, 1], got 1.5"),
    ("cutoff", float("nan"), "'cutoff' must be degrees in (0, 90], got nan"),
    ("ftol", 0.0, "'ftol' must be a number in (0, 1], got 0.0"),
])
def test_fit_refuses_absurd_numeric_options_before_any_work(key, value, message):
    """The check runs before the table is touched: ``None`` as a table would fail later."""
    with pytest.raises(ConfigError) as err:
        brdffit.fit(None, "ggx", **{key: value})
    assert message in str(err.value)
    assert check_fit_options({"subsample": 0.25, "seed": 0, "multistart": 1000, "rtol": 1.0,
                              "max_steps": 1, "atol": 1e-300, "ftol": 0.5}) is not None
