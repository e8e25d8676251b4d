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
                          period_max=30.0, compare_paper=False)
    text = (tmp_path / "activity.json").read_text()
    assert json.loads(text)["rotation"]["period_d"] == pytest.approx(rep["rotation"]["period_d"])
    assert "NaN" not in text and "Infinity" not in text
    json.dumps(rep, allow_nan=False)
    assert abs(rep["rotation"]["period_d"] - 9.37) < rep["rotation"]["period_err_d"]
    for name in ("activity_map.png", "activity_periodogram.png"):
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(rep["rotation"]["bootstrap_percentiles_16_50_84_d"]) == 3


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
])
def test_bad_input_names_parameter(call, name):
    t = np.linspace(0, 100, 500)
    y = 1e-3 * np.sin(t)
    with pytest.raises(ValueError, match=name):
        call(t, y)
