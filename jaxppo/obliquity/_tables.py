"""Table 5 of Mueller et al. (2021): the peaks and dips of Delta chi^2(alpha).

For each hemisphere case, every contiguous run of tilt angles in which
Delta chi^2 stays beyond the paper's threshold (|Delta chi^2| > 0.15, one
sign) is one feature: its extreme value, the alpha of the extreme, and the
interval of the run written as alpha^{+upper}_{-lower} (the paper: "we
consider all Delta chi^2 values aside the maxima and minima, whose values are
larger than +-0.15"; not an error bar). The interval reaches the first grid
angle outside the run on each side (no longer beyond 0.15 with the
feature's sign; where a feature of the other sign follows at once, that
feature's first angle): the curve leaves the run somewhere between, so the
interval holds the whole feature and is never narrower than one grid step
(the paper's does the same: its case-4 dip at 324^{+1}_{-1} deg and peak at
326^{+1}_{-1} deg share 325 deg, which neither run holds). Where a run
reaches the end of a grid that is not a full circle, or covers the whole
circle, the width is to that end and is flagged open (printed ">=": the
feature may go on). Paper cases
3 and 2 follow from cases 1 and 4 by Eq. 2, alpha -> 360 - alpha (which also
swaps the interval's upper and lower widths). Runs that cross 360 -> 0 on a
full-circle grid are one feature.

Plain data in, rows out: ``peaks_and_dips`` for one curve, ``table5_rows``
for a scan table ({case: {"alpha", "delta_chi2", ...}}), and writers for
CSV, markdown (the paper's layout) and plain text.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from ..model._processes import is_writer
from ._stats import full_circle

__all__ = [
    "THRESHOLD", "peaks_and_dips", "table5_rows", "table5_csv", "table5_markdown", "table5_text", "write_table5",
    "paper_case",
]

THRESHOLD = 0.15  # |Delta chi^2| beyond which an angle is part of a feature (paper Sect. 3.3.3)

_PAPER_CASE = {"same": (1, 3), "opposite": (4, 2)}


def paper_case(case) -> tuple[str, str]:
    """(name of the case, name of its Eq. 2 mirror) as the paper numbers them:
    "same" -> ("1", "3"), "opposite" -> ("4", "2"); other cases keep their
    label and mirror as "<label> at 360 - alpha"."""
    label = case if isinstance(case, str) else "".join("+" if v > 0 else "-" for v in case)
    if label in _PAPER_CASE:
        a, b = _PAPER_CASE[label]
        return str(a), str(b)
    return label, f"{label} (360 - alpha)"


def _runs(mask: np.ndarray, circular: bool) -> list[np.ndarray]:
    """Index arrays of the contiguous True runs of ``mask``; on a circular
    grid a run through the end continues at the start."""
    idx = np.flatnonzero(mask)
    if idx.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(idx) > 1) + 1
    runs = np.split(idx, breaks)
    if circular and len(runs) > 1 and runs[0][0] == 0 and runs[-1][-1] == mask.size - 1:
        runs[0] = np.concatenate([runs.pop(), runs[0]])
    return runs


def _width(alpha, j: int, edge: int, side: int, circular: bool, points: int) -> tuple[float, bool]:
    """(width [deg], open) of one side of a feature whose extreme is at
    index ``j`` and whose run ends at index ``edge`` on that ``side``
    (-1 lower, +1 upper): the distance to the first angle beyond the run
    (across 360 -> 0 on a circular grid); to the run's end, open, where
    the grid ends there (or the run is the whole circle)."""
    n = alpha.size
    nxt = edge + side
    if circular and points < n:
        return float(np.mod(side * (alpha[nxt % n] - alpha[j]), 360.0)), False
    if not circular and 0 <= nxt < n:
        return float(side * (alpha[nxt] - alpha[j])), False
    if not circular:
        return float(side * (alpha[edge] - alpha[j])) + 0.0, True  # + 0.0: no "-0" printed
    return float(np.mod(side * (alpha[edge] - alpha[j]), 360.0)), True


def peaks_and_dips(alpha, delta_chi2, threshold: float = THRESHOLD, ppo_transits: dict | None = None) -> list[dict]:
    """Features of one Delta chi^2(alpha) curve, in order of alpha.

    Args:
        alpha: tilt angles [deg], 1D, increasing, spanning less than 360
            deg (0 and 360 are one tilt); a grid whose gap from its last
            angle round to its first is no wider than its steps is
            circular (features run through 360 -> 0).
        delta_chi2: Delta chi^2 at each alpha.
        threshold: |Delta chi^2| must exceed this (strictly) [paper: 0.15].
        ppo_transits: optional {f"{alpha:g}": [transit numbers]} (the scan's
            summary ``cases[case]["ppo_transits"]``).

    Returns:
        dicts with ``kind`` ("peak" | "dip"), ``alpha`` [deg] of the extreme,
        ``delta_chi2`` there, ``lower`` and ``upper`` [deg] (alpha - lower and
        alpha + upper are the first grid angles outside the run: each at
        least one step away), ``lower_open`` and
        ``upper_open`` (True where the run reaches the end of a grid that is
        not a full circle: the width is to that end, and the feature may go
        on; also for a run round the whole circle), ``start`` and ``end`` [deg] of the run (its first and last
        angle beyond the threshold), ``points`` in it, and ``transits`` (PPO
        transits at the extreme).
    """
    alpha = np.asarray(alpha, float)
    d = np.asarray(delta_chi2, float)
    if alpha.ndim != 1 or alpha.shape != d.shape:
        raise ValueError(f"alpha and delta_chi2 must be 1D of one length, got shapes {alpha.shape} and {d.shape}")
    if alpha.size == 0:
        return []
    if not np.all(np.isfinite(alpha)) or not np.all(np.isfinite(d)):
        raise ValueError("alpha and delta_chi2 must be finite")
    if alpha.size > 1 and np.any(np.diff(alpha) <= 0):
        raise ValueError("alpha must increase")
    if alpha[-1] - alpha[0] >= 360.0:
        raise ValueError(f"alpha must span less than 360 deg (0 and 360 are one tilt; a feature through them would "
                         f"count twice), got {alpha[0]:g} .. {alpha[-1]:g}")
    if not threshold >= 0:
        raise ValueError(f"threshold must be >= 0, got {threshold!r}")
    circular = full_circle(alpha)
    rows = []
    for sign, kind in ((1.0, "peak"), (-1.0, "dip")):
        for run in _runs(sign * d > threshold, circular):
            j = run[int(np.argmax(sign * d[run]))]
            a0 = alpha[j]
            lower, lower_open = _width(alpha, j, run[0], -1, circular, run.size)
            upper, upper_open = _width(alpha, j, run[-1], 1, circular, run.size)
            tr = [] if ppo_transits is None else [int(v) for v in ppo_transits.get(f"{a0:g}", [])]
            rows.append({
                "kind": kind, "alpha": float(a0), "delta_chi2": float(d[j]), "lower": lower, "upper": upper,
                "lower_open": lower_open, "upper_open": upper_open,
                "start": float(alpha[run[0]]), "end": float(alpha[run[-1]]), "points": int(run.size), "transits": tr,
            })
    rows.sort(key=lambda r: r["alpha"])
    return rows


def _mirror(row: dict) -> dict:
    """Eq. 2: the same feature at 360 - alpha (upper and lower swap)."""
    return {
        "alpha": float(np.mod(360.0 - row["alpha"], 360.0)), "lower": row["upper"], "upper": row["lower"],
        "lower_open": row["upper_open"], "upper_open": row["lower_open"],
        "start": float(np.mod(360.0 - row["end"], 360.0)), "end": float(np.mod(360.0 - row["start"], 360.0)),
    }


def table5_rows(table: dict, summary: dict | None = None, cases=None, threshold: float = THRESHOLD) -> list[dict]:
    """Table 5 as flat rows: one per feature and case, with the case's Eq. 2
    mirror (paper case 3 for "same", 2 for "opposite").

    Args:
        table: {case: {"alpha": [...], "delta_chi2": [...]}} (e.g.
            ``read_scan_csv(out / "scan.csv")``).
        summary: the scan summary (for ``cases[case]["ppo_transits"]``), or None.
        cases: which cases, in order (default: the table's).
        threshold: see ``peaks_and_dips``.
    """
    cases = tuple(table) if cases is None else tuple(cases)
    out = []
    for case in cases:
        if case not in table:
            raise ValueError(f"case {case!r} is not in the table (cases: {list(table)})")
        ppo = None
        if summary is not None:
            ppo = summary.get("cases", {}).get(case, {}).get("ppo_transits")
        name, mirror_name = paper_case(case)
        for r in peaks_and_dips(table[case]["alpha"], table[case]["delta_chi2"], threshold, ppo):
            m = _mirror(r)
            out.append({
                "case": case, "paper_case": name, **r,
                "mirror_case": mirror_name, "mirror_alpha": m["alpha"], "mirror_lower": m["lower"],
                "mirror_upper": m["upper"], "mirror_lower_open": m["lower_open"], "mirror_upper_open": m["upper_open"],
            })
    return out


_CSV_FIELDS = ("case", "paper_case", "kind", "alpha", "upper", "lower", "delta_chi2", "start", "end", "points",
               "transits", "mirror_case", "mirror_alpha", "mirror_upper", "mirror_lower", "upper_open", "lower_open",
               "mirror_upper_open", "mirror_lower_open")


def table5_csv(rows: list[dict]) -> str:
    """CSV text, one row per feature (transits as "3;4")."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(_CSV_FIELDS)
    for r in rows:
        w.writerow([";".join(str(v) for v in r[k]) if k == "transits" else (f"{r[k]:.10g}" if isinstance(r[k], float) else r[k])
                    for k in _CSV_FIELDS])
    return buf.getvalue()


def _pair(rows: list[dict], cases: tuple) -> list[tuple]:
    """Rows of the paper's layout: features of the first two cases side by
    side, matched by kind and nearest alpha (within 20 deg); unmatched ones
    get a row of their own."""
    a = [r for r in rows if r["case"] == cases[0]]
    if len(cases) < 2:
        return [(r, None) for r in a]
    b = [r for r in rows if r["case"] == cases[1]]
    used, pairs = set(), []
    for r in a:
        best, dist = None, 20.0
        for k, s in enumerate(b):
            dd = abs((s["alpha"] - r["alpha"] + 180.0) % 360.0 - 180.0)
            if k not in used and s["kind"] == r["kind"] and dd <= dist:
                best, dist = k, dd
        if best is not None:
            used.add(best)
        pairs.append((r, None if best is None else b[best]))
    pairs += [(None, s) for k, s in enumerate(b) if k not in used]
    pairs.sort(key=lambda p: (p[0] or p[1])["alpha"])
    return pairs


def _fmt_angle(a, up, lo, tex: bool, up_open: bool = False, lo_open: bool = False) -> str:
    """alpha^{+up}_{-lo}; an open width (the grid ends there) as ">=" it."""
    ge = r"\geq " if tex else ">="
    u, v = (ge if up_open else "") + f"{up:g}", (ge if lo_open else "") + f"{lo:g}"
    if tex:
        return f"${a:g}^{{+{u}}}_{{-{v}}}$"
    return f"{a:g} +{u}/-{v}"


def _cells(r, tex: bool) -> list[str]:
    if r is None:
        return ["", "", "", ""]
    tr = ",".join(str(v) for v in r["transits"])
    return [_fmt_angle(r["alpha"], r["upper"], r["lower"], tex, r["upper_open"], r["lower_open"]),
            _fmt_angle(r["mirror_alpha"], r["mirror_upper"], r["mirror_lower"], tex, r["mirror_upper_open"],
                       r["mirror_lower_open"]),
            f"{r['delta_chi2']:.2f}", tr]


def _header(rows: list[dict], cases: tuple) -> list[str]:
    head = []
    for c in cases[:2]:
        name, mirror = paper_case(c)
        head += [f"alpha_{name} [deg]", f"alpha_{mirror} [deg]" if c in _PAPER_CASE else f"{mirror} [deg]",
                 "Delta chi^2", "PPO transits"]
    return head


def _cases_of(rows: list[dict], cases) -> tuple:
    if cases is not None:
        return tuple(cases)
    seen = []
    for r in rows:
        if r["case"] not in seen:
            seen.append(r["case"])
    return tuple(seen)


def table5_markdown(rows: list[dict], cases=None) -> str:
    """Markdown in the paper's layout: for the first two cases (1 and 4)
    alpha with its interval, the Eq. 2 mirror (3 and 2), Delta chi^2 and the
    PPO transits, features of the two cases side by side."""
    cases = _cases_of(rows, cases)
    if not cases or not rows:
        return "No Delta chi^2 feature beyond the threshold.\n"
    head = _header(rows, cases)
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for p in _pair(rows, cases):
        cells = _cells(p[0], True) + (_cells(p[1], True) if len(cases) > 1 else [])
        lines.append("| " + " | ".join(cells) + " |")
    extra = [c for c in cases[2:]]
    text = "\n".join(lines) + "\n"
    for c in extra:  # more hemisphere configurations: one table each
        sub = [r for r in rows if r["case"] == c]
        text += "\n" + table5_markdown(sub, (c,))
    return text


def table5_text(rows: list[dict], cases=None, threshold: float = THRESHOLD) -> str:
    """Plain-text table for the terminal (same layout as the markdown)."""
    cases = _cases_of(rows, cases)
    title = (f"Table 5: Delta chi^2 peaks and dips (|Delta chi^2| > {threshold:g}; "
             "interval: to the first angle on each side outside the run)")
    if not cases or not rows:
        return title + "\n  none\n"
    head = _header(rows, cases)
    body = [_cells(p[0], False) + (_cells(p[1], False) if len(cases) > 1 else []) for p in _pair(rows, cases)]
    widths = [max(len(h), *(len(r[i]) for r in body)) if body else len(h) for i, h in enumerate(head)]
    fmt = lambda cells: "  ".join(c.rjust(w) for c, w in zip(cells, widths))
    out = [title, fmt(head), fmt(["-" * w for w in widths])] + [fmt(r) for r in body]
    text = "\n".join(out) + "\n"
    for c in cases[2:]:
        text += "\n" + table5_text([r for r in rows if r["case"] == c], (c,), threshold)
    return text


def write_table5(out, table: dict, summary: dict | None = None, cases=None, threshold: float = THRESHOLD) -> list[str]:
    """Write table5.csv and table5.md into the folder ``out``; return the paths."""
    out = Path(out)
    rows = table5_rows(table, summary, cases, threshold)
    paths = []
    for name, text in (("table5.csv", table5_csv(rows)), ("table5.md", table5_markdown(rows, cases))):
        p = out / name
        if is_writer():  # process 0 of several JAX processes
            tmp = p.with_name(p.name + ".tmp")
            tmp.write_text(text)
            tmp.replace(p)
        paths.append(str(p.resolve()))
    return paths
