"""The transit posterior of the marginal scan: its mode (optimistix) against
an independent least-squares solver, and its frame sets."""

import numpy as np
import pytest

import jaxppo as jp


@pytest.fixture(scope="module")
def posterior():
    """One double transit of Kepler-20 b and c (radii doubled, 2e-4 noise
    per 1-min point, a PPO at 147 deg), started off the truth (c 2 min late
    and 5 % small, b's a/R* 2 % large): a/R* tied to rho*, c's t0, p, b."""
    from jaxppo.inference._posterior import TransitPosterior

    true = jp.kepler20_system(radius_scale=2.0)
    lc = jp.simulate_kepler20(seed=2021, alpha=147.0, case="same", radius_scale=2.0, noise=2e-4)
    bump = np.abs(np.asarray(true.flux(lc.time, 147.0, case="same")) - np.asarray(true.flux(lc.time, 0.0)))
    keep = np.abs(lc.time - lc.time[np.argmax(bump)]) < 0.15
    one = jp.LightCurve(lc.time[keep], lc.flux[keep], lc.flux_err[keep], lc.exposure)
    b, c = true.planets
    start = true.replace(planets=(b.replace(a=1.02 * b.a), c.replace(t0=c.t0 + 2.0 / 1440, radius=0.95 * c.radius)))
    return TransitPosterior(start, one, ("b.a", "c.t0", "c.radius", "c.inc"), (1.65, 0.08), 20.0, "same")


def test_mode_agrees_with_scipy(posterior):
    """optimistix's mode against scipy.optimize.least_squares (trust-region
    reflective, the same residuals and Jacobian): chi^2 to 1e-6 relative,
    every coordinate within 1 % of its Laplace width (up to the sign of the
    folded impact parameter's coordinate: b / (1 + p) = |tanh(v / 2)|)."""
    import jax
    from scipy.optimize import least_squares

    from jaxppo.inference._posterior import mode_and_cov

    post = posterior
    u, chol, chi2 = mode_and_cov(post)
    res, jac = jax.jit(post.residuals), jax.jit(jax.jacfwd(post.residuals))
    ref = least_squares(lambda v: np.asarray(res(v)), post.u_start, jac=lambda v: np.asarray(jac(v)),
                        x_scale="jac", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=2000)
    assert ref.success, ref.message
    chi2_ref = float(np.sum(ref.fun**2))
    start = float(np.sum(np.asarray(res(post.u_start)) ** 2))
    assert start > chi2_ref + 100.0  # the start is far from the mode
    assert abs(chi2 - chi2_ref) < 1e-6 * chi2_ref, (chi2, chi2_ref)
    assert chi2 == pytest.approx(float(np.sum(np.asarray(res(u)) ** 2)), rel=1e-12)
    sd = np.sqrt(np.diag(chol @ chol.T))
    # b / (1 + p) = |tanh(v / 2)|: v and -v are the same point
    fold = np.array([p == "inc" for _, p in post.coords])
    diff = np.where(fold, np.abs(u) - np.abs(ref.x), u - ref.x)
    assert np.all(np.abs(diff) < 0.01 * sd), diff / sd
    # the Laplace covariance with the prior widths as curvature
    J = np.asarray(jac(u))
    cov = np.linalg.inv(J.T @ J + np.diag(1.0 / post.prior_sd**2))
    np.testing.assert_allclose(chol @ chol.T, cov, rtol=1e-8, atol=0)


def test_exact_overlaps_anywhere_cover_every_tilt(posterior):
    """The union frames for sampling alpha hold every frame in which two
    disks touch at some tilt (a 0.25 deg grid) at the start, and the
    posterior's Model is a new one (the frames of the old are untouched)."""
    from jaxppo.inference._posterior import TransitPosterior
    from jaxppo.model._overlap import pairs_in_contact

    post = TransitPosterior(posterior.system, posterior.model.lc, posterior.free, posterior.density, 20.0, "same")
    before = post.model
    union0 = before.union_idx.copy()
    post.exact_overlaps_anywhere()
    assert post.model is not before and np.array_equal(before.union_idx, union0)
    t = np.asarray(post.model.t_model)
    touch = np.zeros(t.size, bool)
    for alpha in np.arange(0.0, 360.0, 0.25):
        touch |= pairs_in_contact(*post.system.positions(t, alpha, "same", xp=np))
    assert touch.any() and np.all(np.isin(np.nonzero(touch)[0], post.model.union_idx))
    assert np.all(np.isin(post.model.union_idx, post.model.active_idx))
