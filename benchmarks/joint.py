"""The joint (alpha, transit parameters) sampler (jaxppo.joint_scan) on the
held-out kind of case the importance average fails on, and on the real
Kepler-20 data; every figure it measures is printed with the load average.

    python benchmarks/joint.py injected [--particles 256] [--seeds 0,1]
    python benchmarks/joint.py real [--particles 256] [--seeds 0,1]

injected: Kepler-20 b and c with twice their radii (c's a/R* from b's
stellar density), 1-minute data, noise 2e-4, a PPO at alpha = 147 deg in
case "opposite"; the config starts where a user would: c.t0 4 min late,
b's a/R* 3 % large, b's radius 4 % small; all ten transit parameters free,
both cases. real: the bundled real Kepler-20 long-cadence scan.
"""

import argparse
import os
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)
import numpy as np  # noqa: E402

import jaxppo as jp  # noqa: E402
from jaxppo.inference._coords import a_from_density, density_from_a  # noqa: E402
from jaxppo.obliquity._config import config_from_arguments  # noqa: E402
from jaxppo.obliquity._joint import joint_lines  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def injected_config():
    truth = jp.kepler20_system(None, 2.0)
    b, c = truth.planets
    rho = density_from_a(float(b.a), float(b.period))
    truth = truth.replace(planets=[b, c.replace(a=float(a_from_density(rho, float(c.period))))])
    t = jp.simulate_kepler20(seed=5, noise=2e-4, radius_scale=2.0).time
    lc = jp.simulate(truth, t, 2e-4, 147.0, "opposite", 5)
    b, c = truth.planets
    off = truth.replace(planets=[b.replace(a=float(b.a) * 1.03, radius=float(b.radius) * 0.96),
                                 c.replace(t0=float(c.t0) + 4 / 1440)])
    return config_from_arguments(off, lc, np.arange(0, 360, 1.0), ("same", "opposite"), 0.05, "none", 0.3, "none",
                                 None, 60)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("which", choices=("injected", "real"))
    ap.add_argument("--particles", type=int, default=256)
    ap.add_argument("--seeds", default="0,1")
    a = ap.parse_args()
    seeds = tuple(int(s) for s in a.seeds.split(","))
    cfg = injected_config() if a.which == "injected" else jp.load_config(ROOT / "jaxppo/data/kepler20_real_llc.toml")
    t = time.perf_counter()
    fixed = jp.scan(cfg)
    t_scan = time.perf_counter() - t
    t = time.perf_counter()
    r = jp.joint_scan(cfg, particles=a.particles, seeds=seeds, progress=False, free=cfg.fit_free)
    total = time.perf_counter() - t
    print("\n".join(joint_lines(r)))
    load = "load average %.2f %.2f %.2f" % os.getloadavg()
    print(f"{a.which}: joint_scan end to end {total:.1f} s ({len(seeds)} seeds x {len(cfg.cases)} cases, "
          f"{a.particles} particles); one plain scan {t_scan:.2f} s [{load}]")
    for case, c in r["cases"].items():
        m = c["modes"]
        calls = sum(c["calls"])
        smc = sum(c["seconds"])
        print(f"  {case}: mode search {m['seconds']:.1f} s ({m['starts']} starts, {len(m['modes'])} modes); SMC "
              f"{smc:.1f} s for {calls} likelihood calls ({1e3 * smc / calls:.2f} ms per call); fixed scan: "
              + "; ".join(f"{n} " + ("withheld" if g["probability"] is None else f"{100 * g['probability']:.2f} %")
                          for n, g in fixed.probabilities[case].items() if isinstance(g, dict)))


if __name__ == "__main__":
    main()
