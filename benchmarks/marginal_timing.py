"""Timings and the injected-PPO recovery of the marginal obliquity scan
(jaxppo.obliquity._marginal.marginal_scan, issue 11). Prints every figure it measures,
with the load average beside each time (the machine is shared).

    python benchmarks/marginal_timing.py real 64 [--free b.t0,b.a,...] [--warmup 300]
    python benchmarks/marginal_timing.py fragility 64 [--free ...] [--warmup 300]

real: the bundled real Kepler-20 config end to end (NUTS + chi^2 of all draws
+ fixed scan + outputs), and one plain scan (jp.scan) for the cost per draw.
fragility: synthetic 1-minute photometry of the seven double transits with a
PPO injected at alpha = 147 deg (case "same"); the config's c.t0 is 4 min
late and b.a/R* 3 % too large. The fixed scan and the marginal scan are
compared with the injected alpha.
"""

import argparse
import os
import tempfile
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)
import numpy as np  # noqa: E402

import jaxppo as jp  # noqa: E402
from jaxppo.obliquity._marginal import marginal_scan  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def load():
    return "load average %.2f %.2f %.2f" % os.getloadavg()


def pct(p):
    """A probability in per cent, or 'withheld' (None: too few effective draws)."""
    return "withheld" if p is None else f"{100 * p:.2f} %"


def real(n, free, warmup, out):
    cfg = jp.load_config(ROOT / "jaxppo/data/kepler20_real_llc.toml")
    t = time.perf_counter()
    fixed = jp.scan(cfg)
    t_scan_cold = time.perf_counter() - t
    t = time.perf_counter()
    fixed = jp.scan(cfg)
    t_scan = time.perf_counter() - t
    print(f"plain scan (jp.scan, 2 cases x 360 alphas): cold {t_scan_cold:.2f} s, warm {t_scan:.2f} s [{load()}]")
    t = time.perf_counter()
    m = marginal_scan(cfg, draws=n, out=out, num_warmup=warmup, progress=False, restart=True, free=free)
    total = time.perf_counter() - t
    s = m.summary["seconds"]
    print(f"marginal scan N = {n} ({len(m.summary['sampler'].get('diagnostics') or [])} free, {warmup} warmup): end to end {total:.1f} s = sampler {s.get('sampler_s', 0):.1f} s "
          f"+ chi^2 of all draws {s['chi2_s']:.1f} s ({1e3 * s['per_draw_chi2']:.0f} ms per draw = "
          f"{s['per_draw_chi2'] / t_scan:.3f} x one warm plain scan) + rest [{load()}]")
    for case, c in m.summary["cases"].items():
        geo = c["geometries"]
        names = [k for k in geo if isinstance(geo[k], dict)]
        fx = fixed.probabilities[case]
        print(f"  case {case}: " + "; ".join(
            f"{nm}: marginal {pct(geo[nm]['probability'])} (draws {100 * c['probability_spread_over_draws'][nm]['p16']:.2f}"
            f"-{100 * c['probability_spread_over_draws'][nm]['p84']:.2f}), fixed {pct(fx[nm]['probability'])}"
            for nm in names) + f"; K = {'withheld' if geo['bayes_factor'] is None else format(geo['bayes_factor'], '.4f')} "
            f"({geo['jeffreys']}); importance ESS min {c['importance_ess']['min']:.1f} of {n}")
    if m.summary["sampler"].get("diagnostics"):
        d = m.summary["sampler"]["diagnostics"]
        print("  NUTS r_hat max %.3f, n_eff min %.0f" % (max(v["r_hat"] or np.nan for v in d.values()),
                                                         min(v["n_eff"] or np.nan for v in d.values())))
    print(f"  alpha_ref {m.summary['sampler'].get('alpha_ref')}: quiet for {m.summary['alpha_ref_quiet_fraction']} "
          "of the draws")


def fragility(n, free, warmup, out):
    # planets twice the size (the paper's sensitivity study), 2e-4 noise per
    # 1-min point: a PPO bump of 6.4e-4 in 13 points of one double transit
    true = jp.kepler20_system(radius_scale=2.0)
    lc = jp.simulate_kepler20(seed=2021, alpha=147.0, case="same", radius_scale=2.0, noise=2e-4)
    b, c = true.planets
    wrong = true.replace(planets=[b.replace(a=float(b.a) * 1.03), c.replace(t0=float(c.t0) + 4.0 / 1440.0)])
    kw = dict(alpha=np.arange(0.0, 360.0, 1.0), detrend="none", margin=0.05)
    for name, sysm in (("true parameters", true), ("wrong parameters (c.t0 + 4 min, b.a x 1.03)", wrong)):
        r = jp.scan(sysm, lc, **kw)
        a, d = r.delta_chi2("same")
        print(f"fixed scan, {name}: case same min Delta chi^2 {d.min():.1f} at alpha = {a[np.argmin(d)]:g} deg; "
              f"at 147: {d[a == 147][0]:.1f}")
    t = time.perf_counter()
    m = marginal_scan(wrong, lc, draws=n, out=out, num_warmup=warmup, progress=False, restart=True, free=free, **kw)
    total = time.perf_counter() - t
    for case in ("same", "opposite"):
        tt = m.table[m.table["case"] == case]
        head = (f"marginal scan N = {n} ({len(m.summary['sampler'].get('diagnostics') or [])} free, {warmup} warmup), "
                f"wrong config, case {case}: ")
        if not np.isfinite(tt["posterior"]).any():  # too few effective draws: no posterior, no peak
            print(head + f"posterior withheld ({m.summary['cases'][case]['geometries'].get('withheld')})")
            continue
        i = int(np.argmax(tt["posterior"]))
        print(head + f"posterior peak alpha = {tt['alpha'][i]:g} deg (marginal Delta chi^2 "
              f"{tt['marginal_delta_chi2'][i]:.1f}); "
              f"p(|alpha - 147| <= 3) = {tt['posterior'][np.abs(tt['alpha'] - 147) <= 3].sum():.3f}")
    med = {k: v["median"] for k, v in m.summary["parameters"].items()}
    # the sampler's t0 are at the transit nearest the data's middle: the truth at that epoch
    tc = float(c.t0) + float(c.period) * round((med.get("c.t0", float(c.t0)) - float(c.t0)) / float(c.period))
    print(f"  {total:.1f} s [{load()}]; posterior medians: " +
          ", ".join(f"{k} {v:.6g}" for k, v in med.items() if k in ("b.a", "c.t0")) +
          f" (true b.a {float(b.a):.6g}, c.t0 {tc:.6g} at the same epoch"
          + (f": c.t0 off by {1440 * (med['c.t0'] - tc):+.2f} min)" if "c.t0" in med else ")"))


if __name__ == "__main__":
    p = argparse.ArgumentParser()
    p.add_argument("what", choices=["real", "fragility"])
    p.add_argument("n", type=int)
    p.add_argument("--free", default=None, help="comma-separated free parameters (default: all 5 of each planet)")
    p.add_argument("--warmup", type=int, default=300)
    p.add_argument("--out", default=None)
    a = p.parse_args()
    out = a.out or tempfile.mkdtemp(prefix="marginal_bench_")
    {"real": real, "fragility": fragility}[a.what](a.n, None if a.free is None else a.free.split(","), a.warmup, out)
    print("outputs in", out)
