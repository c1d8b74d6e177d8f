"""A lit sphere rendered by Mitsuba 3 with an exported material (``brdffit render``).

The scene is the one of :mod:`brdffit.plots.sphere`, built for Mitsuba: a unit sphere seen by an
orthographic camera along ``−z`` (viewer at ``+z``, image ``x`` right, ``y`` up, the film
covering ``[−1, 1]²``), one ``directional`` emitter of irradiance ``E`` arriving from
``light_dir`` (the direction *towards* the light), plus a ``constant`` environment of radiance
``L_env``. With ``L_env = 0`` a pixel's radiance is ``E · f_r(wi, wo) · max(0, cos θi)``, exactly
:func:`brdffit.plots.sphere.render_sphere`'s, averaged over the pixel (box filter, ``spp``
jittered samples); the environment adds the directional albedo times ``L_env``. Mitsuba's
``direct`` integrator (one bounce; a sphere does not see itself) and the ``scalar_rgb`` variant,
so no LLVM is needed.

Every option has a range (:data:`RENDER_OPTION_RANGES`: ``size`` in ``[8, 4096]`` pixels,
``spp`` in ``[1, 4096]``, ``environment`` in ``[0, 100]``; ``irradiance`` finite and positive;
at most :data:`MAX_RENDER_SAMPLES` samples in all); a value outside, NaN or infinite is refused
with :class:`~brdffit.errors.ConfigError` before Mitsuba is called, never clamped or dropped.
"""

from __future__ import annotations

import numpy as np

from ..plots.sphere import DEFAULT_LIGHT

#: Ranges of the scene's options, as :func:`brdffit.config.check_fit_options` takes them:
#: name -> (integer, low, high, low included, wanted). ``environment`` is a radiance relative
#: to the light's irradiance (1 by default).
RENDER_OPTION_RANGES = {
    "size": (True, 8, 4096, True, "an integer in [8, 4096]"),
    "spp": (True, 1, 4096, True, "an integer in [1, 4096]"),
    "environment": (False, 0.0, 100.0, True, "a number in [0, 100] (0: the light alone)"),
    "irradiance": (False, 0.0, 1e6, False, "a number in (0, 1e6]"),
    "seed": (True, 0, 2**31 - 1, True, "an integer in [0, 2^31 - 1]"),
}
#: The most samples one render may take (``size² · spp``): a minute or two on one core.
MAX_RENDER_SAMPLES = 1 << 26


def check_render_options(label=None, **options) -> dict:
    """Refuse options outside :data:`RENDER_OPTION_RANGES` or more than
    :data:`MAX_RENDER_SAMPLES` samples (:class:`~brdffit.errors.ConfigError`; ``label(name)``
    names an option in the message, e.g. ``--spp`` on the command line)."""
    from ..config import check_fit_options
    from ..errors import ConfigError

    label = label or repr
    check_fit_options(options, label, RENDER_OPTION_RANGES)
    size, spp = options.get("size"), options.get("spp")
    if size is not None and spp is not None and size * size * spp > MAX_RENDER_SAMPLES:
        raise ConfigError(f"{label('size')} {size} with {label('spp')} {spp} is "
                          f"{size * size * spp:,} samples, more than {MAX_RENDER_SAMPLES:,}; "
                          f"lower the size or the samples per pixel")
    return options


def _mitsuba():
    try:
        import mitsuba as mi
    except ImportError as exc:  # pragma: no cover - depends on the environment
        from ..errors import BrdffitError

        raise BrdffitError(
            "rendering needs Mitsuba 3: pip install 'brdffit[mitsuba]' (or pip install mitsuba)"
        ) from exc
    if mi.variant() is None:
        mi.set_variant("scalar_rgb")
    return mi


def sphere_scene(bsdf: dict, *, size: int = 64, spp: int = 16, light_dir=DEFAULT_LIGHT,
                 irradiance: float = 1.0, environment: float = 0.1, seed: int = 0) -> dict:
    """The ``mitsuba.load_dict`` scene of the module docstring around the material ``bsdf``."""
    check_render_options(size=size, spp=spp, environment=environment, irradiance=irradiance,
                         seed=seed)
    mi = _mitsuba()
    light = np.asarray(light_dir, float)
    if light.shape != (3,) or not np.all(np.isfinite(light)) or not np.linalg.norm(light) > 0:
        from ..errors import ConfigError

        raise ConfigError(f"light_dir {light_dir!r}: give a finite, non-zero 3-vector")
    light = light / np.linalg.norm(light)
    scene = {
        "type": "scene",
        "integrator": {"type": "direct"},
        "sensor": {
            "type": "orthographic",
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "box"},
                     "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp, "seed": seed},
        },
        "sphere": {"type": "sphere", "bsdf": bsdf},
        "sun": {"type": "directional", "direction": [float(-v) for v in light],
                "irradiance": {"type": "rgb", "value": float(irradiance)}},
    }
    if environment > 0:
        scene["environment"] = {"type": "constant",
                                "radiance": {"type": "rgb", "value": float(environment)}}
    return scene


def render_mitsuba(bsdf: dict, **options) -> np.ndarray:
    """Linear RGB radiance ``(size, size, 3)`` (row 0 at the top) of :func:`sphere_scene`."""
    mi = _mitsuba()
    image = mi.render(mi.load_dict(sphere_scene(bsdf, **options)))
    return np.array(image, dtype=float)[..., :3]


def write_png(image: np.ndarray, path) -> tuple[float, float]:
    """Write ``image`` (linear radiance) as a PNG with the figures' logarithmic tone mapping
    (:func:`brdffit.plots.log_tonemap`: the median lit luminance at 0.4, the 99.9th
    percentile at white, hue kept), as brdffit's own lit-sphere figure shows it; returns the
    ``(ref, top)`` luminances used."""
    import matplotlib.image

    from ..plots import log_levels, log_tonemap

    ref, top = log_levels(image)
    matplotlib.image.imsave(str(path), np.clip(log_tonemap(image, ref, top), 0.0, 1.0))
    return ref, top
