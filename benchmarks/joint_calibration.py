"""Calibration of the joint (alpha, transit parameters) sampler
(jaxppo.obliquity._joint.joint_scan): injections with alpha drawn from its
prior U(0, 360) (one per stratum of 360 / n deg; --plain: plain draws),
each fitted from an offset start; for a calibrated posterior the posterior
CDF at the true alpha (its rank) is uniform and the central 68 % / 95 %
intervals cover the truth at those rates.

    python benchmarks/joint_calibration.py OUT [--n 20] [--noise 5e-4] [--radius-scale 2]
        [--particles 128] [--case opposite] [--plain] [--chart PNG]

One line of JSON per injection is appended to OUT/calibration.jsonl as it
finishes (a rerun resumes); the summary (rank histogram, coverage with
binomial errors, timings) is printed and written to OUT/calibration.json;
--chart draws the ranks' histogram and their empirical CDF against the
uniform one with its 95 % band (docs/joint_calibration.png).
"""

import argparse
import json
import os
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)
import numpy as np  # noqa: E402

import jaxppo as jp  # noqa: E402
from jaxppo.inference._coords import a_from_density, density_from_a  # noqa: E402
from jaxppo.obliquity._config import config_from_arguments  # noqa: E402
from jaxppo.obliquity._joint import joint_scan  # noqa: E402


def injection(k, noise, rs, case, n=None):
    """Injection k: alpha uniform in [0, 360), or, with ``n``, uniform within
    the k-th of n equal strata (so that n draws cover the prior evenly: 20
    plain draws put 14 below 180 deg, and an uninformative posterior's
    ranks, alpha / 360, then look skewed by the draws alone)."""
    rng = np.random.default_rng(1000 + k)
    alpha = float(rng.uniform(0.0, 360.0)) if n is None else 360.0 * (k + float(rng.uniform())) / n
    truth = jp.kepler20_system(None, rs)
    rho = density_from_a(float(truth.planets[0].a), float(truth.planets[0].period))
    b, c = truth.planets
    truth = truth.replace(planets=[b, c.replace(a=float(a_from_density(rho, float(c.period))))])
    t = jp.simulate_kepler20(seed=5, noise=noise, radius_scale=rs).time
    lc = jp.simulate(truth, t, noise, alpha, case, 2000 + k)
    b, c = truth.planets
    # a user's start: c.t0 up to 3 min off, b's a/R* and radius up to 2 % off
    off = truth.replace(planets=[b.replace(a=float(b.a) * (1 + 0.02 * rng.uniform(-1, 1)),
                                           radius=float(b.radius) * (1 + 0.02 * rng.uniform(-1, 1))),
                                 c.replace(t0=float(c.t0) + 3.0 / 1440 * rng.uniform(-1, 1))])
    cfg = config_from_arguments(off, lc, np.arange(0, 360, 1.0), (case,), 0.05, "none", 0.3, "none", None, 60)
    return alpha, cfg


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--n", type=int, default=20)
    ap.add_argument("--noise", type=float, default=5e-4)
    ap.add_argument("--radius-scale", type=float, default=2.0)
    ap.add_argument("--particles", type=int, default=128)
    ap.add_argument("--case", default="opposite")
    ap.add_argument("--plain", action="store_true", help="alpha drawn from U(0, 360) without strata")
    ap.add_argument("--chart", default=None, help="PNG of the rank histogram and ECDF")
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "calibration.jsonl"
    done = {}
    if path.exists():
        for line in path.read_text().splitlines():
            rec = json.loads(line)
            done[rec["k"]] = rec
    for k in range(a.n):
        if k in done:
            continue
        alpha, cfg = injection(k, a.noise, a.radius_scale, a.case, None if a.plain else a.n)
        t = time.perf_counter()
        r = joint_scan(cfg, particles=a.particles, seeds=(0,), progress=False)
        c = r["cases"][a.case]
        pa, pw = np.asarray(c["particles"]["alpha"]), np.asarray(c["particles"]["weight"])
        rank = float(np.sum(pw[pa < alpha]) / np.sum(pw))  # the posterior CDF at the truth
        rec = {"k": k, "alpha": alpha, "rank": rank, "ess": c["ess"],
               "peak": c["alpha_peak"], "seconds": time.perf_counter() - t,
               "load": os.getloadavg()[0]}
        with open(path, "a") as f:
            f.write(json.dumps(rec) + "\n")
        done[k] = rec
        print(json.dumps(rec), flush=True)
    ranks = np.array([done[k]["rank"] for k in sorted(done)])
    n = ranks.size
    summary = {"n": n, "noise": a.noise, "radius_scale": a.radius_scale, "particles": a.particles, "case": a.case,
               "stratified": not a.plain,
               "rank_histogram_5_bins": np.histogram(ranks, bins=5, range=(0, 1))[0].tolist(),
               # what a posterior that learned nothing (flat: rank = alpha / 360) would give for these draws
               "flat_posterior_histogram": np.histogram([done[k]["alpha"] / 360.0 for k in sorted(done)], bins=5,
                                                        range=(0, 1))[0].tolist()}
    for level in (0.68, 0.95):
        inside = np.abs(ranks - 0.5) < level / 2
        summary[f"coverage_{int(level * 100)}"] = [float(inside.mean()), float(np.sqrt(level * (1 - level) / n))]
    summary["seconds_per_injection"] = float(np.mean([done[k]["seconds"] for k in done]))
    print(json.dumps(summary))
    (out / "calibration.json").write_text(json.dumps(summary, indent=1))
    if a.chart:
        chart(ranks, np.array([done[k]["alpha"] for k in sorted(done)]), summary, a.chart)


def chart(ranks, alphas, summary, path):
    """The ranks' histogram (5 bins, the binomial 95 % range of a uniform
    rank shaded) beside their empirical CDF minus the uniform CDF with the
    simultaneous 95 % band of a uniform sample (Kolmogorov-Smirnov, 1.36 /
    sqrt(n)); the ranks a posterior that learned nothing would give (alpha
    / 360) drawn for comparison."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy import stats

    n = ranks.size
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 3.6))
    lo, hi = stats.binom.ppf([0.025, 0.975], n, 0.2)
    ax1.axhspan(lo, hi, color="0.88", label="uniform, 95 %")
    ax1.hist(ranks, bins=5, range=(0, 1), histtype="step", lw=2, label="joint sampler")
    ax1.hist(alphas / 360.0, bins=5, range=(0, 1), histtype="step", ls="--", color="0.4",
             label="a flat posterior")
    ax1.set_xlabel("rank of the true alpha (posterior CDF)")
    ax1.set_ylabel("injections")
    ax1.legend(fontsize=8, loc="upper center")
    x = np.linspace(0, 1, 201)
    ecdf = np.searchsorted(np.sort(ranks), x, side="right") / n
    band = 1.36 / np.sqrt(n)
    ax2.fill_between(x, -band, band, color="0.88", label="uniform, 95 % (KS)")
    ax2.plot(x, ecdf - x, lw=2, label="joint sampler")
    ax2.plot(x, np.searchsorted(np.sort(alphas / 360.0), x, side="right") / n - x, ls="--", color="0.4",
             label="a flat posterior")
    ax2.set_xlabel("rank")
    ax2.set_ylabel("ECDF - rank")
    ax2.legend(fontsize=8)
    c68, c95 = summary["coverage_68"], summary["coverage_95"]
    fig.suptitle(f"{n} injections: central 68 % interval covers {c68[0]:.0%} +- {c68[1]:.0%}, "
                 f"95 % covers {c95[0]:.0%} +- {c95[1]:.0%}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
