"""Property-based tests (hypothesis) over the degenerate classes of the
flux engine and the public constructors: scenes of one to three disks
built from the special distances where methods fail (b in {0, p, 1 - p,
1, 1 + p}, external and internal tangency, concentric, identical, disks
larger than the star, tiny next to large), each nudged by 0 or +-1e-15,
+-1e-9, +-1e-3; and inputs in other units and types.

Properties:
* "exact" and "auto" equal the independent radial reference
  (tests/helpers.py ``reference_deficit``) to 1e-10 in float64; "auto"
  equals "exact" to 1e-12;
* 0 <= F <= 1; a disk added never raises the flux; the order of the disks
  does not matter (1e-13);
* jit(grad) of the flux is finite (float32 gradients:
  tests/core/test_adversarial.py);
* in float32 (float32 inputs and star), "exact" and "auto" stay within
  3e-6 of the reference of the rounded scene, and return float32;
* jit and vmap give the eager numbers (1e-13); the sharded path on the
  degenerate grid: tests/model/test_sharding.py;
* the raster (windowed, default settings) stays within [0, 1] and within
  the error envelope RasterSettings documents for its largest disk;
* Planet and System.flux give the same numbers for a quantity in any time
  or length unit as for its value in days / stellar radii, and refuse
  strings and booleans by name;
* so does every other public entry point that takes a time, an angle or a
  stellar-radius value (simulate, LightCurve, transit_times,
  multi_transits, positions, sweep, occultation_flux, Moon, Star, the
  scan's settings): the same numbers in any unit, a wrong kind of unit or
  a string or bool refused with the parameter named.

Profiles: CI runs the example counts written here with fixed draws;
``python benchmarks/properties_long.py --scale K`` runs K times as many,
with fresh random draws.
"""

import math
import os

import astropy.units as u
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import jaxppo as jp
from helpers import numpy_intensity, reference_deficit, reference_total

STAR = jp.Star.quadratic(0.4, 0.25)
_I_MU = numpy_intensity(STAR)


def I_R(r):
    """I at the projected radius r (numpy_intensity is a function of mu)."""
    return _I_MU(np.sqrt(np.clip(1.0 - np.asarray(r, float) ** 2, 0.0, 1.0)))



TOTAL = reference_total(I_R)
# the CI profile: the example counts below; JAXPPO_HYPOTHESIS_SCALE=K runs K
# times as many, with fresh random draws (benchmarks/properties_long.py)
SCALE = int(os.environ.get("JAXPPO_HYPOTHESIS_SCALE", "1"))


def _n(examples: int) -> int:
    return examples * SCALE
SETTINGS = settings(max_examples=_n(25), deadline=None, derandomize=SCALE == 1,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
NUDGES = [0.0, 1e-15, -1e-15, 1e-9, -1e-9, 1e-3, -1e-3]
RADII = [1e-4, 0.01, 0.1, 0.5, 0.99, 1.0, 1.5]


@st.composite
def first_disk(draw):
    p = draw(st.one_of(st.sampled_from(RADII), st.floats(1e-4, 1.5)))
    d = draw(st.one_of(st.sampled_from([0.0, p, abs(1.0 - p), 1.0, 1.0 + p]), st.floats(0.0, 2.6)))
    d = max(d + draw(st.sampled_from(NUDGES)), 0.0)
    phi = draw(st.floats(0.0, 2.0 * math.pi))
    return d * math.cos(phi), d * math.sin(phi), p


@st.composite
def scene(draw, max_disks=3):
    """[(x, y, r)] of one to ``max_disks`` disks; each further disk placed
    against the first in a degenerate relation (or at random)."""
    x0, y0, p0 = draw(first_disk())
    disks = [(x0, y0, p0)]
    for _ in range(draw(st.integers(0, max_disks - 1))):
        kind = draw(st.sampled_from(["tangent", "inside", "concentric", "identical", "free"]))
        q = draw(st.one_of(st.sampled_from(RADII), st.floats(1e-4, 1.5)))
        if kind == "identical":
            disks.append((x0, y0, p0))
            continue
        sep = {"tangent": p0 + q, "inside": abs(p0 - q), "concentric": 0.0}.get(kind)
        if sep is None:
            sep = draw(st.floats(0.0, 2.0))
        sep = max(sep + draw(st.sampled_from(NUDGES)), 0.0)
        phi = draw(st.floats(0.0, 2.0 * math.pi))
        disks.append((x0 + sep * math.cos(phi), y0 + sep * math.sin(phi), q))
    return disks


def _flux(disks, method="exact", dtype=jnp.float64):
    x, y, r = (jnp.asarray([d[k] for d in disks], dtype) for k in range(3))
    return float(jp.occultation_flux(STAR, x[None], y[None], r[None], method=method)[0])


@SETTINGS
@given(scene())
def test_exact_and_auto_equal_the_reference(disks):
    x, y, r = (np.array([d[k] for d in disks]) for k in range(3))
    ref = 1.0 - reference_deficit(I_R, x, y, r) / TOTAL
    exact = _flux(disks)
    assert abs(exact - ref) <= 1e-10, (disks, exact, ref)
    assert abs(_flux(disks, "auto") - exact) <= 1e-12, disks


@SETTINGS
@given(scene(), st.randoms(use_true_random=False))
def test_bounds_monotonicity_and_order(disks, rnd):
    f = _flux(disks, "auto")
    assert -1e-15 <= f <= 1.0 + 1e-15, (disks, f)
    if len(disks) > 1:
        assert f <= _flux(disks[:-1], "auto") + 1e-13, disks
        shuffled = list(disks)
        rnd.shuffle(shuffled)
        assert abs(_flux(shuffled, "auto") - f) <= 1e-13, (disks, shuffled)


def _one_frame(a, b, c, method="auto"):
    return jp.occultation_flux(STAR, a[None], b[None], c[None], method=method)[0]


# compiled once per disk count and reused by every example (a jit of a new
# lambda per example recompiled the engine each time: a minute of CI)
_GRAD = jax.jit(jax.grad(_one_frame, argnums=(0, 1, 2)))
_JIT = {m: jax.jit(lambda a, b, c, m=m: _one_frame(a, b, c, m)) for m in ("exact", "auto")}


@settings(max_examples=_n(15), deadline=None, derandomize=SCALE == 1, suppress_health_check=[HealthCheck.too_slow])
@given(scene(max_disks=2))
def test_gradients_finite(disks):
    x, y, r = (jnp.asarray([d[k] for d in disks]) for k in range(3))
    assert all(np.all(np.isfinite(np.asarray(v))) for v in _GRAD(x, y, r)), disks


@settings(max_examples=_n(12), deadline=None, derandomize=SCALE == 1, suppress_health_check=[HealthCheck.too_slow])
@given(scene(max_disks=2).filter(lambda ds: all(min(d[2], 1.0) >= 0.01 for d in ds)))
def test_raster_within_its_bound(disks):
    exact = _flux(disks)
    raster = _flux(disks, "raster")
    # the envelope RasterSettings documents (its worst over positions, error
    # ~ pixel^2 ~ r^2, steep near r = 1): 1.2e-7 at r = 0.03, 1.3e-6 at 0.1,
    # 6.5e-5 at 0.5, 9.4e-4 at 0.99 (with margins; the sweep that measured
    # them: tests/model/test_raster.py::test_raster_worst_over_positions)
    r_max = min(max(d[2] for d in disks), 1.0)
    bound = float(np.exp(np.interp(r_max, [0.0, 0.03, 0.1, 0.5, 0.99, 1.0],
                                   np.log([2e-7, 2e-7, 2e-6, 1e-4, 2e-3, 2e-3]))))
    assert -1e-12 <= raster <= 1.0 + 1e-12 and abs(raster - exact) <= bound, (disks, raster, exact, bound)


STAR32 = jax.tree_util.tree_map(lambda v: v.astype(jnp.float32) if hasattr(v, "astype") else v, STAR)


@settings(max_examples=_n(20), deadline=None, derandomize=SCALE == 1, suppress_health_check=[HealthCheck.too_slow])
@given(scene().filter(lambda ds: all(d[2] >= 1e-3 for d in ds)))
def test_float32_within_its_bound(disks):
    """float32 inputs and a float32 star run in float32 (docs/methods.md,
    "float32 policy") and stay within 3e-6 of the reference of the scene
    float32 can carry (its inputs rounded to float32; disks below 1e-3
    R* are under float32's resolution of the flux), "exact" and "auto"."""
    x, y, r = (np.array([d[k] for d in disks], np.float32) for k in range(3))
    ref = 1.0 - reference_deficit(I_R, x.astype(float), y.astype(float), r.astype(float)) / TOTAL
    for method in ("exact", "auto"):
        got = jp.occultation_flux(STAR32, jnp.asarray(x)[None], jnp.asarray(y)[None], jnp.asarray(r)[None],
                                  method=method)
        assert got.dtype == jnp.float32, (method, got.dtype)
        assert abs(float(got[0]) - ref) <= 3e-6, (method, disks, float(got[0]), ref)


@settings(max_examples=_n(12), deadline=None, derandomize=SCALE == 1, suppress_health_check=[HealthCheck.too_slow])
@given(scene(), st.sampled_from(["exact", "auto"]))
def test_traced_paths_equal_the_eager_call(disks, method):
    """jit and vmap give the eager call's numbers: the scene and its mirror
    image (x -> -x, the same flux for a radially symmetric star) batched
    under vmap, and the scene under jit, to 1e-13."""
    x, y, r = (jnp.asarray([d[k] for d in disks]) for k in range(3))
    eager = float(jp.occultation_flux(STAR, x[None], y[None], r[None], method=method)[0])
    assert abs(float(_JIT[method](x, y, r)) - eager) <= 1e-13, (disks, method)
    batch = jax.vmap(lambda a, b, c: jp.occultation_flux(STAR, a[None], b[None], c[None], method=method)[0])
    got = np.asarray(batch(jnp.stack([x, -x]), jnp.stack([y, y]), jnp.stack([r, r])))
    assert np.all(np.abs(got - eager) <= 1e-13), (disks, method, got, eager)


@settings(max_examples=_n(20), deadline=None, derandomize=SCALE == 1)
@given(st.sampled_from([(u.d, 1.0), (u.h, 24.0), (u.min, 1440.0), (u.s, 86400.0)]),
       st.sampled_from([(u.dimensionless_unscaled, 1.0)]), st.floats(-0.2, 0.2))
def test_units_give_the_same_numbers(time_unit, _, t):
    unit, per_day = time_unit
    pl = jp.Planet(period=3.7 * per_day * unit, t0=0.0 * unit, a=10.0, inc=89.0, radius=0.05)
    ref = jp.Planet(period=3.7, t0=0.0, a=10.0, inc=89.0, radius=0.05)
    assert float(pl.period) == pytest.approx(3.7, rel=1e-15)
    s, s_ref = jp.System(STAR, [pl]), jp.System(STAR, [ref])
    got = np.asarray(s.flux(np.array([t, 0.0]) * per_day * unit))
    assert np.allclose(got, np.asarray(s_ref.flux(np.array([t, 0.0]))), rtol=0, atol=1e-15)


@settings(max_examples=_n(20), deadline=None, derandomize=SCALE == 1)
@given(st.sampled_from(["period", "t0", "a", "inc", "radius"]), st.sampled_from(["3.7", True, None, "x"]))
def test_bad_parameter_types_are_refused_by_name(name, value):
    kw = dict(period=3.7, t0=0.0, a=10.0, inc=89.0, radius=0.05)
    kw[name] = value
    if (name, value) == ("a", None):
        # a=None is a planet of an N-body System, which derives a; a Keplerian System refuses it by name
        with pytest.raises(ValueError, match="no a"):
            jp.System(jp.Star.uniform(), [jp.Planet(**kw)])
        return
    with pytest.raises((ValueError, TypeError), match=name):
        jp.Planet(**kw)


TIME_UNITS = [(u.d, 1.0), (u.h, 24.0), (u.min, 1440.0), (u.s, 86400.0)]
ANGLE_UNITS = [(u.deg, 1.0), (u.rad, math.pi / 180.0), (u.arcmin, 60.0)]
K20 = jp.kepler20_system()


def _same(a, b):
    """Equal to the rounding of a unit conversion (1e-12 relative)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    assert a.shape == b.shape and np.allclose(a, b, rtol=1e-12, atol=1e-15), (a, b)


@settings(max_examples=_n(12), deadline=None, derandomize=SCALE == 1)
@given(st.sampled_from(TIME_UNITS), st.sampled_from(ANGLE_UNITS), st.floats(-0.15, 0.15), st.floats(0.0, 359.0))
def test_every_entry_point_converts_units(time_unit, angle_unit, dt, alpha):
    """Issue 24 (units over all entry points). Before: ``simulate`` took
    hours as days (t = 3228 for 134.5 d), ``LightCurve`` took a flux_err of
    0.1 % as 0.1, ``occultation_flux`` took metres as stellar radii,
    ``transit_times`` / ``multi_transits`` / ``measure_transit_times(search=)``
    failed with a TypeError, ``scan(alpha=)`` took radians as degrees."""
    from jaxppo.obliquity._config import config_from_arguments

    tu, per_day = time_unit
    au, per_deg = angle_unit
    # each entry point gets the Quantity; the reference the days (degrees)
    # astropy converts it to, so that the comparison is exact and not
    # blurred by the rounding of the conversion itself (1e-14 d in t moves a
    # planet by 1e-12 R*)
    t = float(K20.planets[0].t0) + dt + np.array([0.0, 0.01])
    tq = t * per_day * tu
    td = tq.to_value(u.d)
    assert np.allclose(td, t, rtol=1e-14, atol=0)
    ref = jp.simulate(K20, td, noise=1e-4, seed=1)
    got = jp.simulate(K20, tq, noise=0.01 * u.percent, seed=1)
    _same(got.time, ref.time), _same(got.flux, ref.flux), _same(got.flux_err, ref.flux_err)
    exposure = 30.0 * 60.0 / 86400.0 * per_day * tu
    lc = jp.LightCurve(tq, ref.flux, 0.01 * u.percent * np.ones(2), exposure=exposure)
    _same(lc.time, td), _same(lc.flux_err, [1e-4, 1e-4]), _same(lc.exposure, exposure.to_value(u.d))
    span = (130.0 * per_day * tu, 145.0 * per_day * tu)
    _same(jp.transit_times(K20, *span)["tc"], jp.transit_times(K20, *(v.to_value(u.d) for v in span))["tc"])
    wide = (130.0 * per_day * tu, 700.0 * per_day * tu)
    assert [e.mid for e in jp.multi_transits(K20, *wide)] == \
        [e.mid for e in jp.multi_transits(K20, *(v.to_value(u.d) for v in wide))]
    a_q = alpha * per_deg * au
    a_d = float(a_q.to_value(u.deg))
    for k in range(3):
        _same(K20.positions(tq, alpha=a_q, xp=np)[k], K20.positions(td, alpha=a_d, xp=np)[k])
    _same(jp.sweep(K20, tq, np.array([alpha]) * per_deg * au), jp.sweep(K20, td, np.array([a_d])))
    x = np.array([0.1, 0.3])
    _same(jp.occultation_flux(STAR, x * u.dimensionless_unscaled, x * 0.0, 0.1 * u.one),
          jp.occultation_flux(STAR, x, x * 0.0, 0.1))
    moon = jp.Moon(period=1.2 * per_day * tu, t0=dt * per_day * tu, a=0.3, inc=88.0 * per_deg * au, radius=0.01,
                   lnode=alpha * per_deg * au)
    plain = jp.Moon(period=1.2, t0=dt, a=0.3, inc=88.0, radius=0.01, lnode=alpha)
    for name in ("period", "t0", "inc", "lnode"):
        _same(getattr(moon, name), getattr(plain, name))
    grid = np.arange(0.0, 360.0, 90.0)
    cfg = config_from_arguments(K20, ref, grid * per_deg * au, ("same",), 0.05 * per_day * tu, "none",
                                0.3 * per_day * tu, "none", None, 60)
    _same(cfg.alpha, grid), _same(cfg.margin, 0.05), _same(cfg.baseline, 0.3)
    # plain ints and lists are days and degrees as they stand
    whole = [134, 135]
    _same(jp.simulate(K20, whole, noise=1e-4, seed=1).flux, jp.simulate(K20, np.array(whole, float), noise=1e-4,
                                                                          seed=1).flux)
    _same(K20.positions(whole, alpha=90, xp=np)[0], K20.positions(np.array(whole, float), alpha=90.0, xp=np)[0])


@settings(max_examples=_n(25), deadline=None, derandomize=SCALE == 1)
@given(st.sampled_from(["simulate.t", "simulate.noise", "LightCurve.flux_err", "transit_times.t_start",
                        "multi_transits.t_end", "occultation_flux.x", "occultation_flux.r", "Moon.period",
                        "Moon.inc", "Star.u1", "sweep.alpha", "scan.alpha", "measure_transit_times.search"]),
       st.sampled_from(["3.7", True, "length", "time", "angle", "abstime"]))
def test_wrong_types_and_units_are_refused_by_name(where, value):
    """A string, a bool or a Quantity of the wrong kind at any entry point is
    a ValueError naming the parameter (a string coefficient or True once
    became u1 = 0.4 or 1 in Star.quadratic)."""
    from jaxppo.obliquity._config import config_from_arguments

    kind = {"t": "time", "noise": "one", "flux_err": "one", "t_start": "time", "t_end": "time", "x": "one",
            "r": "one", "period": "time", "inc": "angle", "u1": "one", "alpha": "angle", "search": "time"}
    entry, name = where.split(".")
    if value in ("length", "time", "angle"):
        if value == kind[name] or (value == "length" and kind[name] == "one" and entry == "LightCurve"):
            return  # the right kind converts (test above); a flux_err in metres: its own message below
        value = {"length": 3.0 * u.m, "time": 3.0 * u.h, "angle": 3.0 * u.deg}[value]
    elif value == "abstime":  # an absolute astropy Time: no day count of its own, refused everywhere
        from astropy.time import Time

        value = Time(2455000.0, format="jd")
    t = np.array([134.4, 134.5])
    lc = jp.LightCurve(t, np.ones(2), np.full(2, 1e-4))
    calls = {
        "simulate.t": lambda v: jp.simulate(K20, v if np.ndim(v) else v, noise=1e-4),
        "simulate.noise": lambda v: jp.simulate(K20, t, noise=v),
        "LightCurve.flux_err": lambda v: jp.LightCurve(t, np.ones(2), v),
        "transit_times.t_start": lambda v: jp.transit_times(K20, v, 140.0),
        "multi_transits.t_end": lambda v: jp.multi_transits(K20, 130.0, v),
        "occultation_flux.x": lambda v: jp.occultation_flux(STAR, v, 0.0, 0.1),
        "occultation_flux.r": lambda v: jp.occultation_flux(STAR, 0.0, 0.0, v),
        "Moon.period": lambda v: jp.Moon(period=v, t0=0.0, a=0.3, inc=88.0, radius=0.01),
        "Moon.inc": lambda v: jp.Moon(period=1.0, t0=0.0, a=0.3, inc=v, radius=0.01),
        "Star.u1": lambda v: jp.Star.quadratic(v, 0.2),
        "sweep.alpha": lambda v: jp.sweep(K20, t, v),
        "scan.alpha": lambda v: config_from_arguments(K20, lc, v, ("same",), 0.05, "none", 0.3, "none", None, 60),
        "measure_transit_times.search": lambda v: jp.measure_transit_times(K20, lc, search=v),
    }
    with pytest.raises(ValueError, match=name):
        calls[where](value)


@pytest.mark.parametrize("call, match", [
    (lambda: jp.Star.quadratic(0.4 * u.percent, 0.25), "u1 must be a plain number"),
    (lambda: jp.Star.from_law("quadratic", [0.4, 0.25] * u.percent), "coefficients must be a plain number"),
    (lambda: jp.occultation_flux(STAR, 0.0, 0.0, np.array(True)), "r must be dimensionless"),
    (lambda: jp.occultation_flux(STAR, [True], 0.0, 0.1), "x must be dimensionless"),
    (lambda: jp.LightCurve([1.0, 2.0], [1.0, 1.0], [1e-3, 1e-3], exposure=np.array(True)), "exposure must be a time"),
    (lambda: K20.flux(["0.0", "0.1"]), "t must be a time"),
    (lambda: jp.simulate(K20, [True, False]), "t must be a time"),
    (lambda: jp.simulate(K20, np.ma.masked_array([1.0, 2.0], mask=[0, 1])), "t holds 1 masked"),
    (lambda: jp.transit_times(K20, [0.0, 1.0] * u.d, 10.0), r"t_start must be one time \[d\], got 2 values"),
    (lambda: jp.System(STAR, [jp.Planet(period=3.0, t0=0.0, a=None, inc=89.0, radius=0.1, mass=1e-5)],
                       orbits="nbody", epoch=0.0, star_mass=1.0, star_radius=1.0, span=[155.0, 1600.0, 1700.0] * u.d),
     r"span must be \(t_min, t_max\)"),
])
def test_review_refusals(call, match):
    """What a review found still slipping through: a coefficient in percent
    used as its bare value, bool arrays taken as 0/1, strings as times, a
    masked time used as if present, a three-value span cut to two."""
    with pytest.raises(ValueError, match=match):
        call()


def test_lists_of_quantities_convert():
    """A list of time Quantities raised astropy's bare TypeError."""
    t = float(K20.planets[0].t0)
    got = jp.simulate(K20, [t * 24.0 * u.h, (t + 0.01) * 24.0 * u.h], noise=1e-4, seed=1)
    _same(got.time, [t, t + 0.01])
