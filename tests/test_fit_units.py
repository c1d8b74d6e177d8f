"""Unit tests of the fitting engine's parts: losses, transforms, the normal form, data selection,
errors, and the result object. Independent references: NumPy transcriptions, dense Jacobians
from ``jax.jacfwd``, closed forms."""

import dataclasses
import json
import logging
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pytest

import brdffit
from brdffit.errors import ConfigError, FitError, UnknownNameError
from brdffit.fitting import LOSSES, SOLVERS, FitResult, Subsample, get_loss
from brdffit.fitting.bounded import box_step, optimality, predicted_decrease
from brdffit.fitting.data import CHUNK_CELLS, block_order, select
from brdffit.fitting.losses import RELATIVE_FLOOR, huber_residual
from brdffit.fitting.normal_form import compress, compress_newton, gram, normal_form
from brdffit.fitting.problem import Problem
from brdffit.fitting.parameters import flat_log
from brdffit.fitting.transforms import at_bound, bounds_in_s, to_box, to_physical
from data_formats import SampleSet

RNG = np.random.default_rng(0)
_GGX = jax.jit(lambda p, wi, wo: brdffit.get_model("ggx").fn(p, wi, wo))


def hemisphere(n, rng=RNG):
    """Random unit directions with z > 0.05."""
    v = rng.normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2]) + 0.3
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def ggx_samples(n=3000, params=None, noise=0.0, seed=1, name="synthetic"):
    rng = np.random.default_rng(seed)
    wi, wo = hemisphere(n, rng), hemisphere(n, rng)
    model = brdffit.get_model("ggx")
    p = model.unflatten(model.flatten(params or {}))
    rgb = np.asarray(_GGX(p, wi, wo))
    rgb = rgb * (1 + noise * rng.standard_normal(rgb.shape))
    return SampleSet(wi, wo, rgb, np.ones(n, bool), name=name)


# -- losses -----------------------------------------------------------------------------------
NUMPY_LOSSES = {
    "linear": lambda p, d, ci, co: p - d,
    "cosine": lambda p, d, ci, co: (p - d) * ci * co,
    "log": lambda p, d, ci, co: np.log1p(p * ci) - np.log1p(d * ci),
    "relative": lambda p, d, ci, co: (p - d) / np.maximum(np.abs(d), RELATIVE_FLOOR),
    "cosine-in": lambda p, d, ci, co: (p - d) * ci,
}


@pytest.mark.parametrize("name", sorted(LOSSES))
def test_loss_residual_matches_numpy(name):
    loss = get_loss(name)
    pred, data = RNG.uniform(0, 50, (200, 3)), RNG.uniform(0, 50, (200, 3))
    data[:5] = 1e-5  # below the relative floor
    ci, co = RNG.uniform(0.05, 1, (200, 1)), RNG.uniform(0.05, 1, (200, 1))
    target = loss.transform(jnp.asarray(data), ci, co)
    sw = loss.weight(data, ci, co)
    got = loss.residual(jnp.asarray(pred), target, sw, ci, co)
    np.testing.assert_allclose(got, NUMPY_LOSSES[name](pred, data, ci, co), rtol=1e-12, atol=1e-14)


def test_huber_half_square_is_hubers_loss():
    r, delta = np.linspace(-5, 5, 101), 0.7
    rh = np.asarray(huber_residual(jnp.asarray(r), delta))
    expected = np.where(np.abs(r) <= delta, 0.5 * r**2, delta * np.abs(r) - 0.5 * delta**2)
    np.testing.assert_allclose(0.5 * rh**2, expected, rtol=1e-12, atol=1e-15)
    assert np.all(np.sign(rh) == np.sign(r))


def test_loss_names_and_errors():
    assert get_loss("log+huber").huber == 0.1
    assert get_loss("cosine", huber=2.0).label == "cosine+huber(2)"
    for loss in (get_loss("cosine", huber=2.0), get_loss("log+huber", 0.05), LOSSES["linear"]):
        assert get_loss(loss.label) == loss  # a result's label names its loss again
    with pytest.raises(UnknownNameError, match="linear") as e:
        get_loss("lgo")
    assert "'log'" in str(e.value)  # suggests the close match
    with pytest.raises(ConfigError, match="positive"):
        get_loss("log").robust(-1.0)


# -- transforms -------------------------------------------------------------------------------
def test_transform_round_trip_and_bounds():
    lo, hi = np.array([0.0, 1e-3, 0.3]), np.array([1.0, 1.0, 10.0])
    log = np.array([False, True, True])
    slo, shi = bounds_in_s(lo, hi, log)
    x = np.array([0.25, 0.004, 1.2])
    z = to_box(x, slo, shi, log)
    assert np.all((z > 0) & (z < 1))
    np.testing.assert_allclose(to_physical(jnp.asarray(z), slo, shi, log), x, rtol=1e-12)
    # the box's faces are the bounds, reported as such; values outside are clamped onto them
    ends = np.array([0.0, 1.0, 0.5])
    xb = np.asarray(to_physical(jnp.asarray(ends), slo, shi, log))
    np.testing.assert_allclose(xb[:2], [lo[0], hi[1]], rtol=1e-15)
    assert list(at_bound(ends)) == [-1, 1, 0]
    np.testing.assert_array_equal(to_box(np.array([-1.0, 5.0, 0.3]), slo, shi, log), [0, 1, 0])
    # affine in s: the derivative on a bound equals the one inside (a parameter on its bound
    # can come back), unlike a logistic map whose derivative vanishes there
    grad = jax.grad(lambda v: to_physical(v, slo, shi, log)[0])
    assert grad(jnp.asarray(ends))[0] == pytest.approx(1.0) and grad(jnp.full(3, 0.3))[0] == 1.0
    dlog = jax.grad(lambda v: jnp.log(to_physical(v, slo, shi, log)[1]))(jnp.asarray(ends))[1]
    assert float(dlog) == pytest.approx(shi[1] - slo[1])


# -- the bounded step and the optimality test -----------------------------------------------
def _box_qp_reference(h, g, z):
    """The box-constrained quadratic minimum by scipy's L-BFGS-B (independent reference)."""
    from scipy.optimize import minimize

    f = lambda d: (g @ d + 0.5 * d @ h @ d, g + h @ d)
    sol = minimize(f, np.zeros_like(z), jac=True, method="L-BFGS-B",
                   bounds=list(zip(-z, 1.0 - z)), options={"ftol": 1e-15, "gtol": 1e-12})
    return sol.x


@pytest.mark.parametrize("seed", range(6))
def test_box_step_solves_the_bounded_quadratic(seed):
    rng = np.random.default_rng(seed)
    p = 7
    a = rng.normal(size=(20, p)) * np.logspace(0, 3, p)  # columns over three decades
    h = a.T @ a
    g = rng.normal(size=p) * 30 * np.diag(h) ** 0.5
    z = rng.uniform(0, 1, size=p)
    z[:2] = [0.0, 1.0]  # two coordinates on a bound
    d = np.asarray(jax.jit(box_step)(h, g, z, np.zeros(p)))
    ref = _box_qp_reference(h, g, z)
    assert np.all(z + d >= 0) and np.all(z + d <= 1)
    q = lambda v: g @ v + 0.5 * v @ h @ v
    assert q(d) <= q(ref) + 1e-9 * abs(q(ref))
    # coordinates the minimum puts on a bound are exactly on it
    on = (np.isclose(z + ref, 0, atol=1e-7)) | (np.isclose(z + ref, 1, atol=1e-7))
    assert np.all(((z + d)[on] == 0) | ((z + d)[on] >= 1 - 1e-15))


def test_optimality_is_zero_at_a_bounded_stationary_point_and_positive_elsewhere():
    h = np.array([[4.0, 1.0], [1.0, 3.0]])
    # the unconstrained minimum is at z = (-0.2, 0.5): the first coordinate belongs on its bound
    target = np.array([-0.2, 0.5])
    g_at = lambda z: h @ (z - target)
    cost = lambda z: 0.5 * (z - target) @ h @ (z - target) + 1.0
    zopt = np.array([0.0, target[1] - h[1, 0] * (0.0 - target[0]) / h[1, 1]])  # z1's best at z0 = 0
    om, d = optimality(jnp.asarray(h), jnp.asarray(g_at(zopt)), jnp.asarray(cost(zopt)), jnp.asarray(zopt))
    assert abs(float(om)) < 1e-12 and np.allclose(d, 0, atol=1e-12)
    z = np.array([0.3, 0.9])
    om, d = optimality(jnp.asarray(h), jnp.asarray(g_at(z)), jnp.asarray(cost(z)), jnp.asarray(z))
    expected = float(predicted_decrease(jnp.asarray(h), jnp.asarray(g_at(z)), d)) / cost(z)
    assert float(om) == pytest.approx(expected) and float(om) > 0
    np.testing.assert_allclose(z + np.asarray(d), zopt, atol=1e-9)  # the step reaches the optimum


def test_second_order_term_matches_finite_differences():
    """``Problem.block_second_order`` = Hessian of ½Σr² − JᵀJ, against central differences of
    the gradient (from the dense Jacobian) on a noisy table (large residuals)."""
    model = brdffit.get_model("ggx")
    x0 = {"diffuse": [0.3, 0.2, 0.1], "f0": [0.05, 0.04, 0.03], "alpha": 0.2, "grazing": 0.6}
    s = ggx_samples(400, x0, noise=0.3)
    prob = _problem("ggx", tuple(range(8)), x0)
    sel = select(s, prob.loss)
    z = jnp.asarray(to_box(model.flatten(x0), np.asarray(prob.slo), np.asarray(prob.shi),
                           flat_log(model)))
    second = np.asarray(jax.jit(lambda p, v, d: p.block_second_order(v, d))(prob, z, sel.data))
    grad = jax.jit(lambda p, v, d: jax.jacfwd(p.residual)(v, d).T @ p.residual(v, d))
    jac = jax.jit(lambda p, v, d: jax.jacfwd(p.residual)(v, d))
    h = 1e-5
    hess = np.stack([(np.asarray(grad(prob, z.at[i].add(h), sel.data))
                      - np.asarray(grad(prob, z.at[i].add(-h), sel.data))) / (2 * h) for i in range(8)])
    J = np.asarray(jac(prob, z, sel.data))
    ref = 0.5 * (hess + hess.T) - J.T @ J
    assert np.max(np.abs(ref)) > 1e-3 * np.max(np.abs(J.T @ J))  # the term is not negligible here
    np.testing.assert_allclose(second, ref, atol=1e-6 * np.max(np.abs(J.T @ J)))


def test_second_order_of_a_stage_is_the_exact_term_of_its_leading_blocks():
    """``second_order`` of a stage on ``target`` blocks (forward differences of exact
    gradients) is the exact ``block_second_order`` (``jax.hessian``) over its leading
    ``min(target, slab)`` blocks, scaled by ``target / blocks``, to the differences' accuracy;
    also with coordinates on both bounds of the box, which are stepped inwards. (A
    ``per_pass`` model's forward-mode gradients: the ``gtr`` test below.)"""
    from brdffit.fitting import solve as sv

    x0 = {"diffuse": [0.3, 0.2, 0.1], "f0": [0.05, 0.04, 0.03], "alpha": 0.2, "grazing": 0.6}
    sel = select(ggx_samples(11 * 4096 - 100, x0, noise=0.3), get_loss("log"))  # 11 blocks
    prob = dataclasses.replace(_problem("ggx", tuple(range(8)), x0), chunks=sel.chunks)
    z = jnp.asarray(to_box(brdffit.get_model("ggx").flatten(x0), np.asarray(prob.slo),
                           np.asarray(prob.shi), flat_log(brdffit.get_model("ggx"))))
    block = sel.data.wi.shape[0] // prob.chunks
    assert prob.chunks == 11 and sv._slab_blocks(prob, sel.data) == 8
    direct = jax.jit(lambda p, v, d: p.block_second_order(v, d))
    on_bounds = z.at[0].set(0.0).at[4].set(1.0).at[7].set(1.0)
    for point in (z, on_bounds):
        for target in (1, 3, 5, 8, 11):
            blocks = min(target, 8)
            ref = np.asarray(direct(prob, point, jax.tree.map(lambda a: a[: blocks * block], sel.data)))
            got = sv.second_order(prob, point, sel.data, target)
            np.testing.assert_allclose(got, ref * (target / blocks), rtol=0,
                                       atol=1e-5 * np.max(np.abs(ref)) * (target / blocks))
    # the steps: √ε, towards the inside of the box
    h = np.asarray(sv.second_steps(on_bounds, "float64"))
    assert h[0] > 0 and h[4] < 0 and h[7] < 0 and np.all(np.abs(h) == np.sqrt(np.finfo(float).eps))
    assert np.all(np.abs(np.asarray(sv.second_steps(on_bounds, "float32")))
                  == np.sqrt(np.finfo(np.float32).eps))
    # a model evaluated in float32 takes float32's step (float64's would vanish in rounding)
    prob32 = dataclasses.replace(prob, compute_dtype="float32")
    ref = np.asarray(direct(prob32, z, jax.tree.map(lambda a: a[: 8 * block], sel.data)))
    np.testing.assert_allclose(sv.second_order(prob32, z, sel.data, 8), ref, rtol=0,
                               atol=3e-2 * np.max(np.abs(ref)))


def test_second_order_of_a_model_with_per_pass_tables_is_the_exact_term():
    """``gtr`` builds its Λ table once per point (its gradients by forward mode, the table's
    tangent included) and its forward differences agree with ``jax.hessian``'s exact term."""
    from brdffit.fitting import solve as sv
    from brdffit.models.evaluate import evaluate_model

    model = brdffit.get_model("gtr")
    x0 = {"diffuse": [0.3, 0.2, 0.1], "f0": [0.05, 0.04, 0.03], "alpha": 0.25, "gamma": 1.6,
          "grazing": 0.6}
    rng = np.random.default_rng(3)
    wi, wo = hemisphere(3000, rng), hemisphere(3000, rng)
    rgb = evaluate_model(model, x0, wi, wo) * np.exp(rng.normal(0, 0.3, (3000, 3)))
    sel = select(SampleSet(wi, wo, rgb, np.ones(3000, bool), name="noisy gtr"), get_loss("log"))
    prob = dataclasses.replace(_problem("gtr", tuple(range(9)), x0), chunks=sel.chunks)
    z = jnp.asarray(to_box(model.flatten(x0), np.asarray(prob.slo), np.asarray(prob.shi),
                           flat_log(model)))
    ref = np.asarray(jax.jit(lambda q, v, d: q.block_second_order(v, d))(prob, z, sel.data))
    got = sv.second_order(prob, z, sel.data, sel.chunks)
    assert np.max(np.abs(ref)) > 0
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-5 * np.max(np.abs(ref)))


def _compiles_of_second_order(caplog, call) -> list[str]:
    """The XLA compilations of the second-order program that ``call()`` made (JAX's log)."""
    caplog.clear()
    with jax.log_compiles(True), caplog.at_level(logging.WARNING):
        call()
    return [r.getMessage() for r in caplog.records
            if "Finished XLA compilation" in r.getMessage() and "jit(_second)" in r.getMessage()]


@pytest.mark.parametrize("x64", [True, False])
def test_second_order_program_compiled_ahead_is_the_one_the_fit_then_calls(caplog, x64):
    """``compile_second_ahead`` traces here and compiles on its own thread, under the caller's
    (thread-local) x64 setting, the very program that ``second_order`` then runs: the call
    compiles nothing.
    Without it the same call compiles (the log check can fail). Sample counts of this test
    only, so no other test has compiled these shapes."""
    from brdffit.fitting.solve import compile_second_ahead, second_order

    model = brdffit.get_model("ggx")
    x0 = {"diffuse": [0.3, 0.2, 0.1], "f0": [0.05, 0.04, 0.03], "alpha": 0.2, "grazing": 0.6}
    with jax.enable_x64(x64), warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # "float64 ... truncated to float32"
        prob = _problem("ggx", tuple(range(8)), x0)
        z = jnp.asarray(to_box(model.flatten(x0), np.asarray(prob.slo), np.asarray(prob.shi),
                               flat_log(model)))
        ahead = select(ggx_samples(1237 + 2 * x64, x0, noise=0.1), prob.loss).data
        plain = select(ggx_samples(1238 + 2 * x64, x0, noise=0.1), prob.loss).data
        thread = compile_second_ahead(prob, z, ahead)
        thread.join()
        assert _compiles_of_second_order(caplog, lambda: second_order(prob, z, ahead, 1)) == []
        assert len(_compiles_of_second_order(caplog, lambda: second_order(prob, z, plain, 1))) == 1
        np.testing.assert_array_equal(second_order(prob, z, ahead, 1).dtype,
                                      np.float64 if x64 else np.float32)


# -- the normal form --------------------------------------------------------------------------
def _toy_columns(u, data):
    """A small nonlinear residual with a known dense Jacobian (and a duplicated direction)."""
    x, y = data
    pred = u[0] * jnp.exp(-u[1] * x) + u[2] * jnp.sin(x) + u[3] * u[2] * jnp.sin(x)
    r = pred - y
    cols = jax.vmap(lambda t: jax.jvp(lambda v: _toy_res(v, data), (u,), (t,))[1])(jnp.eye(4))
    return r, cols


def dense_sums(columns):
    """``sums`` for ``gram`` from ``columns(u, block) -> (r, J)`` with ``J`` dense (``p`` rows):
    the straightforward reference for the normal form; every residual counts in ``m``."""

    def sums(u, chunk):
        r, cols = columns(u, chunk)
        cr = cols * r
        return jnp.sum(r * r), cols @ cols.T, cols @ r, cr @ cr.T, jnp.full((1,), r.size, u.dtype)

    return sums


def _toy_res(u, data):
    x, y = data
    return u[0] * jnp.exp(-u[1] * x) + u[2] * jnp.sin(x) + u[3] * u[2] * jnp.sin(x) - y


def test_normal_form_reproduces_cost_gradient_and_gauss_newton_matrix():
    x = jnp.linspace(0, 3, 64)
    data = (x, 2.0 * jnp.exp(-0.7 * x) + 0.1 * jnp.cos(5 * x))
    u = jnp.array([1.5, 0.4, 0.3, 0.0])  # at u[3]=0 the u[2], u[3] columns are parallel
    J = jax.jit(jax.jacfwd(_toy_res))(u, data)
    r = _toy_res(u, data)
    s, jtj, jtr, meat, extra = jax.jit(lambda v, d: gram(dense_sums(_toy_columns), v, d))(u, data)
    assert list(extra) == [64]
    np.testing.assert_allclose(jtj, J.T @ J, rtol=1e-12)
    np.testing.assert_allclose(jtr, J.T @ r, rtol=1e-12)
    # chunked accumulation (4 blocks of 16) equals the single pass
    np.testing.assert_allclose(meat, (J * r[:, None] ** 2).T @ J, rtol=1e-12)
    s4, jtj4, _jtr4, _, _ = jax.jit(lambda v, d: gram(dense_sums(_toy_columns), v, d, chunks=4))(u, data)
    np.testing.assert_allclose([s4], [s], rtol=1e-12)
    np.testing.assert_allclose(jtj4, jtj, rtol=1e-12)
    # the length of the extra sums given instead of found by tracing: the same sums
    known = jax.jit(lambda v, d: gram(dense_sums(_toy_columns), v, d, chunks=4, n_extra=1))(u, data)
    np.testing.assert_array_equal(known[1], jtj4)
    assert list(known[4]) == [64]
    rt, R = compress(s, jtj, jtr)
    assert np.all(np.isfinite(rt)) and np.all(np.isfinite(R))
    np.testing.assert_allclose(jnp.sum(rt**2), jnp.sum(r**2), rtol=1e-12)
    np.testing.assert_allclose(R.T @ R, J.T @ J, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(R.T @ rt[:-1], J.T @ r, rtol=1e-9, atol=1e-9)
    # the quadratic model agrees for any step
    d = jnp.array([0.1, -0.2, 0.05, 0.3])
    full = jnp.sum((J @ d + r) ** 2)
    small = jnp.sum((R @ d + rt[:-1]) ** 2) + rt[-1] ** 2
    np.testing.assert_allclose(small, full, rtol=1e-10)


def _modified_newton(jtj, h):
    """NumPy reference: ``h`` with the eigenvalues of its non-positive eigenvectors replaced by
    Gauss–Newton's curvature along them."""
    lam, vec = np.linalg.eigh(h)
    gn = np.einsum("ik,ij,jk->k", vec, jtj, vec)
    lam = np.where(lam > 1e-13 * np.max(np.abs(lam)), lam, gn)
    return (vec * lam) @ vec.T


def test_newton_model_leaves_out_the_curvature_of_held_coordinates():
    """``JᵀJ + S`` with strong negative curvature along a coordinate held on its bound (the
    aluminium ``beckmann`` case: ``F90`` pressed on 0) is indefinite; the Newton model keeps
    ``S`` on the free coordinates (``R̃ᵀR̃ = JᵀJ + S`` with the held rows and columns of ``S``
    zero). With the coordinate inside the box, the eigenvector of negative curvature gets
    Gauss–Newton's curvature instead; ``J̃ᵀr̃ = Jᵀr`` and ``‖r̃‖² = Σr²`` hold throughout."""
    rng = np.random.default_rng(3)
    a = rng.normal(size=(40, 3))
    jtj = a.T @ a
    s = np.array([[-0.3, 0.1, 0.0], [0.1, -0.2, 0.4], [0.0, 0.4, -3.0 * jtj[2, 2]]])
    jtr = np.array([0.5, -0.4, -2.0])  # coordinate 2 is pushed above its upper bound
    sum_r2 = 100.0
    assert np.linalg.eigvalsh(jtj + s)[0] < 0
    kept = s.copy()
    kept[2, :] = kept[:, 2] = 0.0
    assert np.linalg.eigvalsh(jtj + kept)[0] > 0
    args = (jnp.asarray(jtj), jnp.asarray(s))
    held = jnp.array([0.3, 0.7, 1.0])
    rt, rmat = compress_newton(sum_r2, *args, jnp.asarray(jtr), held)
    np.testing.assert_allclose(rmat.T @ rmat, jtj + kept, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(rmat.T @ rt[:-1], jtr, rtol=1e-10)
    np.testing.assert_allclose(jnp.sum(rt**2), sum_r2, rtol=1e-12)
    modified = _modified_newton(jtj, jtj + s)
    assert np.linalg.eigvalsh(modified)[0] > 0
    for z, g in ((jnp.array([0.3, 0.7, 0.9]), jtr),  # inside the box
                 (jnp.array([0.3, 0.7, 1.0]), -jtr)):  # on the bound, gradient pointing inside
        rt, rmat = compress_newton(sum_r2, *args, jnp.asarray(g), z)
        np.testing.assert_allclose(rmat.T @ rmat, modified, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(rmat.T @ rt[:-1], g, rtol=1e-10)
    # A Newton decrement above the cost (far from the optimum): Gauss–Newton's model.
    _, rmat = compress_newton(1e-6, *args, jnp.asarray(jtr), jnp.array([0.3, 0.7, 0.9]))
    np.testing.assert_allclose(rmat.T @ rmat, jtj, rtol=1e-10, atol=1e-12)


def test_normal_form_derivative_is_R():
    x = jnp.linspace(0, 3, 40)
    data = (x, jnp.cos(x))
    fn = normal_form(dense_sums(_toy_columns))
    u = jnp.array([1.0, 0.5, 0.2, 0.1])
    d = jnp.array([0.3, -0.1, 0.2, 0.4])
    (_rt, aux), (drt, daux) = jax.jit(lambda v, t: jax.jvp(lambda w: fn(w, (data, 0.0)), (v,), (t,)))(u, d)
    _, R = jax.jit(lambda v, dd: compress(*gram(dense_sums(_toy_columns), v, dd)[:3]))(u, data)
    np.testing.assert_allclose(drt[:-1], R @ d, rtol=1e-12)
    assert drt[-1] == 0 and np.all(np.asarray(daux["jtj"]) == 0)
    J = jax.jit(jax.jacfwd(_toy_res))(u, data)
    np.testing.assert_allclose(aux["jtj"], J.T @ J, rtol=1e-12)
    r = _toy_res(u, data)
    np.testing.assert_allclose(aux["meat"], (J * r[:, None] ** 2).T @ J, rtol=1e-12)


def _problem(model_name, free, x0, loss="log", dtype="float64"):
    model = brdffit.get_model(model_name)
    log = flat_log(model)
    lo, hi = model.flat_bounds()
    slo, shi = bounds_in_s(lo, hi, log)
    return Problem(model, get_loss(loss), free, tuple(bool(b) for b in log[list(free)]), dtype, 1,
                   jnp.asarray(model.flatten(x0)), jnp.asarray(slo[list(free)]),
                   jnp.asarray(shi[list(free)]))


def _dense_reference(prob, u, data):
    """``(Σr², JᵀJ, Jᵀr, Jᵀdiag(r²)J)`` from the dense Jacobian of ``jax.jacfwd``."""
    J = np.asarray(jax.jit(lambda p, v, d: jax.jacfwd(p.residual)(v, d))(prob, u, data))
    r = np.asarray(jax.jit(lambda p, v, d: p.residual(v, d))(prob, u, data))
    return np.sum(r * r), J.T @ J, J.T @ r, (J * r[:, None] ** 2).T @ J


@pytest.mark.parametrize(
    "model_name, free, x0, local",
    [
        # f0[1] fixed: a channel-local RGB parameter with a partial tangent
        ("ggx", (0, 1, 2, 3, 5, 6), {"diffuse": [0.3, 0.2, 0.1], "f0": [0.1, 0.2, 0.3], "alpha": 0.2},
         {"diffuse": True, "f0": True, "alpha": False}),
        # base_color couples the channels (the tint's luminance): one jvp per component
        ("disney", (0, 1, 2, 3, 5, 6), {"base_color": [0.6, 0.3, 0.15], "metallic": 0.2,
                                        "roughness": 0.35, "specular_tint": 0.4},
         {"base_color": False}),
    ],
)
@pytest.mark.parametrize("loss, batched", [("log", False), ("cosine-in", True),
                                           ("linear+huber(0.05)", False), ("relative", True)])
def test_block_sums_match_dense_jacobian(model_name, free, x0, local, loss, batched):
    """Both programs of the field sums (per pair, and the batched Gram matrices that a
    residual linear in the model takes) against the dense Jacobian."""
    prob = _problem(model_name, free, x0, loss=loss)
    assert prob.loss.linear_residual is batched
    for name, want in local.items():
        assert prob.model.param(name).per_channel is want, name
    sel = select(ggx_samples(400), get_loss(loss))
    u = jnp.asarray(RNG.uniform(0.1, 0.9, size=len(free)))  # box coordinates
    got = jax.jit(lambda p, v, d: p.block_sums(v, d))(prob, u, sel.data)
    want = _dense_reference(prob, u, sel.data)
    for g, w in zip(got[:4], want):
        np.testing.assert_allclose(g, w, rtol=1e-10, atol=1e-12 * np.max(np.abs(w)))
    assert got[4][0] == np.count_nonzero(np.asarray(sel.data.sqrt_weight))  # m
    assert float(prob.full_vector(prob.physical(u))[4]) == prob.x_fixed[4]  # the fixed entry


def test_tables_built_once_per_pass_give_the_same_jacobian():
    """``gtr`` declares ``per_pass`` (its numerical-Λ table, built from ``α`` and ``γ`` only):
    the fitter builds the table and its tangents once per pass and the blocks use them. The
    model split is exact (``apply(p, build(p)) == fn(p)``), and the sums equal the dense
    Jacobian of the model as one function, the table's tangents included (``γ`` reaches the
    residual only through ``D`` and the table)."""
    model = brdffit.get_model("gtr")
    split = model.per_pass
    assert set(split.uses) == {"alpha", "gamma"}
    s = ggx_samples(300)
    p = {k: jnp.asarray(v) for k, v in model.complete({"alpha": 0.3, "gamma": 1.4}).items()}
    wi, wo = jnp.asarray(s.wi), jnp.asarray(s.wo)
    np.testing.assert_array_equal(np.asarray(split.apply(p, split.build(p), wi, wo)),
                                  np.asarray(model.fn(p, wi, wo)))
    free = (0, 1, 2, 3, 5, 6, 7, 8)  # f0[1] fixed
    prob = _problem("gtr", free, {"diffuse": [0.3, 0.2, 0.1], "f0": [0.1, 0.2, 0.3], "alpha": 0.2,
                                  "gamma": 1.5, "grazing": 0.7})
    sel = select(ggx_samples(400), get_loss("log"))
    u = jnp.asarray(RNG.uniform(0.1, 0.9, size=len(free)))
    got = jax.jit(lambda q, v, d: q.block_sums(v, d, q.pass_tables(v)))(prob, u, sel.data)
    want = _dense_reference(prob, u, sel.data)
    for g, w in zip(got[:4], want):
        np.testing.assert_allclose(g, w, rtol=1e-10, atol=1e-12 * np.max(np.abs(w)))
    assert brdffit.get_model("ggx").per_pass is None
    assert jax.jit(lambda q, v: q.pass_tables(v))(_problem("ggx", (6,), {}), u[:1]) is None


# -- data selection ---------------------------------------------------------------------------
def test_select_masks_cutoff_and_subsample():
    s = ggx_samples(4000)
    s.rgb[0] = np.nan
    s.rgb[1, 2] = -1.0
    s.valid[2] = False
    sel = select(s, get_loss("log"))
    assert sel.n_used == 4000 - 3 and sel.n_usable == 4000
    w = np.asarray(sel.data.sqrt_weight)
    assert np.all(w[:3] == 0) and np.all(np.isfinite(np.asarray(sel.data.target)))
    theta = np.degrees(np.arccos(np.minimum(s.wi[:, 2], s.wo[:, 2])))
    cut = select(s, get_loss("log"), cutoff=60)
    assert cut.n_usable == np.count_nonzero(theta <= 60)
    sub = select(s, get_loss("log"), subsample=Subsample(500, "stratified"), seed=3)
    assert len(sub.index) == 500 and sub.n_used <= 500
    again = select(s, get_loss("log"), subsample=0.125, seed=3)
    assert len(again.index) == 500
    assert not np.array_equal(select(s, get_loss("log"), subsample=500, seed=4).index, again.index)


@pytest.mark.parametrize("loss", ["log", "linear", "cosine"])
def test_cost_floor_adds_the_cost_of_the_values_storage_rounding(loss):
    """``F_d = ½ Σ (w (g(ρ(1 + ε_d)) − g(ρ)))²``, a NumPy transcription against the floor with
    and without ``value_epsilon``; masked cells add nothing, and float64 storage (ε_d = 0)
    leaves the floor as it was."""
    from brdffit.fitting.solve import cost_floor

    s = ggx_samples(500)
    s.valid[:7] = False
    eps = float(np.finfo(np.float32).eps)
    with jax.enable_x64(True):
        problem = _problem("ggx", (0, 3, 6), {}, loss=loss)
        plain = select(s, get_loss(loss))
        stored = select(dataclasses.replace(s, value_epsilon=eps), get_loss(loss))
        floors = [float(cost_floor(problem, sel.data)) for sel in (plain, stored)]
    assert plain.data.value_epsilon == 0.0 and stored.data.value_epsilon == eps
    g, w = NUMPY_LOSSES[loss], np.asarray(stored.data.sqrt_weight)
    rgb, ci, co = (np.asarray(a) for a in (stored.data.rgb, stored.data.wi[:, 2:3],
                                           stored.data.wo[:, 2:3]))
    r = w * (g(rgb * (1 + eps), 0.0, ci, co) - g(rgb, 0.0, ci, co)) if loss != "log" else (
        w * (np.log1p(rgb * (1 + eps) * ci) - np.log1p(rgb * ci)))
    assert floors[1] == pytest.approx(floors[0] + 0.5 * np.sum(r[w > 0] ** 2), rel=1e-6)
    assert 0.5 * np.sum(r[w > 0] ** 2) > floors[0]  # float32 storage outweighs the compute


def test_sample_set_value_epsilon_is_checked():
    s = ggx_samples(10)
    for bad in (-1e-7, 1.0, float("nan")):
        with pytest.raises(ValueError, match="value_epsilon"):
            dataclasses.replace(s, value_epsilon=bad)


def test_select_pads_to_whole_blocks_with_zero_weight():
    n = CHUNK_CELLS + 10
    wi = np.tile([[0.0, 0.6, 0.8]], (n, 1))
    s = SampleSet(wi, wi.copy(), np.full((n, 3), 0.2), np.ones(n, bool))
    sel = select(s, get_loss("log"))
    assert sel.chunks == 2 and sel.data.wi.shape == (2 * CHUNK_CELLS, 3)
    w = np.asarray(sel.data.sqrt_weight)
    pad = np.all(w == 0, axis=1)
    assert np.count_nonzero(pad) == 2 * CHUNK_CELLS - n and sel.n_used == n
    assert np.all(np.asarray(sel.data.wi)[pad] == [0.0, 0.0, 1.0])  # padding: normal incidence
    # interleaved: block j holds rows j, j + 2, ... of the padded selection (padding rows last)
    order = np.arange(2 * CHUNK_CELLS).reshape(-1, 2).T.ravel()
    np.testing.assert_array_equal(pad, order >= n)


@pytest.mark.parametrize("chunks", [1, 2, 5, 8, 34, 272])
def test_block_order_spreads_every_leading_subset(chunks):
    """The first m blocks' row offsets are a permutation prefix spread over [0, chunks): no gap
    between neighbouring offsets (cyclically) wider than 2 chunks / m."""
    order = block_order(chunks)
    assert sorted(order) == list(range(chunks)) and order[0] == 0
    for m in range(1, chunks + 1):
        offs = np.sort(order[:m])
        gaps = np.diff(np.concatenate([offs, [offs[0] + chunks]]))
        assert gaps.max() <= max(1, 2 * chunks / m), (m, offs)


def test_select_interleaves_blocks_in_block_order():
    n = 5 * CHUNK_CELLS
    wi = np.tile([[0.0, 0.6, 0.8]], (n, 1))
    rgb = np.arange(n, dtype=float)[:, None].repeat(3, 1) * 1e-6  # a row's value is its index
    sel = select(SampleSet(wi, wi.copy(), rgb, np.ones(n, bool)), get_loss("log"))
    rows = np.rint(np.asarray(sel.data.rgb)[:, 0] * 1e6).astype(int).reshape(5, -1)
    for b, k in enumerate(block_order(5)):
        np.testing.assert_array_equal(rows[b], np.arange(k, n, 5))


def test_tables_of_one_layout_share_their_selected_directions():
    """Every MERL table of a grid has the same (read-only, cached) cell directions, so the rows
    and the laid-out directions of the last selection are reused: the next table of the layout
    gives exactly the data a fresh selection gives, the directions are the same device arrays,
    and other options, another grid, or writable directions are selected anew."""
    from brdffit.fitting import data as fit_data
    from data_formats.merl import synthesize

    shape = (16, 16, 32)  # 8,192 cells: two blocks
    a = synthesize(lambda wi, wo: 0.1 + wi[..., 2:] * wo[..., 2:], shape=shape)
    b = synthesize(lambda wi, wo: 0.3 + 0.0 * wi, shape=shape)
    loss = get_loss("log")
    first, second = select(a.to_samples(), loss), select(b.to_samples(), loss)
    assert second.data.wi is first.data.wi and second.data.wo is first.data.wo
    fit_data._memo_directions.cache_clear()
    fresh = select(b.to_samples(), loss)
    assert fresh.data.wi is not first.data.wi
    for got, want in zip(jax.tree.leaves(second.data), jax.tree.leaves(fresh.data)):
        np.testing.assert_array_equal(np.asarray(got), np.asarray(want))
    np.testing.assert_array_equal(second.index, fresh.index)
    assert select(b.to_samples(), loss, cutoff=60).data.wi is not fresh.data.wi
    assert select(b.to_samples(), loss, subsample=500).data.wi.shape[0] == 500
    with jax.enable_x64(False), warnings.catch_warnings():  # the dtype JAX makes is in the key
        warnings.simplefilter("ignore", UserWarning)  # "float64 ... truncated to float32"
        assert select(b.to_samples(), loss).data.wi.dtype == np.float32
    s = b.to_samples()
    writable = dataclasses.replace(s, wi=np.array(s.wi), wo=np.array(s.wo))
    once, twice = select(writable, loss), select(writable, loss)
    assert once.data.wi is not twice.data.wi  # a sample list's directions can change in place


def test_select_weights_each_residual_by_its_samples_share_of_the_angles():
    """``weighting="angles"`` multiplies a residual by ``sqrt(SampleSet.weight)`` of its row,
    scaled to mean 1 over the cells used (rows kept by a cutoff keep their own weights);
    ``"samples"`` and data with ``σ`` (χ² terms) do not reweight; an unknown weighting is
    refused."""
    s = ggx_samples(3000)
    w = RNG.uniform(0.0, 3.0, 3000)
    weighted = dataclasses.replace(s, weight=w)
    loss = get_loss("log")
    plain = np.asarray(select(s, loss).data.sqrt_weight)[:3000]
    got = np.asarray(select(weighted, loss).data.sqrt_weight)[:3000]
    np.testing.assert_allclose(got, plain * np.sqrt(w / w.mean())[:, None], rtol=1e-14)
    cut = select(weighted, loss, cutoff=60)  # scaled to mean 1 over the cells kept
    k, kept = len(cut.index), w[cut.index]
    np.testing.assert_allclose(np.asarray(cut.data.sqrt_weight)[:k],
                               plain[cut.index] * np.sqrt(kept / kept.mean())[:, None], rtol=1e-14)
    same = np.asarray(select(weighted, loss, weighting="samples").data.sqrt_weight)[:3000]
    np.testing.assert_array_equal(same, plain)
    sigma = np.full((3000, 3), 0.01)
    np.testing.assert_array_equal(
        np.asarray(select(dataclasses.replace(weighted, sigma=sigma), loss).data.sqrt_weight),
        np.asarray(select(dataclasses.replace(s, sigma=sigma), loss).data.sqrt_weight))
    with pytest.raises(UnknownNameError, match="samples"):
        select(weighted, loss, weighting="angle")
    with pytest.raises(ConfigError, match="every usable sample has weight 0"):
        select(dataclasses.replace(s, weight=np.zeros(3000)), loss)
    with pytest.raises(UnknownNameError, match="angles"):
        brdffit.fit(weighted, "ggx", weighting="solid")


def test_select_option_errors():
    s = ggx_samples(100)
    with pytest.raises(ConfigError, match="cutoff"):  # the one check of the options
        brdffit.fit(s, "ggx", cutoff=120)
    with pytest.raises(ConfigError, match="fraction"):
        select(s, get_loss("log"), subsample=1.5)
    with pytest.raises(ConfigError, match="stratified"):
        select(s, get_loss("log"), subsample=Subsample(10, "every-other"))


# -- fit errors -------------------------------------------------------------------------------
def test_too_few_valid_cells_is_a_clear_error():
    s = ggx_samples(2000)
    s.valid[10:] = False
    with pytest.raises(FitError, match=r"10 usable valid cells out of 2000.*needs at least 24"):
        brdffit.fit(s, "ggx", cutoff=90)  # every cell above the horizon
    s = ggx_samples(2000)
    s.rgb[:] = np.nan
    with pytest.raises(FitError, match="NaNs"):
        brdffit.fit(s, "ggx")


@pytest.mark.parametrize("solver", sorted(SOLVERS))
def test_every_registered_solver_recovers_a_ggx_fit(solver):
    """Each entry of the solver registry, made bounded, fits exact GGX data back to their
    parameters, converged by the optimality test; the name is taken in any case."""
    truth = {"alpha": 0.2, "f0": 0.5, "diffuse": 0.1}
    r = brdffit.fit(ggx_samples(1500, truth), "ggx", solver=solver.upper(), multistart=0,
                    init={"alpha": 0.3, "f0": 0.3, "diffuse": 0.2})
    assert r.success and r.status == "successful", (solver, r.status, r.message)
    assert r.provenance["options"]["solver"].lower() == solver
    for name, value in truth.items():
        np.testing.assert_allclose(np.asarray(r.params[name]), value, rtol=1e-5, atol=1e-7)


def test_option_errors_name_the_choices():
    s = ggx_samples(300)
    with pytest.raises(UnknownNameError, match="dogleg"):
        brdffit.fit(s, "ggx", solver="newton")
    with pytest.raises(UnknownNameError, match="alpha"):
        brdffit.fit(s, "ggx", fixed={"roughness": 0.1})
    with pytest.raises(ConfigError, match=r"outside its bounds \[0.001, 1\]"):
        brdffit.fit(s, "ggx", fixed={"alpha": 2.0})
    with pytest.raises(ConfigError, match="lower bound must be > 0"):
        brdffit.fit(s, "ggx", bounds={"alpha": (0.0, 0.5)})
    with pytest.raises(FitError, match="nothing to fit"):
        brdffit.fit(s, "ggx", fixed={"diffuse": 0.1, "f0": 0.1, "alpha": 0.1, "grazing": 1.0})
    with pytest.raises(UnknownNameError, match="sandwich"):
        brdffit.fit(s, "ggx", covariance="hessian")


# -- the result -------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def small_fit():
    s = ggx_samples(3000, {"diffuse": [0.3, 0.2, 0.1], "f0": [0.9, 0.6, 0.4], "alpha": 0.2},
                    noise=0.02)
    events = []
    # energy="free": this lobe beside this diffuse reflects 1.3 at grazing incidence, and the
    # constrained solve's step events would carry its penalty besides the data's cost
    res = brdffit.fit(s, "ggx", fixed={"f0[2]": 0.4}, energy="free",
                      progress=lambda e, i: events.append((e, i)))
    return s, res, events


def test_result_fields_progress_and_fixed(small_fit):
    s, res, events = small_fit
    assert res.success and res.status == "successful" and res.steps > 0
    assert res.params["f0"][2] == 0.4 and res.fixed == ["f0[2]"] and "f0[2]" not in res.free
    assert res.stderr["f0"][2] == 0 and res.stderr["alpha"] > 0
    kinds = [e for e, _ in events]
    assert kinds[0] == "setup" and "step" in kinds and kinds[-1] == "done"
    steps = [i["cost"] for e, i in events if e == "step"]  # the last stage: the whole table
    assert steps[-1] == pytest.approx(res.cost, rel=1e-6)
    scan = [i["cost"] for e, i in events if e == "scan-step"]  # the start scan (same cells here)
    assert scan[0] > steps[-1] and min(scan) >= steps[-1] * (1 - 1e-9)
    # the default cells: θi, θo ≤ 80° (brdffit.config.DEFAULT_CUTOFF)
    used = np.minimum(s.wi[:, 2], s.wo[:, 2]) >= np.cos(np.radians(80))
    assert res.n_cells == int(used.sum()) < len(s.wi)
    wi, wo, rgb = s.wi[used], s.wo[used], s.rgb[used]
    pred = np.asarray(res.model(wi, wo))
    np.testing.assert_allclose(res.metrics["rel_error"],
                               np.mean(np.abs(pred - rgb) / np.maximum(rgb, 1e-3)), rtol=1e-9)
    # the error figures come from the solver's own last pass: they belong to the reported point
    ci = wi[:, 2:3]
    dlog = np.log1p(pred * ci) - np.log1p(rgb * ci)
    assert res.cost == pytest.approx(0.5 * np.sum(dlog**2), rel=1e-9)
    assert res.metrics["rmse_log"] == pytest.approx(np.sqrt(np.mean(dlog**2)), rel=1e-9)
    dcos = (pred - rgb) * ci * wo[:, 2:3]
    assert res.metrics["rmse_cosine"] == pytest.approx(np.sqrt(np.mean(dcos**2)), rel=1e-9)
    assert "alpha" in res.summary() and "(fixed)" in res.summary()


def test_two_fits_in_two_threads_each_get_only_their_own_events():
    """Step events come from inside the compiled solve (``jax.debug.callback``, possibly on
    another thread); each must still reach the callback of the fit that made it."""
    import threading

    tables = [ggx_samples(3000, {"alpha": 0.15}, seed=5, name="a"),
              ggx_samples(3000, {"alpha": 0.4, "f0": [0.3, 0.2, 0.1]}, seed=6, name="b")]

    def run(table, events, barrier=None):
        if barrier is not None:
            barrier.wait()
        return brdffit.fit(table, "ggx", progress=lambda e, i: events.append((e, i)))

    alone = []
    for table in tables:
        alone.append([])
        run(table, alone[-1])
    together = [[], []]
    barrier = threading.Barrier(2)
    threads = [threading.Thread(target=run, args=(t, ev, barrier)) for t, ev in zip(tables, together)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for solo, both in zip(alone, together):
        assert sum(e.endswith("step") for e, _ in solo) > 3
        assert both == solo  # the same events, in the same order, none of the other fit's


def test_result_json_round_trip(small_fit, tmp_path):
    _, res, _ = small_fit
    res.stderr["alpha"] = float("nan")  # NaNs (at-bound scalars) must survive as null
    text = res.to_json(tmp_path / "r.json")
    assert "NaN" not in text and json.loads(text)["stderr"]["alpha"] is None
    back = FitResult.from_json(tmp_path / "r.json")
    assert back.params == res.params and np.isnan(back.stderr["alpha"])
    np.testing.assert_array_equal(back.cov, res.cov)
    np.testing.assert_array_equal(back.x, res.x)
    assert back.to_dict().keys() == res.to_dict().keys()
    assert FitResult.from_json(text).summary() == res.summary()


def test_non_convergence_throws_or_reports():
    s = ggx_samples(1000)
    with pytest.raises(FitError, match="did not converge.*max_steps"):
        brdffit.fit(s, "ggx", max_steps=2)
    res = brdffit.fit(s, "ggx", max_steps=2, throw=False)
    assert not res.success and res.status == "nonlinear_max_steps_reached"
    assert "max_steps" in res.message and np.all(np.isfinite(res.x))


def test_render_merl_fills_the_grid_with_the_fitted_model(small_fit, tmp_path):
    from data_formats.merl import cell_directions, read_merl, write_merl

    _, res, _ = small_fit
    shape = (9, 9, 18)
    table = res.render_merl(shape=shape)
    wi, wo = cell_directions(shape)
    model = brdffit.get_model("ggx")
    p = {k: jnp.asarray(v) for k, v in res.params.items()}
    expected = np.asarray(_GGX(p, wi.reshape(-1, 3), wo.reshape(-1, 3))).reshape(*shape, 3)
    ok = table.valid
    assert table.shape == shape and 0.5 < ok.mean() < 1.0  # cells below the horizon are missing
    np.testing.assert_allclose(table.rgb[ok], expected[ok], rtol=1e-12)
    write_merl(tmp_path / "fit.binary", table)
    np.testing.assert_array_equal(read_merl(tmp_path / "fit.binary").rgb, table.rgb)
    assert model.name == res.model.name


class _Round(eqx.Module):
    """What the scripted solves of the round tests return for one round (``JᵀJ`` large by
    default: a move of 0.01 changes the predictions far more than ``ftol`` of the cost)."""

    z: np.ndarray
    steps: np.ndarray
    cost: np.ndarray
    step_size: np.ndarray
    ran_out: bool = eqx.field(static=True)
    finite: bool = eqx.field(static=True)
    jtj: np.ndarray = eqx.field(default_factory=lambda: np.eye(2) * 1e6)
    still: bool = False


def _scripted_solve(monkeypatch, script, rounds, z_start, newton):
    """Run ``Run.solve`` over scripted rounds (``(moved, step size at the round's end)``);
    returns ``(seen, out)``, ``seen`` the (initial step size, Newton's model?, start point) of
    each round."""
    from brdffit.fitting import stages
    from brdffit.fitting.bounded import make_solver
    from brdffit.fitting.events import Events

    script, seen = iter(script), []

    def scripted_solve(problem, solver, z0, data, floor, steps, active, second):
        seen.append((float(solver.inner.search.initial_step_size), second is not None,
                     np.asarray(z0).copy()))
        moved, size = next(script)
        z = np.asarray(z0) + (0.01 if moved else 0.0)
        return _Round(z, np.asarray(steps), np.asarray(1.0), np.asarray(size), True, True)

    monkeypatch.setattr(stages, "solve", scripted_solve)
    monkeypatch.setattr(stages, "second_order", lambda *args: np.zeros((2, 2)))
    problem = dataclasses.make_dataclass("P", [("chunks", int)])(chunks=4)
    run = stages.Run(problem, None, 0.0, rounds * stages.ROUND_STEPS, Events())
    return seen, run.solve(make_solver("lm", 1e-8, 1e-8), z_start, active=4, newton=newton)


def test_a_round_that_accepts_no_step_keeps_the_other_models_trust_region(monkeypatch):
    """Rounds alternate between Newton's and Gauss–Newton's model. A Newton round whose every
    trial point was rejected (a wrong second-order term) shrank the trust region on its own
    model's account: the Gauss–Newton round after it starts from the region the failed round
    started with, not from the shrunken one. A round that moved hands on its own region."""
    from brdffit.fitting import stages

    z_start = np.array([0.3, 0.4])
    script = [  # (moved, step size at the round's end) of rounds 1, 2, 3 ...
        (True, 50.0),   # Newton: moved, region 100 -> 50
        (True, 7.0),    # Gauss-Newton: moved, 50 -> 7
        (False, 1e-6),  # Newton: every trial rejected, 7 -> 1e-6
        (True, 30.0),   # Gauss-Newton: must start from 7
        (False, 2e-5),  # Newton: rejected again
        (True, 40.0),   # Gauss-Newton: must start from 30
    ]
    seen, out = _scripted_solve(monkeypatch, script, 6, z_start, newton=True)

    sizes = [size for size, _, _ in seen]
    assert sizes == [100.0, 50.0, 7.0, 7.0, 30.0, 30.0]
    assert [newton for _, newton, _ in seen] == [True, False] * 3
    # The round after a rejected one starts where the rejected one did.
    np.testing.assert_array_equal(seen[3][2], seen[2][2])
    assert int(out.steps) == 6 * stages.ROUND_STEPS

    # Gauss-Newton alone: a round without progress hands on its shrunken region (the same
    # model would otherwise repeat the same rejections).
    seen, _ = _scripted_solve(monkeypatch, [(False, 1e-3), (True, 5.0)], 2, z_start,
                              newton=False)
    assert [size for size, _, _ in seen] == [100.0, 1e-3]


def test_rounds_in_a_row_that_accept_no_step_hand_on_the_shrunken_region(monkeypatch):
    """Two rounds in a row without an accepted step (Newton's model, then Gauss–Newton's, from
    the same point): neither model is at fault alone, and each round restarting from the same
    region would repeat the same rejections until the step limit (``sgd`` under
    ``bagher2012`` on beige-fabric: 200 steps at one cost). From the second such round on,
    the next round starts from the region the last one shrank; a round that moves resets
    the count."""
    script = [  # (moved, step size at the round's end)
        (True, 50.0),   # Newton: moved
        (False, 2e-4),  # Gauss-Newton: rejected; Newton next starts from 50
        (False, 1e-5),  # Newton: rejected too: hand on 1e-5
        (False, 3e-7),  # Gauss-Newton: rejected again: hand on 3e-7
        (True, 20.0),   # Newton: moved
        (False, 1e-3),  # Gauss-Newton: rejected once: Newton starts from 20
        (True, 9.0),
    ]
    seen, _ = _scripted_solve(monkeypatch, script, 7, np.array([0.3, 0.4]), newton=True)
    np.testing.assert_allclose([size for size, _, _ in seen],
                               [100.0, 50.0, 50.0, 1e-5, 3e-7, 20.0, 20.0])


def test_rounds_that_leave_the_fit_where_it_was_end_the_solve_converged(monkeypatch):
    """A solve whose rounds run out of steps ends, converged, after two rounds in a row that
    each accepted steps but lowered the cost by less than ``STILL_RATE · ftol`` of itself per
    step and moved the predictions (``½ ΔzᵀJᵀJΔz``) by less than ``ftol`` of the cost; the
    first round (no cost at its start), a round that moved the cost or the predictions, and a
    round that accepted no step each restart the count. The verdict is success with status
    ``still`` and the optimality ω in its message."""
    from brdffit.fitting import outcome, stages
    from brdffit.fitting.bounded import make_solver
    from brdffit.fitting.events import Events

    F, n = 1000.0, stages.ROUND_STEPS
    allowed = n * stages.STILL_RATE * 1e-9 * F  # the cost's fall a round may have: 1e-4
    script = iter([  # (dz, cost at the round's end, JᵀJ scale)
        (1e-3, F, 1.0),                     # 1: the first round never counts
        (1e-3, F, 1.0),                     # 2: calm (½ dz² · 2 = 1e-6 = 1e-9 F)
        (1e-3, F - 2 * allowed, 1.0),       # 3: the cost fell too much: not calm
        (1e-3, F - 2 * allowed, 1e4),       # 4: the predictions moved: not calm
        (0.0, F - 2 * allowed, 1.0),        # 5: no step accepted: not calm
        (1e-3, F - 2.9 * allowed, 1.0),     # 6: calm
        (1e-3, F - 3.8 * allowed, 1.0),     # 7: calm again: converged
        (1e-3, F, 1.0),
    ])
    rounds = []

    def scripted_solve(problem, solver, z0, data, floor, steps, active, second):
        dz, cost, scale = next(script)
        rounds.append(dz)
        z = np.asarray(z0) + np.array([dz, 0.0])
        return _Round(z, np.asarray(steps), np.asarray(cost), np.asarray(1.0), True, True,
                      jtj=np.eye(2) * scale)

    monkeypatch.setattr(stages, "solve", scripted_solve)
    monkeypatch.setattr(stages, "second_order", lambda *args: np.zeros((2, 2)))
    problem = dataclasses.make_dataclass("P", [("chunks", int)])(chunks=4)
    run = stages.Run(problem, None, 0.0, 20 * stages.ROUND_STEPS, Events())
    out = run.solve(make_solver("lm", 1e-8, 1e-8, ftol=1e-9), np.array([0.3, 0.4]), active=4,
                    newton=True)
    assert len(rounds) == 7 and out.still and int(out.steps) == 7 * stages.ROUND_STEPS

    # the stillness test itself, in the units of the data
    end = _Round(np.array([0.301, 0.4]), np.asarray(10), np.asarray(F), np.asarray(1.0), True,
                 True, jtj=np.eye(2))
    z0 = np.array([0.3, 0.4])
    assert stages.still(z0, F * (1 + 0.9e-7), end, 0.0, 1e-9)  # 10 steps of 0.9e-8 F each
    assert not stages.still(z0, F * (1 + 1.1e-7), end, 0.0, 1e-9)  # 1.1e-8 F a step
    assert not stages.still(z0 - 1e-3, F, end, 0.0, 1e-9)  # ½ · 4e-6 > 1e-9 F
    assert stages.still(z0 - 1e-3, F, end, 3 * F, 1e-9)  # the floor counts in F

    # a solve that ran out of steps, marked still: success, status "still", ω reported
    from brdffit.fitting.solve import Solved

    marked = Solved(z=z0, result=optx.RESULTS.nonlinear_max_steps_reached, steps=np.asarray(70),
                    cost=np.asarray(F), omega=np.asarray(3e-7),
                    gn=(np.eye(2), np.zeros(2), np.asarray(F)), jtj=np.eye(2), meat=np.eye(2),
                    dxdz=np.ones(2), metrics={}, m=np.asarray(100), step_size=np.asarray(1.0),
                    still=True)
    v = outcome.verdict(marked, 1e-9)
    assert v.success and v.status == "still" and "stillness test" in v.message and "3e-07" in v.message
    assert marked.converged(1e-9) and not eqx.tree_at(lambda s: s.still, marked, False).converged(1e-9)


def test_the_optimality_test_leaves_out_the_scalars_the_data_do_not_identify():
    """At an exact fit (cost 1e-12) a direction the cost barely depends on (``JᵀJ`` 1e-20,
    gradient 1e-16) promises a decrease of up to ``g²/(2 JᵀJ)`` = 5e-13, half the cost (``ω``
    4e-5 with the ridge that bounds the step): over all the scalars the fit is stalled; over the identified one it has converged, and the verdict
    says so. With nothing lost, or everything, the test over all of them decides."""
    from brdffit.fitting import outcome
    from brdffit.fitting.solve import Solved

    jtj, g, cost = np.diag([1.0, 1e-20]), np.array([1e-14, 1e-16]), np.asarray(1e-12)
    z = np.array([0.3, 0.4])
    omega = float(optimality(jnp.asarray(jtj), jnp.asarray(g), jnp.asarray(cost),
                             jnp.asarray(z))[0])
    best = Solved(z=z, result=optx.RESULTS.successful, steps=np.asarray(9), cost=cost,
                  omega=np.asarray(omega), gn=(jtj, g, cost), jtj=jtj, meat=jtj,
                  dxdz=np.ones(2), metrics={}, m=np.asarray(100), step_size=np.asarray(1.0))
    assert omega > 1e-5 and best.omega_over([True, False]) < 1e-9
    assert outcome.verdict(best, 1e-9).status == "stalled"
    for lost in ([False, False], [True, True]):
        assert outcome.verdict(best, 1e-9, np.array(lost)).status == "stalled"
    v = outcome.verdict(best, 1e-9, np.array([False, True]))
    assert v.success and v.status == "successful" and "identify" in v.message


def test_the_scan_shifts_the_lobe_widths_only():
    """``mitsuba-principled`` fits ``base_color`` in log space (its tint is steep near the
    bound) but the start scan shifts only the lobe width ``roughness``, ×8 and ÷8 within its
    box; ``ggx`` scans ``alpha``. A scanned parameter must be log-scaled."""
    from brdffit.fitting import stages
    from brdffit.fitting.parameters import free_scalars
    from brdffit.models.registry import Param

    model = brdffit.get_model("mitsuba-principled")
    assert model.param("base_color").log and not model.param("base_color").scanned
    assert model.param("roughness").scanned
    scalars, x0 = free_scalars(model, None, None)
    prob = Problem.build(scalars, get_loss("log"), x0, "float64", 1)
    z0 = scalars.to_box(x0)
    base, low, high = stages.candidates(prob, z0)
    moved = np.flatnonzero(np.abs(low - base) > 0)
    assert len(moved) == 1  # roughness alone
    i = moved[0]
    x = lambda z: prob.flat_host(z)[list(prob.free)][i]
    np.testing.assert_allclose([x(low), x(high)], [x(base) / 8, min(x(base) * 8, 1.0)],
                               rtol=1e-12)  # clamped to the box
    assert np.sum(stages.scanned(_problem("ggx", (0, 1, 2, 3, 4, 5, 6, 7), {}))) == 1
    with pytest.raises(ValueError, match="only a log-scaled parameter"):
        Param("w", (), 0.0, 1.0, 0.5, "a width", scan=True)
