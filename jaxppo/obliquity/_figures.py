"""The paper's figures from a finished scan (Mueller et al. 2021, Figs. 4-7
and Table 6), drawn from plain data so that any scan driver can call them.

``scan_figures(out, summary, table, system, windows, cases)``:

* ``out``: folder to write the PNGs into;
* ``summary``: the scan summary (``summary.json``): ``cases[case]["ppo_transits"]``
  ({f"{alpha:g}": [transit numbers]}) and ``probabilities[case]`` (geometry
  name -> {"probability", "sum_positive_delta_chi2"}, plus "bayes_factor",
  "jeffreys");
* ``table``: {case: {"alpha", "chi2", "delta_chi2", "posterior"}} arrays
  (``read_scan_csv``);
* ``system``: the ``jaxppo.System`` that was scanned;
* ``windows``: the multi-transit windows, objects with ``number`` (1-based),
  ``event`` (``jaxppo.MultiTransit``), ``time`` [d], ``flux`` and
  ``flux_err`` (detrended, relative), ``exposure`` [d] or None (the models
  are averaged over the exposure when given);
* ``cases``: the hemisphere cases, in order.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..model._exposure import supersampled_times
from ..model._processes import on_writer
from ..model._overlap import no_ppo_model
from ..model._sweep import sweep
from ..model._cases import case_label, case_signs
from ._stats import plot_range
from ._tables import peaks_and_dips

__all__ = ["scan_figures", "read_scan_csv", "FIGURES"]

_CASE_COLORS = ("tab:red", "tab:blue", "tab:green", "tab:purple", "tab:orange", "tab:brown", "tab:pink", "tab:olive")


def read_scan_csv(path) -> dict:
    """{case: {"alpha", "chi2", "delta_chi2", "posterior"}} from a scan.csv;
    a file that is not a whole scan.csv is a ValueError naming it."""
    try:
        rows = np.atleast_1d(np.genfromtxt(path, delimiter=",", names=True, dtype=None, encoding=None))
        missing = [k for k in ("case", "alpha", "chi2", "delta_chi2", "posterior") if k not in (rows.dtype.names or ())]
    except (ValueError, OSError) as err:
        raise ValueError(f"{path}: not a readable scan.csv ({' '.join(str(err).split())[:200]}); rerun the scan") from None
    if missing or rows.size == 0:
        raise ValueError(f"{path}: not a complete scan.csv (missing columns {missing} or no rows); rerun the scan")
    for k in ("alpha", "chi2", "delta_chi2", "posterior"):
        bad = ~np.isfinite(np.asarray(rows[k], float))
        if k == "posterior":  # NaN for a whole case whose probabilities are withheld (docs/scan.md)
            bad &= ~np.isin(rows["case"], [c for c in set(rows["case"].tolist()) if bad[rows["case"] == c].all()])
        if np.any(bad):
            raise ValueError(f"{path}: column {k} has empty or non-finite values (a truncated file?); rerun the scan")
    out = {}
    for case in dict.fromkeys(rows["case"].tolist()):  # file order
        sel = rows["case"] == case
        out[str(case)] = {k: np.asarray(rows[k][sel], float) for k in ("alpha", "chi2", "delta_chi2", "posterior")}
    return out


def _key(case) -> str:
    return case_label(case)


def _case_title(case) -> str:
    name = _key(case)
    return {"same": "case 1 (same hemisphere)", "opposite": "case 4 (opposite hemispheres)"}.get(name, f"case {name}")


def _ppo(summary: dict, case) -> dict:
    return summary.get("cases", {}).get(_key(case), {}).get("ppo_transits", {}) or {}


def _model(system, time, alphas, case, exposure, no_overlap: bool = False) -> np.ndarray:
    """[alpha, time] flux, averaged over the exposure [d] when given, by the
    rule of the scan's chi^2 (``LightCurve.supersampled_times``): the
    figures show the model whose chi^2 the scan reports. ``time`` in any
    order, with repeats. ``no_overlap``: the no-PPO model (``no_ppo_model``,
    one row)."""
    # the model at the distinct times (sorted), then back in the order given; the times may be a fine grid for a
    # smooth curve, closer than the exposure (a LightCurve of data refuses that)
    distinct, back = np.unique(np.asarray(time, float), return_inverse=True)
    alphas = np.atleast_1d(np.asarray(alphas, float))
    tm, n = supersampled_times(distinct, exposure or None)
    f = no_ppo_model(system, tm, case)[None] if no_overlap else sweep(system, tm, alphas, cases=(case,))[0]
    return f.reshape(alphas.size, distinct.size, n).mean(-1)[:, back.ravel()]


def _null_models(system, times, case, exposures) -> list:
    """The no-PPO model (``no_ppo_model``: no PPO of the tilted planet) at each array
    of ``times``, with its exposure of ``exposures``: one sweep per distinct
    exposure (one call of ``_model`` per array cost 30 ms each)."""
    out = [None] * len(times)
    for exposure in dict.fromkeys(exposures):
        idx = [k for k, x in enumerate(exposures) if x == exposure]
        flat = _model(system, np.concatenate([np.asarray(times[k], float) for k in idx]), [0.0], case, exposure,
                      no_overlap=True)[0]
        for k, part in zip(idx, np.split(flat, np.cumsum([np.size(times[k]) for k in idx])[:-1])):
            out[k] = part
    return out


def _save(fig, path: Path) -> Path:
    import matplotlib.pyplot as plt

    def write():
        tmp = path.with_name(path.stem + ".tmp.png")
        fig.savefig(tmp, dpi=130)
        tmp.replace(path)

    try:  # process 0 of several JAX processes writes; every process computes the curves (collectives)
        on_writer(f"writing {path}", write)
    finally:
        plt.close(fig)
    return path


def _fig5(plt, out, summary, table, system, cases, colors):
    """Delta chi^2 (alpha) per case; transit numbers at each PPO run's
    extreme, kept inside the axes."""
    from ..model._transits import alpha_limits

    fig, ax = plt.subplots(figsize=(8.0, 4.0))
    ymin, ymax = 0.0, 0.0
    labels = []
    lo, hi = plot_range(table[_key(cases[0])]["alpha"])
    for ci, case in enumerate(cases):
        d = table[_key(case)]
        a, dc = d["alpha"], d["delta_chi2"]
        ax.plot(a, dc, color=colors[_key(case)], lw=1.1, label=_case_title(case))
        ymin, ymax = min(ymin, float(dc.min())), max(ymax, float(dc.max()))
        # one label per Table 5 feature (|Delta chi^2| > 0.15), at its extreme
        for r in peaks_and_dips(a, dc, ppo_transits=_ppo(summary, case)):
            if r["transits"]:
                labels.append((r["alpha"], r["delta_chi2"], ",".join(str(v) for v in r["transits"]),
                               colors[_key(case)], ci))
    span = max(ymax - ymin, 0.5)
    pad = 0.14 * span
    ax.set_ylim(ymin - pad, ymax + pad)
    ax.set_xlim(lo, hi)
    for x, y, text, col, ci in labels:
        # above peaks, below dips, the cases side by side; the anchor is
        # clamped so that the text stays inside the frame
        up = y >= 0
        xx = min(max(x, lo + 0.022 * (hi - lo)), hi - 0.022 * (hi - lo))
        ax.annotate(text, (xx, y), textcoords="offset points", xytext=(4 * (2 * ci - 1) if len(cases) > 1 else 0,
                                                                      3 if up else -3),
                    ha="center", va="bottom" if up else "top", fontsize=7, color=col, clip_on=True)
    ax.axhline(0, color="k", lw=0.5)
    ax.axhspan(-0.15, 0.15, color="0.85", lw=0, zorder=0, label=r"$|\Delta\chi^2| \leq 0.15$ (Table 5 threshold)")
    try:
        for lim in alpha_limits(system):
            x = lo + (lim - lo) % 360.0  # the same tilt on the grid's own range
            if x <= hi:
                ax.axvline(x, color="0.5", lw=0.6, ls=":")
    except ValueError:
        pass
    ax.set_xticks(np.arange(45.0 * np.ceil(lo / 45.0), hi + 1e-9, 45.0))
    ax.set_xlabel(r"tilt angle $\alpha$ [deg]")
    ax.set_ylabel(r"$\Delta\chi^2$")
    fig.suptitle(r"$\Delta\chi^2(\alpha)$; numbers: multi-transits with a PPO; dotted: $\alpha_{a..d}$ (Eqs. 3-6)",
                 fontsize=9)
    # legend above the axes: it never hides the curves or their labels
    ax.legend(fontsize=7, loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=3, frameon=False)
    fig.tight_layout()
    return _save(fig, out / "fig5_delta_chi2.png")


def _fig4(plt, out, summary, table, system, windows, cases):
    """Each multi-transit: data, the model at alpha = 0 (no PPO) and the
    spread of models over alpha; residuals to the no-PPO model."""
    n = len(windows)
    case0 = cases[0]
    alphas = table[_key(case0)]["alpha"]
    fig, axes = plt.subplots(2, n, figsize=(2.5 * n + 0.6, 4.6), sharey="row",
                             gridspec_kw={"height_ratios": [3, 1]}, squeeze=False)
    fine = [np.linspace(w.time.min(), w.time.max(), 300) for w in windows]
    nulls = _null_models(system, [w.time for w in windows] + fine, case0, [w.exposure for w in windows] * 2)
    for i, w in enumerate(windows):
        e = w.event
        t_fine = fine[i]
        # only the alphas that give this transit a PPO differ from the no-PPO model
        ppo = _ppo(summary, case0)
        with_ppo = np.array([a for a in alphas if w.number in ppo.get(f"{a:g}", ())] or [0.0])
        models = _model(system, t_fine, with_ppo, case0, w.exposure)
        null = nulls[i]
        ax, rax = axes[0, i], axes[1, i]
        hours = lambda t: (t - e.mid) * 24.0
        ax.errorbar(hours(w.time), (w.flux - 1) * 1e6, yerr=w.flux_err * 1e6, fmt=".", ms=2, color="0.55", lw=0.4,
                    zorder=1)
        lo, hi = models.min(0), models.max(0)
        if np.any(hi - lo > 1e-9):
            ax.fill_between(hours(t_fine), (lo - 1) * 1e6, (hi - 1) * 1e6, color="tab:red", alpha=0.35, lw=0,
                            zorder=2, label="models over alpha")
        ax.plot(hours(t_fine), (nulls[n + i] - 1) * 1e6, color="k", lw=0.8, zorder=3, label="no PPO")
        rax.errorbar(hours(w.time), (w.flux - null) * 1e6, yerr=w.flux_err * 1e6, fmt=".", ms=2, color="0.4", lw=0.3)
        rax.axhline(0, color="k", lw=0.5)
        ax.set_title(f"{w.number}: {'+'.join(e.planets)} BKJD {e.mid:.2f}", fontsize=7)
        rax.set_xlabel("hours from mid", fontsize=7)
        ax.tick_params(labelsize=7)
        rax.tick_params(labelsize=7)
    axes[0, 0].set_ylabel("flux - 1 [ppm]")
    axes[1, 0].set_ylabel("O - C [ppm]")
    axes[0, 0].legend(fontsize=6, loc="best")
    fig.tight_layout()
    return _save(fig, out / "fig4_multitransits.png")


def _window_chi2(system, w, alphas, case):
    m = _model(system, w.time, alphas, case, w.exposure)
    return np.sum(((w.flux[None, :] - m) / w.flux_err[None, :]) ** 2, axis=1)


def _fig6_choice(summary, table, system, windows, cases):
    """(score, case, window, alpha_best, alpha_worst) for Fig. 6, or None
    when no alpha gives any transit a PPO."""
    # The transit: the one responsible for the deepest dip of Delta chi^2
    # (the paper's transit 2 at alpha_1 = 313 deg); without dips, the one
    # whose chi^2 changes most with alpha. Best and worst alpha are then that
    # transit's own, among the angles that give it a PPO.
    choice = None  # (score, case, window, alpha_best, alpha_worst)
    for case in cases:
        d = table[_key(case)]
        alphas = d["alpha"]
        ppo = _ppo(summary, case)
        for w in windows:
            has = np.array([w.number in ppo.get(f"{a:g}", ()) for a in alphas])
            if not has.any():
                continue
            c2 = _window_chi2(system, w, alphas[has], case)
            dip = -float(d["delta_chi2"][has].min())
            score = (dip > 0.15, dip if dip > 0.15 else float(c2.max() - c2.min()))
            if choice is None or score > choice[0]:
                choice = (score, case, w, alphas[has][np.argmin(c2)], alphas[has][np.argmax(c2)])
    return choice


def _fig6(plt, out, summary, table, system, windows, cases, colors):
    """One multi-transit with its own best (lowest chi^2) and worst (highest)
    alpha among the angles that give it a PPO, zoomed on the PPO (paper
    Fig. 6), with residuals."""
    choice = _fig6_choice(summary, table, system, windows, cases)
    fig, (ax, rax) = plt.subplots(2, 1, figsize=(6.4, 5.0), sharex=True, gridspec_kw={"height_ratios": [2.2, 1]})
    if choice is None:
        ax.text(0.5, 0.5, "no alpha of the grid gives a planet-planet occultation", ha="center", va="center",
                transform=ax.transAxes)
        ax.set_axis_off()
        rax.set_axis_off()
        return _save(fig, out / "fig6_cutout.png")
    _, case, w, a_best, a_worst = choice
    t_fine = np.linspace(w.time.min(), w.time.max(), 2000)
    m_fine = _model(system, t_fine, [a_best, a_worst], case, w.exposure)
    null_fine = _model(system, t_fine, [0.0], case, w.exposure, no_overlap=True)[0]
    null = _model(system, w.time, [0.0], case, w.exposure, no_overlap=True)[0]
    # zoom: where either model departs from the no-PPO model, padded
    moved = np.flatnonzero(np.any(np.abs(m_fine - null_fine) > 1e-8, axis=0))
    t0, t1 = t_fine[moved[0]], t_fine[moved[-1]]
    cadence = np.median(np.diff(w.time)) if w.time.size > 1 else 0.01
    pad = max(0.6 * (t1 - t0), 3 * cadence, 0.01)
    lo, hi = t0 - pad, t1 + pad
    sel = (w.time >= lo) & (w.time <= hi)
    fsel = (t_fine >= lo) & (t_fine <= hi)
    ax.errorbar(w.time[sel], (w.flux[sel] - 1) * 1e6, yerr=w.flux_err[sel] * 1e6, fmt="o", ms=3, color="0.45",
                lw=0.6, label="data (detrended)", zorder=1)
    ax.plot(t_fine[fsel], (null_fine[fsel] - 1) * 1e6, color="k", lw=0.8, ls="--", label="no PPO", zorder=2)
    for m, a, col, what in ((m_fine[0], a_best, "tab:blue", "lowest"), (m_fine[1], a_worst, "tab:red", "highest")):
        ax.plot(t_fine[fsel], (m[fsel] - 1) * 1e6, color=col, lw=1.2,
                label=rf"$\alpha$ = {a:g} deg ({what} $\chi^2$ of this transit)", zorder=3)
        rax.plot(t_fine[fsel], (m[fsel] - null_fine[fsel]) * 1e6, color=col, lw=1.2, zorder=3)
    rax.errorbar(w.time[sel], (w.flux[sel] - null[sel]) * 1e6, yerr=w.flux_err[sel] * 1e6, fmt="o", ms=3,
                 color="0.45", lw=0.6, zorder=1)
    rax.axhline(0, color="k", lw=0.6, ls="--")
    ax.set_ylabel("flux - 1 [ppm]")
    rax.set_ylabel("data - no PPO [ppm]")
    rax.set_xlabel("time [BKJD]")
    rax.ticklabel_format(axis="x", useOffset=False)
    ax.set_title(f"multi-transit {w.number} ({'+'.join(w.event.planets)}), {_case_title(case)}", fontsize=9)
    ax.legend(fontsize=7, loc="best", framealpha=0.9)
    fig.tight_layout()
    return _save(fig, out / "fig6_cutout.png")


def _chord(b, alpha_deg, extent=1.25):
    """Sky path of a planet with impact parameter b (before the tilt) over
    x in [-extent, extent], rotated by alpha (CONVENTIONS)."""
    x = np.array([-extent, extent])
    y = np.full(2, b)
    ar = np.deg2rad(alpha_deg)
    return x * np.cos(ar) + y * np.sin(ar), -x * np.sin(ar) + y * np.cos(ar)


def _arrow(ax, x, y, color, lw=1.2):
    """Arrowhead near the end of a path (x, y) pointing along the motion."""
    f0, f1 = 0.78, 0.88
    p0 = (x[0] + f0 * (x[1] - x[0]), y[0] + f0 * (y[1] - y[0]))
    p1 = (x[0] + f1 * (x[1] - x[0]), y[0] + f1 * (y[1] - y[0]))
    ax.annotate("", xy=p1, xytext=p0, arrowprops=dict(arrowstyle="-|>", color=color, lw=lw, mutation_scale=11))


def _fig7(plt, out, summary, table, system, cases):
    """Sky-plane paths (paper Fig. 7): the tilted planet's path for every
    alpha that gives a PPO (red: Delta chi^2 > 0, blue: < 0), the Table 5
    extremes drawn thicker with direction arrows, the untilted planets'
    paths with arrows, the star and its equator; lengths in R*."""
    k = len(system.planets)
    tilted = system.tilted
    pt = system.planets[tilted]
    b_t = abs(float(pt.impact))
    fig, axs = plt.subplots(1, len(cases), figsize=(4.3 * len(cases), 4.6), squeeze=False)
    for ci, case in enumerate(cases):
        ax = axs[0, ci]
        ax.add_patch(plt.Circle((0, 0), 1, facecolor="#fff3c4", edgecolor="0.3", lw=0.8, zorder=0))
        ax.axhline(0, color="0.3", ls="--", lw=0.6, zorder=1)
        d = table[_key(case)]
        ppo = _ppo(summary, case)
        for a, dc in zip(d["alpha"], d["delta_chi2"]):
            if not ppo.get(f"{a:g}") or dc == 0:
                continue
            x, y = _chord(b_t, a)
            ax.plot(x, y, color="tab:red" if dc > 0 else "tab:blue", lw=0.5, alpha=0.45, zorder=2)
        peaks, dips = [], []
        for r in peaks_and_dips(d["alpha"], d["delta_chi2"], ppo_transits=ppo):
            if not r["transits"]:
                continue
            col = "tab:red" if r["delta_chi2"] > 0 else "tab:blue"
            (peaks if r["delta_chi2"] > 0 else dips).append(f"{r['alpha']:g}")
            x, y = _chord(b_t, r["alpha"])
            ax.plot(x, y, color=col, lw=1.4, zorder=3)
            _arrow(ax, x, y, col)
        signs = case_signs(k, tilted, case)
        for j, pl in enumerate(system.planets):
            if j == tilted:
                continue
            yb = signs[j] * abs(float(pl.impact))
            x, y = _chord(yb, 0.0)
            ax.plot(x, y, color="k", lw=1.3, zorder=4)
            _arrow(ax, x, y, "k")
            ax.add_patch(plt.Circle((0, yb), float(pl.radius), color="k", zorder=6))
            ax.annotate(f"planet {pl.name or j}", (-1.2, yb), textcoords="offset points", xytext=(0, 2), fontsize=7,
                        va="bottom", ha="left")
        x, y = _chord(b_t, 0.0)
        ax.plot(x, y, color="0.4", lw=0.8, ls=":", zorder=3)
        ax.annotate(rf"{pt.name or tilted} at $\alpha$ = 0", (-1.18, b_t), fontsize=6, color="0.35", va="bottom",
                    ha="left")
        ax.set_xlim(-1.25, 1.25)
        ax.set_ylim(-1.25, 1.25)
        ax.set_aspect("equal")
        ax.set_xlabel(r"x [$R_\star$]")
        ax.set_ylabel(r"y [$R_\star$]")
        ext = "Table 5 extremes [deg]: " + ("peaks " + ", ".join(peaks) if peaks else "no peak") + "; " + (
            "dips " + ", ".join(dips) if dips else "no dip")
        ax.set_title(f"{_case_title(case)}: paths of {pt.name or tilted} with a PPO\n"
                     f"red: $\\Delta\\chi^2 > 0$, blue: $< 0$; thick, with arrows: extremes\n{ext}", fontsize=7)
    fig.tight_layout()
    return _save(fig, out / "fig7_paths.png")


def _fig_probabilities(plt, out, summary, cases, colors):
    """Table 6 as bars: each case's geometry probabilities, 50 % marked."""
    probs = summary.get("probabilities", {})
    # no shared y axis: a withheld panel has no axes, and the first drawn panel carries the labels
    fig, axs = plt.subplots(1, len(cases), figsize=(3.6 * len(cases), 3.4), squeeze=False)
    labelled = False
    for ci, case in enumerate(cases):
        ax = axs[0, ci]
        geo = probs.get(_key(case), {})
        names = [n for n, v in geo.items() if isinstance(v, dict) and "probability" in v]
        if geo.get("withheld"):  # the model does not fit the data, or the grid is too coarse
            why = ("the alpha grid does not\nresolve the features" if "alpha grid" in geo["withheld"] else
                   "the model does not fit the data")
            ax.text(0.5, 0.5, f"probabilities withheld:\n{why}", transform=ax.transAxes, ha="center", va="center",
                    fontsize=8)
            ax.set_title(_case_title(case), fontsize=8)
            ax.axis("off")  # an empty frame with 0-1 ticks read as a plot of nothing
            continue
        vals = [100.0 * geo[n]["probability"] for n in names]
        bars = ax.bar(range(len(names)), vals, color=colors[_key(case)], alpha=0.75, width=0.6)
        for bar, v, n in zip(bars, vals, names):
            s = geo[n].get("sum_positive_delta_chi2")
            txt = f"{v:.2f} %" + ("\n" + r"$\Sigma(\Delta\chi^2 > 0)$" + f" = {s:.1f}" if s is not None else "")
            # inside a tall bar (below the 50 % line), above a short one
            ypos, va = (min(v, 50.0) * 0.5, "center") if v >= 25 else (v + 2.0, "bottom")
            ax.text(bar.get_x() + bar.get_width() / 2, ypos, txt, ha="center", va=va, fontsize=7,
                    bbox=dict(boxstyle="round,pad=0.2", facecolor="white", edgecolor="none", alpha=0.85), zorder=4)
        ax.axhline(50, color="k", lw=0.6, ls="--", zorder=3)
        ax.text(len(names) - 0.6, 51, "50 %", fontsize=6, ha="right", va="bottom")
        ax.set_xticks(range(len(names)))
        ax.set_xticklabels([n.replace(", ", ",\n") for n in names], fontsize=7)
        ax.set_ylim(0, 115)
        bf = geo.get("bayes_factor")
        sub = f"\nBayes factor {bf:.4g} ({geo.get('jeffreys', '')})" if isinstance(bf, (int, float)) and np.isfinite(bf) else ""
        ax.set_title(_case_title(case) + sub, fontsize=8)
        if not labelled:
            ax.set_ylabel("probability [%]")
            labelled = True
    fig.tight_layout()
    return _save(fig, out / "probabilities.png")


FIGURES = ("fig4", "fig5", "fig6", "fig7", "probabilities")
"""The names of the scan's figures, in the order ``scan_figures`` draws them."""


def scan_figures(out, summary, table=None, system=None, windows=None, cases=None, which=FIGURES) -> list[str]:
    """Write the scan's figures into ``out`` (see the module docstring for
    the arguments) and return their paths: fig4_multitransits.png,
    fig5_delta_chi2.png, fig6_cutout.png, fig7_paths.png, probabilities.png;
    ``which`` (names from ``FIGURES``) draws those alone, in that order
    (``jaxppo scan`` shares them between two processes).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    names = list(which) if not isinstance(which, str) and hasattr(which, "__iter__") else None
    if names is None or not all(isinstance(w, str) and w in FIGURES for w in names) or len(set(names)) < len(names):
        raise ValueError(f"which must be a sequence of distinct names from {FIGURES}, got {which!r}")

    def check():  # process 0 alone touches the folder; its error stops every process (several JAX processes)
        if not out.is_dir():
            raise ValueError(f"out must be an existing folder, got {out}")

    on_writer(f"drawing into {out}", check)
    cases = tuple(cases) if cases is not None else tuple(table)
    if not cases:
        raise ValueError("cases must not be empty")
    for c in cases:
        if _key(c) not in table:
            raise ValueError(f"case {c!r} is not in the scan table (cases: {list(table)})")
    windows = list(windows)
    if not windows:
        raise ValueError("windows must hold at least one multi-transit window")
    colors = {_key(c): _CASE_COLORS[i % len(_CASE_COLORS)] for i, c in enumerate(cases)}
    draw = {
        "fig4": lambda: _fig4(plt, out, summary, table, system, windows, cases),
        "fig5": lambda: _fig5(plt, out, summary, table, system, cases, colors),
        "fig6": lambda: _fig6(plt, out, summary, table, system, windows, cases, colors),
        "fig7": lambda: _fig7(plt, out, summary, table, system, cases),
        "probabilities": lambda: _fig_probabilities(plt, out, summary, cases, colors),
    }
    return [str(Path(draw[w]()).resolve()) for w in names]  # absolute: summary.json is read from anywhere
