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
    # the interval reaches the first angle not beyond the threshold: the
    # first integer step k with |h| (1 - k / w) <= 0.15
    k = np.arange(0, 100)
    return int(k[np.abs(height) * (1 - k / w) <= 0.15].min())


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
    assert (r["alpha"], r["lower"], r["upper"], r["start"], r["end"], r["points"]) == (358.0, 4.0, 6.0, 355.0, 3.0, 9)
    assert not r["lower_open"] and not r["upper_open"]
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
    # widths: 3 (1 - k / 11) > 0.15 up to k = 10, so the interval reaches 11; 3 (1 - k / 5) up to 4: 5
    assert (_expected_width(3.0, 11), _expected_width(3.0, 5), _expected_width(2.9, 6)) == (11, 5, 6)
    # the paper's first row: 90^{+5}_{-11}, 270^{+11}_{-5}, 93^{+6}_{-11}
    assert "$90^{+5}_{-11}$" in lines[2] and "$270^{+11}_{-5}$" in lines[2] and "$93^{+6}_{-11}$" in lines[2]
    txt = table5_text(rows)
    assert "0.15" in txt and "313 +2/-5" in txt  # 1.9 (1 - 1 / 1.2) = 0.32 > 0.15; 1.9 (1 - 2 / 1.2) < 0
    paths = write_table5(tmp_path, table, summary)
    assert [p.split("/")[-1] for p in paths] == ["table5.csv", "table5.md"]
    assert (tmp_path / "table5.md").read_text() == md


def test_interval_is_never_narrower_than_the_grid_step():
    """A feature one grid point wide printed 140 +0/-0 on a 20-deg grid:
    the curve crosses the threshold somewhere before the neighbouring
    angles, so the interval reaches them (as the paper's does: its case-4
    dip at 324^{+1}_{-1} and peak at 326^{+1}_{-1} share 325 deg)."""
    coarse = np.arange(0.0, 360.0, 20.0)
    d = np.zeros(coarse.size)
    d[7] = -2.0  # 140 deg
    (r,) = peaks_and_dips(coarse, d)
    assert (r["alpha"], r["lower"], r["upper"], r["points"]) == (140.0, 20.0, 20.0, 1)
    assert (r["start"], r["end"]) == (140.0, 140.0)  # the run itself: one angle
    d = np.zeros(ALPHA.size)
    d[[323, 324, 325, 326, 327]] = [0.1, -0.42, 0.0, 0.32, 0.1]  # the paper's case 4, 323-327 deg
    dip, peak = peaks_and_dips(ALPHA, d)
    assert (dip["kind"], dip["alpha"], dip["lower"], dip["upper"]) == ("dip", 324.0, 1.0, 1.0)
    assert (peak["kind"], peak["alpha"], peak["lower"], peak["upper"]) == ("peak", 326.0, 1.0, 1.0)
    rows = table5_rows({"opposite": {"alpha": ALPHA, "delta_chi2": d}})
    assert "324 +1/-1" in table5_text(rows) and "$36^{+1}_{-1}$" in table5_markdown(rows)  # Eq. 2: case 2
    # at the end of a grid that is not a full circle the width is to that end, printed open
    part = np.arange(20.0, 159.0, 1.0)  # the paper's 20-158 deg
    d = np.zeros(part.size)
    d[:3] = [1.0, 0.5, 0.2]
    (r,) = peaks_and_dips(part, d)
    assert (r["alpha"], r["lower"], r["lower_open"], r["upper"], r["upper_open"]) == (20.0, 0.0, True, 3.0, False)
    rows = table5_rows({"same": {"alpha": part, "delta_chi2": d}})
    assert "20 +3/->=0" in table5_text(rows) and r"$20^{+3}_{-\geq 0}$" in table5_markdown(rows)
    assert "340 +>=0/-3" in table5_text(rows)  # the mirror: the open side swaps too
    back = next(csv.DictReader(io.StringIO(table5_csv(rows))))
    assert (back["lower_open"], back["upper_open"], back["mirror_upper_open"]) == ("True", "False", "True")
    # a whole circle beyond the threshold: one feature, open on both sides
    (r,) = peaks_and_dips(ALPHA, np.ones(ALPHA.size))
    assert r["lower_open"] and r["upper_open"] and r["points"] == 360


def test_grid_ends_open_widths_and_a_grid_round_the_circle_at_uneven_steps():
    """Review: an open width at the end of a partial grid was taken modulo 360 (0 for a run over 0 .. 360);
    a grid holding both 0 and 360 counted a feature through them twice; a 7-deg grid (357 -> 0 is 3 deg) split
    one feature into two open ones; a table without features printed a bare header."""
    part = np.arange(0.0, 300.0, 10.0)
    d = np.zeros(part.size)
    d[1:] = 1.0  # beyond the threshold from 10 deg to the grid's end at 290
    d[1] = 2.0
    (r,) = peaks_and_dips(part, d)
    assert (r["alpha"], r["lower"], r["lower_open"], r["upper"], r["upper_open"]) == (10.0, 10.0, False, 280.0, True)
    with pytest.raises(ValueError, match="span less than 360 deg"):
        peaks_and_dips(np.linspace(0.0, 360.0, 361), np.zeros(361))
    seven = np.arange(0.0, 360.0, 7.0)  # ... 350, 357, then 0 again 3 deg on
    d = np.zeros(seven.size)
    d[[-2, -1, 0, 1]] = [0.5, 1.0, 2.0, 0.5]
    (r,) = peaks_and_dips(seven, d)
    assert (r["alpha"], r["start"], r["end"], r["points"]) == (0.0, 350.0, 7.0, 4)
    assert (r["lower"], r["upper"], r["lower_open"], r["upper_open"]) == (17.0, 14.0, False, False)
    rows = table5_rows({"same": {"alpha": ALPHA, "delta_chi2": np.zeros(360)}}, cases=("same", "opposite")[:1])
    assert rows == [] and table5_text(rows, ("same",)).rstrip().endswith("none")
    assert table5_markdown(rows, ("same",)) == "No Delta chi^2 feature beyond the threshold.\n"


def test_bad_input():
    with pytest.raises(ValueError, match="alpha and delta_chi2 must be 1D"):
        peaks_and_dips(ALPHA, np.zeros(3))
    with pytest.raises(ValueError, match="must be finite"):
        peaks_and_dips(ALPHA, np.full(ALPHA.size, np.nan))
    with pytest.raises(ValueError, match="case 'x' is not in the table"):
        table5_rows({"same": {"alpha": ALPHA, "delta_chi2": np.zeros(360)}}, cases=("x",))
