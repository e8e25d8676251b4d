"""The obliquity scan per pair (three planets: the tilted t with b at two
epochs and with d at one): each pair's chi^2 is System.flux's on its own
windows' points, the PPO shows in its own pair only, and the whole scan is
the sum of its pairs."""

import json

import numpy as np
import pytest

import jaxppo as jp
from jaxppo.obliquity._pairs import pair_lines


def _system():
    star = jp.Star.quadratic(0.4, 0.25)
    t = jp.Planet(10.0, 0.0, 15.0, float(np.rad2deg(np.arccos(0.3 / 15.0))), 0.1, name="t")
    b = jp.Planet(20.0, 0.0, 20.0, float(np.rad2deg(np.arccos(0.3 / 20.0))), 0.1, name="b")
    # d crosses 0.7 R* below the centre: t's path (0.3 R* from the centre) never meets it
    d = jp.Planet(30.0, 10.0, 25.0, float(np.rad2deg(np.arccos(-0.7 / 25.0))), 0.1, name="d")
    return jp.System(star, [t, b, d], tilted="t")


@pytest.fixture(scope="module")
def scanned(tmp_path_factory):
    s = _system()
    t = np.concatenate([np.arange(m - 0.3, m + 0.3, 2.0 / 1440.0) for m in (0.0, 10.0, 20.0)])
    lc = jp.simulate(s, t, noise=1e-4, alpha=10.0, case="same", seed=7)
    out = tmp_path_factory.mktemp("pairs")
    alpha = np.arange(0.0, 360.0, 10.0)
    res = jp.scan(s, lc, alpha=alpha, cases=("same", "opposite"), detrend="none", out=out)
    return s, lc, alpha, res, out


def test_each_pair_is_its_own_windows_scan(scanned):
    s, lc, alpha, res, out = scanned
    pairs = res.summary["pairs"]
    assert list(pairs) == ["t+b", "t+d"]
    assert pairs["t+b"]["multi_transits"] == [1, 3] and pairs["t+d"]["multi_transits"] == [2]
    rows = np.genfromtxt(out / "pairs.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    windows = {w.number: w for w in res.windows}
    for key in ("t+b", "t+d"):
        # the pair's points: those of its windows (each once), as loaded (no detrending)
        tw = np.unique(np.concatenate([windows[n].time for n in pairs[key]["multi_transits"]]))
        near = np.isin(lc.time, tw)
        assert near.sum() == tw.size == pairs[key]["points"]
        for case in ("same", "opposite"):
            want = np.sum(((lc.flux[near] - np.asarray(s.flux(lc.time[near], alpha, case=case))) / lc.flux_err[near]) ** 2,
                          axis=1)
            got = rows["chi2"][(rows["pair"] == key) & (rows["case"] == case)]
            np.testing.assert_allclose(got, want, rtol=1e-10, err_msg=f"{key} {case}")


def test_the_ppo_shows_in_its_own_pair_only(scanned):
    """t's PPO with b (injected at 10 deg, case same) is pair t+b's
    detection; pair t+d, with no PPO at 10 deg, detects nothing there (its
    Delta chi^2 only rises where t would hit d), and the whole scan's chi^2
    is the sum of the pairs' (their windows share no point)."""
    _, _, alpha, res, out = scanned
    pairs = res.summary["pairs"]
    tb, td = pairs["t+b"]["cases"]["same"], pairs["t+d"]["cases"]["same"]
    assert tb["min_delta_chi2"]["alpha"] == 10.0 and tb["min_delta_chi2"]["value"] < -100.0
    assert tb["geometries"]["prograde, same hemisphere"]["probability"] > 0.999
    assert "10" not in td["ppo_transits"] and td["ppo_transits"]  # t meets d at other tilts
    k10 = int(np.nonzero(alpha == 10.0)[0][0])
    rows = np.genfromtxt(out / "pairs.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    for case in ("same", "opposite"):
        mine = {key: rows[(rows["pair"] == key) & (rows["case"] == case)] for key in ("t+b", "t+d")}
        whole = res.by_case()[case]["chi2"]
        np.testing.assert_allclose(mine["t+b"]["chi2"] + mine["t+d"]["chi2"], whole, rtol=1e-12)
    assert rows[(rows["pair"] == "t+d") & (rows["case"] == "same")]["delta_chi2"][k10] == 0.0
    assert td["min_delta_chi2"]["value"] > -10.0
    # the summary on disk holds the pairs; the report prints one block per pair
    summary = json.loads((out / "summary.json").read_text())
    assert summary["pairs"]["t+d"]["partner"] == "d"
    text = "\n".join(pair_lines(summary))
    assert "pair t+b: multi-transits [1, 3]" in text and "case same (b: same)" in text


def test_partner_hemisphere_follows_the_case_signs(tmp_path):
    """With signs per planet, each pair's geometries are named by its
    partner's own hemisphere: case "+-" puts b with t, d opposite."""
    s = _system()
    t = np.concatenate([np.arange(m - 0.3, m + 0.3, 4.0 / 1440.0) for m in (0.0, 10.0, 20.0)])
    lc = jp.simulate(s, t, noise=1e-4, seed=8)
    res = jp.scan(s, lc, alpha=np.arange(0.0, 360.0, 30.0), cases=("+-",), detrend="none")
    pairs = res.summary["pairs"]
    assert pairs["t+b"]["cases"]["+-"]["partner_case"] == "same"
    assert pairs["t+d"]["cases"]["+-"]["partner_case"] == "opposite"
    assert "prograde, different hemispheres" in pairs["t+d"]["cases"]["+-"]["geometries"]


def test_two_planets_have_no_pairs_block(tmp_path):
    """With one partner the whole scan is that pair's: no pairs block, no
    pairs.csv (the default outputs are unchanged)."""
    s = _system()
    two = jp.System(s.star, list(s.planets[:2]), tilted="t")
    t = np.arange(-0.3, 0.3, 2.0 / 1440.0)
    lc = jp.simulate(two, t, noise=1e-4, seed=9)
    res = jp.scan(two, lc, alpha=np.arange(0.0, 360.0, 30.0), cases=("same",), detrend="none", out=tmp_path)
    assert "pairs" not in res.summary and not (tmp_path / "pairs.csv").exists()


def test_a_finished_scan_without_its_pairs_is_analysed_again(scanned):
    """A folder finished before the scan reported pairs (or whose pairs.csv
    was removed) came back as finished, without the pairs: it is analysed
    again from the stored chi^2 (no block recomputed)."""
    s, lc, alpha, res, out = scanned
    (out / "pairs.csv").unlink()
    again = jp.scan(s, lc, alpha=alpha, cases=("same", "opposite"), detrend="none", out=out)
    assert not again.summary["resumed"]["finished_before"] and again.summary["resumed"]["alphas_done_before"] == 72
    assert (out / "pairs.csv").is_file() and again.summary["pairs"] == res.summary["pairs"]
    assert jp.scan(s, lc, alpha=alpha, cases=("same", "opposite"), detrend="none",
                   out=out).summary["resumed"]["finished_before"]
