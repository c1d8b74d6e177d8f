"""``brdffit synth``: a synthetic measurement from a model and known parameters.

The output's suffix picks what is written (:data:`brdffit.io.READERS`): a MERL table over
MERL's grid, a sample list of random direction pairs, or an RGL material (a virtual
measurement in the ``.bsdf`` form Mitsuba's ``measured`` BSDF renders,
:func:`data_formats.rgl.synthesize_rgl`; anisotropic when the model is).

``--fit RESULT.json`` takes the model and its parameters from a ``brdffit fit --out`` result
(``--model`` then picks one result of a file of several; ``--param`` overrides a value): a fit
rendered in any format, e.g. as a ``.bsdf`` for Mitsuba's ``measured`` BSDF. (The renderer
exports of ``brdffit export`` write a native BSDF's parameters; a tabulated material is a
measurement, so it is written here.)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io import formats_text, suffixes_of
from ._common import UsageError, check_outputs, check_params, parse_assignments


def add_parser(sub, parents) -> None:
    p = sub.add_parser(
        "synth",
        parents=parents,
        allow_abbrev=False,
        help="write a synthetic table from a model and known parameters",
        description="Evaluate a registered model with known parameters over the MERL grid and "
        f"write it as a MERL table ({suffixes_of('MERL table')}; cells below the horizon are "
        "missing, as in the real database), over N random direction pairs (dense near the "
        f"specular peak) as a sample list ({suffixes_of('sample list')}, --samples), or as a "
        f"virtual measurement in the RGL material format ({suffixes_of('RGL material')}, what "
        "Mitsuba 3's `measured` BSDF renders; anisotropic if the model is). "
        "--fit RESULT.json takes the model and parameters from a fit.",
    )
    p.add_argument("--model", "-m", help="a registered model (see `brdffit models`); with "
                   "--fit, the model whose result to use in a file of several")
    p.add_argument("--fit", metavar="RESULT.json",
                   help="take the model and its parameters from a `brdffit fit --out` result "
                   "(--param overrides a value)")
    p.add_argument("--param", "-p", action="append", metavar="NAME=VALUE",
                   help="a parameter value, e.g. alpha=0.1 or f0=0.9,0.6,0.3 (one number fills "
                   "all three channels); repeatable; others take the model's defaults")
    p.add_argument("--noise", type=float, default=0.0, metavar="SIGMA",
                   help="multiplicative Gaussian noise, relative std. dev. in [0, 10] "
                   "(0.02 = 2%%); negative results are clipped to 0")
    p.add_argument("--seed", type=int, default=0, help="random seed for noise and samples")
    p.add_argument("--samples", type=int, default=100_000, metavar="N",
                   help="number of random direction pairs for a "
                   f"{suffixes_of('sample list')} output (default 100000)")
    p.add_argument("--output", "-o", required=True, metavar="OUT",
                   help=f"output file: {formats_text()}")
    p.add_argument("--force", action="store_true", help="overwrite OUT if it exists")
    p.set_defaults(run=run)


#: The largest relative noise (1000%): beyond it nearly every value is noise or clipped to 0.
MAX_NOISE = 10.0


def _check_noise(sigma) -> None:
    if not (np.isfinite(sigma) and 0 <= sigma <= MAX_NOISE):
        raise UsageError(f"--noise {sigma:g}: the noise level must be a finite number in "
                         f"[0, {MAX_NOISE:g}] (a relative standard deviation)")


def _noisy(rgb, sigma, rng):
    _check_noise(sigma)
    if sigma == 0:
        return rgb
    return np.clip(rgb * (1.0 + sigma * rng.standard_normal(rgb.shape)), 0.0, None)


def random_pairs(rng, n):
    """``n`` direction pairs like a gonioreflectometer's: ``wi`` cosine-distributed, ``wo`` the
    mirror of ``wi`` about a half vector tilted by θh = 90°·u² (dense near the specular peak, as
    MERL's warped θh); pairs with ``wo`` within ~1° of the horizon are redrawn."""
    wi, wo = np.empty((0, 3)), np.empty((0, 3))
    while len(wi) < n:
        m = 2 * (n - len(wi)) + 16
        u1, u2 = rng.uniform(size=m), rng.uniform(size=m)
        r, phi = np.sqrt(u1) * np.sin(np.radians(89.0)), 2 * np.pi * u2
        a = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - r**2)], axis=-1)
        th, ph = np.radians(90.0) * rng.uniform(size=m) ** 2, 2 * np.pi * rng.uniform(size=m)
        h = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1)
        b = 2 * np.sum(a * h, axis=-1, keepdims=True) * h - a
        keep = (b[:, 2] > np.sin(np.radians(1.0))) & (np.sum(a * h, axis=-1) > 0)
        wi, wo = np.concatenate([wi, a[keep]]), np.concatenate([wo, b[keep]])
    wo = wo / np.linalg.norm(wo, axis=-1, keepdims=True)
    return wi[:n], wo[:n]


def synthesize_table(model, params, *, noise=0.0, seed=0, name=""):
    """A MERL table of ``model`` with ``params``; below-horizon cells missing."""
    from data_formats.merl import synthesize

    from ..models.evaluate import evaluate_model

    rng = np.random.default_rng(seed)
    return synthesize(lambda wi, wo: _noisy(evaluate_model(model, params, wi, wo), noise, rng),
                      name=name)


def _check_samples(n) -> None:
    from data_formats.samplelist import MAX_SAMPLES

    if not 0 < n <= MAX_SAMPLES:
        raise UsageError(f"--samples {n}: give a number of direction pairs in [1, {MAX_SAMPLES}] "
                         f"(the sample-list readers' limit)")


def synthesize_samples(model, params, n, *, noise=0.0, seed=0, name=""):
    from data_formats import SampleSet

    from ..models.evaluate import evaluate_model

    _check_samples(n)
    rng = np.random.default_rng(seed)
    wi, wo = random_pairs(rng, n)
    rgb = _noisy(evaluate_model(model, params, wi, wo), noise, rng)
    return SampleSet(wi=wi, wo=wo, rgb=rgb, valid=np.ones(n, bool), name=name)


def synthesize_material(model, params, *, noise=0.0, seed=0, name="", isotropic=None, **tables):
    """A virtual RGL measurement (:func:`data_formats.rgl.synthesize_rgl`) of ``model`` with
    ``params``: the material's tables are made from ``f_r`` evaluated by
    :func:`brdffit.models.evaluate.evaluate_model` (with the multiplicative ``noise``);
    ``isotropic`` defaults to the model's declaration; ``tables`` (``resolution``,
    ``n_theta_i``, ...) go to ``synthesize_rgl``."""
    from data_formats.rgl import synthesize_rgl

    from ..models.evaluate import evaluate_model

    rng = np.random.default_rng(seed)
    iso = model.isotropic if isotropic is None else bool(isotropic)
    return synthesize_rgl(lambda wi, wo: _noisy(evaluate_model(model, params, wi, wo), noise, rng),
                          isotropic=iso, name=name, **tables)


def _merl_writer(model, params, args, out):
    from data_formats.merl import write_merl

    table = synthesize_table(model, params, noise=args.noise, seed=args.seed, name=out.stem)
    return lambda tmp: write_merl(tmp, table)


def _samples_writer(model, params, args, out):
    from data_formats.samplelist import write_samples

    samples = synthesize_samples(model, params, args.samples, noise=args.noise, seed=args.seed,
                                 name=out.stem)
    return lambda tmp: write_samples(tmp, samples)


def _material_writer(model, params, args, out):
    from data_formats.rgl import write_rgl

    material = synthesize_material(model, params, noise=args.noise, seed=args.seed,
                                   name=out.stem)
    return lambda tmp: write_rgl(tmp, material)


#: What each kind of input (:data:`brdffit.io.READERS`) is written by: ``(bytes expected,
#: ``None`` for 200 per sample of ``--samples``; ``maker(model, params, args, out)`` → a
#: function writing the file at a path)``.
WRITERS = {
    "MERL table": (34_992_012, _merl_writer),
    "sample list": (None, _samples_writer),
    "RGL material": (64 << 20, _material_writer),
}


def _shown(value) -> str:
    """``0.1`` or ``(0.9, 0.6, 0.3)`` (``--param``'s spelling), from a number or an array."""
    arr = np.atleast_1d(np.asarray(value, float))
    text = ", ".join(f"{v:.6g}" for v in arr)
    return text if arr.size == 1 else f"({text})"


def run(args) -> int:
    from .. import get_model
    from ..io import INPUT_SUFFIXES, suffixes_text

    from ..config import check_fit_options

    params = parse_assignments(args.param, "--param")
    if args.fit:
        from .plotting import read_result

        result = read_result(args.fit, model=args.model)
        model = get_model(result.model_name)
        params = {**{k: np.asarray(v, float) for k, v in result.params.items()}, **params}
    elif args.model:
        model = get_model(args.model)
    else:
        raise UsageError("give the model: --model NAME (with --param values), or --fit "
                         "RESULT.json (a `brdffit fit --out` result)")
    params = check_params(model, params, "--param")
    check_fit_options({"seed": args.seed}, lambda key: f"--{key}")
    _check_noise(args.noise)
    out = Path(args.output)
    suffix = out.suffix.lower()
    kind = INPUT_SUFFIXES.get(suffix)
    if kind is None:
        raise UsageError(f"{out}: unknown output format {suffix!r}; use {suffixes_text()}")
    if kind == "sample list":
        _check_samples(args.samples)
    size, maker = WRITERS[kind]
    with check_outputs([out], args.force, {out: size or 200 * args.samples}) as outputs:
        outputs.write(out, maker(model, params, args, out))
        outputs.publish()
    if not args.quiet:
        shown = ", ".join(f"{k}={_shown(v)}" for k, v in params.items()) or "defaults"
        print(f"wrote {out} ({model.name}: {shown})")
    return 0
