"""Table 5 (peaks and dips of Delta chi^2) from synthetic curves whose
features are known by construction."""

import csv
import io

import numpy as np
import pytest

from jaxppo.obliquity._tables import peaks_and_dips, table5_csv, table5_markdown, table5_rows, table5_text, write_table5

ALPHA = np.arange(0.0, 360.0, 1.0)


def _tri(center, height, left, right):
    """Triangle of ``height`` at ``center`` falling to 0 over ``left`` /
    ``right`` degrees: beyond 0.15 exactly where |h| (1 - |x| / w) > 0.15."""
    x = ALPHA - center
    w = np.where(x < 0, left, right)
    return height * np.clip(1 - np.abs(x) / w, 0, None)


def _expected_width(height, w):
    # largest integer step k with |h| (1 - k / w) > 0.15
    k = np.arange(0, 100)
    return int(k[np.abs(height) * (1 - k / w) > 0.15].max())


def test_features_of_a_known_curve():
    # widths chosen so that no edge point lies within the noise of 0.15
    # paper-like: a broad peak at 90, a dip at 313 next to a peak at 322, noise at +-0.05
    rng = np.random.default_rng(1)
    d = (_tri(90, 3.0, 20.5, 10) + _tri(313, -1.9, 12, 2.5) + _tri(322, 2.0, 3.2, 6)
         + rng.uniform(-0.05, 0.05, ALPHA.size))
    rows = peaks_and_dips(ALPHA, d, ppo_transits={"90": [3], "313": [2], "322": [2]})
    assert [(r["kind"], r["alpha"]) for r in rows] == [("peak", 90.0), ("dip", 313.0), ("peak", 322.0)]
    r90 = rows[0]
    assert r90["lower"] == _expected_width(3.0, 20.5) and r90["upper"] == _expected_width(3.0, 10)
    assert r90["transits"] == [3]
    assert r90["delta_chi2"] == pytest.approx(d[90])
    # adjacent dip and peak are separate features; the dip ends where the curve crosses -0.15
    dip, peak = rows[1], rows[2]
    assert dip["end"] < peak["start"]
    assert np.all(d[int(dip["start"]):int(dip["end"]) + 1] < -0.15)
    assert d[int(dip["start"]) - 1] >= -0.15 and d[int(dip["end"]) + 1] >= -0.15
    # nothing from noise alone
    assert peaks_and_dips(ALPHA, rng.uniform(-0.05, 0.05, ALPHA.size)) == []


def test_threshold_is_strict_and_run_wraps_through_zero():
    d = np.zeros(ALPHA.size)
    d[10] = 0.15  # not beyond the threshold
    assert peaks_and_dips(ALPHA, d) == []
    # a peak at 358 extending to 3 deg: one feature
    d = np.zeros(ALPHA.size)
    d[[355, 356, 357, 358, 359, 0, 1, 2, 3]] = [0.2, 0.5, 1.0, 2.0, 1.5, 1.0, 0.6, 0.3, 0.16]
    (r,) = peaks_and_dips(ALPHA, d)
    assert (r["alpha"], r["lower"], r["upper"], r["start"], r["end"], r["points"]) == (358.0, 3.0, 5.0, 355.0, 3.0, 9)
    # a partial grid is not circular: the same values give two features
    sub = np.arange(0.0, 359.0, 1.0)
    assert len(peaks_and_dips(sub, d[:359])) == 2


def test_rows_mirror_by_eq2_and_writers(tmp_path):
    same = _tri(90, 3.0, 11, 5) + _tri(313, -1.9, 5, 1.2)
    opp = _tri(93, 2.9, 11, 6) + _tri(310, -1.85, 5, 2)
    table = {"same": {"alpha": ALPHA, "delta_chi2": same}, "opposite": {"alpha": ALPHA, "delta_chi2": opp}}
    summary = {"cases": {"same": {"ppo_transits": {"90": [3]}}, "opposite": {"ppo_transits": {"93": [3]}}}}
    rows = table5_rows(table, summary)
    r = rows[0]
    assert (r["paper_case"], r["mirror_case"]) == ("1", "3")
    assert r["alpha"] == 90 and r["mirror_alpha"] == 270  # Eq. 2
    assert (r["mirror_upper"], r["mirror_lower"]) == (r["lower"], r["upper"])  # widths swap
    assert [x["paper_case"] for x in rows if x["case"] == "opposite"] == ["4", "4"]
    assert rows[-1]["mirror_alpha"] == 50.0 and rows[-1]["mirror_case"] == "2"
    # CSV reads back
    back = list(csv.DictReader(io.StringIO(table5_csv(rows))))
    assert len(back) == 4 and back[0]["transits"] == "3" and float(back[0]["alpha"]) == 90.0
    # paper layout: case 1 and case 4 side by side, matched features on one line
    md = table5_markdown(rows)
    lines = md.strip().splitlines()
    assert "alpha_1" in lines[0] and "alpha_3" in lines[0] and "alpha_4" in lines[0] and "alpha_2" in lines[0]
    assert len(lines) == 4  # header, rule, two paired rows
    # widths: 3 (1 - k / 11) > 0.15 up to k = 10, 3 (1 - k / 5) up to k = 4
    assert (_expected_width(3.0, 11), _expected_width(3.0, 5), _expected_width(2.9, 6)) == (10, 4, 5)
    assert "$90^{+4}_{-10}$" in lines[2] and "$270^{+10}_{-4}$" in lines[2] and "$93^{+5}_{-10}$" in lines[2]
    txt = table5_text(rows)
    assert "0.15" in txt and "313 +1/-4" in txt  # 1.9 (1 - 1 / 1.2) = 0.32 > 0.15
    paths = write_table5(tmp_path, table, summary)
    assert [p.split("/")[-1] for p in paths] == ["table5.csv", "table5.md"]
    assert (tmp_path / "table5.md").read_text() == md


def test_bad_input():
    with pytest.raises(ValueError, match="alpha and delta_chi2 must be 1D"):
        peaks_and_dips(ALPHA, np.zeros(3))
    with pytest.raises(ValueError, match="must be finite"):
        peaks_and_dips(ALPHA, np.full(ALPHA.size, np.nan))
    with pytest.raises(ValueError, match="case 'x' is not in the table"):
        table5_rows({"same": {"alpha": ALPHA, "delta_chi2": np.zeros(360)}}, cases=("x",))
