"""What ``jaxppo scan`` prints about a finished scan: the data, how much was
resumed, the detrending, each case's ground level, geometry probabilities
and Bayes factor, and Table 5."""

from __future__ import annotations

from pathlib import Path

from ._pairs import pair_lines
from ._stats import bayes_factor_text
from ._tables import table5_text

__all__ = ["scan_report", "probability_lines", "dip_lines"]

# a case's rating is said to rest on a dip that a starspot (or no feature at
# all) explains better where the PPO-or-spot verdict's evidence is one of these
_CONTRADICTING = ("strong", "very strong")
# ratings that say nothing (no caution is given for them)
_UNRATED = ("not rated", "barely worth mentioning")


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


def dip_lines(summary: dict) -> list[str]:
    """The PPO-or-spot verdict of each dip (summary.json's ``ppo_or_spot``),
    one line each, and a caution for each rated case whose deepest dip
    (``min_delta_chi2``, where its rating comes from; a rating above
    "barely worth mentioning") the verdict gives to a spot or to no PPO
    with strong or very strong evidence: the case's
    probabilities assume that dip is a PPO (a spot crossing injected into
    Kepler-20 b + c: "retrograde, decisive" printed, "spot, very strong"
    in summary.json alone)."""
    block = summary.get("ppo_or_spot") or {}
    if block.get("error"):
        return [f"PPO or spot: not decided ({block['error']})"]
    dips = block.get("dips") or []
    lines = [f"PPO or spot, dip at alpha = {d['alpha']:g} deg (case {d['case']}, Delta chi^2 = "
             f"{d['scan_delta_chi2']:.2f}): {d['preferred']} ({d['evidence']}, BIC margin {d['bic_margin']:.2f})"
             for d in dips]
    for case, c in (summary.get("cases") or {}).items():
        low = c.get("min_delta_chi2") or {}
        geo = c.get("geometries", {})
        if geo.get("withheld") or geo.get("jeffreys") in _UNRATED or "alpha" not in low:
            continue  # a rating "barely worth mentioning" rests on no dip (1-min data: a negligible dip is "no PPO")
        for d in dips:
            if (d["case"] == case and abs(d["alpha"] - low["alpha"]) < 1e-9 and d["preferred"] != "PPO"
                    and d["evidence"] in _CONTRADICTING):
                what = "a starspot crossing" if d["preferred"] == "spot" else "no PPO at all"
                lines.append(f"caution: case {case}'s rating rests on its deepest dip (alpha = {d['alpha']:g} deg, "
                             f"Delta chi^2 = {d['scan_delta_chi2']:.2f}), which {what} explains better "
                             f"({d['evidence']}, BIC margin {d['bic_margin']:.2f}): its probabilities assume "
                             "that dip is a PPO")
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
    lines += dip_lines(summary)
    text = "\n".join(lines) + "\n" + table5_text(summary["table5"], cfg.cases)
    verb = "results in" if res.get("finished_before") else "wrote"
    n_fig = len(summary.get("figures", [])) + bool((summary.get("ppo_or_spot") or {}).get("figure"))
    pairs = ", pairs.csv" if summary.get("pairs") else ""
    return text + f"{verb} {out / 'scan.csv'}{pairs}, scan.ecsv, summary.json, table5.csv/.md and {n_fig} figures\n"
