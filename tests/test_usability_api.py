"""The library as a notebook user meets it: a failed fit hands back its result, the persistent
compilation cache is on without being asked for, and ``fit_many`` keeps its cluster (and so
its workers' compiled programs) from one call to the next.

Fits here are ``ggx`` on small sample lists (log loss), so they share compiled programs with
``tests/test_api.py``; the cache and the cluster are process state, so those cases run in
fresh processes or read the cluster's own identity."""

import os
import pickle
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import brdffit
from brdffit.errors import FitError

from test_api import write_sample_list

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def samples_csv(tmp_path_factory):
    return write_sample_list(tmp_path_factory.mktemp("usability") / "gold.csv", n=300)


# -- a failed fit hands back its result ---------------------------------------------------------
def test_a_fit_stopped_by_the_step_limit_raises_with_its_result(samples_csv):
    with pytest.raises(FitError, match="did not converge.*max_steps") as info:
        brdffit.fit(samples_csv, "ggx", max_steps=1)
    res = info.value.result
    assert isinstance(res, brdffit.FitResult)
    assert res.success is False and res.status == "nonlinear_max_steps_reached"
    assert "max_steps" in res.message and np.all(np.isfinite(res.x))
    assert res.provenance["options"]["max_steps"] == 1  # finished as a returned result is
    assert res.provenance["input"]["path"] == str(samples_csv.resolve())
    assert "throw=False" in str(info.value) and ".result" in str(info.value)
    back = brdffit.fit(samples_csv, "ggx", max_steps=1, throw=False)
    assert back.status == res.status and back.success is False
    np.testing.assert_array_equal(back.x, res.x)


def test_the_result_of_a_fit_error_survives_pickling(samples_csv):
    """A Dask worker's exception travels pickled: its result must travel with it."""
    with pytest.raises(FitError) as info:
        brdffit.fit(samples_csv, "ggx", max_steps=1)
    again = pickle.loads(pickle.dumps(info.value))
    assert str(again) == str(info.value)
    assert again.result is not None and again.result.status == info.value.result.status
    assert FitError("no cells").result is None  # a fit that could not start has none


def test_data_that_determine_nothing_raise_with_the_result(samples_csv):
    """The data verdicts (here: all zeros) are failures after the fit ran: result attached."""
    from data_formats import SampleSet

    s = brdffit.io.read_path(samples_csv).to_samples()
    zero = SampleSet(s.wi, s.wo, np.zeros_like(s.rgb), s.valid, name="zero")
    with pytest.raises(FitError, match="is degenerate") as info:
        brdffit.fit(zero, "ggx")
    assert info.value.result.status == "degenerate" and not info.value.result.success
    with pytest.raises(FitError, match="is degenerate") as info:  # the posterior's own fit
        brdffit.sample_posterior(zero, "ggx", nwalkers=8, nsteps=4, burn=0)
    assert info.value.result is not None and info.value.result.status == "degenerate"
