"""Stellar activity: rotation period, variability, brightness map
(Mueller et al. 2021, Sects. 2.4, 3.2). Truth comes from injected signals
(independent of the code under test) and from the paper's numbers."""

import json
import math

import numpy as np
import pytest

import jaxppo as jp
from jaxppo.activity import (activity_report, brightness_map, load_kepler20_quarters, prepare_light_curve,
                             quarter_variability, rotation_period, transit_mask)


def _synthetic(period=9.37, amp=5e-4, noise=3e-4, harmonic=0.0, span=360.0, seed=1):
    """Kepler-like long cadence over ``span`` days: 4 quarters with their own
    levels, random data gaps, a sinusoid (plus an optional first harmonic)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, span, 0.0204)
    keep = np.ones(t.size, bool)
    for start in rng.uniform(0, span, 12):  # 12 gaps of 0.5-3 d
        keep &= ~((t > start) & (t < start + rng.uniform(0.5, 3.0)))
    edges = np.linspace(0, span, 5)
    keep &= np.min(np.abs(t[:, None] - edges[None, 1:-1]), axis=1) > 0.6  # quarter gaps
    t = t[keep]
    q = np.digitize(t, edges[1:-1]) + 1
    levels = np.array([1.0, 0.97, 1.03, 0.985])[q - 1] * 1.5e5
    phase = 2 * np.pi * t / period
    signal = amp * (np.sin(phase) + harmonic * np.sin(2 * phase + 0.7))
    return t, levels * (1 + signal + rng.normal(0, noise, t.size)), q


def test_injected_period_recovered_within_uncertainty():
    p_true = 9.37
    t, f, q = _synthetic(p_true)
    prep = prepare_light_curve(t, f, quarters=q, mask_transits=False)
    # stitching: every quarter now has median 0 despite 3 % level offsets
    for qv in np.unique(prep.quarter):
        assert abs(np.median(prep.flux[prep.quarter == qv])) < 1e-4
    rot = rotation_period(prep.time, prep.flux, period_min=2.0, period_max=40.0)
    assert abs(rot.period - p_true) < rot.period_err
    # the HWHM of a 360-d baseline is about P^2 / (2 T) ~ 0.1 d: not vacuous
    assert 0.02 < rot.period_err < 0.2
    # a pure sinusoid is not doubled (a two-harmonic periodogram alone has
    # the same power at 2P: the BIC penalty must keep P)
    assert not rot.doubled and rot.delta_bic < 10
    assert rot.false_alarm < 1e-10


def test_two_spot_signal_found_at_rotation_not_half():
    """A light curve dominated by its first harmonic (two spot groups): the
    single-sinusoid GLS peaks at P/2; the BIC rule finds P."""
    p_true = 13.0
    t, f, q = _synthetic(p_true, amp=3e-4, harmonic=1.5, seed=3)
    prep = prepare_light_curve(t, f, quarters=q, mask_transits=False)
    rot = rotation_period(prep.time, prep.flux)
    assert abs(rot.single_peak - p_true / 2) < 0.05
    assert rot.doubled and rot.delta_bic > 10
    assert abs(rot.period - p_true) < rot.period_err


def test_outliers_and_transits_removed():
    t, f, q = _synthetic()
    rng = np.random.default_rng(5)
    bad = rng.choice(t.size, 20, replace=False)
    f = f.copy()
    f[bad] *= 1 + rng.choice([-1, 1], 20) * 50 * 3e-4  # 50-sigma outliers
    prep = prepare_light_curve(t, f, quarters=q, mask_transits=False)
    assert not np.any(np.isin(t[bad], prep.time))
    assert prep.report["outliers"] <= 22  # a 5-sigma cut drops ~no Gaussian point
    assert abs(prep.report["scatter_ppm"] - 300) < 15


def test_transit_mask_matches_contact_times():
    """Masked span = first-to-last contact (analytic T14, Seager & Mallen-Ornelas 2003) + margin."""
    pl = jp.Planet(period=5.0, t0=1.0, a=12.0, inc=88.0, radius=0.05, name="x")
    system = jp.System(jp.Star.quadratic(0.4, 0.2), [pl])
    b = 12.0 * math.cos(math.radians(88.0))
    t14 = 5.0 / math.pi * math.asin(math.sqrt((1.05) ** 2 - b**2) / (12.0 * math.sin(math.radians(88.0))))
    margin = 0.05
    edge = t14 / 2 + margin
    t = 11.0 + np.array([-edge - 1e-4, -edge + 1e-4, 0.0, edge - 1e-4, edge + 1e-4, 2.5])
    assert transit_mask(t, system, margin=margin).tolist() == [True, False, False, False, True, True]
    # Kepler-20 b and c by default
    t = np.array([134.501962, 138.60847, 136.0])
    assert transit_mask(t, jp.kepler20_system()).tolist() == [False, False, True]


def test_transit_mask_is_the_one_in_transit_mask():
    """transit_mask is the negated model-layer mask (pad = margin), not a copy."""
    from jaxppo.model._overlap import in_transit_mask

    system = jp.kepler20_system()
    t = np.random.default_rng(3).uniform(120.0, 1600.0, 20000)
    for margin in (0.0, 0.1):
        assert np.array_equal(transit_mask(t, system, margin=margin), ~in_transit_mask(system, t, pad=margin))
    with pytest.raises(ValueError, match="system"):
        transit_mask(t, "Kepler-20")


def test_segments_from_gaps_when_no_quarters():
    t, f, q = _synthetic()
    prep = prepare_light_curve(t, f, mask_transits=False, gap=0.5)
    assert prep.report["n_quarters"] >= 4  # quarter gaps + the random gaps
    for qv in np.unique(prep.quarter):
        assert abs(np.median(prep.flux[prep.quarter == qv])) < 1e-4


@pytest.fixture(scope="module")
def kepler20():
    t, f, q = load_kepler20_quarters()
    return prepare_light_curve(t, f, quarters=q)


def test_real_kepler20_period_and_variability(kepler20):
    """Documented ranges (docs/activity.md): the GLS peak lies near the
    paper's 26.948 d (we find 27.51 d; the stitched PDCSAP periodogram is a
    forest of spot-evolution peaks), its single-sinusoid peak near half of
    it; variability 0.05-0.45 % per quarter, Q17 the largest."""
    prep = kepler20
    assert prep.report["n_quarters"] == 17
    assert prep.report["in_transit"] > 6000
    rot = rotation_period(prep.time, prep.flux)
    assert 26.0 < rot.period < 29.0
    assert rot.doubled
    assert 12.5 < rot.single_peak < 14.5
    var = quarter_variability(prep)
    assert set(var) == {str(i) for i in range(1, 18)}
    assert max(var, key=var.get) == "17"
    assert 0.35 < var["17"] < 0.6
    assert 0.1 < np.median([var[str(i)] for i in range(1, 17)]) < 0.2
    assert all(0.05 < v < 0.5 for v in var.values())


def test_map_chunking():
    # binary-exact times: every bin of 0.5 d holds exactly 32 samples
    period, t_ref = 8.0, 96.0
    t = t_ref + np.arange(0.0, 36.0, 1 / 64)
    y = np.sin(2 * np.pi * (t - t_ref) / period)
    m = brightness_map(t, y, period, t_ref=t_ref, bins=16, min_points=1)
    assert m.chunk_start.tolist() == [96.0, 104.0, 112.0, 120.0, 128.0]
    assert m.phase_edges[0] == -0.5 and m.phase_edges[-1] == 1.5
    assert np.count_nonzero(~m.repeated) == 16  # one rotation of own bins in [0, 1)
    assert np.all(m.counts[1:4] == 32)
    own = m.flux[:, ~m.repeated]
    # a strictly periodic signal looks the same in every full chunk
    assert np.allclose(own[:4], own[0], atol=1e-9)
    # each bin holds the mean of its 32 samples: compare with the discrete
    # mean from the sampling formula (independent of the binning code)
    w = 1 / 16
    k = np.arange(32)
    expect = [100 * np.mean(np.sin(2 * np.pi * (j * w + k / 512))) for j in range(16)]
    assert np.allclose(own[1], expect, atol=1e-9)
    # repeated parts: chunk 1 at phase 1.2 is chunk 2 at phase 0.2
    i12 = np.searchsorted(m.phase_edges, 1.2) - 1
    i02 = np.searchsorted(m.phase_edges, 0.2) - 1
    assert m.flux[1, i12] == pytest.approx(m.flux[2, i02])
    i_neg = np.searchsorted(m.phase_edges, -0.3) - 1
    i07 = np.searchsorted(m.phase_edges, 0.7) - 1
    assert m.flux[2, i_neg] == pytest.approx(m.flux[1, i07])
    assert np.isnan(m.flux[0, i_neg])  # nothing before the first chunk


def test_report_writes_json_and_figures(tmp_path):
    t, f, q = _synthetic(span=120.0)
    rep = activity_report(t, f, out=tmp_path, quarters=q, mask_transits=False, bootstrap=5,
                          period_max=30.0, compare_paper=False, spot_chunk=2, n_spots=1)
    text = (tmp_path / "activity.json").read_text()
    assert json.loads(text)["rotation"]["period_d"] == pytest.approx(rep["rotation"]["period_d"])
    assert "NaN" not in text and "Infinity" not in text
    json.dumps(rep, allow_nan=False)
    assert abs(rep["rotation"]["period_d"] - 9.37) < rep["rotation"]["period_err_d"]
    assert [c["chunk"] for c in rep["spots"]["chunks"]] == [2]
    assert len(rep["spots"]["chunks"][0]["longitude_deg"]) == 1
    for name in ("activity_map.png", "activity_periodogram.png", "activity_spots.png"):
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(rep["rotation"]["bootstrap_percentiles_16_50_84_d"]) == 3
    # a doubled period says what it rests on (a BIC gain that correlated residuals also give)
    assert (rep["rotation"]["caution"] is not None) == rep["rotation"]["doubled"]


@pytest.mark.parametrize("call, name", [
    (lambda t, y: rotation_period(t, y, period_min=-1.0), "period_min"),
    (lambda t, y: rotation_period(t, y, period_min=10.0, period_max=5.0), "period_max"),
    (lambda t, y: rotation_period(t, y[:-1]), "flux"),
    (lambda t, y: rotation_period(t, y, harmonic_window=0.7), "harmonic_window"),
    (lambda t, y: rotation_period(t, y, bootstrap=3), "bootstrap"),
    (lambda t, y: brightness_map(t, y, period=-2.0), "period"),
    (lambda t, y: brightness_map(t, y, period=5.0, bins=2), "bins"),
    (lambda t, y: prepare_light_curve(t, 1 + y, quarters=np.ones(3), mask_transits=False), "quarters"),
    (lambda t, y: prepare_light_curve(t, 1 + y, system="Kepler-20"), "system"),
    (lambda t, y: prepare_light_curve(t, 1 + y, clip=0.0, mask_transits=False), "clip"),
    (lambda t, y: activity_report(t, 1 + y, compare_paper="yes"), "compare_paper"),
    (lambda t, y: activity_report(t, 1 + y, mask_transits=False, bootstrap=0, period_max=20.0, spot_chunk=99),
     "spot_chunk"),
])
def test_bad_input_names_parameter(call, name):
    t = np.linspace(0, 100, 500)
    y = 1e-3 * np.sin(t)
    with pytest.raises(ValueError, match=name):
        call(t, y)


def _cap_deficit(t, lon, lat, rho, contrast, period, inc, u1, u2, n=150):
    """Brute-force flux deficit of one spherical cap: sum of c I(mu) mu dOmega
    over the visible part of the cap, on a polar grid around the spot
    centre, divided by F0 = 2 pi int I mu dmu (numerical). Independent of
    the small-spot formula."""
    lon, lat, rho, inc = np.deg2rad([lon, lat, rho, inc])
    obs = np.array([np.sin(inc), 0.0, np.cos(inc)])  # observer, star frame (z = spin axis)
    th = (np.arange(n) + 0.5) / n * rho
    ps = (np.arange(2 * n) + 0.5) / (2 * n) * 2 * np.pi
    TH, PS = np.meshgrid(th, ps, indexing="ij")
    dA = np.sin(TH) * (rho / n) * (np.pi / n)
    mu_grid = np.linspace(0, 1, 200001)
    inten = lambda mu: 1 - u1 * (1 - mu) - u2 * (1 - mu) ** 2
    f0 = 2 * np.pi * np.trapezoid(inten(mu_grid) * mu_grid, mu_grid)
    out = []
    for ti in np.atleast_1d(t):
        rot = 2 * np.pi * ti / period - lon  # spot longitude relative to the sub-observer meridian
        p0 = np.array([np.cos(lat) * np.cos(rot), np.cos(lat) * np.sin(rot), np.sin(lat)])
        e1 = np.cross(p0, [0.3, 0.5, 0.81]); e1 /= np.linalg.norm(e1)
        e2 = np.cross(p0, e1)
        pts = (np.cos(TH)[..., None] * p0 + np.sin(TH)[..., None] * (np.cos(PS)[..., None] * e1 + np.sin(PS)[..., None] * e2))
        mu = pts @ obs
        vis = mu > 0
        out.append(np.sum(np.where(vis, contrast * inten(np.clip(mu, 0, 1)) * mu * dA, 0.0)) / f0)
    return np.array(out)


@pytest.mark.parametrize("inc, lat", [(90.0, 0.0), (60.0, 30.0), (75.0, -20.0)])
def test_spot_flux_matches_brute_force_cap(inc, lat):
    from jaxppo.activity import spot_flux

    rho, c, period, lon, u1, u2 = 4.0, 0.59, 20.0, 100.0, 0.495, 0.154
    t = np.linspace(0, 20, 13)
    ref = _cap_deficit(t, lon, lat, rho, c, period, inc, u1, u2)
    got = -np.asarray(spot_flux(t, [lon], [lat], [rho], c, period, inc, u1, u2))
    mu0 = (np.cos(np.deg2rad(inc)) * np.sin(np.deg2rad(lat))
           + np.sin(np.deg2rad(inc)) * np.cos(np.deg2rad(lat)) * np.cos(2 * np.pi * t / period - np.deg2rad(lon)))
    full = mu0 > 0.1  # cap fully visible (rho = 0.07 rad)
    assert full.sum() >= 5 and (~full).sum() >= 3
    # leading neglected term: the mu^2 part of I(mu) mu averaged over the cap,
    # c sin^2(rho) (u1 + 2 u2) var(mu) / norm with var(mu) <= rho^2 / 4; x2 margin
    r = np.deg2rad(rho)
    bound = 2 * c * np.sin(r) ** 2 * (u1 + 2 * u2) * r**2 / 4 / (1 - u1 / 3 - u2 / 6)
    assert np.max(np.abs(got[full] - ref[full])) < bound
    assert bound < 0.01 * ref.max()  # the bound is tight: 1 % of the signal
    assert np.all(got[mu0 < -0.1] == 0) and np.all(ref[mu0 < -0.1] == 0)
    assert ref.max() > 1e-3  # a real signal, not zeros vs zeros


def test_fit_spots_recovers_injected_spots():
    import jax

    jax.config.update("jax_enable_x64", True)
    from jaxppo.activity import fit_spots, spot_flux

    rng = np.random.default_rng(7)
    period = 26.9
    t = np.sort(rng.uniform(0, period, 1200))
    truth_lon, truth_rad = np.array([70.0, 220.0]), np.array([4.0, 2.5])
    y = 2e-4 + np.asarray(spot_flux(t, truth_lon, [0.0, 0.0], truth_rad, 0.59, period)) + rng.normal(0, 1e-4, t.size)
    fit = fit_spots(t, y, period, n_spots=2, t_ref=0.0, n_starts=4)
    assert fit.success
    assert np.allclose(fit.lon, truth_lon, atol=2.0)
    assert np.allclose(fit.radius, truth_rad, rtol=0.05)
    assert abs(fit.chi2 / t.size - 1) < 0.15


def test_ppo_or_spot_recovers_an_injected_bump():
    """A Gaussian bump injected into a transit (noise-free, errors 1e-5) is
    recovered by the spot model; the PPO model of a one-planet system is the
    no-PPO model, so BIC prefers the spot, and the BIC counts k ln N."""
    import math
    from types import SimpleNamespace

    from jaxppo.activity._ppo_or_spot import bump_model, ppo_or_spot

    pl = jp.Planet(period=3.0, t0=0.0, a=8.0, inc=89.0, radius=0.08, name="b")
    system = jp.System(jp.Star.quadratic(0.4, 0.26), [pl])
    t = np.linspace(-0.1, 0.1, 60)
    base = np.asarray(system.flux(t, method="exact"))
    truth = (8e-4, 0.01, 0.006)
    y = base + np.asarray(bump_model(t, *truth))
    win = SimpleNamespace(number=1, time=t, flux=y, flux_err=np.full(t.size, 1e-5), exposure=None,
                          event=SimpleNamespace(mid=0.0))

    class Result(dict):
        windows = [win]

    res = Result(table5=[{"kind": "dip", "case": "same", "alpha": 10.0, "delta_chi2": -1.0, "transits": [1]}])
    out = ppo_or_spot(res, system)
    dip = out["dips"][0]
    fit = dip["windows"][0]["bump"]
    assert abs(fit["amplitude"] - truth[0]) < 1e-6 and abs(fit["centre"] - truth[1]) < 1e-5
    assert abs(fit["width"] - truth[2]) < 1e-5
    assert dip["windows"][0]["chi2_spot"] < 1e-3 < dip["windows"][0]["chi2_no_ppo"]
    assert dip["delta_chi2"]["ppo"] == 0.0 and dip["preferred"] == "spot"
    assert dip["delta_bic"]["spot"] == pytest.approx(dip["delta_chi2"]["spot"] + 3 * math.log(60))
    # without the bump neither alternative pays for its parameters: the verdict
    # is "no PPO" (it used to be whichever of PPO and spot cost less)
    win.flux = base + np.random.default_rng(3).normal(0.0, 1e-5, t.size)
    quiet = ppo_or_spot(res, system)["dips"][0]
    assert quiet["delta_bic"]["ppo"] > 0 and quiet["delta_bic"]["spot"] > 0
    assert quiet["preferred"] == "no PPO"


def test_ppo_or_spot_on_a_spotted_star_compares_the_right_models():
    """On a star with spots the verdict stopped with "method='exact' needs a
    radially symmetric star; this star has a surface map" (a method the
    user never chose), and its no-PPO model held the overlap (sweep's
    no_overlap was not applied off the "auto" path). A tiny spot on the far
    side now gives the plain star's chi^2 of both models and its verdict."""
    from types import SimpleNamespace

    import jaxppo as jp

    b = jp.Planet(period=3.0, t0=0.0, a=10.0, inc=90.0, radius=0.1, name="b")
    c = jp.Planet(period=10.0, t0=0.0, a=20.0, inc=90.0, radius=0.1, name="c")
    star = jp.Star.quadratic(0.4, 0.25)
    spotted = star.with_spots(lat=[80.0], lon=[180.0], radius=[1.0], contrast=[0.01], period=25.0, inc=90.0)
    t = np.arange(-0.1, 0.1, 2 / 1440)
    plain = jp.System(star, [b, c], tilted="b")
    y = np.asarray(jp.sweep(plain, t, [0.0], cases="same", no_overlap=True))[0, 0]
    y = y + 1e-4 * np.random.default_rng(0).standard_normal(t.size)
    w = SimpleNamespace(number=1, time=t, flux=y, flux_err=np.full(t.size, 1e-4), exposure=None,
                        event=SimpleNamespace(mid=0.0))
    dip = {"kind": "dip", "case": "same", "alpha": 90.0, "delta_chi2": -1.0, "transits": [1]}
    res = SimpleNamespace(windows=[w], summary={"table5": [dip]})
    got = [jp.activity.ppo_or_spot(res, jp.System(s, [b, c], tilted="b"))["dips"][0] for s in (star, spotted)]
    assert got[0]["preferred"] == got[1]["preferred"]
    for key in ("chi2_no_ppo", "chi2_ppo"):
        a, s = got[0]["windows"][0][key], got[1]["windows"][0][key]
        assert abs(a - s) < 1e-3 * a, (key, a, s)


def _triple_with_untilted_overlap():
    """b (tilted) with c and d, untilted, whose disks overlap each other in
    the window (at t ~ -0.032 d): at every tilt, and at none of b's PPOs."""
    star = jp.Star.quadratic(0.4, 0.25)
    b = jp.Planet(period=3.7, t0=0.032, a=10.6, inc=87.7, radius=0.018, name="b")
    c = jp.Planet(period=10.85, t0=0.0, a=22.76, inc=89.97, radius=0.029, name="c")
    d = jp.Planet(period=25.0, t0=0.01, a=40.0, inc=89.98, radius=0.025, name="d")
    return jp.System(star, [b, c, d])


def test_ppo_or_spot_counts_two_untilted_planets_overlap_once():
    """The no-PPO model is the scan's ground level: two untilted planets
    that overlap each other (c and d here, in every tilt) are counted once.
    It was the sum of each disk's own dip (sweep's no_overlap), which counts
    their overlap twice (a 7e-4 dip that is not in the data): on data with
    no PPO of b at all, a noise dip came out as a PPO by Delta chi^2 = -819
    (Delta BIC -813), where the scan says -0.61. Truth: at a tilt where b
    touches no disk the PPO model is the no-PPO model, Delta chi^2 = 0."""
    from types import SimpleNamespace

    from jaxppo.model._overlap import ppo_table

    system = _triple_with_untilted_overlap()
    t = np.arange(-0.2, 0.2, 1 / 1440)
    x, y, r = (np.asarray(v) for v in system.positions(t))
    assert np.sum(np.hypot(x[:, 1] - x[:, 2], y[:, 1] - y[:, 2]) < r[:, 1] + r[:, 2]) > 10  # c and d overlap
    quiet = 200.0  # b's disk meets no other at this tilt (checked below)
    assert not ppo_table(system, [t], [quiet], "same").any()
    y = np.asarray(system.flux(t, quiet, "same", method="exact"))
    y = y + 1e-4 * np.random.default_rng(2).standard_normal(t.size)
    w = SimpleNamespace(number=1, time=t, flux=y, flux_err=np.full(t.size, 1e-4), exposure=None,
                        event=SimpleNamespace(mid=0.0))
    dip = {"kind": "dip", "case": "same", "alpha": quiet, "delta_chi2": -0.5, "transits": [1]}
    got = jp.activity.ppo_or_spot(SimpleNamespace(windows=[w], summary={"table5": [dip]}), system)["dips"][0]
    assert abs(got["delta_chi2"]["ppo"]) < 1e-6, got["delta_chi2"]
    assert got["windows"][0]["chi2_no_ppo"] < 1.3 * t.size  # noise only: chi^2 ~ N
    assert got["preferred"] == "no PPO"


def test_ppo_or_spot_compares_the_spot_with_the_dips_own_feature():
    """A real PPO (injected at alpha = 141 deg, same case) in a transit that
    also holds a brighter, unrelated bump 1.3 h earlier (a spot crossed by
    c at its mid-transit): the spot model used to fit that other bump (t_c
    1017.790, Delta chi^2 -141 against the PPO's -19.9) and the verdict was
    "spot" by Delta BIC -123, though the dip's feature is the PPO. The
    spot's centre now lies in the span of the dip's PPO (its contacts), the
    feature it would explain instead; the other bump is in every model's
    residuals alike."""
    from types import SimpleNamespace

    from jaxppo.activity._ppo_or_spot import bump_model

    system = jp.kepler20_system()
    lc = jp.simulate_kepler20(seed=1, noise=1e-4, alpha=141.0, case="same")
    t = np.asarray(lc.time)
    sel = np.abs(t - 1017.82) < 0.12
    t = t[sel]
    y = np.asarray(lc.flux)[sel] + np.asarray(bump_model(t, 5e-4, 1017.790, 0.002, np))
    w = SimpleNamespace(number=4, time=t, flux=y, flux_err=np.full(t.size, 1e-4), exposure=None,
                        event=SimpleNamespace(mid=1017.82))
    dip = {"kind": "dip", "case": "same", "alpha": 141.0, "delta_chi2": -19.9, "transits": [4]}
    got = jp.activity.ppo_or_spot(SimpleNamespace(windows=[w], summary={"table5": [dip]}), system)["dips"][0]
    assert got["delta_chi2"]["ppo"] < -15
    assert 1017.841 < got["windows"][0]["bump"]["centre"] < 1017.845  # the PPO's contacts: 1017.8418-1017.8439
    assert got["preferred"] == "PPO", got["delta_bic"]


def test_ppo_or_spot_rates_its_preference():
    """The verdict named a preferred model however small its lead: a true
    PPO at 2e-4 noise (seed 4) was "PPO" by Delta BIC 0.26 over no PPO,
    with nothing saying that is no evidence. Now ``bic_margin`` (the
    runner-up's BIC less the preferred one's) and ``evidence``, its Kass &
    Raftery (1995) category: here a noise-free bump (very strong) and noise
    alone, where the PPO of a one-planet system only pays its parameter
    (margin ln N: positive)."""
    import math
    from types import SimpleNamespace

    from jaxppo.activity._ppo_or_spot import _kass_raftery, bump_model

    assert [_kass_raftery(v) for v in (0.26, 1.99, 2.0, 5.9, 6.0, 9.9, 10.0)] == [
        "not worth more than a bare mention", "not worth more than a bare mention", "positive", "positive",
        "strong", "strong", "very strong"]
    pl = jp.Planet(period=3.0, t0=0.0, a=8.0, inc=89.0, radius=0.08, name="b")
    system = jp.System(jp.Star.quadratic(0.4, 0.26), [pl])
    t = np.linspace(-0.1, 0.1, 60)
    base = np.asarray(system.flux(t, method="exact"))
    win = SimpleNamespace(number=1, time=t, flux=base + np.asarray(bump_model(t, 8e-4, 0.01, 0.006)),
                          flux_err=np.full(t.size, 1e-5), exposure=None, event=SimpleNamespace(mid=0.0))
    res = SimpleNamespace(windows=[win], summary={"table5": [{"kind": "dip", "case": "same", "alpha": 10.0,
                                                              "delta_chi2": -1.0, "transits": [1]}]})
    loud = jp.activity.ppo_or_spot(res, system)["dips"][0]
    assert loud["preferred"] == "spot" and loud["evidence"] == "very strong"
    assert loud["bic_margin"] == pytest.approx(-loud["delta_bic"]["spot"])  # the runner-up: no PPO (0)
    win.flux = base + np.random.default_rng(3).normal(0.0, 1e-5, t.size)
    quiet = jp.activity.ppo_or_spot(res, system)["dips"][0]
    assert quiet["preferred"] == "no PPO" and quiet["bic_margin"] == pytest.approx(math.log(60))
    assert quiet["evidence"] == "positive"


def test_ppo_or_spot_fits_the_ppo_alpha_near_the_grid_angle():
    """The PPO model was the system at the scan's grid angle, though its
    BIC counts alpha as a fitted parameter: a real PPO (injected at 141
    deg) seen from 138 deg (a 3-deg grid) came out "spot" (Delta chi^2 of
    the PPO -2.1 against the spot's -19.6), and from 144 deg (6-deg grid)
    "PPO" by a fraction of its margin. The PPO's alpha is now fitted within
    one grid step of the dip (``alpha_ppo``): the same verdict from every
    grid, and the grid angle where there is no step to go by."""
    from types import SimpleNamespace

    system = jp.kepler20_system()
    lc = jp.simulate_kepler20(seed=1, noise=1e-4, alpha=141.0, case="same")
    t = np.asarray(lc.time)
    sel = np.abs(t - 1017.82) < 0.12
    w = SimpleNamespace(number=4, time=t[sel], flux=np.asarray(lc.flux)[sel], flux_err=np.full(sel.sum(), 1e-4),
                        exposure=None, event=SimpleNamespace(mid=1017.82))
    got = {}
    for alpha, step in ((138.0, 3.0), (144.0, 6.0), (141.0, 1.0)):
        dip = {"kind": "dip", "case": "same", "alpha": alpha, "delta_chi2": -5.0, "transits": [4]}
        res = SimpleNamespace(windows=[w], summary={"table5": [dip], "alpha": {"start": 0.0, "stop": 360.0,
                                                                                "step": step}})
        got[step] = jp.activity.ppo_or_spot(res, system)["dips"][0]
        assert got[step]["preferred"] == "PPO" and got[step]["evidence"] == "very strong", got[step]["delta_bic"]
        assert abs(got[step]["alpha_ppo"] - 141.0) < 1.0 and got[step]["alpha"] == alpha
        assert got[step]["grid_step"] == step and got[step]["delta_chi2"]["ppo"] < -15
    assert got[3.0]["delta_chi2"]["ppo"] == pytest.approx(got[1.0]["delta_chi2"]["ppo"], abs=0.05)
    # the step from the dip's widths where the summary has no grid; none: the grid angle
    from jaxppo.activity._ppo_or_spot import grid_step

    assert grid_step({}, {"lower": 4.0, "upper": 2.0}) == 2.0 and grid_step({}, {}) == 0.0
    dip = {"kind": "dip", "case": "same", "alpha": 138.0, "delta_chi2": -5.0, "transits": [4]}
    bare = jp.activity.ppo_or_spot(SimpleNamespace(windows=[w], summary={"table5": [dip]}), system)["dips"][0]
    assert bare["alpha_ppo"] == 138.0 and bare["grid_step"] == 0.0 and bare["preferred"] == "spot"
