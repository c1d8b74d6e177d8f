"""Smith masking and masking-shadowing, every form written once from an NDF's ``Lambda``; and
the Torrance–Sparrow V-groove form of the classic Cook–Torrance model (:func:`G2_vgroove`).

All functions take an NDF object (see :mod:`brdffit.terms.ndf`), directions ``wi``, ``wo`` and the
microfacet normal ``wm``, batched over ``(..., 3)``, and return the batch shape ``(...)``.
Every G2 form has the signature ``(ndf, wi, wo, wm)``; the correlated forms take the empirical
``λ(φ)`` as a keyword, so a variant is ``functools.partial(G2_direction_correlated,
lambda_fn=lambda_van_ginneken)``. Passing any of them as ``g2=`` to
:func:`brdffit.terms.microfacet.microfacet_specular` changes the masking of a lobe.

Ordering (for the same ``Λ``): separable ≤ height-correlated ≤ height-direction correlated ≤
``min(G1(l), G1(v))``, and the direction-correlated form lies between separable and ``min``.
The V-groove form is no Smith form: it ignores ``Λ`` (and the NDF).
"""

from __future__ import annotations

import jax.numpy as jnp

from ._math import chi_plus, dot


def G1(ndf, w, wm):  # noqa: N802 (the book's symbol)
    r"""Smith masking :math:`G_1(\mathbf s, \mathbf m) = \chi^+(\mathbf s\cdot\mathbf m)/(1+\Lambda(\mathbf s))`, RTR eq. 9.24."""
    return chi_plus(dot(w, wm)) / (1.0 + ndf.Lambda(w))


def G2_height_correlated(ndf, wi, wo, wm):  # noqa: N802
    r"""Height-correlated Smith masking-shadowing, RTR eq. 9.31 (the default everywhere).

    .. math::

        G_2(\mathbf l,\mathbf v,\mathbf m) =
        \frac{\chi^+(\mathbf m\cdot\mathbf v)\chi^+(\mathbf m\cdot\mathbf l)}
             {1 + \Lambda(\mathbf v) + \Lambda(\mathbf l)}
    """
    vis = chi_plus(dot(wo, wm)) * chi_plus(dot(wi, wm))
    return vis / (1.0 + ndf.Lambda(wo) + ndf.Lambda(wi))


def G2_separable(ndf, wi, wo, wm):  # noqa: N802
    r"""Separable (uncorrelated) Smith masking-shadowing, RTR eq. 9.27 (APS 2000 eq. 13).

    .. math::  G_2(\mathbf l,\mathbf v,\mathbf m) = G_1(\mathbf v,\mathbf m)\,G_1(\mathbf l,\mathbf m)
    """
    return G1(ndf, wo, wm) * G1(ndf, wi, wm)


def relative_azimuth(wi, wo):
    r"""``φ ∈ [0, π]``, the angle between the projections of ``wi`` and ``wo`` on the surface.

    ``atan2(|l_⊥ × v_⊥|, l_⊥·v_⊥)``, 0 when either direction is at the pole, where every
    correlated G2 form is independent of ``λ(φ)`` anyway (``Λ(n) = 0`` makes both of its
    branches equal the other ``G1``).
    """
    cross = wi[..., 0] * wo[..., 1] - wi[..., 1] * wo[..., 0]
    along = wi[..., 0] * wo[..., 0] + wi[..., 1] * wo[..., 1]
    ok = cross * cross + along * along > 1e-24
    return jnp.where(ok, jnp.arctan2(jnp.where(ok, jnp.abs(cross), 0.0), jnp.where(ok, along, 1.0)), 0.0)


def lambda_ashikhmin(phi):
    r"""``λ(φ) = 1 − exp(−7.3 φ²)``, RTR eq. 9.29 (Ashikhmin et al. 2000's 15° Gaussian)."""
    return -jnp.expm1(-7.3 * phi * phi)


def lambda_van_ginneken(phi):
    r"""``λ(φ) = 4.41 φ / (4.41 φ + 1)``, RTR eq. 9.30 (van Ginneken et al. 1998)."""
    return 4.41 * phi / (4.41 * phi + 1.0)


def G2_direction_correlated(ndf, wi, wo, wm, *, lambda_fn=lambda_ashikhmin):  # noqa: N802
    r"""Direction-correlated Smith masking-shadowing, RTR eq. 9.28 (APS 2000 eq. 14).

    .. math::

        G_2 = \lambda(\phi)\,G_1(\mathbf v,\mathbf m)G_1(\mathbf l,\mathbf m)
            + (1 - \lambda(\phi))\min(G_1(\mathbf v,\mathbf m), G_1(\mathbf l,\mathbf m))

    ``φ`` from :func:`relative_azimuth`; ``lambda_fn`` is :func:`lambda_ashikhmin` (eq. 9.29,
    the default) or :func:`lambda_van_ginneken` (eq. 9.30). APS's ``t(φ)`` is ``1 − λ(φ)``.
    """
    g_v, g_l = G1(ndf, wo, wm), G1(ndf, wi, wm)
    lam = lambda_fn(relative_azimuth(wi, wo))
    return lam * g_v * g_l + (1.0 - lam) * jnp.minimum(g_v, g_l)


def G2_height_direction_correlated(ndf, wi, wo, wm, *, lambda_fn=lambda_ashikhmin):  # noqa: N802
    r"""Height-direction correlated Smith masking-shadowing, RTR eq. 9.32 (Heitz 2014).

    .. math::

        G_2 = \frac{\chi^+(\mathbf m\cdot\mathbf v)\chi^+(\mathbf m\cdot\mathbf l)}
            {1 + \max(\Lambda(\mathbf v), \Lambda(\mathbf l))
               + \lambda(\mathbf v, \mathbf l)\min(\Lambda(\mathbf v), \Lambda(\mathbf l))}

    with the empirical ``λ(v, l) = λ(φ)`` of eq. 9.29 (default) or 9.30 (``lambda_fn``), as RTR
    suggests. ``λ = 1`` gives the height-correlated form 9.31, ``λ = 0`` gives ``min(G1, G1)``.
    """
    lam_v, lam_l = ndf.Lambda(wo), ndf.Lambda(wi)
    lam = lambda_fn(relative_azimuth(wi, wo))
    vis = chi_plus(dot(wo, wm)) * chi_plus(dot(wi, wm))
    return vis / (1.0 + jnp.maximum(lam_v, lam_l) + lam * jnp.minimum(lam_v, lam_l))


def G2_vgroove(ndf, wi, wo, wm):  # noqa: N802
    r"""Torrance–Sparrow V-groove masking-shadowing, as Cook & Torrance 1982 (eq. 9) use it.

    .. math::

        G(\mathbf l,\mathbf v,\mathbf m) = \chi^+(\mathbf m\cdot\mathbf v)\chi^+(\mathbf m\cdot\mathbf l)
            \min\left(1,\ \frac{2(\mathbf n\cdot\mathbf m)(\mathbf n\cdot\mathbf v)}{\mathbf v\cdot\mathbf m},\
            \frac{2(\mathbf n\cdot\mathbf m)(\mathbf n\cdot\mathbf l)}{\mathbf l\cdot\mathbf m}\right)

    Symmetric V-grooves (Torrance & Sparrow 1967), the form of bbm's
    ``maskingshadowing/vgroove.h``. Unlike the Smith forms above it does not depend on the NDF;
    ``ndf`` is taken (and ignored) so that it has the signature of every ``g2``.
    """
    del ndf
    cm = wm[..., 2]
    dv, dl = dot(wo, wm), dot(wi, wm)
    vis = chi_plus(dv) * chi_plus(dl)
    gv = 2.0 * cm * wo[..., 2] / jnp.where(dv > 0, dv, 1.0)
    gl = 2.0 * cm * wi[..., 2] / jnp.where(dl > 0, dl, 1.0)
    return vis * jnp.minimum(1.0, jnp.minimum(gv, gl))
