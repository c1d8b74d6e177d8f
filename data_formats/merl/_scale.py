"""BRDF values <-> the values a MERL file stores: the per-channel scales, what a file can carry.

``BRDF = stored * SCALE[channel]``; a negative stored value marks a cell without measurement.
"""

from __future__ import annotations

import numpy as np

#: The file's channel blocks, in order.
CHANNELS = "RGB"
#: Per-channel factors from stored values to BRDF units (``BRDFRead.cpp``: RED/GREEN/BLUE_SCALE).
SCALE = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])


def check_storable(values, valid, message) -> None:
    """Raise ``ValueError(message(count, cell))`` when a valid cell of ``values`` has a channel
    that is negative, NaN or infinite (what a MERL file cannot store): ``count`` such cells,
    ``cell`` the index of the first."""
    bad = valid & ~np.all(np.isfinite(values) & (values >= 0.0), axis=-1)
    if bad.any():
        first = tuple(int(x) for x in np.argwhere(bad)[0])
        raise ValueError(message(int(np.count_nonzero(bad)), first))


def stored_values(rgb, valid):
    """Stored (unscaled) values, channel-last, ``-1`` in missing cells: ``rgb / SCALE``.

    Raises ``ValueError`` when a valid cell holds a value the format cannot carry (negative,
    NaN, infinite, or so large that ``rgb / SCALE`` overflows).
    """
    stored = rgb / SCALE
    check_storable(stored, valid, lambda count, cell: (
        f"{count} valid cells hold values a MERL file cannot store "
        f"(first: cell {cell} = {rgb[cell].tolist()}): expected finite BRDF values >= 0 "
        f"and below {np.finfo(np.float64).max * SCALE[0]:.3g}. Mark such cells missing "
        "(valid=False) or fix the values"
    ))
    stored[~valid] = -1.0
    return stored


def snap_to_file(rgb, valid=None):
    """The BRDF values a MERL reader gets back after ``rgb`` is written: ``(rgb/SCALE)*SCALE``.

    The reader multiplies the stored double by ``SCALE`` (format fact), and multiplication by
    a scale that is not a power of two does not reach every double: about 10-16% of arbitrary
    doubles (depending on the channel) have no stored value that reads back as themselves.
    Snapping moves those by one ulp (a relative change below ``2.3e-16``) and leaves every other
    value alone: a value ``x`` is reachable exactly when ``(x/SCALE)*SCALE == x`` (checked in the
    tests from subnormals to 1e300), so snapping is idempotent and every snapped
    table round-trips bit for bit. Values in cells where ``valid`` is False are returned as 0.
    """
    rgb = np.asarray(rgb, dtype=np.float64)
    valid = np.ones(rgb.shape[:-1], dtype=bool) if valid is None else np.asarray(valid, bool)
    out = stored_values(rgb, valid) * SCALE
    out[~valid] = 0.0
    return out
