"""The paper's figures from a finished scan (Figs. 4-7 and Table 6)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["scan_figures", "read_scan_csv"]


def read_scan_csv(path) -> dict:
    rows = np.genfromtxt(path, delimiter=",", names=True, dtype=None, encoding=None)
    out = {}
    for case in np.unique(rows["case"]):
        sel = rows["case"] == case
        out[str(case)] = {k: np.asarray(rows[k][sel], float) for k in ("alpha", "chi2", "delta_chi2", "posterior")}
    return out


def _label_ppo_ranges(ax, alpha, dchi2, ppo_transits, color):
    """Write the responsible transit numbers at the extremum of each
    contiguous run of alphas with a PPO (paper Fig. 5)."""
    runs, cur = [], []
    for i, a in enumerate(alpha):
        tr = tuple(ppo_transits.get(f"{a:g}", ()))
        if tr and (not cur or tuple(ppo_transits.get(f"{alpha[cur[-1]]:g}", ())) == tr and i == cur[-1] + 1):
            cur.append(i)
        else:
            if cur:
                runs.append(cur)
            cur = [i] if tr else []
    if cur:
        runs.append(cur)
    for run in runs:
        j = run[int(np.argmax(np.abs(dchi2[run])))]
        tr = ppo_transits.get(f"{alpha[j]:g}", [])
        ax.annotate(",".join(str(v) for v in tr), (alpha[j], dchi2[j]), textcoords="offset points",
                    xytext=(0, 6 if dchi2[j] >= 0 else -12), ha="center", fontsize=7, color=color)


def scan_figures(cfg, out, result) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ._scan import scan_events
    from ._sweep import sweep

    out = Path(out)
    scan = read_scan_csv(out / "scan.csv")
    sysm, lc = cfg.system, cfg.lightcurve
    used = scan_events(cfg)
    files = []
    colors = {"same": "tab:red", "opposite": "tab:blue"}

    # Fig. 5: Delta chi^2 (alpha) for both cases, transit numbers labelled.
    fig, ax = plt.subplots(figsize=(8, 3.6))
    for case, d in scan.items():
        ax.plot(d["alpha"], d["delta_chi2"], color=colors.get(case), lw=1, label=f"case {case}")
        _label_ppo_ranges(ax, d["alpha"], d["delta_chi2"], result["cases"][case]["ppo_transits"], colors.get(case))
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("alpha [deg]")
    ax.set_ylabel("Delta chi^2")
    ax.set_xlim(0, 360)
    ax.legend(fontsize=8)
    ax.set_title("Change of chi^2 with the tilt angle (numbers: transits with a PPO)", fontsize=9)
    fig.tight_layout()
    files.append(_save(fig, out / "fig5_delta_chi2.png"))

    # Fig. 4: the multi-transits with the models of all alphas, residuals of alpha = 0.
    n = len(used)
    fig, axes = plt.subplots(2, n, figsize=(2.6 * n, 4.6), sharey="row", gridspec_kw={"height_ratios": [3, 1]}, squeeze=False)
    case0 = cfg.cases[0]
    alphas = scan[case0]["alpha"]
    for i, (e, s) in enumerate(used):
        d = lc.select(s)
        t_fine = np.linspace(d.time.min(), d.time.max(), 300)
        models = sweep(sysm, t_fine, alphas, cases=(case0,))[0]
        null = sweep(sysm, d.time, np.zeros(1), cases=(case0,))[0, 0]
        ax, rax = axes[0, i], axes[1, i]
        hours = lambda t: (t - e.mid) * 24
        ax.errorbar(hours(d.time), (d.flux - 1) * 1e6, yerr=d.flux_err * 1e6, fmt=".", ms=2, color="0.5", lw=0.3, zorder=1)
        varying = np.any(models != models[:1], axis=0)
        for m in models[np.any(models[:, varying] != models[0, varying], axis=1)] if varying.any() else []:
            ax.plot(hours(t_fine), (m - 1) * 1e6, color="tab:red", lw=0.4, alpha=0.5, zorder=2)
        ax.plot(hours(t_fine), (models[0] - 1) * 1e6, color="k", lw=0.8, zorder=3)
        rax.plot(hours(d.time), (d.flux - null) * 1e6, ".", ms=2, color="0.4")
        rax.axhline(0, color="k", lw=0.5)
        ax.set_title(f"{i + 1}: {e.mid:.2f}", fontsize=8)
        rax.set_xlabel("hours", fontsize=8)
    axes[0, 0].set_ylabel("flux - 1 [ppm]")
    axes[1, 0].set_ylabel("O - C [ppm]")
    fig.tight_layout()
    files.append(_save(fig, out / "fig4_multitransits.png"))

    # Fig. 6: cutout of the transit with the strongest response, best and worst alpha.
    d0 = scan[case0]
    best, worst = d0["alpha"][np.argmin(d0["delta_chi2"])], d0["alpha"][np.argmax(d0["delta_chi2"])]
    tr = result["cases"][case0]["ppo_transits"].get(f"{worst:g}") or result["cases"][case0]["ppo_transits"].get(f"{best:g}") or [1]
    e, s = used[tr[0] - 1]
    d = lc.select(s)
    t_fine = np.linspace(d.time.min(), d.time.max(), 600)
    fig, ax = plt.subplots(figsize=(6, 3.6))
    ax.errorbar(d.time, d.flux, yerr=d.flux_err, fmt=".", ms=3, color="0.5", lw=0.4)
    curves = sweep(sysm, t_fine, np.array([best, worst, 0.0]), cases=(case0,))[0]
    for a, col, m in zip((best, worst, 0.0), ("tab:blue", "tab:red", "k"), curves):
        ax.plot(t_fine, m, color=col, lw=1,
                label=f"alpha = {a:g} deg" + (" (min Delta chi^2)" if a == best else " (max Delta chi^2)" if a == worst else " (null)"))
    ax.set_xlabel("time [d]")
    ax.set_ylabel("relative flux")
    ax.set_title(f"multi-transit {tr[0]} (case {case0})", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    files.append(_save(fig, out / "fig6_cutout.png"))

    # Fig. 7: paths of the tilted planet for alphas with PPOs, by sign of Delta chi^2.
    fig, axs = plt.subplots(1, len(cfg.cases), figsize=(4.2 * len(cfg.cases), 4.2), squeeze=False)
    pl = sysm.planets[sysm.tilted]
    for ci, case in enumerate(cfg.cases):
        ax = axs[0, ci]
        ax.add_patch(plt.Circle((0, 0), 1, color="0.9"))
        ax.axhline(0, color="k", ls="--", lw=0.5)
        dd = scan[case]
        b = float(pl.impact)
        for a, dc in zip(dd["alpha"], dd["delta_chi2"]):
            if not result["cases"][case]["ppo_transits"].get(f"{a:g}") or dc == 0:
                continue
            ar = np.deg2rad(a)
            xs = np.linspace(-1.2, 1.2, 2)
            x1, y1 = xs * np.cos(ar) + b * np.sin(ar), -xs * np.sin(ar) + b * np.cos(ar)
            ax.plot(x1, y1, color="tab:red" if dc > 0 else "tab:blue", lw=0.6, alpha=0.7)
        for j, other in enumerate(sysm.planets):
            if j != sysm.tilted:
                yc = float(other.impact) * (-1 if case == "opposite" else 1)
                ax.plot([0], [yc], "ko", ms=4)
        ax.set_xlim(-1.2, 1.2)
        ax.set_ylim(-1.2, 1.2)
        ax.set_aspect("equal")
        ax.set_title(f"case {case}: red Delta chi^2 > 0, blue < 0", fontsize=8)
    fig.tight_layout()
    files.append(_save(fig, out / "fig7_paths.png"))

    # Table 6 as a figure.
    fig, ax = plt.subplots(figsize=(7, 0.6 + 0.35 * 2 * len(cfg.cases)))
    ax.axis("off")
    cells = []
    for case in cfg.cases:
        geo = result["probabilities"][case]
        for name, v in geo.items():
            if isinstance(v, dict):
                cells.append([case, name, f"{100 * v['probability']:.2f}", f"{v['sum_positive_delta_chi2']:.1f}"])
        cells.append([case, f"Bayes factor {geo['bayes_factor']:.3f}: {geo['jeffreys']}", "", ""])
    tab = ax.table(cellText=cells, colLabels=["case", "geometry", "p [%]", "sum(Delta chi^2 > 0)"], loc="center")
    tab.auto_set_font_size(False)
    tab.set_fontsize(8)
    tab.auto_set_column_width([0, 1, 2, 3])
    fig.tight_layout()
    files.append(_save(fig, out / "probabilities.png"))
    return [str(f) for f in files]


def _save(fig, path: Path) -> Path:
    import matplotlib.pyplot as plt

    tmp = path.with_name(path.stem + ".tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    tmp.replace(path)
    return path
