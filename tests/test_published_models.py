"""Every published fit, evaluated by the registered model its bbm class maps to, reproduces bbm's
own reference values (``../shared/published``, or the embedded ten materials without it).

This is the check that a transcription means what the publication (as bbm implements it)
means: every fit line of every file, at bbm's 64 direction pairs, to ~1e-10 relative.

Where bbm's own double arithmetic fails, its value is NaN (``NganLafortune``'s normalisation
``pow(max(Cz², Cxy²), n/2)`` underflows to 0 for exponents above about 1300, giving 0/0); there
the model must be finite, and ``tests/test_models_classic.py`` checks those lines against bbm's
expression evaluated in 50-digit decimal arithmetic.
"""

from __future__ import annotations

import numpy as np
import pytest

import published
from brdffit.models import published_params

#: Relative tolerance against bbm's values (double precision on both sides), and the absolute
#: floor under which a value counts as zero (bbm's values below the horizon are exact zeros).
RTOL, ATOL = 1e-10, 1e-13


@pytest.mark.parametrize("stem", published.STEMS)
def test_every_fit_line_reproduces_bbm(stem):
    fits, ref = published.load(stem)
    worst = []
    for fit in fits:
        model, params = published_params(fit)
        f = np.asarray(model(params, ref.wi, ref.wo), dtype=float)
        want = ref.of(fit.material)
        assert np.all(np.isfinite(f)), (stem, fit.material)
        known = np.isfinite(want)  # bbm's NaN: see the module docstring
        err = np.where(known, np.abs(f - want) / np.maximum(np.abs(want), ATOL / RTOL), 0.0)
        worst.append((float(err.max()), fit.material))
    bad = [(e, m) for e, m in worst if not e <= RTOL]
    assert not bad, f"{stem}: {len(bad)} of {len(fits)} lines off bbm's values; worst {max(bad)}"
