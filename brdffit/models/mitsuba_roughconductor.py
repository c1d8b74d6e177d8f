r"""Mitsuba 3's ``roughconductor`` BSDF, term for term, as registered fit targets.

Follows ``src/bsdfs/roughconductor.cpp`` (``RoughConductor::eval``) with the microfacet pieces of
``include/mitsuba/render/microfacet.h`` (``MicrofacetDistribution::eval``, ``G``, ``smith_g1``)
and the Fresnel term of ``include/mitsuba/render/fresnel.h`` (``fresnel_conductor``), Mitsuba
3.9. ``eval`` returns ``f_r · cos θo``; the models here return ``f_r``:

.. math::

    f_r(\mathbf i, \mathbf o) = \frac{D(\mathbf h)\,G(\mathbf i, \mathbf o, \mathbf h)}
        {4\cos\theta_i\cos\theta_o}\;F_\text{cond}(\mathbf i\cdot\mathbf h;\ \eta + ik)\;
        R_\text{spec},\qquad \mathbf h = \frac{\mathbf i + \mathbf o}{|\mathbf i + \mathbf o|}

* ``D``: GGX (``m.x/α_u``, ``m.y/α_v``: RTR eq. 9.53) or Beckmann (RTR eq. 9.52), the
  ``distribution`` option; ``α_u`` along the tangent ``x``, ``α_v`` along the bitangent ``y``.
* ``G``: Mitsuba's masking convention is the **separable** Smith form
  ``G = G1(i, h) G1(o, h)`` (``MicrofacetDistribution::G``, RTR eq. 9.27), not the
  height-correlated form the library's other models use. For Beckmann, ``smith_g1`` is Walter et
  al.'s rational approximation (RTR eq. 9.39, ``1/(1 + Λ)`` written out), not the exact erf.
* ``F``: the exact unpolarized conductor Fresnel of the complex index ``η + ik`` per RGB channel
  (:func:`brdffit.terms.fresnel.conductor` is the same closed form), or, in the *tint* form,
  Mitsuba's defaults ``η = 0, k = 1`` (``F ≡ 1``) times ``specular_reflectance``.
* Mitsuba clamps ``α`` at 1e-4 (``configure()``), as :data:`brdffit.terms.ndf.ALPHA_MIN` does.

Parameter names are Mitsuba's: ``alpha`` (isotropic) or ``alpha_u``/``alpha_v``, ``eta``, ``k``,
``specular_reflectance``. :func:`roughconductor_model` builds any combination of the options;
four are registered (``mitsuba-roughconductor``: GGX, isotropic, complex IOR;
``-aniso``, ``-beckmann``, ``-tint``), and the others register themselves under their
canonical name (:func:`canonical_name`) when first built.
"""

from __future__ import annotations

import functools
from functools import partial

import jax.numpy as jnp

from ..terms.fresnel import conductor
from ..terms.masking import G2_separable
from ..terms.microfacet import microfacet_specular
from ..terms.ndf import GGX, Beckmann
from .registry import Model, Param, available_models, get_model, register, register_factory
from .starts import rough_conductor

#: Physical ranges of the optical constants fitted per channel. Metals in the visible have
#: η from about 0.05 (silver) to 3 (iron, titanium) and k from about 0.5 to 10; the bounds
#: leave room either side. η ≥ 0.02 keeps F(η, k) smooth; k = 0 is a dielectric.
ETA_BOUNDS = (0.02, 10.0)
K_BOUNDS = (0.0, 12.0)
ALPHA_BOUNDS = (1e-3, 1.0)

DISTRIBUTIONS = ("ggx", "beckmann")
FRESNEL_FORMS = ("ior", "tint")


def canonical_name(distribution: str = "ggx", anisotropic: bool = False, fresnel: str = "ior") -> str:
    """``mitsuba-roughconductor[-beckmann][-aniso][-tint]``: the registry name of a variant."""
    return ("mitsuba-roughconductor" + ("-beckmann" if distribution == "beckmann" else "")
            + ("-aniso" if anisotropic else "") + ("-tint" if fresnel == "tint" else ""))


def _params(anisotropic: bool, fresnel: str) -> tuple[Param, ...]:
    if anisotropic:
        rough = (
            Param("alpha_u", (), *ALPHA_BOUNDS, 0.1, "roughness along the tangent (Mitsuba alpha_u)", log=True),
            Param("alpha_v", (), *ALPHA_BOUNDS, 0.1, "roughness along the bitangent (Mitsuba alpha_v)", log=True),
        )
    else:
        rough = (Param("alpha", (), *ALPHA_BOUNDS, 0.1, "roughness α (Mitsuba alpha)", log=True),)
    if fresnel == "tint":
        return rough + (
            Param("specular_reflectance", (3,), 0.0, 1.0, 1.0,
                  "RGB factor on the lobe (Mitsuba specular_reflectance; η = 0, k = 1: F = 1)",
                  per_channel=True),
        )
    return rough + (
        Param("eta", (3,), *ETA_BOUNDS, (0.2, 0.9, 1.1), "real part of the complex IOR per channel (Mitsuba eta)",
              log=True, per_channel=True),
        Param("k", (3,), *K_BOUNDS, (3.9, 2.4, 2.2), "imaginary part (extinction) per channel (Mitsuba k)",
              per_channel=True),
    )


def _unit_fresnel(cos_d):
    """``F ≡ 1``: Mitsuba's ``fresnel_conductor`` at its defaults ``η = 0, k = 1``."""
    return jnp.ones_like(cos_d)[..., None]


def _roughconductor_fn(distribution: str, anisotropic: bool, fresnel: str):
    def fn(p, wi, wo):
        au, av = (p["alpha_u"], p["alpha_v"]) if anisotropic else (p["alpha"], p["alpha"])
        ndf = GGX(au, av) if distribution == "ggx" else Beckmann(au, av, lambda_approx=True)
        if fresnel == "tint":
            lobe = microfacet_specular(ndf, _unit_fresnel, wi, wo, g2=G2_separable)
            return lobe * p["specular_reflectance"]
        return microfacet_specular(ndf, partial(conductor, p["eta"], p["k"]), wi, wo, g2=G2_separable)

    return fn


def roughconductor_model(distribution: str = "ggx", anisotropic: bool = False, fresnel: str = "ior") -> Model:
    """The :class:`Model` of Mitsuba's ``roughconductor`` with these options: the same object for
    the same options (the registered one for the common option sets, registered at import).

    Args:
        distribution: ``"ggx"`` or ``"beckmann"`` (Mitsuba's ``distribution`` string).
        anisotropic: ``alpha_u``, ``alpha_v`` instead of one ``alpha``.
        fresnel: ``"ior"`` (fit ``eta``, ``k`` per channel) or ``"tint"``
            (``specular_reflectance`` with ``F = 1``).
    """
    if distribution not in DISTRIBUTIONS:
        raise ValueError(f"distribution must be one of {DISTRIBUTIONS}, got {distribution!r}")
    if fresnel not in FRESNEL_FORMS:
        raise ValueError(f"fresnel must be one of {FRESNEL_FORMS}, got {fresnel!r}")
    name = canonical_name(distribution, anisotropic, fresnel)
    if name in available_models():
        return get_model(name)
    return _variant(distribution, anisotropic, fresnel)


@functools.lru_cache(maxsize=None)
def _variant(distribution: str, anisotropic: bool, fresnel: str) -> Model:
    """The :class:`Model` of one option set, made once (a memo: a call registers nothing)."""
    name = canonical_name(distribution, anisotropic, fresnel)
    ndf = "GGX (RTR 9.53)" if distribution == "ggx" else "Beckmann (RTR 9.52), rational Smith G1 (RTR 9.39)"
    form = "complex-IOR conductor Fresnel" if fresnel == "ior" else "specular_reflectance tint, F = 1"
    return Model(
        name=name,
        description=f"Mitsuba 3 roughconductor: {'anisotropic ' if anisotropic else ''}{ndf}, "
        f"separable Smith G, {form}",
        params=_params(anisotropic, fresnel),
        fn=_roughconductor_fn(distribution, anisotropic, fresnel),
        isotropic=not anisotropic,
        start=partial(rough_conductor, anisotropic=anisotropic, fresnel=fresnel),
        reference="Mitsuba 3 src/bsdfs/roughconductor.cpp, include/mitsuba/render/microfacet.h, "
        "fresnel.h (fresnel_conductor); RTR eqs. 9.27, 9.34",
    )


def variant_of(name: str) -> dict | None:
    """The options ``{distribution, anisotropic, fresnel}`` of a canonical name, else ``None``."""
    for d in DISTRIBUTIONS:
        for a in (False, True):
            for f in FRESNEL_FORMS:
                if canonical_name(d, a, f) == name:
                    return dict(distribution=d, anisotropic=a, fresnel=f)
    return None


ROUGHCONDUCTOR = register(roughconductor_model("ggx", False, "ior"))
ROUGHCONDUCTOR_ANISO = register(roughconductor_model("ggx", True, "ior"))
ROUGHCONDUCTOR_BECKMANN = register(roughconductor_model("beckmann", False, "ior"))
ROUGHCONDUCTOR_TINT = register(roughconductor_model("ggx", False, "tint"))


@register_factory
def _by_name(name):
    """The other option combinations by their canonical name (built once, not registered:
    :func:`~brdffit.models.registry.available_models` lists the same models before and
    after)."""
    options = variant_of(name) if isinstance(name, str) else None
    return roughconductor_model(**options) if options else None
