"""The obliquity scan per pair: with three or more planets, the tilted
planet's multi-transits with each other planet scanned apart.

A pair (tilted planet, partner) takes the scan's windows in which the
partner is on the star with the tilted planet (a window of three planets
counts for both partners), their points each once, and the same chi^2,
ground level and geometry probabilities as the whole scan
(``._chi2``). The geometry names follow the partner's own hemisphere in
each case: with signs per planet ("+-"), a partner in the tilted planet's
hemisphere reads as case "same", one in the other as "opposite".
"""

from __future__ import annotations

import numpy as np

from ..model._cases import case_signs
from ._chi2 import analyse_case, grid_chi2
from ._stats import bayes_factor_text, guard_cases
from ._windows import windows_data

__all__ = ["pair_reports", "pair_lines", "partners_of", "PAIRS_HEADER"]

PAIRS_HEADER = "pair,case,alpha,chi2,delta_chi2,posterior"
"""The columns of pairs.csv (one row per pair, case and alpha)."""


def _labels(system) -> list[str]:
    return [pl.name or str(i) for i, pl in enumerate(system.planets)]


def _partners(system, windows) -> list[str]:
    labels = _labels(system)
    tilted = labels[system.tilted]
    return [p for p in labels if p != tilted and any(p in w.event.planets for w in windows)]


def partners_of(system, windows) -> int:
    """How many planets share a window of ``windows`` with the tilted planet
    (the scan reports pairs when more than one does)."""
    return len(_partners(system, windows))


def pair_reports(cfg, windows, step: float):
    """(pairs, csv rows): per partner of the tilted planet in ``windows``
    (the scan's ``ScanWindow``s of ``cfg``), its windows, points and per
    case the ground level, geometry probabilities and extremes of Delta
    chi^2; ({}, []) when every window holds the same one partner (the whole
    scan is that pair's)."""
    system = cfg.system
    labels = _labels(system)
    tilted = labels[system.tilted]
    partners = _partners(system, windows)
    if len(partners) < 2:
        return {}, []
    pairs, rows = {}, []
    for partner in partners:
        mine = [w for w in windows if partner in w.event.planets]
        data = windows_data(mine, cfg.lightcurve.exposure)
        cases, best = {}, {}
        for case in cfg.cases:
            chi2 = np.concatenate([grid_chi2(system, data, cfg.alpha[i:i + cfg.block], case)
                                   for i in range(0, cfg.alpha.size, cfg.block)])
            best[case] = float(np.min(chi2))
            sign = case_signs(len(labels), system.tilted, case)[labels.index(partner)]
            own = "same" if sign > 0 else "opposite"
            summary, dchi2, post = analyse_case(system, mine, data, cfg.alpha, chi2, case, step, names_case=own)
            cases[case] = {"partner_case": own, **summary}
            key = f"{tilted}+{partner}"
            rows += [f"{key},{case},{a:.10g},{c:.17g},{d:.17g},{p:.17g}"
                     for a, c, d, p in zip(cfg.alpha, chi2, dchi2, post)]
        check = guard_cases(cases, best, int(data.time.size))
        pairs[f"{tilted}+{partner}"] = {"tilted": tilted, "partner": partner,
                                        "multi_transits": [int(w.number) for w in mine],
                                        "points": int(data.time.size), "cases": cases, "goodness_of_fit": check}
    return pairs, rows


def pair_lines(summary: dict) -> list[str]:
    """What ``jaxppo scan`` prints per pair: its windows and, per case, the
    favoured geometry with its probability and Bayes factor."""
    lines = []
    for key, pr in (summary.get("pairs") or {}).items():
        lines.append(f"pair {key}: multi-transits {pr['multi_transits']} ({pr['points']} points)")
        for case, c in pr["cases"].items():
            geo = c["geometries"]
            fav = geo["favoured"]
            if fav is None:
                lines.append(f"   case {case} ({pr['partner']}: {c['partner_case']}): no probability or rating: "
                             f"{geo['withheld']}")
                continue
            k = bayes_factor_text(geo)
            lines.append(f"   case {case} ({pr['partner']}: {c['partner_case']}): {fav} "
                         f"p = {100 * geo[fav]['probability']:.2f} %, Bayes factor {k} ({geo['jeffreys']}); "
                         f"min dchi2 {c['min_delta_chi2']['value']:.2f} at {c['min_delta_chi2']['alpha']:g} deg")
    return lines
