"""Second derivatives at a disk centred on the star (d = 0, b = 0 at
mid-transit): the polar coordinates (d, e) of a centre are singular there,
and guards that give d a zero derivative once made every second derivative
0 (d^2F/dt0^2 at mid-transit 1.891 instead of 1.414 for an inc = 90 orbit).
References: high-order central finite differences of the flux itself."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxppo as jp

STARS = {"quadratic": lambda: jp.Star.quadratic(0.4, 0.25), "kepler20": jp.kepler20_star}


def _fd2(f, x0, h):
    """Second derivative by the 6th-order central difference (error ~h^6 f^(8),
    plus rounding ~eps / h^2)."""
    c = np.array([1 / 90, -3 / 20, 3 / 2, -49 / 18, 3 / 2, -3 / 20, 1 / 90])
    return sum(ci * f(x0 + (i - 3) * h) for i, ci in enumerate(c)) / h**2


@functools.lru_cache(maxsize=None)
def _compiled(law, method):
    """(flux, its Hessian in the centre, its x derivative) of a disk of
    radius p (an argument: both radii below run the same three programs)."""
    star = STARS[law]()

    def flux(x, y, p):
        return jp.occultation_flux(star, x, y, p + 0.0 * x, method=method)

    return jax.jit(flux), jax.jit(jax.hessian(flux, argnums=(0, 1))), jax.jit(jax.grad(flux, 0))


# p varies fastest: the two radii of a law and method are neighbours, so
# xdist's split keeps them in one worker, where they share _compiled's programs
@pytest.mark.parametrize("p", [0.1, 0.6])
@pytest.mark.parametrize("method", ["exact", "auto"])
@pytest.mark.parametrize("law", sorted(STARS))
def test_hessian_in_the_centre_at_and_near_d0(law, method, p):
    flux, hessian, grad_x = _compiled(law, method)
    p = jnp.asarray(p)
    fx = lambda x, y: flux(x, y, p)  # noqa: E731
    hess = lambda x, y: hessian(x, y, p)  # noqa: E731
    grad_x_at = lambda x, y: grad_x(x, y, p)  # noqa: E731
    for d0 in (0.0, 1e-8, 1e-4):
        # references: finite differences of the flux along and across the
        # centre's direction (+x)
        ref_xx = _fd2(lambda h: float(fx(jnp.asarray(d0 + h), jnp.asarray(0.0))), 0.0, 2e-3)
        ref_yy = _fd2(lambda h: float(fx(jnp.asarray(d0), jnp.asarray(h))), 0.0, 2e-3)
        assert abs(ref_xx) > 1e-3 and abs(ref_yy) > 1e-3
        x0, y0 = jnp.asarray(d0), jnp.asarray(0.0)
        (hxx, hxy), (_, hyy) = hess(x0, y0)
        # the references' own rounding: ~8 eps / h^2 ~ 4e-10 at worst
        assert abs(float(hxx) - ref_xx) < 5e-8 * abs(ref_xx), (d0, float(hxx), ref_xx)
        assert abs(float(hyy) - ref_yy) < 5e-8 * abs(ref_yy), (d0, float(hyy), ref_yy)
        assert abs(float(hxy)) < 1e-8 * abs(ref_xx)  # 0 by symmetry in y
        # first derivatives stay finite and right (~ f''(0) d)
        gx = grad_x_at(x0, y0)
        assert np.isfinite(float(gx)) and abs(float(gx) - ref_xx * d0) < 1e-6 * abs(ref_xx) * d0 + 1e-15


@pytest.mark.parametrize("law", sorted(STARS))
@pytest.mark.parametrize("method", ["exact", "auto"])
def test_t0_curvature_at_mid_transit_inc90(law, method):
    star = STARS[law]()

    def flux(t0):
        pl = jp.Planet(period=10.0, t0=t0, a=20.0, inc=90.0, radius=0.1)
        return jp.System(star, [pl]).flux(jnp.zeros(1), method=method)[0]

    f = jax.jit(flux)
    ref = _fd2(lambda t: float(f(jnp.asarray(t))), 0.0, 2e-4)
    got = float(jax.jit(jax.grad(jax.grad(flux)))(jnp.asarray(0.0)))
    assert ref > 0.1
    assert abs(got - ref) < 1e-7 * ref, (got, ref)
