"""The marginal obliquity scan (issue 11) against independent computations:
the plain scan (jp.scan) for draws at the fixed parameters, a brute-force
loop over draws with the exact union integral on every frame, the injected
PPO with wrong fixed parameters, resume and strict JSON."""

import json

import numpy as np
import pytest

import jaxppo as jp
from jaxppo.obliquity._marginal import PROGRESS, marginal_chi2, marginal_scan
from jaxppo.model._overlap import ppo_table
from jaxppo.obliquity._windows import scan_windows

REAL = "jaxppo/data/kepler20_real_llc.toml"
# two of the real double transits (BKJD), so the tests stay small; two the model fits (334.02 alone, at these
# settings: chi^2 47.3 for 17 points, p = 1e-4, and the scan withholds its probabilities)
EVENTS = [496.77, 670.45]
KW = dict(alpha=np.arange(0.0, 360.0, 10.0), detrend=2, baseline=0.3, margin=0.05, clip=5.0, multi_transits=EVENTS)


@pytest.fixture(scope="module")
def real():
    from pathlib import Path

    cfg = jp.load_config(Path(__file__).resolve().parents[2] / REAL)
    return cfg.system, cfg.lightcurve


def _draws(system, n, seed=1):
    """Draws scattered about the fixed parameters (t0 by ~2 min, a by ~2 %,
    inc by ~0.1 deg), so the curves differ from draw to draw."""
    rng = np.random.default_rng(seed)
    out = {}
    for pl in system.planets:
        out[f"{pl.name}.t0"] = float(pl.t0) + rng.normal(0, 2.0 / 1440, n)
        out[f"{pl.name}.a"] = float(pl.a) * (1 + rng.normal(0, 0.02, n))
        out[f"{pl.name}.inc"] = np.minimum(float(pl.inc) + rng.normal(0, 0.1, n), 90.0)
    return out


def _strict(text):
    def bad(c):
        raise AssertionError(f"non-strict JSON constant {c}")

    return json.loads(text, parse_constant=bad)


def test_equal_draws_reproduce_the_plain_scan(real, tmp_path):
    """N draws all at the fixed parameters: every curve, the marginal curve,
    the posterior and the geometry probabilities are those of jp.scan (30
    equal draws: importance ESS 30, above the guard's 25)."""
    system, lc = real
    fixed = jp.scan(system, lc, **KW)
    same = {f"{pl.name}.{p}": np.full(30, float(getattr(pl, p))) for pl in system.planets for p in ("t0", "a")}
    m = marginal_scan(system, lc, samples=same, out=tmp_path, progress=False, figures=False, **KW)
    for case in ("same", "opposite"):
        a, d = fixed.delta_chi2(case)
        t = m.table[m.table["case"] == case]
        np.testing.assert_array_equal(t["alpha"], a)
        for col in ("marginal_delta_chi2", "delta_chi2_median", "delta_chi2_p16", "delta_chi2_p84"):
            np.testing.assert_allclose(t[col], d, atol=1e-8, rtol=0)
        post = fixed.table["posterior"][fixed.table["case"] == case]
        np.testing.assert_allclose(t["posterior"], post, rtol=1e-8, atol=1e-14)
        for name, geo in fixed.summary["probabilities"][case].items():
            if isinstance(geo, dict):
                assert m.summary["probabilities"][case][name]["probability"] == pytest.approx(geo["probability"], abs=1e-10)
        assert m.summary["probabilities"][case]["jeffreys"] == fixed.summary["probabilities"][case]["jeffreys"]
        assert m.summary["cases"][case]["reliable"]
        # the features are not all zero: the check has something to compare
        assert np.ptp(d) > 0.1
    _strict((tmp_path / "marginal.json").read_text())


def test_draws_that_do_not_reach_the_fixed_fit_rate_nothing(real, tmp_path):
    """Draws that fit the data far worse than the configuration's own
    parameters (in a review, NUTS draws whose a/R* were tied to one stellar
    density, on data made from a/R* of two: chi^2 43 above the fixed
    scan's best of 2,884 for 2,924 points, so the goodness of fit passed)
    rated the geometries of a model that does not describe the data. Now
    the least chi^2 of the draws is checked against the fixed scan's best:
    more than k + 3 sqrt(2 k) above it (k free parameters) withholds every
    case with the reason. Here 30 draws at the fixed parameters against a
    fixed scan whose best chi^2 is set 20 lower (a stand-in: on these 27
    points a real offset is caught by the goodness of fit first); the same
    draws against the true fixed scan pass (the test above)."""
    system, lc = real
    fixed = jp.scan(system, lc, **KW)
    same = {f"{pl.name}.{p}": np.full(30, float(getattr(pl, p))) for pl in system.planets for p in ("t0", "a")}
    fixed.summary["goodness_of_fit"]["chi2_best"] -= 20.0
    m = marginal_scan(system, lc, samples=same, fixed=fixed, out=tmp_path, progress=False, figures=False, **KW)
    reach = m.summary["goodness_of_fit"]["reach"]
    assert reach["checked"] and reach["excess"] == pytest.approx(20.0, abs=1e-6), reach
    assert reach["limit"] == pytest.approx(4 + 3 * np.sqrt(8.0)) and not m.summary["goodness_of_fit"]["ok"]
    for case in ("same", "opposite"):
        cs = m.summary["cases"][case]
        assert not cs["reliable"] and cs["importance"]["withheld_by"] == "goodness_of_fit"
        assert "cannot fit these data as well as the fixed parameters do" in cs["importance"]["reason"]
        assert all(g["probability"] is None for g in cs["geometries"].values() if isinstance(g, dict))
    _strict((tmp_path / "marginal.json").read_text())


def test_draws_of_few_independent_samples_rate_nothing(real, tmp_path):
    """Kish's ESS of the importance weights counts N draws as N, also when
    the chains sit in different places or move slowly (a review: R-hat up
    to 5.8, bulk ESS 19 of 16 draws, and the report said nothing of it).
    The sampler's own bulk ESS (least over the parameters) below min_ess
    now withholds every case; R-hat above 1.1 alone prints a caution (from
    16 draws per chain it passes 1.5 for chains that sample correctly but
    slowly). The draws are those of the test above, their stored record
    given the diagnostics a sampler would write."""
    from jaxppo.obliquity._marginal import DRAWS
    from jaxppo.obliquity._marginal_result import sampler_mixing

    system, lc = real
    same = {f"{pl.name}.{p}": np.full(30, float(getattr(pl, p))) for pl in system.planets for p in ("t0", "a")}
    kw = dict(samples=same, out=tmp_path, progress=False, figures=False, **KW)
    assert marginal_scan(system, lc, **kw).summary["cases"]["same"]["reliable"]
    rec = json.loads((tmp_path / DRAWS).read_text())
    for ess, r_hat, reliable, caution in ((19.27, 5.8, False, False), (None, None, False, False),
                                          (30.0, 1.3, True, True), (30.0, 1.004, True, False)):
        rec["sampler"]["diagnostics"] = {n: {"r_hat": 1.002, "ess_bulk": 60.0, "ess_tail": 60.0} for n in same}
        rec["sampler"]["diagnostics"]["c.a"].update(r_hat=r_hat, ess_bulk=ess)
        (tmp_path / DRAWS).write_text(json.dumps(rec))
        m = marginal_scan(system, lc, **kw)
        mixing = m.summary["sampler_mixing"]
        assert mixing == sampler_mixing(rec["sampler"], 25) and mixing["checked"]
        for case in ("same", "opposite"):
            cs = m.summary["cases"][case]
            assert cs["reliable"] == reliable, (ess, r_hat, cs["importance"])
            if not reliable:
                assert cs["importance"]["withheld_by"] == "sampler_mixing"
                assert "the bulk ESS of c.a" in cs["importance"]["reason"]
        said = [line for line in m.summary_lines() if line.startswith("  caution: the sampler's chains mix")]
        assert bool(said) == caution and (not caution or "R-hat c.a 1.30" in said[0])
    assert not sampler_mixing({"method": "given by the caller"}, 25)["checked"]


def test_importance_average_against_brute_force(real, tmp_path):
    """Per-draw Delta chi^2 and the marginal -2 log mean exp(-Delta chi^2/2)
    against a plain loop over draws: System.flux with the exact union
    integral on every frame, exposure-averaged, chi^2_0 from ppo_table."""
    system, lc = real
    samples = _draws(system, 4)
    m = marginal_scan(system, lc, samples=samples, out=tmp_path, progress=False, figures=False, **KW)
    cfg_windows = jp.scan(system, lc, **KW).windows
    data = jp.LightCurve(np.concatenate([w.time for w in cfg_windows]), np.concatenate([w.flux for w in cfg_windows]),
                         np.concatenate([w.flux_err for w in cfg_windows]), lc.exposure)
    tm, nsub = data.supersampled_times()
    per_event = [jp.LightCurve(w.time, w.flux, w.flux_err, w.exposure).supersampled_times()[0] for w in cfg_windows]
    alpha = KW["alpha"]
    loud = 0
    for ci, case in enumerate(("same", "opposite")):
        dcs = []
        for d in range(4):
            planets = [pl.replace(**{p: float(samples[f"{pl.name}.{p}"][d]) for p in ("t0", "a", "inc")})
                       for pl in system.planets]
            s = system.replace(planets=planets)
            model = np.asarray(s.flux(tm, alpha, case=case, method="exact")).reshape(alpha.size, -1, nsub).mean(-1)
            chi2 = np.sum(((data.flux - model) / data.flux_err) ** 2, axis=1)
            quiet = ~ppo_table(s, per_event, alpha, case).any(1)
            assert quiet.any()
            loud += int((~quiet).sum())
            dcs.append(chi2 - np.median(chi2[quiet]))
        dcs = np.array(dcs)
        np.testing.assert_allclose(m.delta_chi2[:, ci], dcs, atol=1e-5, rtol=0)
        brute = -2 * np.log(np.mean(np.exp(-0.5 * dcs), axis=0))
        t = m.table[m.table["case"] == case]
        np.testing.assert_allclose(t["marginal_delta_chi2"], brute, atol=1e-5, rtol=0)
        # the draws differ: the marginal is not any single draw's curve
        assert np.max(np.ptp(dcs, axis=0)) > 0.5
    assert loud > 0  # some draw has PPO tilts on this grid


def _brute(system, samples, windows, exposure, alpha, case, names=("t0", "a", "inc")):
    """chi^2 [draw, alpha] and chi^2_0 [draw] by a plain loop over draws:
    System.flux with the exact union integral on every frame."""
    data = jp.LightCurve(np.concatenate([w.time for w in windows]), np.concatenate([w.flux for w in windows]),
                         np.concatenate([w.flux_err for w in windows]), exposure)
    tm, nsub = data.supersampled_times()
    per_event = [jp.LightCurve(w.time, w.flux, w.flux_err, w.exposure).supersampled_times()[0] for w in windows]
    n = len(next(iter(samples.values())))
    chi2s, c0s = [], []
    for d in range(n):
        planets = [pl.replace(**{p: float(samples[f"{pl.name}.{p}"][d]) for p in names}) for pl in system.planets]
        s = system.replace(planets=planets)
        model = np.asarray(s.flux(tm, alpha, case=case, method="exact")).reshape(alpha.size, -1, nsub).mean(-1)
        chi2 = np.sum(((data.flux - model) / data.flux_err) ** 2, axis=1)
        quiet = ~ppo_table(s, per_event, alpha, case).any(1)
        chi2s.append(chi2)
        c0s.append(np.median(chi2[quiet]) if quiet.any() else np.nan)
    return np.array(chi2s), np.array(c0s)


def test_weights_against_the_sampling_tilt(real, tmp_path, monkeypatch):
    """Draws sampled at a tilt alpha_ref with a PPO: the exact importance
    weight is L(alpha) / L(alpha_ref). The NUTS call is replaced by fixed
    draws (the weighting is what is checked) and alpha_ref is put on a PPO
    feature; the marginal curve is checked against a brute-force loop."""
    import jaxppo.obliquity._marginal as mod

    system, lc = real
    samples = _draws(system, 4, seed=5)
    fixed = jp.scan(system, lc, **KW)
    a, d = fixed.delta_chi2("same")
    a_ref = float(a[np.argmax(np.abs(d))])

    monkeypatch.setattr(mod, "nuts_draws", lambda *args, **kw: ({k: np.asarray(v) for k, v in samples.items()},
                                                                 {"method": "fixed draws"}))
    monkeypatch.setattr(mod, "quiet_alpha", lambda *args: a_ref)
    free = [f"{pl.name}.{p}" for pl in system.planets for p in ("t0", "a", "inc")]
    m = marginal_scan(system, lc, draws=4, free=free, fixed=fixed, out=tmp_path, progress=False, figures=False, **KW)
    assert m.summary["sampler"]["alpha_ref"] == a_ref
    chi2_ref, _ = _brute(system, samples, fixed.windows, lc.exposure, np.array([a_ref]), "same")
    assert m.summary["alpha_ref_quiet_fraction"] < 1  # some draw has a PPO at alpha_ref: the reference matters
    for case in ("same", "opposite"):
        chi2, c0 = _brute(system, samples, fixed.windows, lc.exposure, KW["alpha"], case)
        ref = chi2_ref[:, 0]
        lme = lambda v: np.log(np.mean(np.exp(v), axis=0))  # noqa: E731
        expect = -2 * lme(-0.5 * (chi2 - ref[:, None])) + 2 * lme(-0.5 * (c0 - ref))
        t = m.table[m.table["case"] == case]
        np.testing.assert_allclose(t["marginal_delta_chi2"], expect, atol=1e-5, rtol=0)
        # and it is not the chi^2_0-referenced average
        other = -2 * lme(-0.5 * (chi2 - c0[:, None]))
        assert np.max(np.abs(expect - other)) > 0.05


def test_marginal_chi2_no_overlap_is_null(real):
    """A grid with no overlap anywhere (a planet shrunk to a point far from
    the other's path cannot touch it): chi^2 is the no-PPO chi^2 for every
    alpha and case."""
    system, lc = real
    tiny = system.replace(planets=[system.planets[0].replace(radius=1e-6), system.planets[1]])
    w = scan_windows(jp.load_config(__import__("pathlib").Path(__file__).resolve().parents[2] / REAL))[:1]
    data = jp.LightCurve(w[0].time, w[0].flux, w[0].flux_err, w[0].exposure)
    tm, nsub = data.supersampled_times()
    chi2, null, ppo = marginal_chi2([tiny], tm, nsub, data.flux, data.flux_err, np.arange(0, 360, 30.0), ("same",))
    ref = np.sum(((data.flux - np.asarray(tiny.flux(tm, 0.0, method="exact")).reshape(-1, nsub).mean(-1))
                  / data.flux_err) ** 2)
    assert null[0] == pytest.approx(ref, rel=1e-9)  # midpoint rule vs union integral
    # a 1e-6 R* disk overlaps c at a few alphas; its effect is < 1e-9 in flux
    np.testing.assert_allclose(chi2[0, 0], null[0], rtol=1e-9)


def test_resume_after_interruption(real, tmp_path, monkeypatch):
    """An interrupted run (the last record torn, one chunk missing) resumes:
    only the missing draws are recomputed and the result is unchanged."""
    system, lc = real
    samples = _draws(system, 5, seed=3)
    kw = dict(samples=samples, out=tmp_path, progress=False, figures=False, chunk=2, **KW)
    full = marginal_scan(system, lc, **kw)
    ref_table = full.table.copy()
    prog = tmp_path / PROGRESS
    lines = prog.read_text().split("\n")
    # header + 5 draws x (null + 2 x (curve + chi2_0)) records; keep the
    # first chunk (2 draws) and half of the next record
    per_draw = 5
    keep = lines[: 1 + 2 * per_draw]
    prog.write_text("\n".join(keep) + "\n" + lines[1 + 2 * per_draw][:40])
    (tmp_path / "marginal.json").unlink()
    import jaxppo.obliquity._marginal as mod

    seen = []
    orig = mod.marginal_chi2

    def counting(systems, *a, **k):
        seen.append(len(systems))
        return orig(systems, *a, **k)

    monkeypatch.setattr(mod, "marginal_chi2", counting)
    with pytest.warns(UserWarning, match="cut by an interruption"):
        again = marginal_scan(system, lc, **kw)
    assert sum(seen) == 3  # draws 2, 3, 4 only
    for name in ref_table.dtype.names[1:]:
        np.testing.assert_allclose(again.table[name], ref_table[name], rtol=1e-12, atol=1e-14)
    _strict((tmp_path / "marginal.json").read_text())
    # a changed setting is refused, not mixed in, naming what changed (it said "a different configuration"
    # for a new number of draws of the same config, and its advice threw the draws away)
    other = dict(kw, samples=_draws(system, 5, seed=4))
    with pytest.raises(ValueError, match="same config with other marginal settings .*samples_sha256"):
        marginal_scan(system, lc, **other)
    with pytest.raises(ValueError, match=r"other marginal settings \(draws 5 -> 4; samples_sha256"):
        marginal_scan(system, lc, **dict(kw, samples=_draws(system, 4, seed=3)))
    moved = system.replace(planets=(system.planets[0].replace(radius=0.019), system.planets[1]))
    with pytest.raises(ValueError, match="different configuration"):  # another config: the plain refusal
        marginal_scan(moved, lc, **kw)


def test_bad_input(real):
    system, lc = real
    with pytest.raises(ValueError, match="draws"):
        marginal_scan(system, lc, draws=0, **KW)
    with pytest.raises(ValueError, match="samples"):
        marginal_scan(system, lc, samples={"b.t0": np.ones(3), "c.a": np.ones(2)}, **KW)
    with pytest.raises(ValueError, match="'b.ecc'"):
        marginal_scan(system, lc, samples={"b.ecc": np.ones(3)}, **KW)
    with pytest.raises(ValueError, match="chunk"):
        marginal_scan(system, lc, samples={"b.t0": np.full(2, 134.5)}, chunk=0, **KW)
    with pytest.raises(ValueError, match="stellar_density"):
        marginal_scan(system, lc, draws=2, stellar_density=(-1.5, 0.1), progress=False, figures=False, **KW)
    with pytest.raises(ValueError, match="'star.c1'"):
        marginal_scan(system, lc, draws=2, free=["b.t0", "star.c1"], progress=False, figures=False, **KW)


def test_config_stellar_density_is_checked(tmp_path):
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / REAL).read_text()
    base = str((Path(__file__).resolve().parents[2] / REAL).parent)
    text = text.replace('path = "kepler20_kic', f'path = "{base}/kepler20_kic')
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("stellar_density = [1.53, 0.15]", "stellar_density = [1.53, -0.15]"))
    with pytest.raises(ValueError, match=r"\[fit\] stellar_density"):
        jp.load_config(bad)
    good = jp.load_config(Path(__file__).resolve().parents[2] / REAL)
    assert good.raw["fit"]["stellar_density"] == [1.53, 0.15]


def _fragility():
    """The fragility case of issue 11: a PPO injected at alpha = 147 deg
    (case "same"; planets twice Kepler-20's size, 2e-4 noise per 1-min
    point) and the scanned parameters off (c's t0 by 4 min, b's a/R* by
    3 %). Returns (true system, light curve, wrong system, scan keywords,
    the fixed scan of the wrong system), after checking that the fixed scan
    is fooled (its best tilt more than 90 deg from 147)."""
    true = jp.kepler20_system(radius_scale=2.0)
    lc = jp.simulate_kepler20(seed=2021, alpha=147.0, case="same", radius_scale=2.0, noise=2e-4)
    b, c = true.planets
    wrong = true.replace(planets=[b.replace(a=float(b.a) * 1.03), c.replace(t0=float(c.t0) + 4.0 / 1440.0)])
    kw = dict(alpha=np.arange(0.0, 360.0, 1.0), cases=("same",), detrend="none")
    fixed = jp.scan(wrong, lc, **kw)
    a, d = fixed.delta_chi2("same")
    assert abs(a[np.argmin(d)] - 147.0) > 90  # the fixed scan is fooled
    return true, lc, wrong, kw, fixed


def test_wrong_fixed_parameters_are_mitigated(tmp_path):
    """The fragility of issue 11: a PPO injected at alpha = 147 deg (case
    "same"; planets twice Kepler-20's size, 2e-4 noise per 1-min point), the
    scanned parameters off (c's t0 by 4 min, b's a/R* by 3 %). The fixed scan
    picks a wrong alpha; the scan marginalised over draws of the (b.a, c.t0)
    posterior (a Gaussian about jp.fit with its covariance: the posterior is
    Gaussian here; the NUTS draws are in the next test) peaks within 3 deg
    of 147."""
    from jaxppo.obliquity._marginal import quiet_alpha

    true, lc, wrong, kw, fixed = _fragility()
    free = ("b.a", "c.t0")
    fit = jp.fit(wrong, lc, free=free, alpha=quiet_alpha(wrong, lc.time, "same"))
    assert fit.success, fit.message
    draws = np.random.default_rng(0).multivariate_normal(fit.values, fit.covariance, size=64)
    m = marginal_scan(wrong, lc, samples={n: draws[:, i] for i, n in enumerate(free)}, fixed=fixed, out=tmp_path,
                      progress=False, figures=False, **kw)
    assert m.summary["cases"]["same"]["reliable"], m.summary["cases"]["same"]["importance"]["groups"]
    assert m.summary["cases"]["same"]["peak"]["alpha"] == pytest.approx(147.0, abs=3.0)
    t = m.table
    peak = t["alpha"][np.argmax(t["posterior"])]
    assert abs(peak - 147.0) <= 3.0, peak
    # the posterior mass near the injected alpha dominates (1-deg grid)
    assert t["posterior"][np.abs(t["alpha"] - 147.0) <= 3.0].sum() > 0.5


def test_fixed_scan_of_another_config_is_refused(real):
    system, lc = real
    other = jp.scan(system, lc, **dict(KW, multi_transits=EVENTS[:1]))
    with pytest.raises(ValueError, match="fixed"):
        marginal_scan(system, lc, samples={"b.t0": np.full(2, float(system.planets[0].t0))}, fixed=other,
                      progress=False, figures=False, **KW)


def test_kepler_third_law_against_the_earth():
    """a/R* from the stellar density: the Sun's mean density (M_sun / (4/3
    pi R_sun^3) = 1.4098 g/cm^3, IAU 2015 nominal values) and the sidereal
    year give 1 au / R_sun = 215.03 (Earth's mass changes it by 1e-6)."""
    from jaxppo.inference._coords import a_from_density, density_from_a

    m_sun, r_sun, au = 1.98847e33, 6.957e10, 1.495978707e13  # [g], [cm], [cm]
    rho_sun = m_sun / (4.0 / 3.0 * np.pi * r_sun**3)
    assert a_from_density(rho_sun, 365.256363) == pytest.approx(au / r_sun, rel=2e-5)
    assert density_from_a(au / r_sun, 365.256363) == pytest.approx(rho_sun, rel=6e-5)
    # Kepler-20: Buchhave et al. (2016)'s a/R* of b and c imply one density
    assert density_from_a(10.34, 3.69611525) == pytest.approx(1.53, abs=0.01)
    assert density_from_a(21.17, 10.85409089) == pytest.approx(1.53, abs=0.01)


def test_flat_without_a_ppo(tmp_path):
    """Synthetic data without a PPO (planets twice Kepler-20's size, 2e-4
    noise per 1-min point, simulated at a tilt with no overlap in any
    frame), the marginal over draws scattered about the truth: at every
    alpha where no draw has a PPO the marginal Delta chi^2 and its 16-84 %
    band are exactly 0 (the model is the no-PPO model there), and nowhere
    does the marginal favour a PPO tilt by more than noise; at the PPO
    tilts the model predicts a bump the data lack, so the curve rises."""
    from jaxppo.obliquity._marginal import quiet_alpha

    true = jp.kepler20_system(radius_scale=2.0)
    kw = dict(alpha=np.arange(0.0, 360.0, 1.0), cases=("same",), detrend="none")  # 2 deg: the grid check
    tm0 = jp.simulate_kepler20(seed=7, alpha=0.0, case="same", radius_scale=2.0, noise=2e-4).time
    quiet = quiet_alpha(true, tm0, "same")
    lc = jp.simulate_kepler20(seed=7, alpha=quiet, case="same", radius_scale=2.0, noise=2e-4)
    rng = np.random.default_rng(3)
    b, c = true.planets
    draws = {"b.a": float(b.a) * (1 + rng.normal(0, 0.005, 32)), "c.t0": float(c.t0) + rng.normal(0, 0.3 / 1440, 32)}
    m = marginal_scan(true, lc, samples=draws, out=tmp_path, progress=False, figures=False, **kw)
    t = m.table
    loud = np.any(m.delta_chi2[:, 0] != 0.0, axis=0)  # some draw has a PPO at this alpha
    assert loud.any() and (~loud).any()
    for col in ("marginal_delta_chi2", "delta_chi2_p16", "delta_chi2_p84", "delta_chi2_median"):
        np.testing.assert_array_equal(t[col][~loud], 0.0)
    assert t["marginal_delta_chi2"].min() > -4.0  # no PPO preferred beyond 2 sigma
    assert t["marginal_delta_chi2"].max() > 10.0  # the PPO tilts are excluded
    # the posterior is flat (uniform density 1/360) wherever no PPO can occur, up to normalisation
    assert m.summary["cases"]["same"]["reliable"], m.summary["cases"]["same"]["importance"]["groups"]
    flat = t["posterior"][~loud]
    assert np.all(np.isfinite(flat)) and flat[0] > 0
    np.testing.assert_allclose(flat, flat[0], rtol=1e-12)


def test_wrong_fixed_parameters_with_nuts_draws(tmp_path):
    """The fragility case of issue 11 end to end with the marginal's own
    sampler: NUTS draws of (b.a tied to rho*, c.t0) at the quiet tilt from
    the wrong starting values (c's t0 4 min late, b's a/R* 3 % large; the
    density prior centred on the wrong a/R*, 10 % wide), then the marginal
    scan: the posterior peaks within 3 deg of the injected 147 deg where the
    fixed scan picks a tilt more than 90 deg away."""

    true, lc, wrong, kw, fixed = _fragility()
    c = true.planets[1]
    m = marginal_scan(wrong, lc, draws=64, free=("b.a", "c.t0"), num_warmup=150, chains=2, fixed=fixed,
                      out=tmp_path, progress=False, figures=False, **kw)
    diag = m.summary["sampler"]["diagnostics"]
    assert max(v["r_hat"] for v in diag.values()) < 1.1, diag
    off = m.summary["parameters"]["c.t0"]["median"] - float(c.t0)  # sampled at the transit nearest the windows' middle
    off -= np.round(off / float(c.period)) * float(c.period)
    assert abs(off) < 0.5 / 1440, off * 1440  # c's t0 back within 0.5 min of the truth
    assert m.summary["cases"]["same"]["reliable"], m.summary["cases"]["same"]["importance"]
    t = m.table
    peak = t["alpha"][np.argmax(t["posterior"])]
    assert abs(peak - 147.0) <= 3.0, peak


def test_guard_withholds_what_one_draw_carries(tmp_path):
    """The held-out failure of issue 22: when a few draws carry the
    importance average the scan printed their probability, peak and a
    "decisive" rating. The fragility case (high-SNR PPO at 147 deg) with 30
    draws of (b.a, c.t0) five times wider than jp.fit's errors: a handful
    of draws put the PPO where the data have it (geometry-mass ESS ~4 of
    30). No probability, peak or rating in the result, the JSON, the CSV or
    the printed summary; the case says why; the figure is still drawn."""
    from jaxppo.obliquity._marginal import quiet_alpha

    true, lc, wrong, kw, fixed = _fragility()
    free = ("b.a", "c.t0")
    fit = jp.fit(wrong, lc, free=free, alpha=quiet_alpha(wrong, lc.time, "same"))
    draws = np.random.default_rng(0).multivariate_normal(fit.values, 25.0 * fit.covariance, size=30)
    m = marginal_scan(wrong, lc, samples={n: draws[:, i] for i, n in enumerate(free)}, fixed=fixed, out=tmp_path,
                      progress=False, figures=True, **kw)
    cc = m.summary["cases"]["same"]
    assert cc["reliable"] is False
    assert cc["importance"]["groups"]["total"]["ess"] < 10.0
    assert cc["peak"] is None and "unreliable" in cc["importance"]["reason"]
    geo = m.summary["probabilities"]["same"]
    assert geo["bayes_factor"] is None and geo["jeffreys"] == "not rated" and geo["favoured"] is None
    assert all(v["probability"] is None for v in geo.values() if isinstance(v, dict))
    assert np.all(np.isnan(m.table["posterior"]))
    text = "\n".join(m.summary_lines())
    assert "decisive" not in text and "%" not in text and "no probability" in text
    saved = _strict((tmp_path / "marginal.json").read_text())
    assert saved["cases"]["same"]["reliable"] is False
    assert "nan" in (tmp_path / "marginal.csv").read_text().splitlines()[1]
    assert (tmp_path / "marginal.png").is_file()


def test_guard_refuses_bad_min_ess(real):
    system, lc = real
    with pytest.raises(ValueError, match="min_ess"):
        marginal_scan(system, lc, samples={"b.t0": np.full(30, float(system.planets[0].t0))}, min_ess=0,
                      progress=False, figures=False, **KW)


def test_guard_withholds_a_peak_one_draw_carries(real, tmp_path, monkeypatch):
    """The geometry masses may be sound while the density at the peak rests
    on one draw: 30 draws with flat curves but draw 0 with Delta chi^2 = -6
    at alpha = 130 deg. The probabilities stay (geometry-mass ESS ~29 of 30)
    but no peak is given (its ESS is 5.6 < 25); the CSV carries the ESS of
    every alpha. (The old guard gave peak = 130 deg.)"""
    import jaxppo.obliquity._marginal as mod

    system, lc = real
    real_chi2 = mod.marginal_chi2

    def stub(systems, tm, nsub, y, sig, alpha, cases):
        _, _, ppo = real_chi2(systems[:1], tm, nsub, y, sig, alpha, cases)
        n = len(systems)
        level = float(np.size(y))  # chi^2 ~ N: a model that fits (the scan withholds a misfit's probabilities)
        chi2 = np.full((n, len(cases), alpha.size), level)
        first = stub.next
        stub.next += n
        if first == 0:
            chi2[0, :, alpha == 130.0] -= 6.0
        return chi2, np.full(n, level), np.zeros((n, len(cases), alpha.size), bool)

    stub.next = 0
    monkeypatch.setattr(mod, "marginal_chi2", stub)
    b, c = system.planets
    samples = {"b.t0": np.full(30, float(b.t0)), "c.t0": float(c.t0) + np.linspace(-1e-4, 1e-4, 30)}
    m = marginal_scan(system, lc, samples=samples, out=tmp_path, progress=False, figures=False, **KW)
    for case in ("same", "opposite"):
        cc = m.cases[case]
        assert cc["reliable"] and cc["geometries"]["favoured"] is not None
        assert cc["peak"] is None and "peak" in cc["importance"]["peak_withheld"]
        assert cc["importance"]["peak_ess"] < 6.0 and cc["min_delta_chi2"] is None
    t = m.table[m.table["case"] == "same"]
    assert t["importance_ess"][t["alpha"] == 130.0][0] < 6.0 and t["importance_ess"].max() == pytest.approx(30.0)
    assert "no posterior peak" in "\n".join(m.summary_lines())


def test_free_transit_times_in_the_transit_posterior_and_the_draws():
    """Issue 23: a listed transit time is a free parameter of the marginal
    scan ("b.tc[1]", or "b.tc" for every listed epoch): the transit
    posterior's mode moves a time listed 4 min late back to the one the
    data were made with, and each draw's System carries its sampled time
    (the chi^2 of the true time is the lower)."""
    from jaxppo.inference._posterior import TransitPosterior, mode_and_cov
    from jaxppo.obliquity._marginal import _check_samples, _systems_from, marginal_chi2

    star = jp.Star.quadratic(0.4, 0.25)
    true_times = [0.0, 10.004, 19.998]
    b = jp.Planet(10.0, 0.0, 20.0, 89.5, 0.1, name="b", transit_times=true_times, transit_epochs=[0, 1, 2])
    c = jp.Planet(10.0, 0.02, 25.0, 89.6, 0.08, name="c")
    truth = jp.System(star, [b, c], tilted="b")
    t = np.concatenate([np.arange(m - 0.25, m + 0.25, 2.0 / 1440.0) for m in (0.0, 10.0, 20.0)])
    lc = jp.simulate(truth, t, noise=2e-4, seed=4)
    late = truth.replace(planets=(b.replace(transit_times=[0.0, 10.004 + 4.0 / 1440.0, 19.998]), c))
    post = TransitPosterior(late, lc, ("b.tc[1]", "b.radius"), (1.5, 0.15), 0.0, "same")
    assert post.free == ("b.tc[1]", "b.radius")
    u, _, _ = mode_and_cov(post)
    phys, _ = post.physical(u)
    assert abs(float(phys[0]) - 10.004) < 0.5 / 1440.0, (float(phys[0]) - 10.004) * 1440.0
    every = TransitPosterior(late, lc, ("b.tc",), (1.5, 0.15), 0.0, "same")
    assert every.free == ("b.tc[0]", "b.tc[1]", "b.tc[2]")
    samples = {"b.tc[1]": np.array([10.004, 10.004 + 4.0 / 1440.0])}
    assert _check_samples(late, samples)[0] == ["b.tc[1]"]
    systems = _systems_from(late, samples, list(samples))
    assert [float(s.planets[0].transit_times[1]) for s in systems] == list(samples["b.tc[1]"])
    chi2, _, _ = marginal_chi2(systems, lc.time, 1, lc.flux, lc.flux_err, np.array([0.0]), ("same",))
    assert chi2[0, 0, 0] < chi2[1, 0, 0] - 100.0
    with pytest.raises(ValueError, match="lists no epoch 7"):
        TransitPosterior(late, lc, ("b.tc[7]",), (1.5, 0.15), 0.0, "same")


def test_free_period_with_fixed_t0_scans_the_orbits_it_sampled(tmp_path):
    """NUTS samples P about each t0 moved to the middle of the data; the
    draws' systems kept the config's t0 (100 periods before the data) with
    the sampled P, so every transit sat n dP off (chi^2 of the no-PPO model
    40 times the number of points): they are now built about the t0 the
    sampler used (review of issue 22/23's change)."""
    star = jp.Star.quadratic(0.4, 0.25)
    b = jp.Planet(10.0, -1000.0, 20.0, 89.5, 0.1, name="b")
    c = jp.Planet(10.0, -999.98, 25.0, float(np.degrees(np.arccos(-0.5 / 25))), 0.08, name="c")
    truth = jp.System(star, [b, c], tilted="b")
    t = np.concatenate([np.arange(m - 0.25, m + 0.25, 2.0 / 1440.0) for m in (0.0, 10.0, 20.0)])
    lc = jp.simulate(truth, t, noise=2e-4, seed=4)
    res = jp.marginal_scan(truth, lc, draws=8, num_warmup=50, chains=2, free=["b.period", "b.radius"],
                           alpha=np.arange(0.0, 360.0, 30.0), cases=("same",), detrend="none", min_ess=1,
                           progress=False, figures=False, out=tmp_path)
    n = res.summary["points"] if "points" in res.summary else t.size
    assert res.summary["chi2_null"]["max"] < 1.5 * n, (res.summary["chi2_null"], n)


def test_transit_time_names_in_draws_are_checked():
    """Two columns of draws for one listed time ("b.tc[1]", "b.tc[ 1]")
    were both accepted and one silently dropped; "b.tc" for a planet
    without transit times said to write what was written (review)."""
    from jaxppo.obliquity._marginal import _check_samples

    star = jp.Star.quadratic(0.4, 0.25)
    b = jp.Planet(10.0, 0.0, 20.0, 89.5, 0.1, name="b", transit_times=[0.0, 10.0], transit_epochs=[0, 1])
    c = jp.Planet(10.0, 0.02, 25.0, 89.6, 0.08, name="c")
    system = jp.System(star, [b, c], tilted="b")
    with pytest.raises(ValueError, match=r"'b.tc\[1\]' and 'b.tc\[ 1\]' name the same parameter"):
        _check_samples(system, {"b.tc[1]": np.zeros(2) + 10.0, "b.tc[ 1]": np.zeros(2) + 10.004})
    with pytest.raises(ValueError, match=r"one listed transit time each, like 'b.tc\[12\]'"):
        _check_samples(system, {"b.tc": np.zeros(2)})
    with pytest.raises(ValueError, match="planet 'c' has no transit_times"):
        _check_samples(system, {"c.tc": np.zeros(2)})
    from jaxppo.inference._posterior import TransitPosterior

    lc = jp.simulate(system, np.linspace(-0.2, 0.2, 50), noise=1e-4)
    with pytest.raises(ValueError, match="planet 'c' has no transit_times"):
        TransitPosterior(system, lc, ("c.tc",), (1.5, 0.15), 0.0, "same")
