"""joint.png: per hemisphere case, the joint sampler's posterior of alpha
(its particles' mass per degree, transit parameters marginalised) against
the fixed-parameter scan's posterior of the same config, with the joint
posterior's peak, its 68 % arc and the geometry probabilities."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..model._processes import is_writer

__all__ = ["plot_joint"]


def plot_joint(out, result: dict, fixed) -> Path:
    """Draw ``out``/joint.png from a :func:`jaxppo.obliquity._joint.joint_scan`
    result and the fixed scan ``fixed`` (a ScanResult of the same config):
    one panel per case, p(alpha | D) [1/deg] of both; returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cases = list(result["cases"])
    fig, axes = plt.subplots(1, len(cases), figsize=(6.5 * len(cases), 3.8), squeeze=False)
    for ax, case in zip(axes[0], cases):
        c = result["cases"][case]
        fa, fd = fixed.delta_chi2(case)
        fw = np.exp(-0.5 * (fd - fd.min()))
        step = float(fa[1] - fa[0]) if fa.size > 1 else 360.0
        if c.get("withheld"):  # the model does not fit the data: no posterior drawn, as none is reported
            ax.text(0.5, 0.5, "joint posterior withheld:\nthe model does not fit the data", transform=ax.transAxes,
                    ha="center", va="center", fontsize=8, zorder=5, bbox=dict(fc="white", ec="0.6"))
            ax.set_title(f"case {case}: no probability, peak or rating", fontsize=7)
        else:
            post = np.asarray(c["posterior"], float)  # mass per 1-degree bin = density [1/deg]
            ax.stairs(post, np.arange(0.0, 361.0, 1.0), color="C3", lw=1.0, label="joint (transit parameters sampled)")
            lo, hi = c["alpha_68"]
            spans = [(lo, hi)] if lo <= hi else [(lo, 360.0), (0.0, hi)]  # an arc through 0 deg
            for k, (a, b) in enumerate(spans):
                ax.axvspan(a, b, color="C3", alpha=0.12, lw=0, label="joint 68 % arc" if k == 0 else None)
            geo = ", ".join(f"{n} {100 * g['probability']:.1f} +- {100 * g['error']:.1f} %"
                            for n, g in c["geometries"].items())
            ax.set_title(f"case {case}: peak {c['alpha_peak']:.1f} deg\n{geo}", fontsize=7)
        if not fixed.probabilities.get(case, {}).get("withheld"):  # the fixed scan's own guard
            ax.plot(fa, fw / (fw.sum() * step), color="k", lw=0.8, ls="--", label="fixed parameters")
        ax.set_xlabel("tilt angle alpha [deg]")
        ax.set_ylabel("p(alpha | D) [1/deg]")
        ax.set_xlim(0, 360)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7)
    fig.tight_layout()
    path = Path(out) / "joint.png"
    if is_writer():
        tmp = path.with_name("joint.tmp.png")
        fig.savefig(tmp, dpi=110)
        tmp.replace(path)
    plt.close(fig)
    return path
