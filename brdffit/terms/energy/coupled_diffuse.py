r"""Kelemen / Ashikhmin–Shirley coupled diffuse term for a microfacet lobe, RTR eq. 9.65.

.. math::

    f_\text{diff}(\mathbf l,\mathbf v) = \rho_{ss}\,
        \frac{(1-R_\text{spec}(\mathbf l))(1-R_\text{spec}(\mathbf v))}{\pi(1-\overline{R_\text{spec}})}

``R_spec`` is the directional albedo of the specular lobe it accompanies and
``\overline{R_\text{spec}}`` its cosine-weighted average (RTR eq. 9.57). With Schlick's Fresnel
both are linear in ``F₀`` (Karis's split, RTR §9.9.3), so one precomputed 2-D table serves all
``F₀``: :func:`brdffit.terms.energy.albedo_table.albedo_table` stores ``E₀, E₁`` over 32
roughness × 33 elevation nodes and their averages over 32 roughness nodes (sizes and measured
accuracy are in that module's docstring). With ``ρ_ss = 1`` the total directional albedo (lobe + this term) is
``R_spec + (1 − R_spec) = 1`` for every direction.

.. note::
   ``R_spec`` here is that of the single-scattering lobe; Imageworks also include the
   multiple-scattering term in it (a 3-D table over the index of refraction, RTR p. 352). Adding
   :func:`brdffit.terms.energy.multiscatter.kulla_conty` on top of this term therefore exceeds
   energy conservation by the multiple-scattering albedo; use one or the other.

This is the same construction as APS 2000 eq. 30 (:mod:`brdffit.terms.aps.diffuse`), there with
the reflectance of the APS specular term.
"""

from __future__ import annotations

import jax.numpy as jnp

from .._math import chi_plus, cos_theta


def coupled_diffuse(table, alpha, f0, albedo, wi, wo):
    """RTR eq. 9.65 for the lobe described by ``table`` at roughness ``alpha``, RGB ``(..., 3)``.

    ``f0`` and ``albedo`` (ρ_ss) are RGB ``(3,)`` (or scalars); ``table`` is an
    :class:`~brdffit.terms.energy.albedo_table.AlbedoTable`.
    """
    f0 = jnp.asarray(f0)
    e0_l, e1_l = table.lookup(alpha, cos_theta(wi))
    e0_v, e1_v = table.lookup(alpha, cos_theta(wo))
    a0, a1 = table.average(alpha)
    r_l = e0_l[..., None] + f0 * (e1_l - e0_l)[..., None]
    r_v = e0_v[..., None] + f0 * (e1_v - e0_v)[..., None]
    r_avg = a0 + f0 * (a1 - a0)
    vis = chi_plus(cos_theta(wi)) * chi_plus(cos_theta(wo))
    c = 1.0 / (jnp.pi * jnp.maximum(1.0 - r_avg, 1e-12))
    return jnp.asarray(albedo) * c * (1.0 - r_l) * (1.0 - r_v) * vis[..., None]
