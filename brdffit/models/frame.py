r"""The tangent frame of an anisotropic model: a fitted rotation about the normal.

An anisotropic lobe has principal axes (the tangent ``x`` of ``α_x`` and the bitangent ``y``);
a measured material's axes (the brushing direction of a brushed metal, the weave of a satin)
need not lie along the file's ``x`` and ``y``. The anisotropic models therefore carry the
azimuth of their tangent as a parameter, ``frame_angle`` ``φ_t``: the model is evaluated at
the directions expressed in its own frame,

.. math::

    \mathbf w' = (\cos\varphi_t\,w_x + \sin\varphi_t\,w_y,\;
                 -\sin\varphi_t\,w_x + \cos\varphi_t\,w_y,\; w_z),

i.e. the tangent is ``t = (cos φ_t, sin φ_t, 0)`` in the file's frame. Why a parameter and not
a rotation of the data before the fit: the fitted model then *is* the material in the file's
frame: its parameters, standard errors, figures, fitted tables and exports need no side
channel for the rotation, and the solver refines the angle together with the widths. The start
(:class:`brdffit.fitting.start.Features`) reads the angle off the data.

A lobe with ``α_x = α_y`` does not depend on ``φ_t``; a symmetric lobe (GGX, the APS Gaussian)
is the same at ``φ_t`` and ``φ_t + π``, and at ``φ_t + π/2`` with its widths swapped, so
:data:`FRAME_ANGLE` spans ``[-π/2, π/2]`` and the start picks the labelling with
``|φ_t| ≤ π/4``, a quarter turn from either bound. The APS satin and V-grooves are the same at
``φ_t + π`` but not at ``φ_t + π/2`` (their widths do not swap): their starts put the tangent
on the lobe's narrow or wide axis, anywhere in the range
(:func:`brdffit.models.starts.oriented`).
"""

from __future__ import annotations

import numpy as np

from .registry import Param

#: The azimuth of the model's tangent (its ``α_x`` axis) in the file's frame.
FRAME_ANGLE = Param(
    "frame_angle", (), -np.pi / 2, np.pi / 2, 0.0,
    "azimuth φ_t (rad) of the tangent x (the first width's axis) from the data's x axis, "
    "counter-clockwise about the normal",
)


def to_frame(w, angle):
    """Directions ``w`` ``(..., 3)`` expressed in the frame whose tangent has azimuth ``angle``
    (module docstring); works on NumPy and JAX arrays."""
    import jax.numpy as jnp

    c, s = jnp.cos(angle), jnp.sin(angle)
    x, y = w[..., 0], w[..., 1]
    return jnp.stack([c * x + s * y, -s * x + c * y, w[..., 2]], axis=-1)


def rotated(fn):
    """``fn(params, wi, wo)`` of a model in its own frame → the same model in the file's frame,
    its frame's azimuth the parameter ``frame_angle``."""

    def in_file_frame(p, wi, wo):
        a = p["frame_angle"]
        return fn(p, to_frame(wi, a), to_frame(wo, a))

    return in_file_frame


def rotated_stages(stages):
    """``Model.stages`` ``(prepare, per_pair, combine)`` with the directions turned into the
    model's frame in ``per_pair``; the state carries the angle beside the model's own."""
    prepare, per_pair, combine = stages

    def prepare_rotated(p):
        return prepare(p), p["frame_angle"]

    def per_pair_rotated(state, wi, wo):
        inner, a = state
        return per_pair(inner, to_frame(wi, a), to_frame(wo, a))

    def combine_rotated(state, quantities):
        return combine(state[0], quantities)

    return prepare_rotated, per_pair_rotated, combine_rotated
