"""What ``jaxppo scan`` prints about a finished scan: the data, how much was
resumed, the detrending, each case's ground level, geometry probabilities
and Bayes factor, and Table 5."""

from __future__ import annotations

from pathlib import Path

from ._pairs import pair_lines
from ._stats import bayes_factor_text
from ._tables import table5_text

__all__ = ["scan_report", "probability_lines"]


def probability_lines(summary: dict) -> list[str]:
    """Per case: chi^2_0 (per point), each geometry's probability and sum of
    positive Delta chi^2, the Bayes factor and its rating."""
    lines = []
    for case, geo in summary["probabilities"].items():
        n = summary.get("points")
        per = f" for {n} points (chi2_0 / N = {summary['chi2_0'][case] / n:.3f})" if n else ""
        lines.append(f"case {case}: chi2_0 = {summary['chi2_0'][case]:.3f}{per}")
        if geo.get("withheld"):
            said = any(geo["withheld"] in ln for ln in lines)
            lines.append("   no probability or rating (as above)" if said else
                         f"   no probability or rating: {geo['withheld']}")
            continue
        for name, v in geo.items():
            if isinstance(v, dict):
                lines.append(f"   {name:36s} p = {100 * v['probability']:6.2f} %   "
                             f"sum(dchi2 > 0) = {v['sum_positive_delta_chi2']:.2f}")
        k = bayes_factor_text(geo)
        lines.append(f"   Bayes factor {k} for '{geo['favoured']}': {geo['jeffreys']}")
    return lines


def scan_report(summary: dict, cfg, out, seconds: float) -> str:
    """The text ``jaxppo scan`` prints for the scan ``summary`` of ``cfg``
    written to ``out``, which took ``seconds`` [s]."""
    out = Path(out)
    lines = [f"data: {summary['data']['loaded']}" if "data" in summary else f"data: {cfg.lightcurve.report_line()}"]
    res = summary.get("resumed", {})
    if res.get("finished_before"):
        redone = res.get("redone")
        what = (f"nothing recomputed; made again, missing: {', '.join(redone)}" if redone else
                "nothing recomputed or redrawn")
        lines.append(f"resumed: the scan in {out} had already finished with this config ({res['alphas_total']} "
                     f"(case, alpha) points, digest {summary['config_digest']}); {what}")
    elif res.get("alphas_done_before"):
        lines.append(f"resumed from {out / 'scan_progress.jsonl'}: {res['alphas_done_before']} of "
                     f"{res['alphas_total']} (case, alpha) points were already done")
    if not res.get("finished_before"):
        verb = "analysed" if res.get("alphas_done_before") == res.get("alphas_total") else "scanned"
        lines.append(f"{verb} {len(cfg.cases)} case(s) x {cfg.alpha.size} alphas over "
                     f"{len(summary['multi_transits'])} multi-transits ({summary['points']} points) in {seconds:.2f} s")
    det = summary.get("detrending", {})
    if det.get("order") not in (None, "none"):
        lines.append(f"each multi-transit divided by its order-{det['order']} out-of-transit polynomial; "
                     f"{sum(m.get('clipped', 0) for m in summary['multi_transits'])} outliers clipped; "
                     f"errors {det['flux_err']}")
    caution = (summary.get("goodness_of_fit") or {}).get("caution")
    if caution:
        lines.append(f"caution: {caution}")
    lines += probability_lines(summary)
    lines += pair_lines(summary)
    text = "\n".join(lines) + "\n" + table5_text(summary["table5"], cfg.cases)
    verb = "results in" if res.get("finished_before") else "wrote"
    n_fig = len(summary.get("figures", [])) + bool((summary.get("ppo_or_spot") or {}).get("figure"))
    pairs = ", pairs.csv" if summary.get("pairs") else ""
    return text + f"{verb} {out / 'scan.csv'}{pairs}, scan.ecsv, summary.json, table5.csv/.md and {n_fig} figures\n"
