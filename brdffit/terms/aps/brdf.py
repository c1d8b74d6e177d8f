"""The whole APS 2000 BRDF for any distribution: specular term plus coupled diffuse term.

:func:`aps_brdf` is the model of APS 2000: specular term (eq. 26 or 14) plus the
energy-conserving diffuse term (eqs. 28–30, or the metal variant), tables built from the
current parameters. It is computed in three stages, which :func:`aps_brdf` composes in one
traced function (and the registered models of :mod:`brdffit.models.aps` declare as
``Model.stages``):

1. :func:`aps_prepare`: from the parameters, the tables ``g`` (eq. 18) and ``R₀, R₁`` (eq. 29)
   and the constant ``c`` of eq. 30 (:class:`APSState`);
2. :func:`aps_per_pair`: per direction pair, the quantities that do not depend on the colour
   channel: ``p(h) S / 4`` with the visibility, ``(k₁·h)``, and ``R₀, R₁`` at ``k₁`` and ``k₂``;
3. :func:`aps_combine`: the RGB BRDF from those (Schlick with RGB ``f0``, eq. 31; eq. 30).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .._math import chi_plus, cos_theta, dot, half_vector
from ..fresnel import schlick
from .diffuse import RTable, build_r_table, coupled_scale, coupled_term
from .specular import UNCORRELATED, specular_geometry
from .tables import DEFAULT_RESOLUTION, GTable, build_g_table


class APSState(eqx.Module):
    """Stage 1 of the APS BRDF: the distribution, its tables and the colour parameters.

    ``rtable``, ``rho_d``, ``scale`` (``c`` of eq. 30, RGB) and ``white`` (1, or ``f0`` for
    the metal variant) are ``None`` when the diffuse term is left out.
    """

    dist: object
    table: GTable
    f0: jax.Array
    rtable: RTable | None = None
    rho_d: jax.Array | None = None
    scale: jax.Array | None = None
    white: jax.Array | None = None


def aps_prepare(dist, f0, diffuse, *, dtype, shadowing=UNCORRELATED, resolution=DEFAULT_RESOLUTION,
                metal=False) -> APSState:
    """Stage 1: tables of ``dist`` (eqs. 18, 29) and the constant ``c`` of eq. 30."""
    f0 = jnp.asarray(f0)
    table = build_g_table(dist, dtype, resolution)
    if diffuse is None and not metal:
        return APSState(dist, table, f0)
    rtable = build_r_table(dist, table, dtype, resolution, shadowing)
    white = f0 if metal else jnp.ones((), f0.dtype)
    rho_d = f0 if metal else jnp.asarray(diffuse)
    return APSState(dist, table, f0, rtable, rho_d, coupled_scale(rtable, f0, white), white)


def aps_per_pair(state: APSState, wi, wo, shadowing=UNCORRELATED) -> dict:
    """Stage 2: the channel-independent quantities of each pair (arrays of batch shape)."""
    q = {
        "geometry": specular_geometry(state.dist, state.table, wi, wo, shadowing),
        "cos_d": dot(wi, half_vector(wi, wo)),
    }
    if state.rtable is not None:
        q["r_in"], q["r_out"] = state.rtable.both(wi), state.rtable.both(wo)
        q["vis"] = chi_plus(cos_theta(wi)) * chi_plus(cos_theta(wo))
    return q


def aps_combine(state: APSState, q: dict):
    """Stage 3: ``ρ_s`` (eq. 26/14 with Schlick F, eq. 31) plus the coupled diffuse term
    (eq. 30, or the metal variant), RGB ``(..., 3)``."""
    out = schlick(state.f0, q["cos_d"]) * q["geometry"][..., None]
    if state.rtable is None:
        return out
    r_in, r_out = RTable.mix(q["r_in"], state.f0), RTable.mix(q["r_out"], state.f0)
    return out + coupled_term(state.rho_d, state.scale, state.white, r_in, r_out, q["vis"])


def aps_brdf(dist, f0, diffuse, wi, wo, *, shadowing=UNCORRELATED, resolution=DEFAULT_RESOLUTION, metal=False):
    """``ρ = ρ_s + ρ_diffuse`` of APS 2000 for the distribution ``dist``, RGB ``(..., 3)``.

    Args:
        dist: a :class:`~.distributions.Distribution` (any ``p(h)``).
        f0: Schlick normal reflectance (RGB).
        diffuse: ρ_d (RGB) of eq. 30; ignored (``ρ_d = f0``) when ``metal=True``; ``None``
            leaves the diffuse term out (and its table unbuilt).
        shadowing: ``UNCORRELATED`` (eq. 26) or ``Correlated(width)`` (eq. 14).
        resolution: table and quadrature sizes (:class:`~.tables.Resolution`).
        metal: use the metal variant of the diffuse term (§5.1).
    """
    f0 = jnp.asarray(f0)
    dtype = jnp.result_type(wi, wo, f0)
    state = aps_prepare(dist, f0, diffuse, dtype=dtype, shadowing=shadowing, resolution=resolution,
                        metal=metal)
    return aps_combine(state, aps_per_pair(state, wi, wo, shadowing))
