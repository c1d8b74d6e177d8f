"""Rusinkiewicz (1998) half/difference angles: direction pairs <-> ``(theta_h, theta_d, phi_d)``.

General, not MERL-specific; NumPy only. Conventions (``brdffit.terms._math`` states them too):
``z`` is the normal, ``wi`` and ``wo`` are unit vectors pointing away from the surface, batched
as ``(..., 3)``.

Forward map (Rusinkiewicz 1998, "A New Change of Variables for Efficient BRDF Representation"):

.. math::

    h = \\frac{w_i + w_o}{\\lVert w_i + w_o \\rVert},\\quad
    \\theta_h = \\angle(h, n),\\quad \\phi_h = \\operatorname{atan2}(h_y, h_x),\\qquad
    d = R_y(-\\theta_h)\\,R_z(-\\phi_h)\\,w_i,\\quad
    \\theta_d = \\angle(d, n),\\quad \\phi_d = \\operatorname{atan2}(d_y, d_x).

``R_a(t)`` is the right-handed rotation by ``t`` about axis ``a``, so ``R_y(theta_h) z = h`` when
``phi_h = 0``. The inverse takes ``d`` from ``(theta_d, phi_d)``, rotates it by ``+theta_h`` about
``y`` and then ``+phi_h`` about ``z`` to get ``wi``; ``wo`` is the same rotation applied to ``d``
mirrored about the normal, ``(-d_x, -d_y, d_z)``, which equals ``2 (wi . h) h - wi``.

Convention choices (the MERL database's own reader, ``BRDFRead.cpp``, is the reference):

* Angles come from ``atan2`` of a sine and a cosine rather than ``acos`` of a cosine: the same
  angles mathematically, but accurate near 0 where ``acos`` loses half the digits. The rotations are
  applied with ``cos/sin phi_h = h_x/r, h_y/r`` (``r = |h_xy|``) instead of evaluating trig
  functions; ``phi_h`` is taken as 0 when ``h`` is the normal (as ``atan2(0, 0) = 0`` does there).
* ``wi = -wo`` (no half vector) is mapped to ``h = n``; such pairs are never both above the horizon.
* Swapping ``wi`` and ``wo`` maps ``phi_d -> phi_d + pi`` and leaves ``theta_h, theta_d`` alone
  (reciprocity), so an isotropic reciprocal BRDF needs ``phi_d`` only modulo ``pi``:
  ``fold=True`` (the default) returns it folded into ``[0, pi)``; see :func:`fold_phi_d`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["half_diff_from_dirs", "dirs_from_half_diff", "fold_phi_d"]


def fold_phi_d(phi_d):
    """Fold ``phi_d`` into ``[0, pi)`` using reciprocity (``phi_d ~ phi_d + pi``).

    Expects ``phi_d`` in ``[-pi, pi]`` (what ``atan2`` returns); values outside are folded
    with ``np.mod``. Negative values get ``+pi`` exactly as the MERL reader does
    (``if (phi_diff < 0.0) phi_diff += M_PI``); a result equal to ``pi`` (``atan2`` returning
    ``pi``, or ``phi + pi`` rounding up to ``pi`` for tiny negative ``phi``) becomes ``0``, its
    reciprocal twin. **Departure from the MERL reader:** that reader leaves ``pi`` in place and
    clamps it into the last ``phi_d`` cell; folding it to ``0`` keeps the fold continuous and
    swapping ``wi``/``wo`` exactly symmetric. Only that single value is treated differently.
    NaN stays NaN.
    """
    phi = np.asarray(phi_d, dtype=np.float64)
    if phi.size and not (np.nanmin(phi, initial=0.0) >= -np.pi
                         and np.nanmax(phi, initial=0.0) <= np.pi):
        phi = np.mod(phi, np.pi)
    phi = np.where(phi < 0.0, phi + np.pi, phi)
    at_pi = phi >= np.pi
    if at_pi.any():
        phi = np.where(at_pi, 0.0, phi)
    return phi


def _fix_where(mask, a, value):
    """``where(mask, value, a)``, skipping the copy when ``mask`` is all False (the usual case)."""
    return np.where(mask, value, a) if mask.any() else a


def half_diff_from_dirs(wi, wo, fold: bool = True):
    """Rusinkiewicz half/difference angles of direction pairs (the forward map in the module doc).

    Args:
        wi, wo: unit directions ``(..., 3)`` (broadcast against each other); not renormalised.
        fold: fold ``phi_d`` into ``[0, pi)`` by reciprocity (:func:`fold_phi_d`); with
            ``False`` it is the raw ``atan2`` value in ``[-pi, pi]``.

    Returns:
        ``(theta_h, theta_d, phi_d)``, each of the broadcast batch shape, in radians.
        ``theta_h`` and ``theta_d`` are in ``[0, pi]``. ``phi_h`` is dropped (isotropy).

    Written component-wise with the unnormalised sum ``s = wi + wo`` (``theta_h`` and the
    azimuth of ``h`` do not depend on its length), which keeps it at about twenty array passes.
    """
    wi = np.asarray(wi, dtype=np.float64)
    wo = np.asarray(wo, dtype=np.float64)
    wx, wy, wz = wi[..., 0], wi[..., 1], wi[..., 2]
    sx, sy, sz = wx + wo[..., 0], wy + wo[..., 1], wz + wo[..., 2]
    rs = np.sqrt(sx * sx + sy * sy)  # |s| sin(theta_h)
    no_sum = (rs == 0.0) & (sz == 0.0)  # wi = -wo: take h = n
    sz = _fix_where(no_sum, sz, 1.0)
    theta_h = np.arctan2(rs, sz)
    inv = 1.0 / np.sqrt(rs * rs + sz * sz)
    pole = rs == 0.0  # h = n: phi_h = 0, as atan2(0, 0) gives
    inv_rs = 1.0 / _fix_where(pole, rs, 1.0)
    c = _fix_where(pole, sx * inv_rs, 1.0)  # cos(phi_h)
    s = sy * inv_rs  # sin(phi_h); 0 at the pole
    x1 = c * wx + s * wy  # R_z(-phi_h) wi
    dy = c * wy - s * wx
    r, hz = rs * inv, sz * inv  # sin, cos of theta_h
    dx = x1 * hz - wz * r  # R_y(-theta_h): x' = x cos - z sin, z' = x sin + z cos
    dz = x1 * r + wz * hz
    theta_d = np.arctan2(np.sqrt(dx * dx + dy * dy), dz)
    phi_d = np.arctan2(dy, dx)
    if fold:
        phi_d = fold_phi_d(phi_d)
    return theta_h, theta_d, phi_d


def dirs_from_half_diff(theta_h, theta_d, phi_d, phi_h=0.0):
    """Direction pairs ``(wi, wo)`` from half/difference angles (the inverse map in the module doc).

    All four angles broadcast; ``phi_h = 0`` puts the half vector in the ``xz`` plane, which is
    all an isotropic BRDF needs. Returns ``wi, wo`` of shape ``(..., 3)``.
    ``half_diff_from_dirs(*dirs_from_half_diff(th, td, pd, ph), fold=False)`` gives back
    ``(th, td, pd)`` up to rounding for ``0 < th < pi/2``, ``0 < td < pi/2``, ``|pd| < pi``.

    With ``d = (sin theta_d cos phi_d, sin theta_d sin phi_d, cos theta_d)``,
    ``wi = R_z(phi_h) R_y(theta_h) d`` and ``wo = R_z(phi_h) R_y(theta_h) (-d_x, -d_y, d_z)``.
    Each sine and cosine is taken on its own angle's shape before anything broadcasts, so for
    separable axes (a grid as ``th[:, None, None]``, ``td[None, :, None]``, ``pd[None, None,
    :]``) the trigonometry is a few hundred values and the full-size work a dozen products;
    ``phi_h = 0`` (a plain scalar zero, the default) skips the azimuthal rotation.
    """
    theta_h, theta_d, phi_d, phi_h = (np.asarray(a, dtype=np.float64)
                                      for a in (theta_h, theta_d, phi_d, phi_h))
    shape = np.broadcast_shapes(theta_h.shape, theta_d.shape, phi_d.shape, phi_h.shape)
    st, dz = np.sin(theta_d), np.cos(theta_d)
    dx, dy = st * np.cos(phi_d), st * np.sin(phi_d)
    sh, ch = np.sin(theta_h), np.cos(theta_h)
    # R_y(theta_h) (+-dx, +-dy, dz): x = dz sh +- dx ch, z = dz ch -+ dx sh.
    a, b, c, e = dz * sh, dx * ch, dz * ch, dx * sh
    azimuth = not (phi_h.ndim == 0 and phi_h == 0.0)
    sp, cp = np.sin(phi_h), np.cos(phi_h)
    wi, wo = np.empty(shape + (3,)), np.empty(shape + (3,))
    # 0.0 - dy: +0, not -0, where phi_d = 0
    for out, x1, y, z1 in ((wi, a + b, dy, c - e), (wo, a - b, 0.0 - dy, c + e)):
        if azimuth:  # R_z(phi_h)
            x1, y = x1 * cp - y * sp, x1 * sp + y * cp
        out[..., 0], out[..., 1], out[..., 2] = x1, y, z1
    return wi, wo
