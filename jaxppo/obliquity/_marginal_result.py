"""The marginal scan's result: the analysis of the per-draw chi^2 curves
(importance weights, marginal Delta chi^2, geometry probabilities and their
spread over the draws, the importance-sampling guard), the result class,
marginal.csv and marginal.png."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ._stats import case_ruled_out, geometry_probabilities, goodness_of_fit, plot_range, reach_check, withheld
from ._summary import DeprecatedSummaryAccess
from ..inference._importance import MIN_IMPORTANCE_ESS, importance_reliability, kish_ess

__all__ = ["MarginalResult", "MARGINAL_DTYPE", "analyse_draws", "marginal_csv", "plot_marginal",
           "logmeanexp"]


def logmeanexp(v: np.ndarray, axis: int) -> np.ndarray:
    """log(mean(exp(v))) along ``axis`` without overflow."""
    m = np.max(v, axis=axis, keepdims=True)
    return np.squeeze(m, axis) + np.log(np.mean(np.exp(v - m), axis=axis))


@dataclasses.dataclass(frozen=True, eq=False)
class MarginalResult(DeprecatedSummaryAccess):
    """The obliquity scan marginalised over the transit parameters (immutable).

    As ``jaxppo.marginal_scan`` returns it: the per-draw Delta chi^2
    curves, their importance-weighted average (the marginal Delta chi^2 and
    posterior p(alpha | D)), the geometry probabilities from it and their
    spread over the draws, beside the fixed-parameter scan. A case whose
    importance weights rest on too few draws gives no probability, peak or
    rating (None), with the reason (docs/marginal.md).

    ``result["key"]``, ``result.get(key)`` and ``key in result`` still read
    ``summary`` (the result used to be that dict) but warn: deprecated, gone
    in 1.0.

    Attributes
    ----------
    summary : dict
        What marginal.json holds: per case (``cases``) the geometry
        probabilities from the marginal posterior, their spread over the
        draws, the Bayes factor and Jeffreys rating (withheld, with the
        reason, when the importance weights are unreliable), the posterior
        peak [deg], the importance-sampling effective sample size;
        ``probabilities``, ``draws``, ``sampler``, ``parameters``,
        ``seconds`` [s], ``cpu``, ``progress_notes`` and, with the figure,
        ``figures``. Treat it as read-only.
    table : numpy.ndarray
        The rows of marginal.csv, a structured array [n_cases * n_alpha]
        with ``case``, ``alpha`` [deg], ``posterior`` [1/deg],
        ``marginal_delta_chi2``, ``delta_chi2_median`` / ``_p16`` / ``_p84``
        (over the draws), ``fixed_delta_chi2`` and ``importance_ess``.
    delta_chi2 : numpy.ndarray
        The per-draw Delta chi^2 curves, [n_draws, n_cases, n_alpha].
    fixed : ScanResult
        The fixed-parameter scan of the same config.

    Examples
    --------
    Three given draws of planet b's inclination [deg]
    (``min_ess=1`` only because three draws can never pass the default
    guard of 25 effective draws; real use keeps it, with >= 64 draws):

    >>> from importlib.resources import files
    >>> import numpy as np
    >>> import jaxppo as jp
    >>> cfg = jp.load_config(files("jaxppo") / "data" / "kepler20_synthetic.toml", alpha=[0, 360, 1])
    >>> draws = {"b.inc": np.array([87.65, 87.687, 87.72])}
    >>> res = jp.marginal_scan(cfg, samples=draws, min_ess=1, progress=False)
    >>> res.delta_chi2.shape
    (3, 2, 360)
    >>> res.cases["same"]["peak"]["alpha"], res.fixed.probabilities["same"]["favoured"]
    (151.0, 'retrograde, different hemispheres')
    >>> print(f"{res.probabilities['same']['bayes_factor']:.2f}")
    1.18
    >>> print(res.summary_lines()[0])
    marginalised over 3 draws (given by the caller)
    """

    summary: dict
    table: np.ndarray
    delta_chi2: np.ndarray
    fixed: object

    @property
    def probabilities(self) -> dict:
        """Per case: the marginal geometry probabilities, Bayes factor and rating (None when withheld)."""
        return self.summary["probabilities"]

    @property
    def cases(self) -> dict:
        """Per case: geometries, spread over draws, the guard, posterior peak [deg], importance ESS, chi^2_0."""
        return self.summary["cases"]

    def summary_lines(self) -> list[str]:
        """The report ``jaxppo scan --marginalize N`` prints.

        Per case, each geometry's marginal probability (16-84 % over draws)
        beside the fixed scan's, the Bayes factor and rating, the posterior
        peak, the importance ESS (or why they are withheld); then the
        timings.

        Returns
        -------
        list of str
            The lines, without newlines.
        """
        lines = [f"marginalised over {self.summary['draws']} draws ({self.summary['sampler'].get('method', '')})"]
        mixing = self.summary.get("sampler_mixing") or {}
        if mixing.get("caution"):
            lines.append(f"  caution: {mixing['caution']}")
        for case, c in self.summary["cases"].items():
            geo, fx = c["geometries"], self.fixed.probabilities[case]
            imp = c["importance"]
            if not c["reliable"] and imp.get("withheld_by"):  # the fit or the grid check, not the weights
                lines.append(f"  case {case}: no probability, peak or rating: {imp['reason']}")
                continue
            if not c["reliable"]:
                lines.append(f"  case {case}: no probability, peak or rating: {imp['reason']}; sample alpha "
                             "jointly with the transit parameters (jaxppo scan --joint N, jp.joint_scan; "
                             f"docs/marginal.md) or draw more (--marginalize N, now {self.summary['draws']})")
                continue
            for name, g in geo.items():
                if isinstance(g, dict):
                    sp = c["probability_spread_over_draws"][name]
                    pf = fx[name]["probability"]
                    fixed = "withheld" if pf is None else f"{100 * pf:.2f} %"
                    lines.append(f"  case {case}: {name}: {100 * g['probability']:.2f} % "
                                 f"(draws {100 * sp['p16']:.2f}-{100 * sp['p84']:.2f} %; fixed {fixed})")
            k = geo["bayes_factor"]
            kt = f"K = {k:.4g}" if k is not None else f"log10 K = {geo['log10_bayes_factor']:.4g}"
            ess = min(g["ess"] for g in imp["groups"].values())
            pk = (f"posterior peak alpha = {c['peak']['alpha']:g} deg" if c["peak"] is not None else
                  f"no posterior peak ({imp.get('peak_withheld', 'withheld')})")
            lines.append(f"  case {case}: {kt} ({geo['jeffreys']}), favoured {geo['favoured']}; {pk} (fixed "
                         f"{c['fixed_peak']['alpha']:g}); importance ESS of the geometry masses min {ess:.1f} of "
                         f"{self.summary['draws']} (per alpha min {c['importance_ess']['min']:.1f})")
        sec = self.summary.get("seconds") or {}
        if sec:
            lines.append(f"  {sec['total']:.1f} s (sampler {sec.get('sampler_s', 0.0):.1f} s, chi^2 of "
                         f"{sec['draws_computed']} draws {sec['chi2_s']:.1f} s); load average "
                         + " ".join(f"{v:.2f}" for v in self.summary["cpu"]["load_average"]))
        return lines




# R-hat of the sampler's draws (rank-normalised, split) above CAUTION_R_HAT
# (Vehtari et al. 2021 ask for 1.01) prints a caution; R-hat alone does not
# withhold: from 16 draws per chain it exceeds 1.5 for chains that sample
# the posterior correctly but slowly (autocorrelation 0.7: in 73 % of runs)
CAUTION_R_HAT = 1.1


def sampler_mixing(sampler: dict, min_ess: float) -> dict:
    """How many independent draws do the sampler's draws hold? From its
    per-parameter diagnostics (``nuts_draws``; draws given by the caller
    have none: "checked" False): {"checked", "ess_min" (the least
    rank-normalised bulk ESS over the parameters, which counts chains in
    different places and autocorrelation alike), "r_hat_max", "worst" (the
    parameters with R-hat above CAUTION_R_HAT or not computable), "ok"
    (False where ess_min < ``min_ess`` or cannot be computed: Kish's ESS of
    the importance weights counts N draws of a stuck or slow chain as N),
    "reason", "caution"}."""
    diag = sampler.get("diagnostics") or {}
    out = {"checked": bool(diag), "ess_min": None, "r_hat_max": None, "worst": [], "ok": True, "reason": None,
           "caution": None}
    if not diag:
        return out

    def finite(v):
        return v is not None and np.isfinite(v)

    ess = {n: d.get("ess_bulk") for n, d in diag.items()}
    r = {n: d.get("r_hat") for n, d in diag.items()}
    bad = {n: v for n, v in r.items() if not finite(v) or v > CAUTION_R_HAT}
    out.update(r_hat_max=max([v for v in r.values() if finite(v)], default=None), worst=sorted(bad))
    low = min(ess, key=lambda n: ess[n] if finite(ess[n]) else -1.0)
    out["ess_min"] = float(ess[low]) if finite(ess[low]) else None
    if out["ess_min"] is None or out["ess_min"] < min_ess:
        got = "cannot be computed (too few draws per chain)" if out["ess_min"] is None else f"is {out['ess_min']:.1f}"
        out.update(ok=False, reason=(
            f"the sampler's draws hold too few independent samples: the bulk ESS of {low} {got}, below "
            f"{min_ess:g} (chains in different places or slow to mix; Kish's ESS of the importance weights counts "
            "every draw as one): the average rests on a handful of draws; draw more (--marginalize N, more "
            "warm-up)"))
    elif bad:
        text = ", ".join(f"{n} {v:.2f}" if finite(v) else f"{n} n/a" for n, v in sorted(bad.items()))
        out["caution"] = (f"the sampler's chains mix partially (R-hat {text}, above {CAUTION_R_HAT:g}): the "
                          "probabilities carry more Monte Carlo error than their spread over draws shows; draw more")
    return out


def _other_checks(check: dict, fit: dict, grid: dict, mixing: dict, ruled: "str | None" = None) -> None:
    """The importance ``check`` of a case made unreliable (in place) where
    the best draw does not fit the data (``fit``), the data rule this case
    out (``ruled``: ``case_ruled_out``'s reason, None where they do not),
    the fixed scan's alpha grid does not resolve this case's features
    (``grid``, its entry of ``alpha_grid_check``) or the sampler's chains
    disagree (``mixing``, ``sampler_mixing``), with the reason and
    ``withheld_by``."""
    if check["reliable"] and not fit["ok"]:
        check.update(reliable=False, reason=fit["reason"], withheld_by="goodness_of_fit")
    elif check["reliable"] and ruled is not None:
        check.update(reliable=False, reason=ruled, withheld_by="case_ruled_out")
    elif check["reliable"] and grid.get("ok") is False:
        check.update(reliable=False, reason=grid["reason"], withheld_by="alpha_grid_check")
    elif check["reliable"] and not mixing["ok"]:
        check.update(reliable=False, reason=mixing["reason"], withheld_by="sampler_mixing")


def _draw_checks(chi2, fixed, samples: dict, sampler: dict, min_ess: float, cases) -> tuple:
    """(fit, grid, mixing, ruled): ``goodness_of_fit`` of the least chi^2
    of the draws ``chi2`` [draw, case, alpha] with its ``reach_check``
    against the fixed scan's best ("ok" False with the reason where the
    draws do not reach it), the fixed scan's ``alpha_grid_check`` per
    case, ``sampler_mixing`` of the sampler's record (``min_ess``), and
    per case of ``cases`` why the data rule it out (``case_ruled_out`` of
    its least chi^2 over draws and tilts), or None."""
    points = int(fixed.summary["points"])
    fit = goodness_of_fit(float(np.min(chi2)), points)
    fit["reach"] = reach_check(fit, fixed.summary.get("goodness_of_fit") or {}, len(samples), "draws")
    if fit["ok"] and not fit["reach"]["ok"]:
        fit.update(ok=False, reason=fit["reach"]["reason"])
    least = {case: float(np.min(chi2[:, ci])) for ci, case in enumerate(cases)}
    ruled = {case: case_ruled_out(case, least[case], least, points, "draw and tilt") for case in cases}
    return (fit, (fixed.summary.get("alpha_grid_check") or {}).get("cases", {}), sampler_mixing(sampler, min_ess),
            ruled)


def analyse_draws(cfg, dchi2, chi2, c0, chi2_null, chi2_ref, fixed, samples, sampler, digest, ref_quiet,
             min_ess=MIN_IMPORTANCE_ESS) -> MarginalResult:
    """The marginal scan's result from the per-draw chi^2 curves: per case
    the importance-weighted marginal Delta chi^2 and posterior, the geometry
    probabilities and their spread over draws, the guard (withheld where the
    weights are unreliable), the peak; the table of marginal.csv."""
    n_d = dchi2.shape[0]
    step = float(cfg.alpha[1] - cfg.alpha[0]) if cfg.alpha.size > 1 else 360.0
    rows, cases = [], {}
    fit, grid, mixing, ruled = _draw_checks(chi2, fixed, samples, sampler, min_ess, cfg.cases)
    for ci, case in enumerate(cfg.cases):
        dc = dchi2[:, ci]  # [draw, alpha]
        ref = c0[:, ci] if chi2_ref is None else chi2_ref
        # log importance weights L(alpha) / L(reference of the draw)
        logw = -0.5 * (chi2[:, ci] - ref[:, None])
        # marginal Delta chi^2: -2 log of the mean importance weight, against
        # the same average of the ground levels (0 when every reference is
        # the draw's chi^2_0, as for draws given by the caller)
        ground = -2.0 * logmeanexp(-0.5 * (c0[:, ci] - ref)[:, None], axis=0)[0]
        dm = -2.0 * logmeanexp(logw, axis=0) - ground
        w = np.exp(-0.5 * (dm - dm.min()))
        post = w / (np.sum(w) * step)
        med, lo, hi = np.percentile(dc, [50.0, 15.865, 84.135], axis=0)
        geo = geometry_probabilities(cfg.alpha, dm, case)
        names = [k for k in geo if isinstance(geo[k], dict)]
        per = [geometry_probabilities(cfg.alpha, dc[d], case) for d in range(n_d)]
        spread = {}
        for nm in names:
            p = np.array([g[nm]["probability"] for g in per])
            spread[nm] = {"median": float(np.median(p)), "p16": float(np.percentile(p, 15.865)),
                          "p84": float(np.percentile(p, 84.135)), "std": float(np.std(p))}
        # Kish effective sample size of the importance weights at each alpha
        ess = kish_ess(logw, axis=0)
        # the guard: a probability, peak or rating only from weights that
        # do not rest on a handful of draws (per geometry and in total)
        a_mod = np.mod(cfg.alpha, 360.0)
        pro = (a_mod <= 90.0) | (a_mod > 270.0)
        check = importance_reliability(logw, {names[0]: pro, names[1]: ~pro}, min_ess)
        _other_checks(check, fit, grid.get(case, {}), mixing, ruled[case])
        if not check["reliable"]:
            geo = withheld(geo, names, check["reason"])
            post = np.full_like(post, np.nan)
        fx_a, fx_d = fixed.delta_chi2(case)
        ok = check["reliable"]
        # the peak is the density at one alpha: its own weights must be sound too
        top = int(np.argmin(dm))
        check["peak_ess"] = float(ess[top])
        peak = None
        if ok and ess[top] >= min_ess:
            peak = {"alpha": float(cfg.alpha[top]), "marginal_delta_chi2": float(dm[top]),
                    "importance_ess": float(ess[top])}
        elif ok:
            check["peak_withheld"] = (f"the importance ESS at the peak alpha is {ess[top]:.1f} < {min_ess:g}: "
                                      "a few draws carry it, so no peak is given")
        cases[case] = {
            "geometries": geo, "probability_spread_over_draws": spread,
            "reliable": ok, "importance": check, "peak": peak,
            "fixed_peak": {"alpha": float(fx_a[np.argmin(fx_d)]), "delta_chi2": float(fx_d.min())},
            "min_delta_chi2": ({"alpha": float(cfg.alpha[np.argmin(dm)]), "value": float(dm.min())}
                               if peak is not None else None),
            "max_delta_chi2": ({"alpha": float(cfg.alpha[np.argmax(dm)]), "value": float(dm.max())}
                               if ok else None),
            "importance_ess": {"min": float(ess.min()), "alpha_at_min": float(cfg.alpha[np.argmin(ess)]),
                               "median": float(np.median(ess))},
            "chi2_0": {"median": float(np.median(c0[:, ci])), "min": float(c0[:, ci].min()),
                       "max": float(c0[:, ci].max())},
        }
        for j, a in enumerate(cfg.alpha):
            rows.append((case, float(a), float(post[j]), float(dm[j]), float(med[j]), float(lo[j]), float(hi[j]),
                         float(fx_d[j]), float(ess[j])))
    pstats = {n: {"median": float(np.median(v)), "p16": float(np.percentile(v, 15.865)),
                  "p84": float(np.percentile(v, 84.135))} for n, v in samples.items()}
    summary = dict(
        config=cfg.source, config_digest=cfg.digest, marginal_digest=digest, draws=n_d, sampler=sampler,
        parameters=pstats, alpha_ref_quiet_fraction=ref_quiet,
        chi2_null={"median": float(np.median(chi2_null)), "min": float(chi2_null.min()),
                   "max": float(chi2_null.max())},
        weight=("p(alpha|D) ~ mean over draws of exp(-(chi2(alpha) - chi2_ref) / 2); chi2_ref per draw: "
                + ("chi2_0 (draws given by the caller, taken as no-PPO posterior draws)" if chi2_ref is None else
                   f"chi2 at the sampling tilt alpha_ref = {sampler['alpha_ref']:g} deg, case {sampler['case_ref']}")),
        cases=cases, probabilities={c: cases[c]["geometries"] for c in cfg.cases}, goodness_of_fit=fit,
        sampler_mixing=mixing,
    )
    return MarginalResult(summary, np.array(rows, dtype=MARGINAL_DTYPE), dchi2, fixed)


MARGINAL_DTYPE = [("case", "U16"), ("alpha", float), ("posterior", float), ("marginal_delta_chi2", float),
          ("delta_chi2_median", float), ("delta_chi2_p16", float), ("delta_chi2_p84", float),
          ("fixed_delta_chi2", float), ("importance_ess", float)]


def marginal_csv(table) -> str:
    """marginal.csv's text: a header of the ``MARGINAL_DTYPE`` columns and
    one row per (case, alpha), full precision."""
    head = ",".join(n for n, _ in MARGINAL_DTYPE)
    lines = [f"{r[0]},{r[1]:.10g}," + ",".join(f"{v:.17g}" for v in list(r)[2:]) for r in table]
    return head + "\n" + "\n".join(lines) + "\n"


def plot_marginal(out: Path, result: MarginalResult, cfg) -> Path:
    """Per case: the Delta chi^2 band (16-84 % over draws), its median, the
    marginal Delta chi^2 and the fixed-parameter curve; below, the marginal
    posterior against the fixed-parameter posterior."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = result.table
    fig, axes = plt.subplots(2, len(cfg.cases), figsize=(5.5 * len(cfg.cases), 6), squeeze=False, sharex=True)
    for ci, case in enumerate(cfg.cases):
        s = t[t["case"] == case]
        ax = axes[0, ci]
        ax.fill_between(s["alpha"], s["delta_chi2_p16"], s["delta_chi2_p84"], color="C0", alpha=0.3, lw=0,
                        label="draws, 16-84 %")
        ax.plot(s["alpha"], s["delta_chi2_median"], color="C0", lw=0.8, label="draws, median")
        ax.plot(s["alpha"], s["marginal_delta_chi2"], color="C3", lw=1.0, label="marginal")
        ax.plot(s["alpha"], s["fixed_delta_chi2"], color="k", lw=0.8, ls="--", label="fixed parameters")
        ax.axhline(0, color="k", lw=0.4)
        ax.set_title(f"case {case}: {result.summary['draws']} draws")
        ax.set_ylabel("Delta chi^2")
        ax.legend(fontsize=7)
        ax = axes[1, ci]
        fa, fd = result.fixed.delta_chi2(case)
        fw = np.exp(-0.5 * (fd - fd.min()))
        step = float(fa[1] - fa[0]) if fa.size > 1 else 360.0
        if result.cases[case]["reliable"]:
            ax.plot(s["alpha"], s["posterior"], color="C3", lw=1.0, label="marginal")
        else:
            ax.text(0.5, 0.5, "marginal withheld:\nimportance weights unreliable", transform=ax.transAxes,
                    ha="center", va="center", color="C3", fontsize=8)
        ax.plot(fa, fw / (fw.sum() * step), color="k", lw=0.8, ls="--", label="fixed parameters")
        ax.set_xlabel("tilt angle alpha [deg]")
        ax.set_ylabel("p(alpha | D) [1/deg]")
        ax.set_xlim(*plot_range(fa))
        ax.legend(fontsize=7)
    fig.tight_layout()
    path = out / "marginal.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
