"""Stars: laws, tables and their exact totals."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxppo as jp
from helpers import KEPLER20_P100, reference_deficit, reference_total


def test_laws_match_conventions():
    mu = np.linspace(0, 1, 11)
    q = jp.Star.quadratic(0.4, 0.26)
    np.testing.assert_allclose(q.intensity(mu), 1 - 0.4 * (1 - mu) - 0.26 * (1 - mu) ** 2, atol=1e-15)
    c = KEPLER20_P100
    nl = jp.Star.nonlinear(*c)
    expect = 1 - sum(ck * (1 - mu ** ((k + 1) / 2)) for k, ck in enumerate(c))
    np.testing.assert_allclose(nl.intensity(mu), expect, atol=1e-14)
    p2 = jp.Star.power2(0.7, 0.6)
    np.testing.assert_allclose(p2.intensity(mu), 1 - 0.7 * (1 - mu**0.6), atol=1e-15)


@pytest.mark.parametrize("star", [jp.Star.uniform(), jp.Star.quadratic(0.495, 0.154), jp.Star.nonlinear(*KEPLER20_P100), jp.Star.power2(0.72, 0.78)])
def test_total_flux_is_exact(star):
    f0 = reference_total(lambda r: float(star.intensity(np.sqrt(max(1 - r * r, 0)))))
    assert abs(float(star.total_flux) - f0) < 1e-13


def test_quadratic_total_closed_form():
    u1, u2 = 0.3, 0.2
    assert abs(float(jp.Star.quadratic(u1, u2).total_flux) - np.pi * (1 - u1 / 3 - u2 / 6)) < 1e-15


def test_table_sqrt_poly_recovers_nonlinear_law_exactly():
    """A table sampled from a Claret law is reproduced to rounding: the
    sqrt(mu) polynomial basis contains the law."""
    nl = jp.Star.nonlinear(*KEPLER20_P100)
    mu = np.linspace(0, 1, 100)
    tab = jp.Star.tabulated(mu, np.asarray(nl.intensity(mu)))
    assert tab.degree == 4 and tab.table_residual < 1e-12
    mm = np.linspace(0, 1, 1001)
    np.testing.assert_allclose(tab.intensity(mm), nl.intensity(mm), atol=1e-12)
    x, y, r = np.array([0.3, 0.33]), np.array([0.1, 0.11]), np.array([0.05, 0.03])
    assert abs(float(jp.occultation_flux(tab, x, y, r)) - float(jp.occultation_flux(nl, x, y, r))) < 1e-13


@pytest.mark.parametrize("interpolation", ["linear", "cubic"])
def test_piecewise_tables_interpolate_and_integrate(interpolation):
    """Piecewise tables pass through every point; their exact flux has the
    quadrature error of a kinked integrand (documented: < 1e-8 at order 20,
    < 3e-10 at order 64)."""
    nl = jp.Star.nonlinear(*KEPLER20_P100)
    mu = np.linspace(0, 1, 40)
    vals = np.asarray(nl.intensity(mu))
    tab = jp.Star.tabulated(mu, vals, interpolation=interpolation)
    np.testing.assert_allclose(tab.intensity(mu), vals, atol=1e-14)
    from scipy.interpolate import CubicSpline

    interp = CubicSpline(mu, vals, bc_type="natural") if interpolation == "cubic" else (lambda m: np.interp(m, mu, vals))
    ir = lambda r: float(interp(np.sqrt(max(1 - r * r, 0))))
    f0 = reference_total(ir, breaks_mu=mu)
    assert abs(float(tab.total_flux) - f0) < 1e-13
    for x, y, p in [([0.3], [0.1], [0.05]), ([0.9], [0.2], [0.1]), ([0.3, 0.32], [0.1, 0.11], [0.05, 0.03])]:
        ref = 1 - reference_deficit(ir, x, y, p, breaks_mu=mu) / f0
        got = float(jp.occultation_flux(tab, np.array(x), np.array(y), np.array(p), method="exact", order=64))
        assert abs(got - ref) < 3e-10


def test_interpolation_error_measured():
    """Against a known profile sampled at 78 PHOENIX-like mu points: the
    sqrt(mu) polynomial beats linear-in-mu interpolation (the paper's scheme)."""
    truth = jp.Star.power2(0.72, 0.78)  # not in the sqrt(mu) basis
    mu = np.sort(np.concatenate([[0.0], np.cos(np.linspace(0, np.pi / 2, 78))[:-1]]))
    mu[-1] = 1.0
    vals = np.asarray(truth.intensity(mu))
    mm = np.linspace(0, 1, 2001)
    err = {}
    for interp in ("sqrt-poly", "linear", "cubic"):
        tab = jp.Star.tabulated(mu, vals, interpolation=interp)
        err[interp] = float(np.max(np.abs(np.asarray(tab.intensity(mm)) - np.asarray(truth.intensity(mm)))))
    assert err["sqrt-poly"] < 1e-3 and err["sqrt-poly"] < err["linear"]


def test_gradient_through_table_and_coefficients():
    mu = np.linspace(0, 1, 30)
    vals = jnp.asarray(1 - 0.6 * (1 - mu) - 0.1 * (1 - mu) ** 2)

    def f(v):
        return jp.occultation_flux(jp.Star(law="tabulated", params=v, mu_nodes=jnp.asarray(mu), interpolation="linear"), jnp.array([0.3]), jnp.array([0.1]), jnp.array([0.05]))

    g = jax.grad(f)(vals)
    assert np.all(np.isfinite(np.asarray(g))) and np.any(np.asarray(g) != 0)
    gq = jax.grad(lambda u: jp.occultation_flux(jp.Star.quadratic(u[0], u[1]), 0.3, 0.1, 0.05))(jnp.array([0.4, 0.2]))
    assert np.all(np.isfinite(np.asarray(gq)))


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(mu=[0, 0.5, 1.2], intensity=[1, 1, 1]), "mu must lie in"),
        (dict(mu=[0, 0.7, 0.5, 1], intensity=[1, 1, 1, 1]), "strictly increasing"),
        (dict(mu=[0, 0.5, 1], intensity=[1, -0.1, 1]), "intensity must be >= 0"),
        (dict(mu=[0, 0.5, 1], intensity=[1, np.nan, 1]), "intensity must be finite"),
        (dict(mu=[0, 1], intensity=[1, 1]), "at least 3"),
        (dict(mu=[0, 0.5, 1], intensity=[1, 1]), "equal length"),
        (dict(mu=[0, 0.5, 1], intensity=[1, 1, 1], interpolation="akima"), "interpolation"),
    ],
)
def test_bad_tables(kwargs, match):
    with pytest.raises(ValueError, match=match):
        jp.Star.tabulated(**kwargs)


def test_table_short_of_the_limb_is_refused_unless_padded():
    """Issue 24 item 5: a table from mu = 0.2 was extended without a word, and
    not flat as documented: sqrt-poly gave I(0.05) = 0.18 for I(0.2) = 0.3."""
    mu, inten = [0.2, 0.6, 1.0], [0.3, 0.7, 1.0]
    for m in (mu, [0.0, 0.5, 0.9]):
        with pytest.raises(ValueError, match=r"mu must reach 0 and 1 .*pad_ends=True"):
            jp.Star.tabulated(m, inten)
    lin = jp.Star.tabulated(mu, inten, interpolation="linear", pad_ends=True)
    np.testing.assert_allclose(np.asarray(lin.intensity(np.array([0.0, 0.05, 0.2]))), 0.3, rtol=0, atol=1e-15)
    sp = jp.Star.tabulated(mu, inten, pad_ends=True)  # asked for: the padded node is at mu = 0
    assert float(sp.mu_nodes[0]) == 0.0 and float(sp.mu_nodes[-1]) == 1.0
    # PHOENIX tables: tests/model/test_phoenix.py (test_grid_short_of_mu_0_loads_with_every_limb_method)


@pytest.mark.parametrize("make, match", [
    (lambda: jp.Star.quadratic(np.array([0.4, 0.5]), 0.2), r"u1 must be one number .*shape \(2,\)"),
    (lambda: jp.Star.quadratic(0.4, [0.2, 0.3]), r"u2 must be one number"),
    (lambda: jp.Star.nonlinear(0.1, 0.2, np.zeros(3), 0.1), r"c3 must be one number"),
    (lambda: jp.Star.power2(np.array([0.6]), 0.5), r"c must be one number"),
])
def test_coefficient_arrays_are_refused_by_name(make, match):
    """Star.quadratic(np.array([0.4, 0.5]), 0.2) raised numpy's "Cannot
    stack arrays with different numbers of dimensions", and two arrays of
    one length a broadcasting error deep in the total flux."""
    with pytest.raises(ValueError, match=match):
        make()


def test_unknown_law():
    with pytest.raises(ValueError, match="unknown limb-darkening law 'squareroot'"):
        jp.Star.from_law("squareroot", [0.1, 0.2])
    with pytest.raises(ValueError, match="needs 2 coefficients"):
        jp.Star.from_law("quadratic", [0.1])
    with pytest.raises(ValueError, match="alpha must be > 0"):
        jp.Star.power2(0.5, -1.0)


def test_sqrt_poly_table_in_float32():
    """A high-degree table (a power-2 profile, not in the sqrt(mu) basis) is
    fitted and evaluated in a Chebyshev basis: float32 stays accurate."""
    import jax.numpy as jnp

    truth = jp.Star.power2(0.72, 0.78)
    mu = np.sort(np.concatenate([[0.0], np.cos(np.linspace(0, np.pi / 2, 78))[:-1]]))
    mu[-1] = 1.0
    tab = jp.Star.tabulated(mu, np.asarray(truth.intensity(mu)))
    assert tab.degree >= 8
    x, y, r = np.array([[0.3, 0.33], [0.95, 0.97]]), np.array([[0.1, 0.11], [0.1, 0.12]]), np.array([[0.05, 0.03], [0.05, 0.04]])
    f64 = np.asarray(jp.occultation_flux(tab, x, y, r, method="exact"))
    tab32 = jax.tree_util.tree_map(lambda v: v.astype(jnp.float32) if hasattr(v, "astype") else v, tab)
    f32 = np.asarray(jp.occultation_flux(tab32, x.astype(np.float32), y.astype(np.float32), r.astype(np.float32), method="exact"), float)
    assert np.max(np.abs(f32 - f64)) < 1e-6


# ---------------------------------------------------------------------------
# Issue 16 items 7 and 9, issue 15 item 4 (star part)
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("interpolation", ["linear", "cubic", "sqrt-poly"])
def test_gradient_through_tabulated_intensities(interpolation):
    """Star.tabulated with traced intensities (a fit of the table's values)
    raised TracerArrayConversionError; the gradient now matches central
    differences, and jit gives the concrete table's value."""
    mu = np.linspace(0.05, 1, 30)  # padded at mu = 0: the traced concatenation too
    i0 = 1 - 0.6 * (1 - mu) - 0.1 * (1 - mu) ** 2
    kw = {"degree": jp.Star.tabulated(mu, i0, pad_ends=True).degree} if interpolation == "sqrt-poly" else {}

    def f(v):
        st = jp.Star.tabulated(mu, v, interpolation=interpolation, pad_ends=True, **kw)
        return jp.occultation_flux(st, jnp.array([0.3, 0.33]), jnp.array([0.1, 0.1]), jnp.array([0.05, 0.03]), method="exact")

    g = np.asarray(jax.grad(f)(jnp.asarray(i0)))
    h = 1e-5
    for j in (0, 10, 29):
        e = np.zeros_like(i0)
        e[j] = h
        fd = (float(f(jnp.asarray(i0 + e))) - float(f(jnp.asarray(i0 - e)))) / (2 * h)
        assert abs(g[j] - fd) < 1e-9 + 1e-5 * abs(fd), (j, g[j], fd)
    assert abs(float(jax.jit(f)(jnp.asarray(i0))) - float(f(i0))) < 1e-15
    if interpolation == "sqrt-poly":
        with pytest.raises(ValueError, match="needs degree="):
            jax.grad(lambda v: jp.occultation_flux(jp.Star.tabulated(mu, v, pad_ends=True), 0.3, 0.1, 0.05))(jnp.asarray(i0))


def test_non_physical_laws():
    """Star.quadratic(3, 0) has total flux 0 (its light curves were -6.8e13):
    refused, naming the coefficients; a profile negative somewhere on [0, 1]
    warns; a numpy alpha <= 0 is refused like the Python scalar."""
    with pytest.raises(ValueError, match=r"Star.quadratic\(u1=3, u2=0\) has total flux F0 = 0"):
        jp.Star.quadratic(3, 0)
    # zero to rounding: F0 = 3e-14 of pi was accepted, and its light curves
    # were noise times 1e13
    with pytest.raises(ValueError, match=r"has total flux F0 = 0 <= 0"):
        jp.Star.quadratic(3.0 * (1.0 - 1e-14), 0.0)
    with pytest.raises(ValueError, match="total flux"):
        jp.Star.nonlinear(2.0, 2.0, 0.0, 0.0)
    # numbers from a config or an array print as numbers, not np.float64(5.0)
    with pytest.raises(ValueError, match=r"Star.nonlinear\(c1=5.0, c2=5.0, c3=5.0, c4=5.0\) has total flux"):
        jp.Star.from_law("nonlinear", [5, 5, 5, 5])
    with pytest.raises(ValueError, match=r"law 'nonlinear' needs 4 coefficients, got 2: \[0.4, 0.2\]$"):
        jp.Star.from_law("nonlinear", np.array([0.4, 0.2]))
    with pytest.warns(UserWarning, match=r"u1=1.5, u2=0.5\) has negative intensity I\(mu=0\) = -1"):
        jp.Star.quadratic(1.5, 0.5)
    with pytest.warns(UserWarning, match="negative intensity"):
        jp.Star.power2(1.2, 0.6)
    for alpha in (np.array(-1.0), np.float64(0.0), np.array([-0.5])):
        with pytest.raises(ValueError, match="alpha must be > 0"):
            jp.Star.power2(0.5, alpha)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        jp.Star.quadratic(0.495, 0.154)
        jp.Star.nonlinear(*KEPLER20_P100)
        jp.Star.power2(0.72, 0.78)
    # traced coefficients are not checked (fits may pass through such values)
    assert np.isfinite(float(jax.grad(lambda u: jp.occultation_flux(jp.Star.quadratic(u, 0.0), 0.3, 0.1, 0.05))(0.4)))


def test_tabulated_warns_when_rtol_is_not_met():
    """A kinked table cannot meet rtol with a smooth sqrt(mu) polynomial: it
    used to be smoothed (2.7e-2 residual against rtol = 1e-6) silently."""
    import warnings

    mu = np.r_[np.linspace(0, 0.05, 20), np.linspace(0.06, 1, 60)]
    inten = np.where(mu < 0.03, mu / 0.03 * 0.3, 0.3 + 0.7 * mu)
    with pytest.warns(UserWarning, match="meets rtol"):
        jp.Star.tabulated(mu, inten)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        jp.Star.tabulated(mu, inten, interpolation="linear")
        jp.Star.tabulated(mu, 1 - 0.5 * (1 - mu))  # smooth: no warning
