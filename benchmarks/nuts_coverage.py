"""Coverage of ``jaxppo.sample``'s intervals over simulated data sets.

Each seed simulates the Kepler-20 b + c light curve with its own noise
(``jp.simulate_kepler20``), samples ``--free`` with NUTS from the true
system and records whether the reported 68.3 % interval (``intervals``)
and the central 95 % interval of the draws hold the truth. For calibrated
intervals the hit rates are 0.683 and 0.95 within their binomial errors;
R-hat is recorded too. (This was the test suite's 4-seed check; with 4
seeds only a gross failure shows, so it lives here with many.)

    python benchmarks/nuts_coverage.py OUT [--seeds 20] [--free b.t0 c.radius]
        [--warmup 60] [--samples 150] [--noise 4e-4]

One line of JSON per seed is appended to OUT/coverage.jsonl as it finishes
(a rerun resumes); the summary is printed and written to OUT/coverage.json.
"""

import argparse
import json
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)
import numpy as np  # noqa: E402

import jaxppo as jp  # noqa: E402


def truth_values(system, names):
    """The true values of planet parameters named like 'b.t0'."""
    out = []
    for n in names:
        owner, par = n.split(".")
        out.append(float(getattr(system.planets[system.index(owner)], par)))
    return np.array(out)


def one_seed(seed, free, warmup, samples, noise):
    """Sample one simulated data set; hits of the 68.3 % and 95 % intervals."""
    truth = jp.kepler20_system()
    lc = jp.simulate_kepler20(seed=100 + seed, noise=noise)
    t = time.perf_counter()
    res = jp.sample(truth, lc, free=free, num_warmup=warmup, num_samples=samples, seed=seed, num_chains=1,
                    progress_bar=False)
    tv = truth_values(truth, free)
    row = {"seed": seed, "seconds": time.perf_counter() - t}
    for i, n in enumerate(free):
        _, lo, hi = res.intervals[n]
        lo95, hi95 = np.quantile(np.asarray(res.samples[n]), [0.025, 0.975])
        row[n] = {"in68": bool(lo <= tv[i] <= hi), "in95": bool(lo95 <= tv[i] <= hi95),
                  "r_hat": float(res.diagnostics[n]["r_hat"])}
    return row


def summary(rows, free):
    """Hit rates with binomial errors and the largest R-hat, per parameter."""
    n = len(rows)
    out = {"seeds": n}
    for name in free:
        s = {}
        for key, p in (("in68", 0.683), ("in95", 0.95)):
            rate = float(np.mean([r[name][key] for r in rows]))
            s[key] = {"rate": rate, "expected": p, "binomial_error": float(np.sqrt(p * (1 - p) / n))}
        s["max_r_hat"] = float(max(r[name]["r_hat"] for r in rows))
        out[name] = s
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out")
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--free", nargs="+", default=["b.t0", "c.radius"])
    ap.add_argument("--warmup", type=int, default=60)
    ap.add_argument("--samples", type=int, default=150)
    ap.add_argument("--noise", type=float, default=4e-4)
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    log = out / "coverage.jsonl"
    rows = [json.loads(x) for x in log.read_text().splitlines()] if log.exists() else []
    done = {r["seed"] for r in rows}
    for seed in range(a.seeds):
        if seed in done:
            continue
        row = one_seed(seed, tuple(a.free), a.warmup, a.samples, a.noise)
        rows.append(row)
        with open(log, "a") as fh:
            fh.write(json.dumps(row) + "\n")
        print(json.dumps(row), flush=True)
    s = summary([r for r in rows if r["seed"] < a.seeds], a.free)
    (out / "coverage.json").write_text(json.dumps(s, indent=1))
    for name in a.free:
        print(f"{name}: 68.3 % interval holds the truth in {s[name]['in68']['rate']:.2f} "
              f"(+-{s[name]['in68']['binomial_error']:.2f}), 95 %: {s[name]['in95']['rate']:.2f} "
              f"(+-{s[name]['in95']['binomial_error']:.2f}), max R-hat {s[name]['max_r_hat']:.3f}")


if __name__ == "__main__":
    main()
