"""Fits (jp.fit) and MCMC (numpyro) on synthetic and real Kepler data."""

import warnings

import numpy as np
import pytest

import jaxppo as jp
from jaxppo.model._phoenix import data_path

FREE = ("b.t0", "b.radius", "c.t0", "c.radius")


def _truth_values(system, names):
    out = []
    for n in names:
        owner, par = n.split(".")
        out.append(float(getattr(system.planets[system.index(owner)], par)))
    return np.array(out)


def test_fit_recovers_truth_within_3_sigma():
    truth = jp.kepler20_system()
    lc = jp.simulate_kepler20(seed=11, noise=4e-4)
    b, c = truth.planets
    start = truth.replace(planets=(b.replace(t0=b.t0 + 0.003, radius=0.0195, inc=87.9), c.replace(t0=c.t0 - 0.002, radius=0.027)))
    free = FREE + ("b.inc",)
    res = jp.fit(start, lc, free=free)
    assert res.success, res.message
    pulls = (res.values - _truth_values(truth, free)) / res.errors
    assert np.all(np.abs(pulls) < 3), pulls
    assert 0.85 < res.reduced_chi2 < 1.15


def test_fit_refits_when_the_solution_brings_disks_together():
    """The union-integral frames are fixed from the start; a start that puts
    c 0.15 R* away from where it occults b (outside the 0.05 R* margin) must
    still end with every PPO frame of the solution in the union set."""
    from jaxppo.inference._model import Model

    truth = jp.kepler20_system()
    lc = jp.simulate_kepler20(seed=5, noise=2e-4, alpha=90.0)
    b, c = truth.planets
    start = truth.replace(planets=(b, c.replace(t0=c.t0 + 0.014)))
    free = ("b.t0", "c.t0")
    start_frames = Model(start, lc, free, alpha=90.0).union_frames_of(start, lc.time)
    truth_frames = Model(truth, lc, free, alpha=90.0).union_frames_of(truth, lc.time)
    assert not np.all(np.isin(truth_frames, start_frames))  # the start misses PPO frames
    res = jp.fit(start, lc, free=free, alpha=90.0)
    assert res.success, res.message
    assert np.all(np.isin(truth_frames, res.union_frames))
    # the solution is optimal for the model with every PPO frame exact: a fit
    # started there does not move
    again = jp.fit(res.system, lc, free=free, alpha=90.0)
    assert np.all(np.abs(again.values - res.values) < 0.05 * res.errors), (again.values - res.values) / res.errors
    pulls = (res.values - _truth_values(truth, free)) / res.errors
    assert np.all(np.abs(pulls) < 3), pulls


def test_bad_start_reports_failure_without_raising():
    truth = jp.kepler20_system()
    lc = jp.simulate_kepler20(seed=11, noise=4e-4)
    b = truth.planets[0]
    # transit times half a period away: no gradient information, a flat chi^2
    start = truth.replace(planets=(b.replace(t0=b.t0 + 0.5 * float(b.period)), truth.planets[1]))
    res = jp.fit(start, lc, free=("b.t0",), max_steps=5)
    assert not res.success and res.message.startswith("failed")


def test_passes_cut_by_max_steps_end_where_the_minimum_check_accepts():
    """Each pass ends with the minimum check, whatever ended the pass:
    passes of 2 steps that stop at a point the check accepts give
    a converged fit (within the check's 0.01 of the full fit's chi^2).
    (Before, optimistix's "maximum number of steps" failed such a fit.)"""
    truth = jp.kepler20_system()
    lc = jp.simulate_kepler20(seed=11, noise=4e-4)
    b = truth.planets[0]
    start = truth.replace(planets=(b.replace(t0=b.t0 + 0.001, radius=0.019), truth.planets[1]))
    full = jp.fit(start, lc, free=("b.t0", "b.radius"))
    short = jp.fit(start, lc, free=("b.t0", "b.radius"), max_steps=2)
    assert full.success and short.success, short.message
    assert short.message.startswith("converged: Newton step would lower chi^2 by")
    assert 0.0 <= short.chi2 - full.chi2 < 0.01
    assert np.all(np.abs(short.values - full.values) < 0.2 * full.errors)


def test_unknown_free_parameter():
    truth = jp.kepler20_system()
    lc = jp.simulate_kepler20(seed=1)
    with pytest.raises(ValueError, match="no planet named 'z'"):
        jp.fit(truth, lc, free=("z.t0",))
    with pytest.raises(ValueError, match="planet parameters are"):
        jp.fit(truth, lc, free=("b.albedo",))
    with pytest.raises(ValueError, match="N-body orbits only"):
        jp.fit(truth, lc, free=("b.mass",))  # a parameter of N-body systems
    with pytest.raises(ValueError, match="N-body orbits only"):
        jp.fit(truth, lc, free=("star.mass",))
    with pytest.raises(ValueError, match="has no moon 'I'"):
        jp.fit(truth, lc, free=("b.I.a",))
    with pytest.raises(ValueError, match="star has"):
        jp.fit(truth, lc, free=("star.u1",))  # the default star is non-linear: c1..c4


def test_real_kepler20_q1_window_fit():
    """The real Q1 long-cadence window (29.4-minute exposures, integrated):
    fit b and c mid-times and radii; reduced chi^2 near 1."""
    lc = jp.LightCurve.from_csv(data_path("kepler20_kic6850504_q1_llc_BKJD159.0-161.5.csv"), exposure=0.02043357)
    assert lc.report["flagged"] == 7
    system = jp.kepler20_system(jp.Star.quadratic(0.495, 0.154))
    ev = jp.multi_transits(system, 159.0, 161.5)[0]
    model0 = np.asarray(system.flux(lc.time, 0.0))
    lc = lc.normalized([(159.0, 161.5)], in_transit=model0 < 1.0)
    res = jp.fit(system, lc, free=("b.t0", "b.radius", "c.t0", "c.radius"))
    assert res.success, res.message
    assert 0.6 < res.reduced_chi2 < 1.6
    assert abs(res.values[0] - float(system.planets[0].t0)) < 0.02
    assert 159.0 < ev.mid < 161.5


def test_sample_widens_the_union_frames_to_the_posterior():
    """As in fit: NUTS started where c misses its PPO frames samples again
    with every PPO frame its posterior reaches integrated exactly."""
    from jaxppo.inference._model import Model

    truth = jp.kepler20_system()
    lc = jp.simulate_kepler20(seed=5, noise=2e-4, alpha=90.0)
    b, c = truth.planets
    start = truth.replace(planets=(b, c.replace(t0=c.t0 + 0.014)))
    free = ("c.t0",)
    truth_frames = Model(truth, lc, free, alpha=90.0).union_frames_of(truth, lc.time)
    assert not np.all(np.isin(truth_frames, Model(start, lc, free, alpha=90.0).union_idx))
    post = jp.sample(start, lc, free=free, num_warmup=150, num_samples=150, num_chains=1, alpha=90.0,
                     progress_bar=False)
    assert np.all(np.isin(truth_frames, post.union_frames))
    lo, hi = post.intervals["c.t0"][1:]
    width = hi - lo
    assert lo - 2 * width < c.t0 < hi + 2 * width


def test_fit_from_a_tiny_radius_reaches_the_minimum():
    """Issue 16 item 10: from radius 1e-6 R* chi^2 is flat in log p and
    Levenberg-Marquardt's step criteria were met at once (success at chi^2
    3668 against 2999). The fit must end below chi^2 at the true
    parameters (an independent upper bound on the minimum) and agree with
    the fit started at the truth."""
    truth = jp.kepler20_system()
    lc = jp.simulate_kepler20(seed=11, noise=4e-4)
    b, c = truth.planets
    chi2_truth = float(np.sum(((lc.flux - np.asarray(truth.flux(lc.time, 0.0))) / lc.flux_err) ** 2))
    free = ("b.t0", "b.radius")
    res = jp.fit(truth.replace(planets=(b.replace(radius=1e-6), c)), lc, free=free)
    assert res.success, res.message
    assert res.chi2 < chi2_truth
    ref = jp.fit(truth, lc, free=free)
    assert np.all(np.abs(res.values - ref.values) < 0.01 * ref.errors), (res.values - ref.values) / ref.errors


def test_fit_reports_what_went_wrong():
    """Issue 16 item 10: starts where no fit can succeed say why, instead of
    success (a non-transiting start, one point for two parameters) or
    "max steps reached" (chi^2 = inf from flux_err = 1e-300)."""
    truth = jp.kepler20_system()
    lc = jp.simulate_kepler20(seed=11, noise=4e-4)
    b, c = truth.planets
    res = jp.fit(truth.replace(planets=(b.replace(inc=0.0), c)), lc, free=("b.t0", "b.radius", "b.inc"))
    assert not res.success and "planet b does not transit" in res.message, res.message
    assert res.values[2] == 0.0  # the start, not a clipped version of it
    deepest = int(np.argmin(np.asarray(truth.flux(lc.time, 0.0))))
    one = jp.LightCurve(lc.time[deepest:deepest + 1], lc.flux[deepest:deepest + 1], lc.flux_err[deepest:deepest + 1])
    res = jp.fit(truth, one, free=("b.t0", "b.radius"))
    assert not res.success and "1 data points for 2 free parameters" in res.message, res.message
    assert np.all(np.isnan(res.errors))
    tiny = jp.LightCurve(lc.time, lc.flux, np.full(len(lc), 1e-300))
    res = jp.fit(truth, tiny, free=("b.t0", "b.radius"))
    assert not res.success and "flux_err" in res.message and "maximum number of steps" not in res.message, res.message


def test_fit_flags_a_point_that_is_not_a_minimum():
    """A fit stopped after two steps from a shifted start is not at a
    minimum: the Newton decrement says so even if the optimiser did not."""
    from jaxppo.inference._minimum import assess
    from jaxppo.inference._model import Model

    truth = jp.kepler20_system()
    lc = jp.simulate_kepler20(seed=11, noise=4e-4)
    b, c = truth.planets
    model = Model(truth, lc, ("b.t0", "b.radius"))
    shifted = truth.replace(planets=(b.replace(t0=b.t0 + 0.0003, radius=0.0178), c))
    verdict = assess(model, model.to_theta(shifted))
    assert not verdict["optimum"] and "Newton step would lower chi^2" in verdict["problems"][0], verdict["problems"]
    assert assess(model, model.to_theta(jp.fit(truth, lc, free=model.free).system))["optimum"]


def test_fit_computes_every_frame_the_solution_transits():
    """The model computes only frames where a disk is within 0.25 R* of the
    star at the start (the rest are exactly 1). A start 0.03 d early (b moves
    ~0.5 R* in that time) must end with every frame of the solution's transit
    computed: chi^2 of the result equals chi^2 of System.flux at it."""
    from jaxppo.inference._model import Model

    truth = jp.kepler20_system()
    lc = jp.simulate_kepler20(seed=11, noise=4e-4)
    b, c = truth.planets
    start = truth.replace(planets=(b.replace(t0=b.t0 - 0.03), c))
    free = ("b.t0", "b.radius")
    assert not np.all(np.isin(Model(truth, lc, free).active_frames_of(truth, lc.time, 0.0), Model(start, lc, free).active_idx))
    res = jp.fit(start, lc, free=free)
    assert res.success, res.message
    chi2 = float(np.sum(((lc.flux - np.asarray(res.system.flux(lc.time, 0.0))) / lc.flux_err) ** 2))
    assert abs(res.chi2 - chi2) < 1e-6 * chi2
    assert abs(res.values[0] - float(b.t0)) < 5 * res.errors[0]


# ---- user-facing parameters: Kipping q1/q2, nuisance terms, results on disk ----

def _one_planet(u=(0.4, 0.25), inc=89.0, radius=0.1, noise=2e-4, seed=0, jitter=0.0, offset=0.0, trend=None,
                two=False):
    """One planet (P = 10 d, a = 20 R*) on a quadratic star, 2-min cadence
    over +-0.25 d of each transit (``two``: two transits); returns (truth,
    LightCurve)."""
    truth = jp.System(jp.Star.quadratic(*u), [jp.Planet(period=10.0, t0=0.0, a=20.0, inc=inc, radius=radius, name="b")])
    t = np.arange(-0.25, 0.25, 2.0 / 1440.0)
    if two:
        t = np.concatenate([t, t + 10.0])
    f = np.asarray(truth.flux(t)) * (1.0 + offset)
    if trend is not None:
        f = f * trend(t)
    f = f + np.random.default_rng(seed).normal(0.0, np.hypot(noise, jitter), t.size)
    return truth, jp.LightCurve(t, f, np.full(t.size, noise))


def test_kipping_map_is_the_analytic_one():
    from jaxppo.inference._model import Model
    from jaxppo.inference._params import kipping_q, kipping_u

    # Kipping (2013) eqs. 15-18 by hand: q1 = 0.36, q2 = 0.25 -> u1 = 2 * 0.6 * 0.25, u2 = 0.6 * (1 - 0.5)
    assert np.allclose(kipping_u(0.36, 0.25), (0.3, 0.3), rtol=0, atol=1e-15)
    assert np.allclose(kipping_q(0.3, 0.3), (0.36, 0.25), rtol=0, atol=1e-15)
    assert np.allclose(kipping_q(*kipping_u(0.81, 0.1)), (0.81, 0.1), rtol=0, atol=1e-14)
    # the Model's coordinates: q = logistic(theta), u from the map, u fixed when only one q is free
    truth, lc = _one_planet()
    m = Model(truth, lc, ("star.q1", "star.q2"))
    th = np.log(np.array([0.36, 0.25]) / (1 - np.array([0.36, 0.25])))
    assert np.allclose(np.asarray(m.to_system(th).star.params), [0.3, 0.3], atol=1e-12)
    assert np.allclose(np.asarray(m.physical(th)), [0.36, 0.25], atol=1e-12)
    assert np.allclose(np.asarray(m.to_system(m.to_theta(truth)).star.params), [0.4, 0.25], atol=1e-12)
    m1 = Model(truth, lc, ("star.q1",))
    q2 = 0.4 / (2 * 0.65)  # from u1 = 0.4, u2 = 0.25
    u = np.asarray(m1.to_system(np.array([0.0])).star.params)  # q1 = 0.5
    assert np.allclose(u, [2 * np.sqrt(0.5) * q2, np.sqrt(0.5) * (1 - 2 * q2)], atol=1e-12)
    with pytest.raises(ValueError, match="name one pair"):
        Model(truth, lc, ("star.q1", "star.u2"))
    with pytest.raises(ValueError, match="need a quadratic star"):
        jp.fit(jp.kepler20_system(), jp.simulate_kepler20(seed=1), free=("star.q1",))


@pytest.fixture(scope="module")
def q_fit():
    truth, lc = _one_planet()
    start = truth.replace(star=jp.Star.quadratic(0.3, 0.3))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = jp.fit(start, lc, free=("b.t0", "b.radius", "star.q1", "star.q2"))
    res.caught = [str(w.message) for w in caught]
    return truth, lc, res


def test_fit_with_q1_q2_recovers_the_injected_u1_u2(q_fit):
    truth, lc, res = q_fit
    assert res.success, res.message
    assert set(res.derived) == {"star.u1", "star.u2"}
    for k, name in enumerate(("star.u1", "star.u2")):
        v, e = res.derived[name]
        assert 0 < e < 0.1 and abs(v - (0.4, 0.25)[k]) < 3 * e, (name, v, e)
        assert np.isclose(v, float(res.system.star.params[k]), rtol=0, atol=1e-14)
    # the linearised errors are invariant under the reparameterisation: a fit
    # of u1, u2 themselves reaches the same minimum with the same errors
    direct = jp.fit(truth.replace(star=jp.Star.quadratic(0.3, 0.3)), lc, free=("b.t0", "b.radius", "star.u1", "star.u2"))
    assert direct.success, direct.message
    for k, name in enumerate(("star.u1", "star.u2")):
        assert abs(direct.values[2 + k] - res.derived[name][0]) < 0.01 * direct.errors[2 + k]
        assert np.isclose(direct.errors[2 + k], res.derived[name][1], rtol=0.01)


def test_fit_recovers_an_injected_offset_and_jitter():
    s, noise, n = 4e-4, 2e-4, None
    truth, lc = _one_planet(jitter=s, offset=0.002)
    n = len(lc)
    res = jp.fit(truth, lc, free=("b.t0", "b.radius", "lc.offset", "lc.jitter"))
    assert res.success, res.message
    names = list(res.names)
    off, jit = names.index("lc.offset"), names.index("lc.jitter")
    assert abs(res.values[off] - 0.002) < 3 * res.errors[off]
    assert abs(res.values[jit] - s) < 3 * res.errors[jit]
    # Gaussian variance V = noise^2 + s^2 from N points: sd(V) = V sqrt(2 / N), so sd(s) = V / (s sqrt(2 N))
    expect = (noise**2 + s**2) / (s * np.sqrt(2.0 * n))
    assert abs(res.errors[jit] / expect - 1) < 0.1, (res.errors[jit], expect)
    assert 0.85 < res.reduced_chi2 < 1.15  # chi^2 with the inflated errors
    # chi2 is the full objective: chi^2 part + sum ln(1 + s^2 / sigma^2)
    assert np.isclose(res.chi2, res.reduced_chi2 * (n - 4) + n * np.log1p((res.values[jit] / noise) ** 2), rtol=1e-9)
    # the printed table names the objective as what it is ("chi2 = 4062.54, reduced 1.001" read as a
    # mismatch: 4062.54 / 2452 = 1.66)
    last = res.table().splitlines()[-1]
    assert last.startswith(f"-2 ln L - sum ln(2 pi sigma^2) = {res.chi2:.2f} (the objective with a free jitter)")
    assert f"chi^2 with the jitter's errors / (N - k) = {res.reduced_chi2:.3f}" in last


def test_fit_per_window_baseline():
    def trend(t):  # a different linear trend in each window, in x = (t - mid) / half-width
        x = np.where(t < 5, t / 0.2479, (t - 10.0) / 0.2479)
        return np.where(t < 5, 1.0 + 1e-3 + 4e-4 * x, 1.0 - 5e-4 - 3e-4 * x)

    truth, lc = _one_planet(trend=trend, two=True)
    res = jp.fit(truth, lc, free=("b.t0", "b.radius", "lc.baseline"))
    assert res.success, res.message
    assert res.names[2:] == ("lc.baseline.w0.c0", "lc.baseline.w0.c1", "lc.baseline.w1.c0", "lc.baseline.w1.c1")
    half = 0.5 * (lc.time[lc.time < 5][-1] - lc.time[0])
    want = np.array([1e-3, 4e-4 * half / 0.2479, -5e-4, -3e-4 * half / 0.2479])
    pulls = (res.values[2:] - want) / res.errors[2:]
    assert np.all(np.abs(pulls) < 3), pulls
    with pytest.raises(ValueError, match="degenerate"):
        jp.fit(truth, lc, free=("b.t0", "lc.offset", "lc.baseline2"))


def test_degenerate_covariance_warns_and_points_to_sample(q_fit):
    # a grazing transit (b = 1.05, p = 0.1): radius, a and inc are degenerate
    truth, lc = _one_planet(inc=87.0)
    with pytest.warns(UserWarning, match="jaxppo.sample"):
        res = jp.fit(truth, lc, free=("b.t0", "b.radius", "b.a", "b.inc"))
    assert res.condition > 1e6
    # well constrained (t0, p, q1, q2 of a full transit): no warning
    assert q_fit[2].success and q_fit[2].condition < 100 and q_fit[2].caught == []


def test_a_negative_variance_is_no_error_and_no_success(monkeypatch):
    """An indefinite covariance (a float32 fit of a nearly circular N-body
    orbit with secosw, sesinw free gave variances -4.6e-3, -8.7e6, -756)
    printed every error as +- 0.00e+00 with success True: clipped to 0, a
    negative variance read as perfect knowledge. Now NaN, and the fit
    says it failed, naming the parameters."""
    import jaxppo.inference._fit as fit_module

    real = fit_module._physical_covariance

    def indefinite(model, theta, cov_theta):
        cov, derived, values = real(model, theta, cov_theta)
        cov = cov.copy()
        cov[1, 1] = -abs(cov[1, 1])
        return cov, derived, values

    truth, lc = _one_planet()
    monkeypatch.setattr(fit_module, "_physical_covariance", indefinite)
    res = jp.fit(truth, lc, free=("b.t0", "b.radius"))
    assert np.isfinite(res.errors[0]) and res.errors[0] > 0
    assert np.isnan(res.errors[1]), res.errors
    assert not res.success and "b.radius" in res.message and "negative" in res.message, res.message
    assert "nan" in res.table().lower()


def test_covariance_warning_names_a_flat_or_non_finite_axis():
    """The warning read "chi^2 rises by nan" for a non-finite axis, and a
    float32 run's zero rise raised numpy's divide-by-zero RuntimeWarning
    (its 1e-300 floor was 0 in float32)."""
    from jaxppo.inference._fit import _warn_if_degenerate

    for dchi2, text in ((np.array([0.0, 1.0], np.float32), "rises by 0 instead"),
                        (np.array([np.nan, 1.0]), "is not finite")):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            _warn_if_degenerate(("b.t0", "b.radius"), {"condition": 1.0, "dchi2_1sigma": dchi2, "weakest": ""})
        assert [type(w.message) for w in caught] == [UserWarning], [str(w.message) for w in caught]
        assert text in str(caught[0].message) and "nan" not in str(caught[0].message)


def test_fit_result_save_load_round_trip(q_fit, tmp_path):
    import json

    res = q_fit[2]
    path = res.save(tmp_path / "fit.json")
    raw = json.loads(open(path).read())
    assert raw["format"] == "jaxppo.FitResult" and raw["version"] == jp.__version__
    assert raw["names"] == list(res.names)
    back = jp.FitResult.load(path)
    assert back.names == res.names and back.success == res.success and back.message == res.message
    for a, b in ((back.values, res.values), (back.errors, res.errors), (back.covariance, res.covariance)):
        assert np.array_equal(np.asarray(a), np.asarray(b))
    assert back.chi2 == res.chi2 and back.reduced_chi2 == res.reduced_chi2 and back.derived == res.derived
    assert np.array_equal(np.asarray(back.system.star.params), np.asarray(res.system.star.params))
    for p, q in zip(back.system.planets, res.system.planets):
        assert p.name == q.name and all(float(getattr(p, k)) == float(getattr(q, k))
                                        for k in ("t0", "period", "a", "inc", "radius"))
    # a tabulated star (the bundled Kepler-20 model) round-trips too, and NaN survives as null
    sysk = jp.kepler20_system()
    nan = dataclasses_replace(res, system=sysk, errors=np.full(4, np.nan))
    back = jp.FitResult.load(nan.save(tmp_path / "k20.json"))
    assert np.all(np.isnan(back.errors))
    assert np.allclose(np.asarray(back.system.flux(np.linspace(-0.1, 0.1, 5) + float(sysk.planets[0].t0))),
                       np.asarray(sysk.flux(np.linspace(-0.1, 0.1, 5) + float(sysk.planets[0].t0))), rtol=0, atol=0)
    with pytest.raises(ValueError, match="not a FitResult"):
        (tmp_path / "x.json").write_text("{}")
        jp.FitResult.load(tmp_path / "x.json")


def dataclasses_replace(obj, **kw):
    import dataclasses

    return dataclasses.replace(obj, **kw)


def test_fit_accepts_a_lightkurve_lightcurve(q_fit):
    import lightkurve as lk
    from astropy.time import Time

    truth, lc, res = q_fit
    # lightkurve's own Kepler time format (BKJD, the planets' zero point)
    klc = lk.LightCurve(time=Time(lc.time, format="bkjd", scale="tdb"), flux=lc.flux, flux_err=lc.flux_err)
    start = truth.replace(star=jp.Star.quadratic(0.3, 0.3))
    got = jp.fit(start, klc, free=("b.t0", "b.radius", "star.q1", "star.q2"))
    assert got.success, got.message
    assert np.allclose(got.values, res.values, rtol=0, atol=0.01 * res.errors.min())
    with pytest.raises(ValueError, match="lightcurve must be"):
        jp.fit(truth, (lc.time, lc.flux), free=("b.t0",))


def test_fit_model_keeps_an_eccentric_orbit():
    """The fit's model is the system's light curve, eccentricity included:
    it used to rebuild every planet circular (e and omega dropped), so an
    eccentric planet was fitted with the wrong transit duration and shape."""
    from jaxppo.inference._model import Model

    truth = jp.System(jp.Star.quadratic(0.4, 0.25),
                      [jp.Planet(period=10.0, t0=0.0, a=20.0, inc=89.0, radius=0.1, name="b", e=0.5, omega=30.0)])
    t = np.arange(-0.25, 0.25, 2.0 / 1440.0)
    f = np.asarray(truth.flux(t))
    lc = jp.LightCurve(t, f, np.full(t.size, 2e-4))
    m = Model(truth, lc, ("b.t0", "b.radius"))
    theta = m.to_theta(truth)
    assert np.max(np.abs(np.asarray(m.flux(theta)) - f)) < 1e-12
    sys_back = m.to_system(theta)
    assert float(sys_back.planets[0].e) == 0.5 and float(sys_back.planets[0].omega) == 30.0
    res = jp.fit(truth, lc, free=("b.t0", "b.radius"))
    assert res.success, res.message
    assert abs(res.values[0]) < 1e-6 and abs(res.values[1] - 0.1) < 1e-6


def _one_transit(flux_scale=1.0, err_scale=1.0):
    """A simulated transit (radius 0.1, noise 1e-3, 200 points) and a start
    off in t0 and radius."""
    star = jp.Star.quadratic(0.4, 0.25)
    truth = jp.System(star, [jp.Planet(period=3.0, t0=0.0, a=10.0, inc=89.0, radius=0.1, name="b")])
    lc = jp.simulate(truth, np.linspace(-0.15, 0.15, 200), noise=1e-3, seed=1)
    lc = jp.LightCurve(lc.time, lc.flux * flux_scale, lc.flux_err * flux_scale * err_scale)
    start = jp.System(star, [jp.Planet(period=3.0, t0=0.003, a=10.0, inc=89.0, radius=0.09, name="b")])
    return start, lc


@pytest.mark.parametrize("scale", [1e3, 1e2, 2e5])
def test_fit_refuses_flux_that_is_not_relative(scale):
    """Flux in ppt, percent or electrons (median 1000, 100, 2e5) used to end
    in "failed: Levenberg-Marquardt stopped: no step lowers chi^2" with
    a = 5e12 R*; it is refused by name, with its median, before fitting."""
    start, lc = _one_transit(flux_scale=scale)
    with pytest.raises(ValueError, match=r"flux has median .*relative flux"):
        jp.fit(start, lc, free=("b.t0", "b.radius"))
    deviations = jp.LightCurve(lc.time, lc.flux / scale - 1.0, lc.flux_err / scale)
    with pytest.raises(ValueError, match="normalised first"):
        jp.fit(start, deviations, free=("b.t0", "b.radius"))


def test_fit_warns_where_chi2_says_the_errors_are_off():
    """flux_err 3 times too small: success True, chi^2 / (N - k) ~ 9 and
    errors 3 times too small, and fit said nothing; it now warns with the
    factor. With the right errors it stays silent."""
    start, lc = _one_transit(err_scale=1.0 / 3.0)
    with pytest.warns(UserWarning, match=r"chi\^2 / \(N - k\) = 7\.[0-9]+ .*too small by about a factor 2\.[0-9]"):
        res = jp.fit(start, lc, free=("b.t0", "b.radius"))
    assert res.success and res.reduced_chi2 > 7
    start, lc = _one_transit(err_scale=10.0)  # flux_err 10x too large: so are the errors
    with pytest.warns(UserWarning, match=r"chi\^2 / \(N - k\) = 0\.00[0-9]+ .*too large by about a factor 1[01]\."):
        jp.fit(start, lc, free=("b.t0", "b.radius"))
    start, lc = _one_transit()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        jp.fit(start, lc, free=("b.t0", "b.radius"))


@pytest.mark.parametrize("alpha, match", [(np.nan, "alpha must be one finite angle"),
                                          (np.inf, "alpha must be one finite angle"),
                                          ([10.0, 20.0], "alpha must be one finite angle")])
def test_fit_refuses_an_alpha_that_is_not_one_finite_angle(alpha, match):
    """alpha=NaN gave success False with "planet b does not transit in the
    data at the start (impact parameter 0.37 ...)" (System.flux refuses it
    by name), and a list of two tilts a numpy broadcasting error."""
    start, lc = _one_transit()
    with pytest.raises(ValueError, match=match):
        jp.fit(start, lc, free=("b.t0", "b.radius"), alpha=alpha)
