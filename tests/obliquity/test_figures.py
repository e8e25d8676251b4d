"""Scan figures from plain data: a small synthetic scan (computed here with
sweep, not with the scan module) and the exposure average of the models."""

from pathlib import Path
import types

import numpy as np
import pytest

import jaxppo as jp
from jaxppo.obliquity._figures import _model, _null_models, read_scan_csv, scan_figures
from jaxppo.model._kepler20 import kepler20_system, paper_multi_transits


def small_scan(step=3.0, exposure=None, cadence=2.0 / 1440.0, noise=2e-5, inject=(312.0, "same"), seed=3):
    """Three of the paper's b + c transits (2, 3, 4) with a PPO injected at
    alpha = 312 deg (case "same", transit 2); chi^2 per case and alpha."""
    system = kepler20_system(jp.Star.quadratic(0.495, 0.154))
    events = paper_multi_transits(system)
    rng = np.random.default_rng(seed)
    windows = []
    for n in (2, 3, 4):
        e = events[n - 1]
        t = np.arange(e.start - 0.05, e.end + 0.05, cadence)
        f = _model(system, t, [inject[0]], inject[1], exposure)[0] + rng.normal(0, noise, t.size)
        windows.append(types.SimpleNamespace(number=n, event=e, time=t, flux=f, flux_err=np.full(t.size, noise),
                                             exposure=exposure))
    alpha = np.arange(0.0, 360.0, step)
    cases = ("same", "opposite")
    table, summary = {}, {"cases": {}, "probabilities": {}}
    for case in cases:
        chi2 = np.zeros(alpha.size)
        ppo = {}
        for w in windows:
            m = _model(system, w.time, alpha, case, exposure)
            chi2 += np.sum(((w.flux - m) / w.flux_err) ** 2, axis=1)
            x, y, r = (np.asarray(v) for v in system.positions(w.time[None, :], alpha[:, None], case, xp=np))
            hit = (np.hypot(x[..., 0] - x[..., 1], y[..., 0] - y[..., 1]) < r[..., 0] + r[..., 1]).any(1)
            for a in alpha[hit]:
                ppo.setdefault(f"{a:g}", []).append(w.number)
        quiet = np.array([f"{a:g}" not in ppo for a in alpha])
        dchi2 = chi2 - np.median(chi2[quiet])
        post = np.exp(-0.5 * (dchi2 - dchi2.min()))
        post /= post.sum() * step
        table[case] = {"alpha": alpha, "chi2": chi2, "delta_chi2": dchi2, "posterior": post}
        pro = (alpha <= 90) | (alpha > 270)
        p_pro = float(post[pro].sum() * step)
        names = ("prograde, same hemisphere", "retrograde, different hemispheres") if case == "same" else (
            "prograde, different hemispheres", "retrograde, same hemisphere")
        summary["cases"][case] = {"ppo_transits": ppo}
        summary["probabilities"][case] = {
            names[0]: {"probability": p_pro, "sum_positive_delta_chi2": float(np.clip(dchi2[pro], 0, None).sum())},
            names[1]: {"probability": 1 - p_pro, "sum_positive_delta_chi2": float(np.clip(dchi2[~pro], 0, None).sum())},
            "bayes_factor": max(p_pro, 1 - p_pro) / min(p_pro, 1 - p_pro), "jeffreys": "test",
        }
    return system, windows, table, summary, cases


def test_figures_from_a_small_scan(tmp_path):
    system, windows, table, summary, cases = small_scan()
    # the injected PPO is found: transit 2 has the deepest dip near 312 deg (case "same")
    d = table["same"]
    assert abs(d["alpha"][np.argmin(d["delta_chi2"])] - 312.0) <= 3.0 and d["delta_chi2"].min() < -10
    files = scan_figures(tmp_path, summary, table, system, windows, cases)
    names = [f.split("/")[-1] for f in files]
    assert names == ["fig4_multitransits.png", "fig5_delta_chi2.png", "fig6_cutout.png", "fig7_paths.png",
                     "probabilities.png"]
    for f in files:
        with open(f, "rb") as fh:
            assert fh.read(8) == b"\x89PNG\r\n\x1a\n"
    assert not list(tmp_path.glob("*.tmp.png"))
    # some of them, in the order asked (jaxppo scan shares them between two processes): the same files
    again = tmp_path / "again"
    again.mkdir()
    some = scan_figures(again, summary, table, system, windows, cases, which=("fig7", "fig4"))
    assert [f.split("/")[-1] for f in some] == ["fig7_paths.png", "fig4_multitransits.png"]
    assert sorted(p.name for p in again.iterdir()) == ["fig4_multitransits.png", "fig7_paths.png"]
    for f in some:
        assert Path(f).read_bytes() == (tmp_path / Path(f).name).read_bytes()


def test_read_scan_csv_keeps_file_order(tmp_path):
    p = tmp_path / "scan.csv"
    p.write_text("case,alpha,chi2,delta_chi2,posterior\nopposite,0,1,0,0.5\nopposite,1,2,1,0.5\nsame,0,3,0,1\nsame,1,3,0,1\n")
    t = read_scan_csv(p)
    assert list(t) == ["opposite", "same"]
    np.testing.assert_array_equal(t["opposite"]["chi2"], [1, 2])


def test_exposure_averaged_model_against_fine_integration():
    """The figures' models average over the exposure: compare with a
    trapezoid integral of System.flux over each 29.4-min cadence."""
    system = kepler20_system(jp.Star.quadratic(0.495, 0.154))
    t = np.array([670.40, 670.43, 670.46, 670.49])
    exp = 0.0204336
    got = _model(system, t, [313.0], "same", exp)[0]
    ref = []
    for ti in t:
        s = np.linspace(ti - exp / 2, ti + exp / 2, 2001)
        f = np.asarray(system.flux(s, 313.0, "same"))
        ref.append(np.sum((f[1:] + f[:-1]) / 2) / (s.size - 1))
    np.testing.assert_allclose(got, ref, atol=2e-7)
    inst = _model(system, t, [313.0], "same", None)[0]
    assert np.abs(inst - np.asarray(ref)).max() > 1e-5  # the average matters here


def test_null_models_in_one_sweep_equal_one_call_per_array():
    """Fig. 4's no-PPO models in one sweep per exposure: unsorted arrays that
    share times (a LightCurve sorts and drops repeated times) come back in
    their own order, each as its own call of ``_model`` gives it."""
    system = kepler20_system(jp.Star.quadratic(0.495, 0.154))
    a = np.array([670.49, 670.40, 670.46])
    b = np.linspace(670.38, 670.52, 9)
    c = np.array([670.46, 670.43])
    times, exposures = [a, b, c, a], [0.0204336, 0.0204336, None, None]
    got = _null_models(system, times, "same", exposures)
    for t, e, g in zip(times, exposures, got):
        order = np.argsort(t)
        want = np.empty(t.size)  # the model at the sorted times (it returned them sorted, for any order given)
        want[order] = _model(system, t[order], [0.0], "same", e, no_overlap=True)[0]
        assert g.shape == t.shape
        np.testing.assert_allclose(g, want, rtol=0, atol=1e-14)
        np.testing.assert_allclose(_model(system, t, [0.0], "same", e, no_overlap=True)[0], want, rtol=0, atol=1e-14)


def test_figures_do_not_import_the_scan():
    """Imports point down: the figures take plain data and import neither the
    scan nor the config (the package __init__ re-exports both, so look at the
    module's own import statements)."""
    import ast

    import jaxppo.obliquity._figures as figures_module

    tree = ast.parse(Path(figures_module.__file__).read_text())
    imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
    imported |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    assert not {m for m in imported if m.lstrip(".").split(".")[-1] in ("_scan", "_config", "cli")}, imported


def test_bad_figure_input(tmp_path):
    system, windows, table, summary, cases = small_scan(step=30.0)
    with pytest.raises(ValueError, match="case 'sideways' is not in the scan table"):
        scan_figures(tmp_path, summary, table, system, windows, ("sideways",))
    with pytest.raises(ValueError, match="windows must hold"):
        scan_figures(tmp_path, summary, table, system, [], cases)
    with pytest.raises(ValueError, match="out must be an existing folder"):
        scan_figures(tmp_path / "missing", summary, table, system, windows, cases)
    for which in (("fig4", "fig9"), "fig4", ("fig4", "fig4"), None):
        with pytest.raises(ValueError, match=r"which must be a sequence of distinct names from \("):
            scan_figures(tmp_path, summary, table, system, windows, cases, which=which)


def test_fig6_shows_one_transit_with_its_own_best_and_worst_alpha():
    """Issue 10 item 6: the old Fig. 6 took the best alpha (global min of
    Delta chi^2, here transit 2) and the worst (global max, transit 3) from
    different transits. Now both are the chosen transit's own, checked with
    chi^2 of that transit alone from System.flux (exact method)."""
    from jaxppo.obliquity._figures import _fig6_choice

    system, windows, table, summary, cases = small_scan()
    _, case, w, a_best, a_worst = _fig6_choice(summary, table, system, windows, cases)
    assert (case, w.number) == ("same", 2)  # the injected PPO: the deepest dip
    own = np.array([a for a in table["same"]["alpha"] if 2 in summary["cases"]["same"]["ppo_transits"].get(f"{a:g}", ())])
    f = np.asarray(system.flux(w.time, own, "same", method="exact"))
    chi2 = np.sum(((w.flux - f) / w.flux_err) ** 2, axis=1)
    assert a_best == own[np.argmin(chi2)] == 312.0
    assert a_worst == own[np.argmax(chi2)]
    d = table["same"]
    # the global maximum lies in another transit: the old choice mixed them
    assert 2 not in summary["cases"]["same"]["ppo_transits"][f"{d['alpha'][np.argmax(d['delta_chi2'])]:g}"]


def test_a_withheld_panel_of_the_probabilities_has_no_axes(tmp_path, monkeypatch):
    """A case whose probabilities are withheld was drawn as an empty frame with 0-1 ticks beside the other
    case's bars (sharing its y axis); now it is the note alone, and the drawn panel keeps its labels."""
    import jaxppo.obliquity._figures as figures

    system, windows, table, summary, cases = small_scan(step=12.0)
    geo = summary["probabilities"]["same"]
    summary["probabilities"]["same"] = {k: (dict(v, probability=None) if isinstance(v, dict) else v)
                                        for k, v in geo.items()}
    summary["probabilities"]["same"].update(favoured=None, bayes_factor=None, withheld="the alpha grid (step 12 deg)")
    drawn = []
    save = figures._save
    monkeypatch.setattr(figures, "_save", lambda fig, path: (drawn.append(fig), save(fig, path))[1])
    scan_figures(tmp_path, summary, table, system, windows, cases, which=("probabilities",))
    (fig,) = drawn
    held, shown = fig.axes
    assert not held.axison and "withheld" in " ".join(t.get_text() for t in held.texts)
    assert shown.axison and shown.get_ylabel() == "probability [%]" and len(shown.patches) == 2
    assert all(lab.get_visible() for lab in shown.get_yticklabels())


def test_fig5_shows_a_grid_that_does_not_start_at_zero(tmp_path, monkeypatch):
    """``--alpha -180 180 1`` is a grid the command accepts; Fig. 5's x axis was fixed at 0 .. 360, so half of
    both curves was off the plot and the transit labels of the features at negative alpha were clamped to
    the left edge with no curve under them."""
    import jaxppo.obliquity._figures as figures
    from jaxppo.obliquity._stats import plot_range

    assert plot_range(np.arange(-180.0, 180.0, 1.0)) == (-180.0, 180.0)
    assert plot_range(np.arange(10.0, 370.0, 5.0)) == (10.0, 370.0)
    assert plot_range(np.arange(0.0, 360.0, 7.0)) == (0.0, 360.0)  # 357 -> 360 is within a step
    assert plot_range(np.arange(20.0, 159.0, 1.0)) == (20.0, 158.0)  # a partial grid: its own span
    system, windows, table, summary, cases = small_scan(step=12.0)
    for case in cases:  # the same curves on the grid -180 .. 168 (alpha and alpha - 360 are one tilt)
        d = table[case]
        order = np.argsort(np.where(d["alpha"] >= 180.0, d["alpha"] - 360.0, d["alpha"]))
        table[case] = {k: np.asarray(v)[order] for k, v in d.items()}
        table[case]["alpha"] = np.where(table[case]["alpha"] >= 180.0, table[case]["alpha"] - 360.0, table[case]["alpha"])
        ppo = summary["cases"][case]["ppo_transits"]  # keyed by the grid's own angles, as the scan writes them
        summary["cases"][case]["ppo_transits"] = {f"{float(k) - 360.0 if float(k) >= 180.0 else float(k):g}": v
                                                  for k, v in ppo.items()}
    drawn = []
    save = figures._save
    monkeypatch.setattr(figures, "_save", lambda fig, path: (drawn.append(fig), save(fig, path))[1])
    scan_figures(tmp_path, summary, table, system, windows, cases, which=("fig5",))
    ax = drawn[0].axes[0]
    assert ax.get_xlim() == (-180.0, 180.0)
    for text in ax.texts:  # every transit label over its own feature (none clamped to an edge)
        assert -180.0 < text.xy[0] < 180.0
    assert any(t.xy[0] < 0 for t in ax.texts)  # the injected PPO at 312 deg is at -48 deg here
    ticks = ax.get_xticks()
    assert ticks[0] == -180.0 and ticks[-1] == 180.0
    assert all(-180.0 <= line.get_xdata()[0] <= 180.0 for line in ax.lines if line.get_linestyle() == ":")
