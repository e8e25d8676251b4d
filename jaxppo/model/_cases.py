"""The hemisphere cases of a system with one tilted planet: which side of
the star's disk each untilted planet's orbit crosses (Mueller et al. 2021,
Sect. 2.5; docs/conventions.md).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from ._system import System

__all__ = ["CASES", "case_signs", "case_label", "scan_cases", "hemisphere_cases"]

# Named hemisphere cases: every untilted planet in the tilted planet's
# hemisphere ("same", paper case 1) or every one in the other ("opposite",
# paper case 4). Systems of k planets have 2^(k-1) distinct configurations,
# given as a tuple of +-1 signs (one per untilted planet, in planet order).
CASES = ("same", "opposite")


def case_signs(n_planets: int, tilted: int, case) -> np.ndarray:
    """Hemisphere sign of every planet [n_planets] for ``case``: +1 for the
    tilted planet and for untilted planets on its side of the stellar equator,
    -1 for the mirrored ones.

    ``case``: "same" (all +1), "opposite" (all -1), a tuple of +-1 (one per
    untilted planet, in planet order), or a string of "+"/"-" of that length
    (as written by ``case_label``).
    """
    k = n_planets - 1
    if isinstance(case, str):
        if case == "same":
            rel = (1,) * k
        elif case == "opposite":
            rel = (-1,) * k
        elif case and set(case) <= {"+", "-"}:
            rel = tuple(1 if ch == "+" else -1 for ch in case)
        else:
            raise ValueError(
                f"unknown case {case!r}: case must be one of {CASES}, a tuple of +-1 or a '+'/'-' string "
                "(one per untilted planet)"
            )
    else:
        try:
            rel = tuple(case)
        except TypeError:
            raise ValueError(f"case must be one of {CASES} or a tuple of +-1, got {case!r}") from None
        if not all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_)) and v in (1, -1) for v in rel):
            raise ValueError(f"case signs must each be +1 or -1, got {case!r}")
    if len(rel) != k:
        raise ValueError(f"case must give {k} sign(s) (one per untilted planet), got {case!r}")
    signs = list(rel)
    signs.insert(tilted, 1)
    return np.asarray(signs, float)


def case_label(case) -> str:
    """Name a hemisphere case as text.

    Uniform sign tuples become "same" (all +1) or "opposite" (all -1); mixed
    ones become a string of "+"/"-" (one character per untilted planet, in
    planet order). The text is safe in CSV files, and
    ``jaxppo.model._system.case_signs`` reads it back.

    Parameters
    ----------
    case : str or tuple of int
        A case as ``hemisphere_cases`` gives it: "same", "opposite"
        (returned unchanged, as is any string), or a tuple of +1/-1 signs of
        the untilted planets relative to the tilted one.

    Returns
    -------
    label : str
        "same", "opposite" or the "+"/"-" string.

    See Also
    --------
    hemisphere_cases : the distinct cases of a system.

    Examples
    --------
    >>> import jaxppo as jp
    >>> jp.case_label((1, -1))
    '+-'
    >>> jp.case_label((1, 1)), jp.case_label((-1, -1)), jp.case_label("same")
    ('same', 'opposite', 'same')
    """
    if isinstance(case, str):
        return case
    rel = tuple(int(v) for v in case)
    if all(v == 1 for v in rel):
        return "same"
    if all(v == -1 for v in rel):
        return "opposite"
    return "".join("+" if v == 1 else "-" for v in rel)


def scan_cases(system: "System", cases) -> tuple[str, ...]:
    """The hemisphere cases of a scan as text labels (``case_label``):
    ``"all"`` gives every configuration that differs (``hemisphere_cases``),
    otherwise a non-empty list of "same", "opposite" or "+"/"-" strings (one
    sign per untilted planet). Raises ValueError naming the bad entry."""
    if isinstance(cases, str):
        if cases != "all":
            cases = [cases]
        else:
            return tuple(case_label(c) for c in hemisphere_cases(system))
    if isinstance(cases, (bytes, dict)) or not hasattr(cases, "__iter__"):
        raise ValueError(f"cases must be 'all', a case or a list of cases ('same', 'opposite', or '+'/'-' signs), "
                         f"got {cases!r}")
    cases = list(cases)
    if not cases:
        raise ValueError("cases must not be empty")
    if len(system.planets) < 2:
        raise ValueError(f"an obliquity scan needs two or more planets (one is tilted against the others); this "
                         f"system has one ({system.planets[0].name or 0!r})")
    out = []
    for c in cases:
        if not isinstance(c, str):
            raise ValueError(f"each case must be a string ('same', 'opposite', or '+'/'-' signs), got {c!r}")
        signs = case_signs(len(system.planets), system.tilted, c)  # raises with the reason
        # canonical label: "+" of a two-planet system is "same", "-+" stays "-+"
        label = case_label(tuple(int(v) for i, v in enumerate(signs) if i != system.tilted))
        if label in out:
            raise ValueError(f"case {c!r} is listed twice (it is the configuration {label!r} of this system, "
                             f"given as {[x for x in cases if x != c] or [c]})")
        out.append(label)
    return tuple(out)


def hemisphere_cases(system: "System") -> tuple:
    """List the hemisphere configurations of a system that give different light curves.

    A k-planet system has 2^(k-1) of them: each untilted planet crosses the
    stellar disk either in the tilted planet's hemisphere (+1) or in the
    other one (-1). Only the untilted planets' signs relative to the tilted
    planet matter: a mirror y -> -y of the whole sky maps any configuration
    at alpha to its mirror image at 360 - alpha, and a radially symmetric
    star gives both the same flux, so a full alpha scan covers both signs of
    the tilted planet.

    Parameters
    ----------
    system : System
        The star and planets; ``system.tilted`` is the tilted planet.

    Returns
    -------
    cases : tuple
        "same" first (every untilted planet in the tilted planet's
        hemisphere, paper case 1) and "opposite" last (every one in the
        other, paper case 4); the mixed ones in between as tuples of +1/-1
        (one per untilted planet, in planet order). A single-planet system
        gives ``("same",)``. Each is a valid ``case`` of ``System.flux``;
        ``case_label`` names them as text.

    Examples
    --------
    >>> import jaxppo as jp
    >>> jp.hemisphere_cases(jp.kepler20_system())
    ('same', 'opposite')
    >>> planets = [jp.Planet(3.0 * k, 0.0, 10.0 * k, 89.5, 0.02, name=n) for k, n in ((1, "b"), (2, "c"), (3, "d"))]
    >>> jp.hemisphere_cases(jp.System(jp.Star.uniform(), planets))
    ('same', (1, -1), (-1, 1), 'opposite')
    """
    k = len(system.planets) - 1
    if k == 0:
        return ("same",)
    out = []
    for bits in range(2**k):
        rel = tuple(-1 if (bits >> (k - 1 - j)) & 1 else 1 for j in range(k))
        out.append(case_label(rel) if len(set(rel)) == 1 else rel)
    return tuple(out)
