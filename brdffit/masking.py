"""Smith masking and masking-shadowing, every form written once from an NDF's ``Lambda``.

All functions take an NDF object (see :mod:`brdffit.ndf`), directions ``wi``, ``wo`` and the
microfacet normal ``wm``, batched over ``(..., 3)``, and return the batch shape ``(...)``.
"""

from __future__ import annotations

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
