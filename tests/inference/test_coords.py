"""The one coordinate system of jaxppo's posteriors (``_coords``): the
prior density in u integrates to one (the maps' Jacobians are right), the
stellar-density tie sets every free a/R* by Kepler's third law, and the
transit posterior of the marginal scan and ``sample`` evaluate the same
prior."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import quad

import jaxppo as jp
from jaxppo.inference._coords import Coordinates, a_from_density, default_priors, density_from_a, start_q
from jaxppo.inference._model import Model


@pytest.fixture(scope="module")
def two_planets():
    truth = jp.kepler20_system()
    lc = jp.simulate_kepler20(seed=3, noise=4e-4)
    b = truth.planets[0]
    near = np.abs(((lc.time - float(b.t0)) / float(b.period) + 0.5) % 1 - 0.5) * float(b.period) < 0.3
    return truth, lc.select(near & (np.cumsum(near) <= 200))


@pytest.mark.parametrize("name", ["b.t0", "b.period", "b.radius", "b.inc", "b.a"])
def test_each_prior_integrates_to_one_in_u(two_planets, name):
    """int exp(log_prior(u)) du = 1 for each coordinate alone (numerical
    quadrature over u): the prior's density times |dq/du|, the folded
    impact parameter's two branches and a's logistic map included."""
    truth, lc = two_planets
    model = Model(truth, lc, (name,))
    coords = Coordinates(model, default_priors(model))
    f = jax.jit(lambda u: jnp.exp(coords.log_prior(jnp.atleast_1d(u))))
    total, err = quad(lambda u: float(f(u)), -60.0, 60.0, limit=400, points=[0.0])
    assert total == pytest.approx(1.0, abs=1e-6), (total, err)


def test_density_coordinate_integrates_to_one_and_ties_a(two_planets):
    """With a density prior, u holds log rho* in place of both a/R*: its
    prior (truncated Gaussian in rho*, Jacobian rho*) integrates to one over
    log rho*, and each a/R* is (G rho* P^2 / 3 pi)^(1/3)."""
    truth, lc = two_planets
    model = Model(truth, lc, ("b.a", "c.a", "b.t0"))
    coords = Coordinates(model, default_priors(model), density=(1.5, 0.2))
    assert coords.coords == [(0, "t0"), ("star", "density")] and coords.tied == [0, 1]
    q0 = start_q(model, truth)
    u = coords.from_q(q0, rho=1.7)
    q = np.asarray(coords.to_q(u))
    for k, pl in ((0, truth.planets[0]), (1, truth.planets[1])):
        assert q[k] == pytest.approx(a_from_density(1.7, float(pl.period)), rel=1e-12)
        assert density_from_a(q[k], float(pl.period)) == pytest.approx(1.7, rel=1e-12)
    assert q[2] == pytest.approx(q0[2], rel=1e-12)
    # the prior factorises into t0's and rho*'s: (int over log rho* at a
    # fixed t0) x (int over t0 at a fixed rho*) / (the density at both) = 1
    lp = jax.jit(lambda x, v: coords.log_prior(jnp.asarray([x, v])))
    x0, v0 = float(u[0]), float(np.log(1.5))
    over_rho, _ = quad(lambda v: float(jnp.exp(lp(x0, v))), np.log(1e-3), np.log(10.0), limit=200)
    over_t0, _ = quad(lambda x: float(jnp.exp(lp(x, v0))), -60.0, 60.0, limit=400, points=[0.0])
    assert over_rho * over_t0 / float(jnp.exp(lp(x0, v0))) == pytest.approx(1.0, abs=1e-6)


def test_the_transit_posterior_uses_samples_prior(two_planets):
    """TransitPosterior.log_density = -chi^2 / 2 + Coordinates.log_prior:
    the same prior ``sample`` adds to its likelihood, at every u."""
    from jaxppo.inference._posterior import TransitPosterior

    truth, lc = two_planets
    free = ("b.t0", "b.radius", "b.inc", "b.a", "c.t0")
    post = TransitPosterior(truth, lc, free, (1.5, 0.15), 0.0, "same")
    model = Model(truth, lc, free)
    coords = Coordinates(model, default_priors(model), density=(1.5, 0.15))
    assert post.coords == coords.coords
    rng = np.random.default_rng(0)
    for _ in range(3):
        u = post.u_start + 0.1 * rng.standard_normal(len(post.coords))
        chi2 = float(jnp.sum(post.data_residuals(jnp.asarray(u)) ** 2))
        assert float(post.log_density(jnp.asarray(u))) == pytest.approx(
            -0.5 * chi2 + float(coords.log_prior(jnp.asarray(u))), rel=1e-12)


def test_model_is_an_immutable_module(two_planets):
    """Model is an eqx.Module: attributes cannot be set, ``with_frames``
    returns a new Model (the old one's frames and data untouched), and a
    bound method jits like a plain one."""
    import dataclasses

    import equinox as eqx

    truth, lc = two_planets
    model = Model(truth, lc, ("b.t0", "b.radius"))
    assert isinstance(model, eqx.Module)
    with pytest.raises(dataclasses.FrozenInstanceError):
        model.alpha = 10.0
    union0, data0 = model.union_idx.copy(), model.data()
    extra = model.active_idx[:3]
    wider = model.with_frames(union=extra)
    assert np.array_equal(model.union_idx, union0) and model.data() is data0
    assert np.all(np.isin(extra, wider.union_idx)) and wider.data() is not data0
    theta = model.to_theta(truth)
    # no two disks touch in those frames: the union integral gives the one-disk sums
    np.testing.assert_allclose(np.asarray(jax.jit(wider.residuals)(theta)), np.asarray(model.residuals(theta)),
                               rtol=0, atol=1e-9)


def test_the_t14_coordinate_prior_integrates_to_one(two_planets):
    """a and inc free: u places log T14 in place of a, whose map covers a
    in (1 + p, 4 a_start); the prior there integrates to one over that
    coordinate at a fixed impact parameter (it lacked p / (4 a - 1) before,
    which also tilted p's prior; found in review)."""
    truth, lc = two_planets
    model = Model(truth, lc, ("b.a", "b.inc", "b.radius"))
    coords = Coordinates(model, default_priors(model))
    assert coords.duration == {0}
    alone = Model(truth, lc, ("b.inc", "b.radius"))
    inc_p = Coordinates(alone, default_priors(alone))
    u0 = coords.from_q(start_q(model, truth))
    lp = jax.jit(lambda x: coords.log_prior(jnp.asarray([x, u0[1], u0[2]])))
    over_a, _ = quad(lambda x: float(jnp.exp(lp(x))), -60.0, 60.0, limit=400, points=[0.0])
    rest = float(jnp.exp(inc_p.log_prior(jnp.asarray(u0[1:]))))
    assert over_a / rest == pytest.approx(1.0, abs=1e-7)
