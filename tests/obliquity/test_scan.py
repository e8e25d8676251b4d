"""The obliquity scan end to end (paper Sects. 2.1 and 3.3)."""

import json
import warnings

import numpy as np
import pytest

import jaxppo as jp
from jaxppo.obliquity._config import load_config
from jaxppo.obliquity._scan import run_scan

CONFIG = """
[star]
law = "nonlinear"
coefficients = [1.0984732924, -1.74332475724, 2.46865245453, -0.995093958392]

[[planet]]
name = "b"
period = 3.69611590
t0 = 134.501962
a = 10.60
inc = 87.687
radius = {rb}
tilted = true

[[planet]]
name = "c"
period = 10.85408479
t0 = 138.608470
a = 22.764
inc = 89.967
radius = {rc}

[data]
path = "{data}"

[scan]
alpha = [{a0}, {a1}, {step}]
cases = ["same", "opposite"]
block = {block}
"""


def _config(tmp_path, lc, a0=0.0, a1=360.0, scale=1.0, block=60, name="scan.toml", inc_c=89.967, step=1.0):
    lc.to_csv(tmp_path / "data.csv")
    text = CONFIG.format(rb=0.01805 * scale, rc=0.02878 * scale, data="data.csv", a0=a0, a1=a1, block=block, step=step)
    text = text.replace("inc = 89.967", f"inc = {inc_c}")
    (tmp_path / name).write_text(text)
    return tmp_path / name


@pytest.mark.parametrize("case_true", ["same", "opposite"])
def test_injected_ppo_is_recovered(tmp_path, case_true):
    """Planets enlarged 2x, noise 1e-4. Kepler-20 c crosses almost centrally
    (b = 0.013), which makes the two hemisphere cases nearly degenerate; here
    c is given b = 0.40 (i = 88.99 deg) so that the case is identifiable."""
    scale, inc_c = 2.0, 88.99
    system = jp.kepler20_system(radius_scale=scale)
    c = system.planets[1].replace(inc=inc_c)
    system = system.replace(planets=(system.planets[0], c))
    events = [e for e in jp.multi_transits(system, 300, 1600)]
    t = np.concatenate([np.arange(e.start - 0.05, e.end + 0.05, 1 / 1440) for e in events])
    # inject at the middle of the widest alpha range that gives a PPO
    from jaxppo.model._overlap import ppo_table

    grid = np.arange(0.0, 360.0)
    hit = ppo_table(system, [np.arange(e.start, e.end, 1 / 1440) for e in events], grid, case_true).any(1)
    runs, cur = [], []
    for i in np.nonzero(hit)[0]:
        if cur and i != cur[-1] + 1:
            runs.append(cur)
            cur = []
        cur.append(i)
    runs.append(cur)
    widest = max(runs, key=len)
    alpha_true = float(grid[widest[len(widest) // 2]])
    lc = jp.simulate(system, t, noise=1e-4, alpha=alpha_true, case=case_true, seed=5)
    path = _config(tmp_path, lc, 0.0, 360.0, scale, inc_c=inc_c)
    res = run_scan(load_config(path), tmp_path / "out", progress=False)
    other = "opposite" if case_true == "same" else "same"
    best = res.summary["cases"][case_true]["min_delta_chi2"]
    assert abs(best["alpha"] - alpha_true) <= 2.0
    assert best["value"] < res.summary["cases"][other]["min_delta_chi2"]["value"]  # the right case fits better
    prograde = alpha_true <= 90 or alpha_true > 270
    expect = {("same", True): "prograde, same hemisphere", ("same", False): "retrograde, different hemispheres",
              ("opposite", True): "prograde, different hemispheres", ("opposite", False): "retrograde, same hemisphere"}
    assert res.summary["probabilities"][case_true]["favoured"] == expect[(case_true, prograde)]


def test_null_data_is_exactly_flat_without_ppo(tmp_path):
    lc = jp.simulate_kepler20(seed=3, noise=4e-4)
    cfg = load_config(_config(tmp_path, lc, 0.0, 360.0))
    res = run_scan(cfg, tmp_path / "out", progress=False)
    rows = np.genfromtxt(tmp_path / "out" / "scan.csv", delimiter=",", names=True, dtype=None, encoding=None)
    for case in ("same", "opposite"):
        sel = rows["case"] == case
        alpha, dchi2 = rows["alpha"][sel], rows["delta_chi2"][sel]
        ppo = res.summary["cases"][case]["ppo_transits"]
        has = np.array([f"{a:g}" in ppo for a in alpha])
        assert np.all(dchi2[~has] == 0.0)  # exactly: no render noise
        assert np.all(dchi2[has] != 0.0)
        post = rows["posterior"][sel]
        assert abs(np.sum(post) * 1.0 - 1.0) < 1e-12
    # case "opposite" shifts the PPO ranges by a few degrees (paper Table 5)
    def first(case, lo, hi):
        return min(float(a) for a in res.summary["cases"][case]["ppo_transits"] if lo < float(a) < hi)
    assert 0 < first("opposite", 60, 120) - first("same", 60, 120) <= 6
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["chi2_0"]["same"] > 0


def test_interrupted_scan_resumes_without_recomputing(tmp_path, monkeypatch):
    lc = jp.simulate_kepler20(seed=4, noise=4e-4)
    path = _config(tmp_path, lc, 0.0, 360.0, block=12, step=5.0)
    cfg = load_config(path)
    full = run_scan(cfg, tmp_path / "ref", progress=False)

    import jaxppo.obliquity._scan as scan_mod

    calls = {"n": 0}
    real = scan_mod.grid_chi2  # one call per block of alphas

    def flaky(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 4:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(scan_mod, "grid_chi2", flaky)
    with pytest.raises(KeyboardInterrupt):
        run_scan(cfg, tmp_path / "out", progress=False)
    lines = (tmp_path / "out" / "scan_progress.jsonl").read_text().splitlines()
    assert len(lines) == 1 + 3  # header + three finished blocks kept
    calls["n"] = 10
    res = run_scan(cfg, tmp_path / "out", progress=False)
    assert calls["n"] == 10 + 12 - 3  # 12 blocks in all, 3 already done
    a = (tmp_path / "ref" / "scan.csv").read_text()
    b = (tmp_path / "out" / "scan.csv").read_text()
    assert a == b and res.summary["chi2_0"] == full.summary["chi2_0"]


def test_changed_config_is_not_mixed(tmp_path):
    lc = jp.simulate_kepler20(seed=4, noise=4e-4)
    cfg = load_config(_config(tmp_path, lc, step=12.0))
    run_scan(cfg, tmp_path / "out", progress=False)
    cfg2 = load_config(_config(tmp_path, lc, scale=1.1, name="other.toml", step=12.0))
    with pytest.raises(ValueError, match="different configuration .*; changed: ") as err:
        run_scan(cfg2, tmp_path / "out", progress=False)
    assert "radius" in str(err.value), err.value  # the key that differs is named
    run_scan(cfg2, tmp_path / "out", restart=True, progress=False)


def test_python_scan_digest_sees_eccentricity_and_node():
    """A scan from Python arguments hashed only period, t0, a, inc and radius:
    `jp.scan(eccentric_system, lc, out=DIR)` after the circular system's scan
    in DIR returned the circular chi^2 (2885.9 instead of 2902.2 for
    Kepler-20 b at e = 0.3) as "finished before". Circular, unrotated
    planets keep their digest."""
    from jaxppo.obliquity._config import config_from_arguments

    s = jp.kepler20_system()
    lc = jp.LightCurve(np.linspace(134.4, 134.6, 20), np.ones(20), np.full(20, 1e-4))
    b, c = s.planets

    def digest(system):
        return config_from_arguments(system, lc, None, ("same",), 0.05, "none", 0.3, "none", None, 60).digest

    base = digest(s)
    assert digest(s.replace(planets=[b.replace(omega=30.0), c])) == base  # omega of a circular orbit: no effect
    others = [digest(s.replace(planets=[b.replace(e=0.3, omega=30.0), c])),
              digest(s.replace(planets=[b.replace(e=0.3, omega=40.0), c])),
              digest(s.replace(planets=[b, c.replace(lnode=5.0)]))]
    assert len({base, *others}) == 4, others


@pytest.mark.parametrize(
    "edit, match",
    [
        (lambda t: t.replace("period = 3.69611590\n", ""), r"missing \['period'\]"),
        (lambda t: t.replace('law = "nonlinear"', 'law = "gaussian"'), "unknown limb-darkening law 'gaussian'"),
        (lambda t: t.replace('path = "data.csv"', 'path = "nowhere.csv"'), "file not found"),
        (lambda t: t.replace("alpha = [0.0, 360.0, 1.0]", "alpha = [10.0, 10.0, 1.0]"), "empty"),
        (lambda t: t.replace("alpha = [0.0, 360.0, 1.0]", "alpha = [100.0, 200.0, 1.0]"), r"\[scan\] alpha = .*whole circle"),
        (lambda t: t.replace("alpha = [0.0, 360.0, 1.0]", "alpha = [0.0, 360.0, 7.0]"), r"\[scan\] alpha = .*divides 360"),
        (lambda t: t.replace("alpha = [0.0, 360.0, 1.0]", "alpha = [-180.0, 180.0, 2.0]"), None),
        (lambda t: t.replace('cases = ["same", "opposite"]', 'cases = ["sideways"]'), "unknown case"),
        (lambda t: t.replace("radius = 0.01805", "radius = -0.01805"), "radius must be > 0"),
    ],
)
def test_bad_configs_fail_before_work(tmp_path, edit, match):
    lc = jp.simulate_kepler20(seed=1)
    path = _config(tmp_path, lc)
    path.write_text(edit(path.read_text()))
    if match is None:  # a valid edit (any full circle is fine)
        load_config(path)
        return
    with pytest.raises(ValueError, match=match):
        load_config(path)


def test_unreadable_data(tmp_path):
    lc = jp.simulate_kepler20(seed=1)
    path = _config(tmp_path, lc)
    (tmp_path / "data.csv").write_text("time,flux,flux_err\n1.0,abc,0.1\n")
    with pytest.raises(ValueError, match="unreadable row"):
        load_config(path)
    (tmp_path / "data.csv").write_text("when,what\n1,2\n")
    with pytest.raises(ValueError, match="no time column"):
        load_config(path)


# ---- per-window detrending (paper Sect. 2.2) ---------------------------------

def _wide_windows(system, half_width=0.4, cadence=2 / 1440):
    events = [e for e in jp.multi_transits(system, 300, 1600)]
    return events, [np.arange(e.start - half_width, e.end + half_width, cadence) for e in events]


def _write_csv(path, t, f, e=None):
    cols = (t, f) if e is None else (t, f, e)
    head = "time,flux" if e is None else "time,flux,flux_err"
    path.write_text(head + "\n" + "\n".join(",".join(f"{v:.12g}" for v in r) for r in zip(*cols)) + "\n")


def _scan_text(extra="", step=1.0):
    return CONFIG.format(rb=0.01805, rc=0.02878, data="data.csv", a0=0.0, a1=360.0, block=120, step=step) + extra


def test_detrending_removes_per_window_levels_slopes_and_curvature(tmp_path):
    """Each multi-transit gets its own level (raw quarter fluxes differ by
    per cent), slope and curvature. Dividing every window by its
    out-of-transit polynomial must give the same geometry probabilities
    (0.5 percentage points) and chi^2_0 (3 %) as the clean data; without
    the detrending chi^2_0 is in the millions."""
    system = jp.kepler20_system()
    events, ts = _wide_windows(system)
    rng = np.random.default_rng(11)
    clean, trended = [], []
    for e, t in zip(events, ts):
        lc = jp.simulate(system, t, noise=2e-4, seed=int(rng.integers(1 << 30)))
        x = t - e.mid
        trend = rng.uniform(0.97, 1.03) * (1 + rng.uniform(-3e-3, 3e-3) * x + rng.uniform(-6e-3, 6e-3) * x**2)
        clean.append(lc.flux)
        trended.append(lc.flux * trend)
    t = np.concatenate(ts)
    err = np.full(t.size, 2e-4)
    results = {}
    for name, f in (("clean", np.concatenate(clean)), ("trended", np.concatenate(trended))):
        d = tmp_path / name
        d.mkdir()
        _write_csv(d / "data.csv", t, f, err)
        (d / "scan.toml").write_text(_scan_text("detrend = 2\nbaseline = 0.35\n", step=2.0))
        results[name] = run_scan(load_config(d / "scan.toml"), d / "out", progress=False)
    a, b = results["clean"], results["trended"]
    for case in ("same", "opposite"):
        assert abs(b.summary["chi2_0"][case] / a.summary["chi2_0"][case] - 1) < 0.03, (a.summary["chi2_0"], b.summary["chi2_0"])
        for geo, v in a.summary["probabilities"][case].items():
            if isinstance(v, dict):
                assert abs(100 * (b.summary["probabilities"][case][geo]["probability"] - v["probability"])) < 0.5
    n = b.summary["points"]
    assert 0.8 < b.summary["chi2_0"]["same"] / n < 1.2
    assert b.summary["detrending"]["order"] == 2


def test_errors_estimated_and_outliers_clipped_out_of_transit_only(tmp_path):
    system = jp.kepler20_system()
    events, ts = _wide_windows(system, cadence=4 / 1440)
    t = np.concatenate(ts)
    lc = jp.simulate(system, t, noise=3e-4, seed=8)
    f = lc.flux.copy()
    e0 = events[0]
    from jaxppo.model._overlap import in_transit_mask

    in_tr = in_transit_mask(system, t)
    # three out-of-transit outliers inside the chi^2 window of event 1, and a
    # 10-sigma "bump" in transit (a PPO-like brightening that must survive)
    oot_idx = np.nonzero((t > e0.end + 0.015) & (t < e0.end + 0.05) & ~in_tr)[0][:3]
    f[oot_idx] += 0.01
    bump = np.nonzero((t > e0.overlap_start) & (t < e0.overlap_end))[0][0]
    f[bump] += 3e-3
    _write_csv(tmp_path / "data.csv", t, f)  # no flux_err column
    (tmp_path / "scan.toml").write_text(_scan_text())
    cfg = load_config(tmp_path / "scan.toml")
    assert cfg.lightcurve.errors_estimated
    from jaxppo.obliquity._windows import scan_windows

    w = scan_windows(cfg)[0]
    def kept(tt):
        return np.min(np.abs(w.time - tt)) < 1e-7  # times went through the CSV (12 digits)

    assert w.clipped == 3 and not any(kept(tt) for tt in t[oot_idx])
    assert kept(t[bump])  # in-transit points are never clipped
    assert abs(w.sigma / 3e-4 - 1) < 0.15
    res = run_scan(cfg, tmp_path / "out", progress=False)
    assert "estimated" in res.summary["detrending"]["flux_err"]
    assert res.summary["multi_transits"][0]["clipped"] == 3


def test_in_transit_mask_against_contact_times():
    """First to last contact of a circular orbit (Winn 2010, Eq. 14):
    T14 = P / pi * asin(sqrt((1 + p)^2 - b^2) / (a sin i))."""
    from jaxppo.model._overlap import in_transit_mask

    system = jp.kepler20_system()
    for k, pl in enumerate(system.planets):
        P, a, inc, p = float(pl.period), float(pl.a), np.deg2rad(float(pl.inc)), float(pl.radius)
        b = a * np.cos(inc)
        half = P / (2 * np.pi) * np.arcsin(np.sqrt((1 + p) ** 2 - b**2) / (a * np.sin(inc)))
        mid = float(pl.t0) + 40 * P
        t = mid + np.array([-half - 1e-6, -half + 1e-6, half - 1e-6, half + 1e-6])
        # the other planet must not be in transit at these times
        one = jp.System(system.star, [pl], tilted=0)
        np.testing.assert_array_equal(in_transit_mask(one, t), [False, True, True, False])
        np.testing.assert_array_equal(in_transit_mask(one, t, pad=2e-6), [True, True, True, True])


def test_summary_is_strict_json_and_bayes_factor_never_infinite():
    """A decisive signal (Delta chi^2 of thousands in one range) underflows
    exp(-Delta chi^2 / 2): the Bayes factor comes from log space, and what
    cannot be a float is null, never Infinity (invalid JSON)."""
    from jaxppo.obliquity._stats import bayes_factor_text, geometry_probabilities

    alpha = np.arange(0.0, 360.0, 1.0)
    retro = (alpha > 90) & (alpha <= 270)
    geo = geometry_probabilities(alpha, np.where(retro, 5000.0, 0.0), "same")
    text = json.dumps(geo, allow_nan=False)
    assert geo["bayes_factor"] is None and abs(geo["log10_bayes_factor"] - 2500 / np.log(10)) < 1e-9  # 180 angles in each range
    assert geo["favoured"] == "prograde, same hemisphere" and geo["jeffreys"] == "decisive"
    assert "Infinity" not in text
    assert bayes_factor_text(geo) == "10^1085.7"
    big = geometry_probabilities(alpha, np.where(retro, 250.0, 0.0), "same")  # K = e^125 ~ 2e54: a float
    assert big["bayes_factor"] > 1e54 and bayes_factor_text(big) == "10^54.3"  # it printed 55 digits
    # a moderate one: K = sum over the ranges of exp(-Delta chi^2 / 2), exactly
    d = np.where(retro, 3.0, 0.0)
    geo = geometry_probabilities(alpha, d, "opposite")
    k = np.exp(1.5)
    assert abs(geo["bayes_factor"] - k) < 1e-12 * k and bayes_factor_text(geo) == "4.482"
    assert abs(geo["prograde, different hemispheres"]["probability"] - k / (1 + k)) < 1e-14


def test_no_probability_or_rating_from_a_model_that_does_not_fit(tmp_path):
    """Flux in physical units over windows that are mostly in transit: the loader divided by a median 0.2 %
    below the baseline, chi^2_0 / N was 121, and the scan printed "prograde 100 %, decisive" at the wrong
    tilt. Where the best chi^2 is far above N (chi^2 / N > 1.5 and p < 1e-3) every probability, Bayes factor
    and rating is withheld (null in summary.json, the reason printed and in the figure); the same data
    normalised keep theirs, and what was divided by is in the data line."""
    from jaxppo.obliquity._report import scan_report
    from jaxppo.obliquity._stats import goodness_of_fit

    lc = jp.simulate_kepler20(seed=4, noise=2e-4, radius_scale=2.0)
    scaled = jp.LightCurve(lc.time, lc.flux * 1e4, lc.flux_err * 1e4)
    path = _config(tmp_path, scaled, block=30, step=12.0, scale=2.0)
    path.write_text(path.read_text() + 'detrend = "none"\n')
    cfg = load_config(path)
    assert "divided by their median" in cfg.lightcurve.report_line()
    res = run_scan(cfg, tmp_path / "out", progress=False)
    check = res.summary["goodness_of_fit"]
    assert not check["ok"] and check["reduced"] > 1.5 and check["p_value"] < 1e-3
    for case in ("same", "opposite"):
        geo = res.summary["probabilities"][case]
        assert geo["favoured"] is None and geo["bayes_factor"] is None and geo["jeffreys"] == "not rated"
        assert all(v["probability"] is None for v in geo.values() if isinstance(v, dict))
        assert "does not fit the data" in geo["withheld"]
    json.loads((tmp_path / "out" / "summary.json").read_text())  # strict JSON with the nulls
    text = scan_report(res.summary, cfg, tmp_path / "out", 1.0)
    assert "no probability or rating: the model does not fit" in text and " %" not in text.split("Table 5")[0]
    path = _config(tmp_path, lc, block=90, step=1.0, scale=2.0, name="good.toml")  # (12 deg: the grid check)
    path.write_text(path.read_text() + 'detrend = "none"\n')
    good = run_scan(load_config(path), tmp_path / "good", progress=False)
    assert good.summary["goodness_of_fit"]["ok"]
    assert good.summary["probabilities"]["same"]["favoured"] is not None
    # the thresholds: both must be exceeded (a short light curve's chi^2 / N of 1.6 is chance)
    assert goodness_of_fit(1.6 * 20, 20)["ok"] and not goodness_of_fit(1.6 * 2000, 2000)["ok"]
    assert goodness_of_fit(1.2 * 2000, 2000)["ok"] and "raise every ln K by about 20 %" in goodness_of_fit(
        1.2 * 2000, 2000)["caution"]  # kept, with a caution
    assert not goodness_of_fit(1.3 * 2000, 2000)["ok"]  # a PPO of K ~ 5.5 read "decisive" at 1.36 and 1.47
    assert goodness_of_fit(1.05 * 100, 100)["caution"] is None
    # a chi^2 that is not finite, or no points: not ok (NaN once compared as "fitting"), strict JSON
    for chi2, n in ((float("nan"), 100), (float("inf"), 100), (50.0, 0)):
        bad = goodness_of_fit(chi2, n)
        assert not bad["ok"] and bad["chi2_best"] is None and "nothing can be rated" in bad["reason"]
        json.dumps(bad, allow_nan=False)
    # no posterior where no probability: NaN in the table and in scan.csv
    assert np.all(np.isnan(res.table["posterior"]))
    rows = np.genfromtxt(tmp_path / "out" / "scan.csv", delimiter=",", names=True, dtype=None, encoding=None)
    assert np.all(np.isnan(rows["posterior"]))
    from jaxppo.obliquity._figures import read_scan_csv

    assert np.isnan(read_scan_csv(tmp_path / "out" / "scan.csv")["same"]["posterior"]).all()  # jaxppo plot reads it
    assert np.all(np.isfinite(good.table["posterior"]))


def test_a_grid_too_coarse_for_the_features_gives_no_probability(tmp_path):
    """A PPO injected at 147 deg (planets enlarged 2x): its Delta chi^2 dips are 1-3 deg wide, and a 10-deg
    grid stepped over them and printed 49 / 51 %, "barely worth mentioning", where 1 deg gives K ~ 5e4,
    "decisive". The scan computes chi^2 at the grid's midpoints too; where half the step moves a geometry's
    probability by more than 0.01 or changes the rating, every probability and rating is withheld, naming
    the step to use. The same scan at 1 deg passes the check."""
    lc = jp.simulate_kepler20(seed=5, noise=2e-4, radius_scale=2.0, alpha=147.0, case="same")
    coarse = run_scan(load_config(_config(tmp_path, lc, step=10.0, scale=2.0, name="coarse.toml")),
                      tmp_path / "coarse", progress=False)
    grid = coarse.summary["alpha_grid_check"]
    assert not grid["ok"] and grid["step"] == 10.0 and grid["half_step"] == 5.0
    assert grid["cases"]["same"]["largest_shift"] > 0.1
    assert grid["cases"]["same"]["jeffreys_on_grid"] != grid["cases"]["same"]["jeffreys_at_half_step"]
    assert not grid["cases"]["same"]["ok"]
    # the check's numbers are named for their grid: no answer under the summary's own keys (a withheld case's
    # coarse-grid "favoured" and "probabilities" read as the answer)
    for c in grid["cases"].values():
        assert not {"favoured", "probabilities", "jeffreys", "log10_bayes_factor"} & set(c), sorted(c)
        assert set(c["probabilities_on_grid"]) == set(c["probabilities_at_half_step"])
    for case in ("same", "opposite"):  # each case by its own check (its probabilities are its own)
        geo = coarse.summary["probabilities"][case]
        if grid["cases"][case]["ok"]:
            assert geo["favoured"] is not None and grid["cases"][case]["largest_shift"] <= 0.01
        else:
            assert geo["favoured"] is None and f"features of case {case}" in geo["withheld"]
            assert "[0, 360, 2.5]" in geo["withheld"]
            assert np.all(np.isnan(coarse.table["posterior"][coarse.table["case"] == case]))
    fine = run_scan(load_config(_config(tmp_path, lc, step=1.0, scale=2.0, name="fine.toml")), tmp_path / "fine",
                    progress=False)
    assert fine.summary["alpha_grid_check"]["ok"]
    geo = fine.summary["probabilities"]["same"]
    assert geo["favoured"] == "retrograde, different hemispheres" and geo["jeffreys"] == "decisive"


def test_no_mirror_block_with_the_other_cases_names(tmp_path):
    """Cases 3 and 2 are cases 1 and 4 at 360 - alpha (paper Eq. 2): the
    same physical geometries, so a case-1 summary may only name case 1's
    geometries (old code printed case 4's names for "case 3")."""
    lc = jp.simulate_kepler20(seed=4, noise=4e-4)
    res = run_scan(load_config(_config(tmp_path, lc, step=6.0)), tmp_path / "out", progress=False)
    allowed = {"same": {"prograde, same hemisphere", "retrograde, different hemispheres"},
               "opposite": {"prograde, different hemispheres", "retrograde, same hemisphere"}}

    def names(obj):
        if isinstance(obj, dict):
            for k, v in obj.items():
                if "hemisphere" in k:
                    yield k
                yield from names(v)
        elif isinstance(obj, str) and "hemisphere" in obj:  # a name, or a reason that names geometries
            known = [n for n in allowed["same"] | allowed["opposite"] if n in obj]
            yield from known or [obj]

    for case in ("same", "opposite"):
        assert set(names(res.summary["cases"][case])) <= allowed[case]


def test_buchhave_parameters_show_the_papers_dip_near_26_deg(tmp_path):
    """Paper Table 3 (left columns, T0 in BJD - 2454000) in the bundled
    config, and its Fig. 5 right panel: with these parameters the scan of the
    seven double transits has one prominent dip, at alpha = 26 deg (case 1);
    the long-cadence data show it too."""
    from jaxppo.model._phoenix import data_path

    text = data_path("kepler20_buchhave2016_llc.toml").read_text()
    text = text.replace('path = "', f'path = "{data_path("")}/').replace("alpha = [0.0, 360.0, 1.0]", "alpha = [0.0, 360.0, 2.0]")
    text = text.replace("multi_transits = [334.02, 496.77, ", "multi_transits = [334.02, ")  # the paper's seven
    text = text.replace('cases = ["same", "opposite"]', 'cases = ["same"]')
    (tmp_path / "b16.toml").write_text(text)
    cfg = load_config(tmp_path / "b16.toml")
    b, c = cfg.system.planets
    table3 = {"b": (0.01774, 87.355, 10.34, 967.502014, 3.69611525), "c": (0.02895, 89.815, 21.17, 971.607955, 10.85409089)}
    for pl in (b, c):
        p, i, a, t0, per = table3[pl.name]
        assert (float(pl.radius), float(pl.inc), float(pl.a), float(pl.period)) == (p, i, a, per)
        assert abs(float(pl.t0) - (t0 + 2454000 - 2454833)) < 1e-9
    res = run_scan(cfg, tmp_path / "out", progress=False)
    rows = np.genfromtxt(tmp_path / "out" / "scan.csv", delimiter=",", names=True, dtype=None, encoding=None)
    low = rows["alpha"][(rows["alpha"] < 90) & (rows["delta_chi2"] < -0.5)]
    assert low.size and np.all((low >= 24) & (low <= 30)), low
    assert len(res.summary["multi_transits"]) == 7


# ---- progress bookkeeping -------------------------------------------------------

def _small(tmp_path, **kw):
    lc = jp.simulate_kepler20(seed=4, noise=4e-4)
    return load_config(_config(tmp_path, lc, block=6, step=12.0, **kw))  # 2 cases x 30 alphas: 10 blocks


def _interrupt_after(monkeypatch, n_blocks):
    import jaxppo.obliquity._scan as scan_mod

    real, calls = scan_mod.grid_chi2, {"n": 0}  # one call per block of alphas

    def flaky(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] > n_blocks:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(scan_mod, "grid_chi2", flaky)
    return lambda: monkeypatch.setattr(scan_mod, "grid_chi2", real)


def test_torn_last_line_is_truncated_before_appending(tmp_path, monkeypatch):
    cfg = _small(tmp_path)
    ref = run_scan(cfg, tmp_path / "ref", progress=False)
    undo = _interrupt_after(monkeypatch, 3)
    with pytest.raises(KeyboardInterrupt):
        run_scan(cfg, tmp_path / "out", progress=False)
    undo()
    prog = tmp_path / "out" / "scan_progress.jsonl"
    with open(prog, "a") as fh:
        fh.write('{"config_digest": "x", "case": "same", "alpha": [0.0, 12')  # killed mid-write
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = run_scan(cfg, tmp_path / "out", progress=False)
        run_scan(cfg, tmp_path / "out", progress=False)  # and once more: the file stays sound
    for line in prog.read_text().splitlines():
        json.loads(line)  # every line whole: nothing appended onto the torn one
    assert len(prog.read_text().splitlines()) == 1 + 10
    assert (tmp_path / "ref" / "scan.csv").read_text() == (tmp_path / "out" / "scan.csv").read_text()
    assert res.summary["chi2_0"] == ref.summary["chi2_0"]
    assert any("cut by an interruption" in str(w.message) for w in caught)


def test_edited_record_is_rejected_and_recomputed(tmp_path):
    cfg = _small(tmp_path)
    run_scan(cfg, tmp_path / "out", progress=False)
    good = (tmp_path / "out" / "scan.csv").read_text()
    prog = tmp_path / "out" / "scan_progress.jsonl"
    lines = prog.read_text().splitlines()
    rec = json.loads(lines[2])
    rec["chi2"][0] -= 50.0  # a hand-edited chi^2 must not be used
    lines[2] = json.dumps(rec)
    prog.write_text("\n".join(lines) + "\n")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run_scan(cfg, tmp_path / "out", progress=False)
    assert (tmp_path / "out" / "scan.csv").read_text() == good
    assert any("line 3: checksum mismatch" in str(w.message) for w in caught)


def test_torn_header_is_not_a_different_configuration(tmp_path, monkeypatch):
    cfg = _small(tmp_path)
    run_scan(cfg, tmp_path / "ref", progress=False)
    undo = _interrupt_after(monkeypatch, 4)
    with pytest.raises(KeyboardInterrupt):
        run_scan(cfg, tmp_path / "out", progress=False)
    undo()
    prog = tmp_path / "out" / "scan_progress.jsonl"
    lines = prog.read_text().splitlines()
    lines[0] = lines[0][:17]  # damaged header, four good records behind it
    prog.write_text("\n".join(lines) + "\n")
    import jaxppo.obliquity._scan as scan_mod

    calls = {"n": 0}
    real = scan_mod.grid_chi2

    def counting(*a, **k):
        calls["n"] += 1
        return real(*a, **k)

    monkeypatch.setattr(scan_mod, "grid_chi2", counting)
    with pytest.warns(UserWarning, match="header line is damaged"):
        run_scan(cfg, tmp_path / "out", progress=False)
    assert calls["n"] == 10 - 4  # the four good blocks kept
    assert (tmp_path / "ref" / "scan.csv").read_text() == (tmp_path / "out" / "scan.csv").read_text()


def test_restart_removes_the_old_outputs_first(tmp_path, monkeypatch):
    cfg = _small(tmp_path)
    out = tmp_path / "out"
    run_scan(cfg, out, progress=False)
    (out / "fig5_delta_chi2.png").write_bytes(b"old figure")
    cfg2 = _small(tmp_path, scale=1.1, name="other.toml")
    undo = _interrupt_after(monkeypatch, 1)
    with pytest.raises(KeyboardInterrupt):
        run_scan(cfg2, out, restart=True, progress=False)
    undo()
    # an interrupted restart leaves no result of the old config beside the new one
    for name in ("scan.csv", "summary.json", "fig5_delta_chi2.png"):
        assert not (out / name).exists(), name
    assert json.loads((out / "config.json").read_text())["digest"] == cfg2.digest
    run_scan(cfg2, out, progress=False)  # resumes the restarted scan
    assert json.loads((out / "summary.json").read_text())["config_digest"] == cfg2.digest

    # an earlier joint run's outputs go too (they stayed beside the new scan)
    for name in ("joint.json", "joint.csv", "joint.png"):
        (out / name).write_text("old joint run")
    run_scan(cfg, out, restart=True, progress=False)
    assert not any((out / n).exists() for n in ("joint.json", "joint.csv", "joint.png"))


def test_a_scan_never_writes_over_files_it_did_not_write(tmp_path):
    """--out onto a folder of the user's own files replaced them (config.json,
    scan.csv, ...), and a scan whose data file was named scan.csv in --out
    replaced its own input; --restart did the same."""
    cfg = _small(tmp_path)
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "scan.csv").write_text("my own table")
    for restart in (False, True):
        with pytest.raises(ValueError, match=r"holds scan.csv but no scan progress"):
            run_scan(cfg, mine, restart=restart, progress=False)
    assert (mine / "scan.csv").read_text() == "my own table"
    # a marginal run's files (jp.marginal_scan(cfg, out=DIR) writes no scan progress) are not in the way
    (mine / "scan.csv").unlink()
    (mine / "marginal.csv").write_text("a marginal run's table")
    run_scan(cfg, mine, progress=False)
    assert (mine / "marginal.csv").exists()
    # the data file itself where the scan would write scan.csv
    text = (tmp_path / "scan.toml").read_text().replace('path = "data.csv"', 'path = "scan.csv"')
    (tmp_path / "scan.csv").write_bytes((tmp_path / "data.csv").read_bytes())
    (tmp_path / "in.toml").write_text(text)
    before = (tmp_path / "scan.csv").read_bytes()
    with pytest.raises(ValueError, match=r"a scan there would write .*scan.csv: that file is an input of this run"):
        run_scan(load_config(tmp_path / "in.toml"), tmp_path, progress=False)
    assert (tmp_path / "scan.csv").read_bytes() == before


def test_another_block_size_resumes(tmp_path):
    """``block`` only sets how often progress is saved; a rerun with another
    was refused as "a different configuration (changed: scan.block)"."""
    cfg = _small(tmp_path)
    run_scan(cfg, tmp_path / "out", progress=False)
    text = (tmp_path / "scan.toml").read_text().replace("block = 6", "block = 10")
    (tmp_path / "scan.toml").write_text(text)
    cfg2 = load_config(tmp_path / "scan.toml")
    assert cfg2.block == 10 and cfg2.digest == cfg.digest
    run_scan(cfg2, tmp_path / "out", progress=False)


# ---- public API ---------------------------------------------------------------------

def test_public_scan_matches_the_config_route(tmp_path):
    lc = jp.simulate_kepler20(seed=4, noise=4e-4)
    via_file = run_scan(load_config(_config(tmp_path, lc, step=6.0)), tmp_path / "cfg", progress=False)
    lc_read = jp.load_config(tmp_path / "scan.toml").lightcurve  # the same (CSV-rounded) points
    res = jp.scan(jp.kepler20_system(), lc_read, alpha=np.arange(0.0, 360.0, 6.0))
    np.testing.assert_array_equal(res.table["chi2"], via_file.table["chi2"])
    assert res.summary["probabilities"] == via_file.summary["probabilities"]
    assert list(res.table.dtype.names) == ["case", "alpha", "chi2", "delta_chi2", "posterior"]
    a, d = res.delta_chi2("opposite")
    assert a.size == 60 and np.all(d[a < 15] == 0)
    assert len(res.windows) == 7 and isinstance(res.windows[0], jp.ScanWindow)
    ax = res.plot()
    assert len(ax.get_lines()) == 3  # two cases and the zero line
    import matplotlib.pyplot as plt

    plt.close(ax.figure)
    with pytest.raises(ValueError, match="alpha covers 100 .. 199 deg"):
        jp.scan(jp.kepler20_system(), lc_read, alpha=np.arange(100.0, 200.0, 1.0))
    with pytest.raises(ValueError, match="cases = .*unknown case 'sideways'"):
        jp.scan(jp.kepler20_system(), lc_read, alpha=np.arange(0.0, 360.0, 6.0), cases=("sideways",))


@pytest.mark.parametrize("name,value", [("alpha", np.arange(0.0, 360.0, 10.0)), ("margin", 0.1), ("detrend", 0),
                                        ("baseline", 0.5), ("clip", "none"), ("multi_transits", [334.02]),
                                        ("cases", ("same",)), ("margin", 0.05), ("block", 30)])
def test_scan_settings_with_a_config_are_refused_not_ignored(name, value, monkeypatch):
    """Issue 24 item 2: jp.scan(config, alpha=36 alphas) scanned the config's
    360 and used its margin and detrend order, without a word; so did
    jp.marginal_scan. A setting given with a config is refused, even one equal
    to the default (it may still differ from the config's)."""
    from jaxppo.obliquity import _marginal, _scan

    def ran(*args, **kwargs):  # a regression fails here at once, not after a whole scan
        raise AssertionError(f"the scan ran with the config's settings, {name} ignored")

    for module, attr in ((_scan, "run_scan"), (_marginal, "run_scan"), (_marginal, "nuts_draws")):
        monkeypatch.setattr(module, attr, ran)
    cfg = jp.load_config()
    match = rf"jaxppo.scan: {name} must not be given with a ScanConfig.*{name} = .*the config has"
    with pytest.raises(ValueError, match=match):
        jp.scan(cfg, **{name: value})
    if name != "block":
        with pytest.raises(ValueError, match=match.replace("scan", "marginal_scan", 1)):
            jp.marginal_scan(cfg, draws=2, **{name: value})
    if name == "alpha":
        with pytest.raises(ValueError, match=r"360 alphas, 0 to 359 deg.*jp.load_config\(path, alpha="):
            jp.scan(cfg, alpha=value)
    elif name == "margin":
        with pytest.raises(ValueError, match=r"\[scan\] margin in the config file"):
            jp.scan(cfg, margin=value)


# ---- results out and the load report ------------------------------------------------

def test_ecsv_table_with_units_and_provenance(tmp_path):
    """scan.ecsv beside scan.csv: the same numbers (read back exactly), with
    units and the config digest, jaxppo version and cases in its metadata;
    the summary carries the load report (what loading dropped)."""
    import astropy.units as u
    from astropy.table import Table

    lc = jp.simulate_kepler20(seed=4, noise=4e-4)
    path = _config(tmp_path, lc, step=30.0)
    # two flagged rows and a repeated cadence: reported, not silent
    text = (tmp_path / "data.csv").read_text().splitlines()
    rows = ["time,flux,flux_err,quality"] + [r + ",0" for r in text[1:]]
    rows[5] = rows[5][:-1] + "1"
    rows[9] = rows[9][:-1] + "32"
    rows.insert(12, rows[11])
    (tmp_path / "data.csv").write_text("\n".join(rows) + "\n")
    cfg = load_config(path)
    res = run_scan(cfg, tmp_path / "out", progress=False)
    tab = Table.read(tmp_path / "out" / "scan.ecsv")
    csv = np.genfromtxt(tmp_path / "out" / "scan.csv", delimiter=",", names=True, dtype=None, encoding=None)
    assert tab.colnames == ["case", "alpha", "chi2", "delta_chi2", "posterior"]
    assert tab["alpha"].unit == u.deg and tab["posterior"].unit == 1 / u.deg
    np.testing.assert_array_equal(tab["chi2"], res.table["chi2"])
    np.testing.assert_array_equal(np.asarray(tab["alpha"]), csv["alpha"])
    np.testing.assert_array_equal(np.asarray(tab["case"]), csv["case"])
    assert tab.meta["config_digest"] == cfg.digest == res.summary["config_digest"]
    assert tab.meta["jaxppo_version"] == jp.__version__ and tab.meta["cases"] == ["same", "opposite"]
    assert tab.meta["alpha_grid_deg"] == {"start": 0.0, "stop": 360.0, "step": 30.0}
    assert tab.meta["chi2_0"]["same"] == res.summary["chi2_0"]["same"]
    rep = json.loads((tmp_path / "out" / "summary.json").read_text())["data"]
    assert rep["report"]["flagged"] == 2 and rep["report"]["duplicated"] == 1
    assert "dropped: 2 flagged" in rep["loaded"] and "1 repeated time stamps" in rep["loaded"]


def test_long_cadence_exposure_average_is_converged(tmp_path):
    """The real default scan's Delta chi^2 against an independent 401-point
    exposure average of System.flux (exact) over the same detrended points.
    With 2-minute sub-exposures (15 per 29.4-min cadence) the scan was off by
    up to 0.08 (e.g. 0.562 against 0.514 at alpha = 125 deg) because b's
    ingress and a PPO last only 3-9 min."""
    cfg = load_config()
    res = run_scan(cfg, tmp_path / "o", progress=False)
    windows = res.windows
    t = np.concatenate([w.time for w in windows])
    y = np.concatenate([w.flux for w in windows])
    sig = np.concatenate([w.flux_err for w in windows])
    n = 401
    off = ((np.arange(n) + 0.5) / n - 0.5) * cfg.lightcurve.exposure
    tm = (t[:, None] + off[None, :]).ravel()
    alphas = np.array([0.0, 141.0, 150.0, 225.0, 311.0, 319.0])
    model = np.asarray(cfg.system.flux(tm, alpha=alphas, case="same", method="exact")).reshape(alphas.size, t.size, n)
    chi2 = np.sum(((y - model.mean(-1)) / sig) ** 2, axis=1)
    dchi2_ref = chi2[1:] - chi2[0]  # alpha = 0: no PPO in any frame (the ground level)
    a, d = res.delta_chi2("same")
    ours = np.array([d[np.isclose(a, al)][0] for al in alphas[1:]])
    assert np.max(np.abs(ours - dchi2_ref)) < 0.01, (ours, dchi2_ref)
    assert abs(res.summary["chi2_0"]["same"] - chi2[0]) < 0.01


def test_scan_refuses_float32(tmp_path):
    """With x64 off the real scan ran in float32 without a word (chi^2_0
    146.266 instead of 146.275); it must refuse, naming the fix."""
    import subprocess
    import sys

    code = ("import jaxppo as jp\n"
            "try:\n    jp.scan(jp.load_config(), out=None)\n"
            "except ValueError as e:\n    print('REFUSED', e)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert "REFUSED" in out and "jax_enable_x64" in out


def test_case_labels_are_canonical():
    """'+' of a two-planet system is case 'same' (and '-' is 'opposite'):
    they were scanned twice under different geometry names."""
    from jaxppo.model._cases import scan_cases

    system = jp.kepler20_system()
    assert scan_cases(system, ["+"]) == ("same",)
    assert scan_cases(system, "-") == ("opposite",)
    with pytest.raises(ValueError, match="listed twice"):
        scan_cases(system, ["same", "+"])
    with pytest.raises(ValueError, match="sign"):
        system.positions(np.zeros(1), 0.0, (True,))


def test_figures_show_the_model_whose_chi2_the_scan_reports():
    """Figs. 4 and 6 and the choice of Fig. 6's transit average the model
    over each exposure by the chi^2's own rule (LightCurve.supersampled_times,
    30-s sub-exposures): the chi^2 of the figures' model summed over the
    windows is the scan's chi^2. The figures used their own 60-s rule (31
    instead of 59 sub-exposures of a Kepler long cadence)."""
    from jaxppo.obliquity._figures import _model

    system = jp.kepler20_system()
    events = jp.multi_transits(system, 300, 700)
    t = np.concatenate([np.arange(e.start - 0.08, e.end + 0.08, 0.0204335982) for e in events])
    sim = jp.simulate(system, t, noise=1e-5, alpha=312.0, case="same", seed=2)
    lc = jp.LightCurve(sim.time, sim.flux, sim.flux_err, exposure=0.0204335982)
    alpha = np.arange(0.0, 360.0, 4.0)
    res = jp.scan(system, lc, alpha=alpha, cases=("same",), detrend="none")
    chi2 = np.zeros(alpha.size)
    for w in res.windows:
        m = _model(system, w.time, alpha, "same", w.exposure)
        chi2 += np.sum(((w.flux[None, :] - m) / w.flux_err[None, :]) ** 2, axis=1)
    np.testing.assert_allclose(chi2, res.table["chi2"], rtol=1e-11)


def test_scan_result_is_frozen_and_dict_access_is_deprecated(tmp_path):
    """ScanResult is an immutable dataclass; result["key"], .get and `in`
    still read its summary for one release, with a DeprecationWarning."""
    import dataclasses

    lc = jp.simulate_kepler20(seed=1)
    res = run_scan(load_config(_config(tmp_path, lc, step=30.0)), tmp_path / "out", progress=False)
    with pytest.raises(dataclasses.FrozenInstanceError):
        res.table = None
    assert res.chi2_0 == res.summary["chi2_0"] == json.loads((tmp_path / "out" / "summary.json").read_text())["chi2_0"]
    with pytest.warns(DeprecationWarning, match=r"ScanResult\['chi2_0'\] is deprecated"):
        assert res["chi2_0"] == res.chi2_0
    with pytest.warns(DeprecationWarning):
        assert res.get("points") == res.summary["points"]
    with pytest.warns(DeprecationWarning):
        assert "table5" in res
    assert "figures" not in res.summary and "ppo_or_spot" not in res.summary  # the scan draws and judges nothing


def _three(lnode_d=0.0):
    star = jp.Star.quadratic(0.4, 0.25)
    b = jp.Planet(5.0, 0.0, 12.0, 90.0, 0.1, name="b")
    c = jp.Planet(7.0, 0.0, 14.0, 90.0, 0.15, name="c")
    d = jp.Planet(8.0, 0.0, 16.0, 90.0, 0.1, name="d", lnode=lnode_d)
    return jp.System(star, [b, c, d], tilted="c")


def test_ground_level_keeps_the_overlap_of_two_untilted_planets(tmp_path):
    """When every alpha has a PPO of the tilted planet, chi^2_0 fell back to
    the sum of one-disk terms, leaving out the overlap of the untilted b and
    d (4.165e6 instead of 2.096e6 here, every Delta chi^2 shifted): it is
    now the chi^2 of b and d together (System.flux of [b, d]) beside c's own
    transit."""
    from jaxppo.obliquity._config import config_from_arguments

    s = _three()
    t = np.arange(-0.3, 0.3, 2.0 / 1440.0)
    lc = jp.simulate(s, t, noise=1e-4, seed=3)
    alpha = np.arange(0.0, 360.0, 30.0)
    res = jp.scan(s, lc, alpha=alpha, cases=("same",), detrend="none")
    assert res.summary["cases"]["same"]["alphas_without_ppo"] == 0
    (w,) = jp.scan_windows(config_from_arguments(s, lc, alpha, ("same",), 0.05, "none", 0.3, "none", None, 60))
    b, c, d = s.planets
    bd = np.asarray(jp.System(s.star, [b, d]).flux(w.time))
    c_alone = np.asarray(jp.System(s.star, [c]).flux(w.time))
    want = float(np.sum(((w.flux - (bd + c_alone - 1.0)) / w.flux_err) ** 2))
    assert abs(res.chi2_0["same"] - want) < 1e-9 * want, (res.chi2_0["same"], want)
    # the marginal scan's ground level of a draw (its own copy of the rule had the same fault)
    from jaxppo.obliquity._marginal import _chi2_0, marginal_chi2

    chi2, _, ppo = marginal_chi2([s], w.time, 1, w.flux, w.flux_err, alpha, ("same",))
    assert ppo.all()  # no quiet alpha: the fallback
    assert abs(_chi2_0(chi2, ppo, [s], w.time, 1, w.flux, w.flux_err, ("same",))[0, 0] - want) < 1e-9 * want


def test_marginal_chi2_mirrors_a_planet_with_a_node_as_system_flux_does():
    """The marginal scan's chi^2 mirrored the untilted planet after its node
    (y -> -y of the turned position) like the sweep did: case "opposite"
    with lnode = 30 deg was another light curve than System.flux's."""
    from jaxppo.obliquity._marginal import marginal_chi2

    star = jp.Star.quadratic(0.4, 0.25)
    s = jp.System(star, [jp.Planet(3.0, 0.0, 10.0, 89.0, 0.1, name="b"),
                         jp.Planet(10.0, 0.0, 20.0, 89.5, 0.1, name="c", lnode=30.0)], tilted="b")
    t = np.linspace(-0.08, 0.08, 61)
    alpha = np.arange(0.0, 360.0, 20.0)
    y = np.asarray(s.flux(t, 150.0, case="opposite")) + 1e-4
    sig = np.full(t.size, 1e-4)
    chi2, _, _ = marginal_chi2([s], t, 1, y, sig, alpha, ("same", "opposite"))
    for ci, case in enumerate(("same", "opposite")):
        want = np.sum(((y - np.asarray(s.flux(t, alpha, case=case))) / sig) ** 2, axis=1)
        np.testing.assert_allclose(chi2[0, ci], want, rtol=1e-9, err_msg=case)


def test_scan_of_events_sharing_a_transit_counts_each_point_once(tmp_path):
    """b + c, then c + d through one transit of the tilted c: the two
    windows share points and the scan crashed ("repeated time stamps"); each
    point now counts once, and the chi^2 is System.flux's on those points."""
    from jaxppo.obliquity._config import config_from_arguments

    star = jp.Star.quadratic(0.4, 0.25)
    s = jp.System(star, [jp.Planet(6.0, -0.25, 10.0, 89.5, 0.1, name="b"), jp.Planet(10.0, 0.0, 12.0, 90.5, 0.12, name="c"),
                         jp.Planet(20.0, 0.25, 20.0, 89.7, 0.09, name="d", e=0.2, omega=45.0)], tilted="c")
    t = np.arange(-1.0, 1.5, 2.0 / 1440.0)
    lc = jp.simulate(s, t, noise=1e-4, alpha=200.0, seed=5)
    alpha = np.arange(0.0, 360.0, 30.0)
    res = jp.scan(s, lc, alpha=alpha, cases=("same",), detrend="none")
    cfg = config_from_arguments(s, lc, alpha, ("same",), 0.05, "none", 0.3, "none", None, 60)
    wins = jp.scan_windows(cfg)
    times = np.concatenate([w.time for w in wins])
    assert len(wins) == 2 and np.unique(times).size < times.size  # the windows share points
    tt, first = np.unique(times, return_index=True)
    ff, ee = np.concatenate([w.flux for w in wins])[first], np.concatenate([w.flux_err for w in wins])[first]
    want = np.sum(((ff - np.asarray(s.flux(tt, alpha, case="same"))) / ee) ** 2, axis=1)
    np.testing.assert_allclose(res.by_case()["same"]["chi2"], want, rtol=1e-10)


def test_scan_refuses_untilted_planets_on_different_nodes():
    """With untilted planets on different nodes, the mirror image of the
    tilted planet is no tilt of the listed cases: the scan missed half the
    geometries (light curves 5e-3 from any it computed); it refuses them."""
    s = _three(lnode_d=30.0)
    lc = jp.simulate(s, np.linspace(-0.2, 0.2, 50), noise=1e-4)
    with pytest.raises(ValueError, match=r"untilted planets on one node \(lnode\), got \[0.0, 30.0\]"):
        jp.scan(s, lc, alpha=np.arange(0.0, 360.0, 30.0))
    jp.sweep(s, lc.time, [0.0, 90.0])  # the light curves themselves are fine


def _as_an_older_release(summary: dict, release: str) -> dict:
    """A finished scan's summary as an older release wrote it: "checks" without the goodness-of-fit and grid
    checks; "intervals" with Table 5 rows spanning the run alone (no open flags) and the grid check's numbers
    under the answer's own names."""
    old = json.loads(json.dumps(summary))
    if release == "checks":
        for key in ("goodness_of_fit", "alpha_grid_check"):
            old.pop(key)
        return old
    for r in old["table5"]:
        for k in ("lower_open", "upper_open", "mirror_lower_open", "mirror_upper_open"):
            r.pop(k)
    for c in old["alpha_grid_check"]["cases"].values():
        for k in ("probabilities", "favoured", "jeffreys", "log10_bayes_factor"):
            c[k] = c.pop(k + "_on_grid")
    return old


@pytest.mark.parametrize("release", ["checks", "intervals"])
def test_a_scan_finished_before_the_checks_is_analysed_again(tmp_path, release):
    """A finished scan whose summary.json has no goodness-of-fit and grid checks (written by a version without
    them) was handed back as stored, its probabilities unchecked: it is analysed again from its progress file
    (no chi^2 of the grid recomputed) and gets both checks. So is one whose Table 5 spans each run alone (a
    feature one point wide printed +0/-0) and whose grid check names its coarse numbers as the answer."""
    import jaxppo.obliquity._scan as scan_mod

    cfg = _small(tmp_path)
    run_scan(cfg, tmp_path / "out", progress=False)
    path = tmp_path / "out" / "summary.json"
    path.write_text(json.dumps(_as_an_older_release(json.loads(path.read_text()), release)))
    calls = []
    real = scan_mod.grid_chi2

    def counting(system, data, alphas, case):
        calls.append(len(alphas))
        return real(system, data, alphas, case)

    scan_mod.grid_chi2 = counting
    try:
        again = run_scan(cfg, tmp_path / "out", progress=False)
    finally:
        scan_mod.grid_chi2 = real
    assert again.summary["goodness_of_fit"]["ok"] and again.summary["alpha_grid_check"]["step"] == 12.0
    assert all("probabilities_on_grid" in c for c in again.summary["alpha_grid_check"]["cases"].values())
    assert all("lower_open" in r for r in again.summary["table5"])
    assert not again.resumed["finished_before"] and again.resumed["alphas_done_before"] == 60
    assert calls == []  # the grid's chi^2 came from the progress file (the midpoints: resolution_check's own)


def test_grid_check_compares_the_bayes_factor_too(monkeypatch):
    """Both grids "decisive" and the probabilities 1.0 to 1e-7, but log10 K 7.5 on the grid and 12.2 at half
    the step (a 5-deg grid on an injected PPO against 1 deg): the printed K was off by 4.7 orders of
    magnitude. ``resolution_check`` fails a case whose log10 K moves by more than 0.5 (a half category)."""
    import jaxppo.obliquity._chi2 as chi2_mod

    alpha = np.arange(0.0, 360.0, 5.0)
    retro = (alpha > 90) & (alpha <= 270)
    chi2 = np.where(retro, 1000.0, 1000.0 + 2 * 7.5 * np.log(10.0) + 2 * np.log(1.0))  # log10 K = 7.5
    mids = alpha + 2.5
    deep = 1000.0 - 2 * 12.2 * np.log(10.0) + 2 * np.log(len(alpha))  # one midpoint alone carries K ~ 1e12
    at_mids = np.where(mids == 152.5, deep, np.where((mids % 360 > 90) & (mids % 360 <= 270), 1000.0, chi2.max()))
    monkeypatch.setattr(chi2_mod, "grid_chi2", lambda system, data, alphas, case: at_mids[np.searchsorted(mids, alphas)])
    check = chi2_mod.resolution_check(None, None, alpha, {"same": chi2}, {"same": 1000.0}, 72)
    c = check["cases"]["same"]
    assert c["jeffreys_on_grid"] == c["jeffreys_at_half_step"] == "decisive" and c["largest_shift"] < 1e-6
    assert c["log10_bayes_factor_at_half_step"] - c["log10_bayes_factor_on_grid"] > 0.5
    assert not c["ok"] and "log10 K" in c["reason"]


def test_grid_check_skips_midpoints_without_a_ppo_exactly():
    """The grid check computes chi^2 only at midpoints where some frame has a PPO (elsewhere chi^2 is the
    ground level exactly): the same numbers, bit for bit, as computing every midpoint."""
    from jaxppo.obliquity._chi2 import resolution_check
    from jaxppo.obliquity._windows import windows_data

    lc = jp.simulate_kepler20(seed=5, noise=2e-4, radius_scale=2.0, alpha=147.0, case="same")
    system = jp.kepler20_system(radius_scale=2.0)
    res = jp.scan(system, lc, alpha=np.arange(0.0, 360.0, 4.0), detrend="none")
    data = windows_data(list(res.windows), lc.exposure)
    chi2 = {c: res.table["chi2"][res.table["case"] == c] for c in ("same", "opposite")}
    c0 = res.chi2_0
    full = resolution_check(system, data, np.arange(0.0, 360.0, 4.0), chi2, c0, 45)
    quick = resolution_check(system, data, np.arange(0.0, 360.0, 4.0), chi2, c0, 45, windows=res.windows)
    assert full == quick


def test_grid_check_does_not_withhold_a_near_even_split_for_its_side_of_50_percent(monkeypatch):
    """The real Kepler-20 scan on a 5-deg grid: 50.04 / 49.96 % on the grid, 49.95 / 50.05 % at 2.5 deg, both
    "barely worth mentioning", log10 K 7e-4 and 8e-4: the favoured geometry "changed", and the check withheld
    an answer that a 0.5-deg grid confirms (50/50). A flip counts only where a grid rates the preference; a
    flip of a rated preference still fails."""
    import jaxppo.obliquity._chi2 as chi2_mod

    alpha = np.arange(0.0, 360.0, 5.0)
    mids = alpha + 2.5
    pro, pro_mids = (alpha <= 90) | (alpha > 270), (mids % 360 <= 90) | (mids % 360 > 270)
    for gap, ok in ((0.004, True), (2.0, False)):  # Delta chi^2 between the geometries: K ~ 1.002, K ~ e
        chi2 = np.where(pro, 100.0 - gap / 2, 100.0 + gap / 2)  # the grid: prograde favoured
        at_mids = np.where(pro_mids, 100.0 + 2 * gap, 100.0 - 2 * gap)  # half the step: retrograde favoured
        monkeypatch.setattr(chi2_mod, "grid_chi2", lambda s, d, a, c: at_mids[np.searchsorted(mids, a)])
        c = chi2_mod.resolution_check(None, None, alpha, {"same": chi2}, {"same": 100.0}, 72)["cases"]["same"]
        assert c["favoured_on_grid"] != c["favoured_at_half_step"]
        assert c["ok"] is ok, c
        if ok:
            assert c["jeffreys_on_grid"] == c["jeffreys_at_half_step"] == "barely worth mentioning"
            assert c["largest_shift"] < 0.005


def test_chi2_null_model_counts_two_untilted_planets_overlap_once():
    """summary cases[case]["chi2_null_model"] (the no-PPO model's chi^2) for
    a triple whose untilted planets c and d overlap each other in the
    window: it summed each disk's own dip, counting their overlap twice
    (1266.05 on data simulated without any PPO of b, whose chi^2 is 447.69
    for 438 points). Data without a PPO of b: the no-PPO model is the truth
    and its chi^2 is the scan's ground level."""
    star = jp.Star.quadratic(0.4, 0.25)
    b = jp.Planet(period=3.7, t0=0.032, a=10.6, inc=87.7, radius=0.018, name="b")
    c = jp.Planet(period=10.85, t0=0.0, a=22.76, inc=89.97, radius=0.029, name="c")
    d = jp.Planet(period=25.0, t0=0.01, a=40.0, inc=89.98, radius=0.025, name="d")
    system = jp.System(star, [b, c, d])
    t = np.arange(-0.2, 0.2, 1 / 1440)
    lc = jp.simulate(system, t, noise=1e-4, seed=2)
    res = jp.scan(system, lc, alpha=np.arange(0.0, 360.0, 2.0), detrend="none")
    for case, v in res.summary["cases"].items():
        assert v["chi2_null_model"] == pytest.approx(v["chi2_0"], rel=1e-9), case
        assert v["chi2_null_model"] < 1.3 * res.summary["points"]


RULED_OUT = """
[star]
law = "quadratic"
coefficients = [0.4, 0.25]

[[planet]]
name = "t"
period = 10.0
t0 = 0.0
a = 15.0
inc = 88.854
radius = 0.1
tilted = true

[[planet]]
name = "b"
period = 20.0
t0 = 0.0
a = 20.0
inc = 89.141
radius = 0.1

[data]
path = "data.csv"

[scan]
alpha = [0.0, 360.0, 2.0]
cases = ["same", "opposite"]
detrend = "none"
"""


def test_a_case_the_data_rule_out_is_not_rated(tmp_path):
    """Two planets whose double transits overlap in every case, the truth in
    case "opposite" at alpha = 200 deg: case "same" fits at no tilt (its
    least chi^2 / N = 145), yet the check of the best case alone passed and
    the scan printed "prograde, same hemisphere 100 %, decisive" for it.
    Each case's own least chi^2 is now checked: "same" is withheld with the
    reason, "opposite" (which fits) keeps its rating, in the report too."""
    from jaxppo.obliquity._report import scan_report

    star = jp.Star.quadratic(0.4, 0.25)
    system = jp.System(star, [jp.Planet(10.0, 0.0, 15.0, 88.854, 0.1, name="t"),
                              jp.Planet(20.0, 0.0, 20.0, 89.141, 0.1, name="b")], tilted="t")
    t = np.concatenate([np.arange(m - 0.3, m + 0.3, 2.0 / 1440.0) for m in (0.0, 20.0, 40.0)])
    jp.simulate(system, t, noise=1e-4, alpha=200.0, case="opposite", seed=7).to_csv(tmp_path / "data.csv")
    (tmp_path / "scan.toml").write_text(RULED_OUT)
    cfg = load_config(tmp_path / "scan.toml")
    res = run_scan(cfg, tmp_path / "out", progress=False)
    check = res.summary["goodness_of_fit"]
    assert check["ok"] and set(check["ruled_out"]) == {"same"}
    same, opposite = (res.summary["probabilities"][c] for c in ("same", "opposite"))
    assert same["favoured"] is None and same["jeffreys"] == "not rated" and "rule case same out" in same["withheld"]
    assert opposite["favoured"] == "retrograde, same hemisphere" and not opposite.get("withheld")
    assert res.summary["cases"]["same"]["min_delta_chi2"]["value"] + res.summary["chi2_0"]["same"] > 100 * len(t)
    text = scan_report(res.summary, cfg, tmp_path / "out", 1.0)
    assert "the data rule case same out" in text
    assert np.all(np.isnan(res.table["posterior"][res.table["case"] == "same"]))
    # a review's edges: least chi^2 straddling the goodness-of-fit limit 0.008 apart fit alike (both rated); a
    # case whose chi^2 is NaN is withheld for the NaN, not "ruled out by the data"
    from jaxppo.obliquity._stats import case_ruled_out, guard_cases, ruled_out_margin

    geo = res.summary["probabilities"]["opposite"]
    for best, ruled in (({"same": 3655.008, "opposite": 3655.0}, set()), ({"same": 3655.0 + 230.0, "opposite": 3655.0},
                                                                       {"same"})):
        cases = {c: {"geometries": dict(geo)} for c in best}
        assert set(guard_cases(cases, best, 2924)["ruled_out"]) == ruled
        assert bool(cases["same"]["geometries"].get("withheld")) == bool(ruled)
    assert ruled_out_margin(2924) == pytest.approx(3 * np.sqrt(2 * 2924)) and ruled_out_margin(10) == 25.0
    nan = case_ruled_out("same", float("nan"), {"same": float("nan"), "opposite": 1000.0}, 1000)
    assert "nothing can be rated" in nan and "rule" not in nan


def test_report_says_where_a_rating_rests_on_a_dip_a_spot_explains_better():
    """A spot crossing (a Gaussian bump) in Kepler-20 b + c data without a
    PPO: the scan's deepest dip (Delta chi^2 -207.9 at 248 deg) carried
    "retrograde, different hemispheres: decisive", and only summary.json
    said that a spot explains it better (BIC margin 175, very strong). The
    report prints each dip's verdict, and a caution where a rated case's
    deepest dip goes to a spot or to no PPO with strong evidence or more;
    none where the verdict is the PPO's or the case is withheld."""
    from jaxppo.obliquity._report import dip_lines

    def dip(alpha, dchi2, preferred, evidence, margin):
        return {"case": "same", "alpha": alpha, "scan_delta_chi2": dchi2, "preferred": preferred,
                "evidence": evidence, "bic_margin": margin}

    summary = {"cases": {"same": {"geometries": {"favoured": "retrograde, different hemispheres"},
                                  "min_delta_chi2": {"alpha": 248.0, "value": -207.88}}},
               "ppo_or_spot": {"dips": [dip(216.0, -0.83, "no PPO", "positive", 4.53),
                                        dip(248.0, -207.88, "spot", "very strong", 175.17)]}}
    lines = dip_lines(summary)
    assert lines[1] == ("PPO or spot, dip at alpha = 248 deg (case same, Delta chi^2 = -207.88): spot (very strong, "
                        "BIC margin 175.17)")
    assert len(lines) == 3 and lines[2].startswith("caution: case same's rating rests on its deepest dip (alpha = 248")
    assert "a starspot crossing explains better" in lines[2]
    summary["ppo_or_spot"]["dips"][1].update(preferred="PPO")
    assert not any(ln.startswith("caution") for ln in dip_lines(summary))
    summary["ppo_or_spot"]["dips"][1].update(preferred="no PPO", evidence="strong")
    assert "no PPO at all explains better" in dip_lines(summary)[-1]
    summary["cases"]["same"]["geometries"]["jeffreys"] = "barely worth mentioning"  # a rating that rests on no dip
    assert not any(ln.startswith("caution") for ln in dip_lines(summary))
    summary["cases"]["same"]["geometries"].update(jeffreys="decisive", withheld="not rated")
    assert not any(ln.startswith("caution") for ln in dip_lines(summary))
    assert dip_lines({"ppo_or_spot": {"error": "ValueError: x"}}) == ["PPO or spot: not decided (ValueError: x)"]
