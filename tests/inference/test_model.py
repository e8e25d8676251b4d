"""``jaxppo.inference._model``: the fit's model flux computes the union
integral only in blocks of frames where disks meet, with the values and
derivatives of the union integral on every frame."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxppo as jp
from jaxppo.inference._model import UNION_BLOCK, union_frames
from jaxppo.model._terms import exact_frames, separate_frames


def _ppo_frames():
    """Frames about an injected PPO of Kepler-20 b and c (radii x 2, alpha
    147 deg, case "same"), 1-minute spacing over 0.3 d: some blocks hold
    the overlap, most do not."""
    system = jp.kepler20_system(radius_scale=2.0)
    lc = jp.simulate_kepler20(seed=2021, alpha=147.0, case="same", radius_scale=2.0, noise=2e-4)
    bump = np.abs(np.asarray(system.flux(lc.time, 147.0, case="same")) - np.asarray(system.flux(lc.time, 0.0)))
    t_ppo = float(lc.time[np.argmax(bump)])
    t = jnp.asarray(t_ppo + np.arange(-0.15, 0.15, 1.0 / 1440)[:-3])
    x, y, r = system.positions(t, 147.0, case="same")
    return system.star, x, y, r


def test_union_frames_equal_the_union_integral_on_every_frame():
    star, x, y, r = _ppo_frames()
    exact = np.asarray(exact_frames(star, x, y, r, 24))
    sep = separate_frames(star, x, y, r, 24)
    # the overlap is in the frames: the one-disk sum is wrong there
    assert np.max(np.abs(exact - np.asarray(sep))) > 1e-4
    assert x.shape[0] % UNION_BLOCK != 0  # a padded last block
    got = np.asarray(jax.jit(lambda x, y, r, s: union_frames(star, x, y, r, s))(x, y, r, sep))
    np.testing.assert_allclose(got, exact, rtol=0, atol=1e-15)
    # under vmap (the cond computes both branches) the same
    xs, ys, rs = (jnp.stack([v, v[::-1]]) for v in (x, y, r))
    ss = jnp.stack([sep, sep[::-1]])
    got2 = np.asarray(jax.vmap(lambda x, y, r, s: union_frames(star, x, y, r, s))(xs, ys, rs, ss))
    np.testing.assert_allclose(got2[0], exact, rtol=0, atol=1e-15)
    np.testing.assert_allclose(got2[1], exact[::-1], rtol=0, atol=1e-15)


def test_union_frames_derivatives_equal_the_union_integrals():
    """Forward and reverse derivatives in the planets' x positions."""
    star, x, y, r = _ppo_frames()

    def blocks(x):
        return union_frames(star, x, y, r, separate_frames(star, x, y, r, 24)).sum()

    def whole(x):
        return exact_frames(star, x, y, r, 24).sum()

    want = np.asarray(jax.grad(whole)(x))
    assert np.max(np.abs(want)) > 1e-3
    np.testing.assert_allclose(np.asarray(jax.grad(blocks)(x)), want, rtol=0, atol=1e-12)
    v = jnp.ones_like(x)
    np.testing.assert_allclose(float(jax.jvp(blocks, (x,), (v,))[1]), float(jax.jvp(whole, (x,), (v,))[1]),
                               rtol=1e-12)


def test_physical_jacobian_equals_the_derivatives_of_physical_and_derived():
    """The stored program of the fit's covariance: the values and forward
    derivatives of ``Model.physical`` (then u1, u2 when q1 or q2 is free)
    at a point off the start, for a circular and an eccentric planet."""
    from jaxppo.inference._model import Model

    truth = jp.kepler20_system()
    b, c = truth.planets
    system = truth.replace(star=jp.Star.quadratic(0.45, 0.2), planets=(b, c.replace(e=0.1, omega=40.0)))
    lc = jp.simulate_kepler20(seed=3, noise=4e-4)
    for free in (("b.t0", "b.period", "b.a", "b.inc", "b.radius", "c.inc", "c.radius"),
                 ("b.a", "b.inc", "star.q1", "star.q2")):
        model = Model(system, lc, free)
        theta = model.to_theta(system) + 0.01 * jnp.arange(len(model.free))
        jac, q = (np.asarray(v) for v in model.physical_jacobian(theta))
        k = len(model.free)
        derived = bool(model.derived_names())
        assert q.shape == (k + 2 * derived,) and jac.shape == (q.size, k)
        np.testing.assert_allclose(q[:k], np.asarray(model.physical(theta)), rtol=1e-14, atol=1e-14)
        np.testing.assert_allclose(jac[:k], np.asarray(jax.jacfwd(model.physical)(theta)), rtol=1e-12, atol=1e-14)
        if derived:
            np.testing.assert_allclose(q[k:], np.asarray(model.derived(theta)), rtol=1e-14, atol=1e-14)
            np.testing.assert_allclose(jac[k:], np.asarray(jax.jacfwd(model.derived)(theta)), rtol=1e-12, atol=1e-14)


def test_residuals_batch_stops_at_its_count():
    """The residuals program of a batch computes its first ``count`` rows,
    each equal (bit for bit) to the residuals at that row alone, and
    leaves the padding rows zero; by default every row."""
    from jaxppo.inference._model import Model, residuals

    truth = jp.kepler20_system()
    lc = jp.simulate_kepler20(seed=3, noise=4e-4)
    model = Model(truth, lc, ("b.t0", "b.a", "c.radius"))
    theta = np.asarray(model.to_theta(truth))
    thetas = theta + 1e-3 * np.arange(15.0).reshape(5, 3)
    one = jax.jit(residuals)
    want = np.stack([np.asarray(one(jnp.asarray(t), model.data())) for t in thetas])
    assert np.all(np.any(want[1:] != want[0], axis=1))  # the rows differ
    part = np.asarray(model.residuals_batch(thetas, count=3))
    np.testing.assert_array_equal(part[:3], want[:3])
    assert np.all(part[3:] == 0.0)
    np.testing.assert_array_equal(np.asarray(model.residuals_batch(thetas)), want)
    np.testing.assert_array_equal(np.asarray(model.residuals_batch(thetas, count=np.int64(5))), want)
    for bad in (2.9, True, -1, 6, np.array([2]), "3"):
        with pytest.raises(ValueError, match="count must be a whole number from 0 to the 5 rows"):
            model.residuals_batch(thetas, count=bad)


def test_float64_data_turned_float32_is_an_error(monkeypatch):
    """With JAX's float64 on, a light curve's float64 arrays that come out
    of ``jnp.asarray`` as float32 (JAX 0.10's ``jax.enable_x64`` context in
    another thread does this to ~30 % of a thread's conversions; a fit of
    such data converged "successfully" to another point) stop the Model
    with an error naming the array, not a float32 fit."""
    from jaxppo.inference._model import Model

    truth = jp.kepler20_system()
    lc = jp.simulate_kepler20(seed=3, noise=4e-4)
    real = jnp.asarray
    n = len(lc.flux)

    def leaky(a, *args, **kwargs):
        out = real(a, *args, **kwargs)
        if isinstance(a, np.ndarray) and a.dtype == np.float64 and a.shape == (n,) and not args and not kwargs:
            return out.astype(jnp.float32)
        return out

    monkeypatch.setattr(jnp, "asarray", leaky)
    with pytest.raises(RuntimeError, match=r"light curve's flux \(float64\) became a float32 array"):
        Model(truth, lc, ("b.t0", "b.radius"))
    monkeypatch.undo()
    assert Model(truth, lc, ("b.t0", "b.radius")).data().y.dtype == jnp.float64
