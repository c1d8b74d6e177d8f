r"""Imageworks / Kulla–Conty multiple-scattering specular term, RTR eqs. 9.56–9.60.

.. math::

    f_\text{ms}(\mathbf l,\mathbf v) =
      \frac{\bar F\,\overline{R_{sF1}}}{\pi(1-\overline{R_{sF1}})(1-\bar F(1-\overline{R_{sF1}}))}
      (1-R_{sF1}(\mathbf l))(1-R_{sF1}(\mathbf v)) \qquad\text{(RTR eq. 9.56)}

``R_sF1`` is the directional albedo of the single-scattering lobe with ``F = 1`` and
``\overline{R_{sF1}}`` its cosine-weighted average (RTR eq. 9.57), both read from the
precomputed :func:`brdffit.terms.energy.albedo_table.albedo_table` (32 × 33 over ``(α, μ)``, the
Imageworks 32 × 32 of RTR p. 346). ``F̄ = 20/21 F₀ + 1/21`` for Schlick's Fresnel (RTR eq. 9.60,
the ``p = 5``, ``F₉₀ = 1`` case of eq. 9.59).

With ``F = 1`` the term's albedo is exactly ``1 − R_sF1(l)``, so single + multiple scattering
passes the white furnace test (albedo 1) by construction.

.. warning::
   RTR eq. 9.56 has one factor ``F̄`` in the numerator. Kulla & Conty's 2017 course notes
   (the source RTR cites) have ``F̄²``: each escaping path bounced at least twice. Both agree at
   ``F = 1``; ``fresnel_power=2`` selects the course notes' form, the default (1) follows the book.

For an anisotropic NDF Imageworks use an intermediate roughness (RTR p. 346): pass e.g.
``sqrt(alpha_x * alpha_y)`` as ``alpha``.
"""

from __future__ import annotations

from functools import partial

import jax.numpy as jnp

from .._math import chi_plus, cos_theta
from ..fresnel import schlick
from ..masking import G2_height_correlated
from ..microfacet import microfacet_specular
from .albedo_table import albedo_table


def schlick_average(f0):
    """Cosine-weighted average of Schlick's Fresnel, ``F̄ = 20/21 F₀ + 1/21`` (RTR eq. 9.60)."""
    return 20.0 / 21.0 * jnp.asarray(f0) + 1.0 / 21.0


def kulla_conty(table, alpha, f0, wi, wo, *, fresnel_power=1):
    """``f_ms(l, v)`` of RTR eq. 9.56, RGB ``(..., 3)``, from an
    :class:`~brdffit.terms.energy.albedo_table.AlbedoTable`."""
    _, e_l = table.lookup(alpha, cos_theta(wi))
    _, e_v = table.lookup(alpha, cos_theta(wo))
    _, e_avg = table.average(alpha)
    f_avg = schlick_average(f0)
    denom = jnp.pi * (1.0 - e_avg) * (1.0 - f_avg * (1.0 - e_avg))
    scale = f_avg**fresnel_power * e_avg / jnp.maximum(denom, 1e-12)
    vis = chi_plus(cos_theta(wi)) * chi_plus(cos_theta(wo))
    return scale * ((1.0 - e_l) * (1.0 - e_v) * vis)[..., None]


def multiscatter_specular(ndf_factory, alpha, f0, wi, wo, *, g2=G2_height_correlated, table=None, fresnel_power=1):
    """Single-scattering lobe (RTR eq. 9.34, Schlick F) plus :func:`kulla_conty`: the option on any
    microfacet lobe. ``ndf_factory(alpha)`` builds the NDF; its table is built once and cached.
    """
    table = table if table is not None else albedo_table(ndf_factory, g2)
    single = microfacet_specular(ndf_factory(alpha), partial(schlick, f0), wi, wo, g2=g2)
    return single + kulla_conty(table, alpha, f0, wi, wo, fresnel_power=fresnel_power)
