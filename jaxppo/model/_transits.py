"""Transits in time: when several planets are on the star at once
(multi-transits, paper Table 2) and the tilt range alpha_limits in which two
of them can occult each other (Mueller et al. 2021, Eqs. 3-6)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ._system import System
from ._units import from_quantity

__all__ = ["transit_times", "alpha_limits", "MultiTransit", "multi_transits", "multi_transit_counts", "transit_windows",
           "simultaneous_sets", "planet_label"]


def _one_time(name: str, value) -> float:
    """One time [d]: a number, a time Quantity or a TimeDelta (a string,
    bool, other unit or several values refused by name)."""
    days = np.asarray(from_quantity(name, value, "d"))
    if days.ndim != 0:
        raise ValueError(f"{name} must be one time [d], got {days.size} values: {value!r}")
    return float(days)


def transit_times(system: System, t_start, t_end):
    """List the mid-transit times [d] the model predicts in [t_start, t_end].

    Every planet's transits are its conjunctions t0 + n P (t0 is the time of
    inferior conjunction, eccentric orbits included); in an N-body system
    (``orbits="nbody"``) the times of least sky distance from the star's
    centre on the integrated orbits (epoch 0: the transit nearest to the
    planet's t0); a planet with
    ``transit_times`` has the listed times at its listed epochs and t0 + n P
    plus the offset of the nearest listed epoch elsewhere
    (``Planet.mid_time``). A planet that never crosses the stellar disk
    has none. The question every orbit model answers alike, so users and
    checks can compare them.

    Parameters
    ----------
    system : System
        The planets.
    t_start, t_end : float or Quantity or TimeDelta
        The time span [d] (a time Quantity or TimeDelta is converted),
        inclusive; finite, with t_start <= t_end.

    Returns
    -------
    astropy.table.Table
        Columns ``planet`` (name, or index as text when unnamed), ``epoch``
        (int; 0 is the transit at the planet's t0) and ``tc`` [d], one row per
        transit, sorted by time.

    Raises
    ------
    ValueError
        When t_start or t_end is not finite, or t_end < t_start.

    Examples
    --------
    >>> import jaxppo as jp
    >>> table = jp.transit_times(jp.kepler20_system(), 130.0, 145.0)
    >>> table.colnames
    ['planet', 'epoch', 'tc']
    >>> for row in table:
    ...     print(row["planet"], row["epoch"], f"{row['tc']:.4f}")
    b -1 130.8058
    b 0 134.5020
    b 1 138.1981
    c 0 138.6085
    b 2 141.8942
    """
    from astropy.table import Table

    t_start, t_end = (_one_time(n, v) for n, v in (("t_start", t_start), ("t_end", t_end)))
    if not (math.isfinite(t_start) and math.isfinite(t_end) and t_end >= t_start):
        raise ValueError(f"need finite t_start <= t_end [d], got t_start = {t_start!r}, t_end = {t_end!r}")
    rows = []
    if system.orbits == "nbody":
        from ._nbody import nbody_transit_times

        rows = [(planet_label(system, j), n, tc) for j, n, tc in nbody_transit_times(system, t_start, t_end)]
    for i, pl in enumerate(system.planets if system.orbits == "kepler" else ()):
        t1, t4 = (float(v) for v in pl.contacts())
        if t4 <= t1:
            continue  # never on the stellar disk
        for n, tc in _epochs_between(pl, t_start, t_end):
            rows.append((planet_label(system, i), n, tc))
    rows.sort(key=lambda r: r[2])
    table = Table(rows=rows or None, names=("planet", "epoch", "tc"), dtype=(str, int, float))
    table["tc"].unit = "d"
    return table


def _epochs_between(pl, t_start: float, t_end: float, pad: float = 0.0) -> list[tuple[int, float]]:
    """(epoch, predicted mid-time [d]) of the planet's transits with
    t_start - pad <= tc <= t_end + pad."""
    period, t0 = float(pl.period), float(pl.t0)
    lo, hi = t_start - pad, t_end + pad
    if pl.transit_times is None:
        return [(n, t0 + n * period) for n in range(math.ceil((lo - t0) / period), math.floor((hi - t0) / period) + 1)]
    # a listed time lies within P/2 of t0 + n P, and so does every predicted one
    # (it takes the offset of a listed epoch): one more epoch on each side
    out = []
    for n in range(math.ceil((lo - t0) / period) - 1, math.floor((hi - t0) / period) + 2):
        tc = pl.mid_time(n)
        if lo <= tc <= hi:
            out.append((n, tc))
    return out


def alpha_limits(system: System, other: int | str | None = None) -> tuple[float, float, float, float]:
    """Give the tilt angles alpha [deg] between which two planets can occult each other.

    Mueller et al. (2021), Eqs. 3-6: from the planets' |b| and radii,
    planet-planet occultations of the tilted planet and ``other`` can occur
    only for alpha in [alpha_a, alpha_b] or [alpha_c, alpha_d]. Each range is
    widened by 1 deg at both ends.

    Parameters
    ----------
    system : System
        The planets; ``system.tilted`` is the tilted one.
    other : int or str or None, optional
        The second planet (index or name); default the first planet that is
        not tilted.

    Returns
    -------
    alpha_a, alpha_b, alpha_c, alpha_d : float
        The limits [deg]; alpha_c = 360 - alpha_b, alpha_d = 360 - alpha_a.

    Raises
    ------
    ValueError
        When the system has a single planet, ``other`` is not a planet's
        name or an index in range, or ``other`` is the tilted planet itself;
        for an N-body system, planets with moons, or a planet whose lnode
        is not 0.

    Examples
    --------
    >>> import jaxppo as jp
    >>> limits = jp.alpha_limits(jp.kepler20_system())
    >>> print(", ".join(f"{v:.2f}" for v in limits))
    20.79, 157.71, 202.29, 339.21
    """
    from ._system import require_keplerian

    require_keplerian(system, "alpha_limits (Eqs. 3-6)")
    if any(np.any(np.asarray(pl.lnode, float) != 0) for pl in system.planets):
        raise ValueError("alpha_limits (Eqs. 3-6) takes every planet's node at 0 (the tilt alpha is then the angle "
                         f"between the orbits); got lnode = {[float(np.asarray(pl.lnode)) for pl in system.planets]}")
    tb = system.planets[system.tilted]
    if other is None:
        candidates = [i for i in range(len(system.planets)) if i != system.tilted]
        if not candidates:
            raise ValueError("alpha_limits needs a second planet")
        other = candidates[0]
    if isinstance(other, str):
        other = system.index(other)
    if isinstance(other, bool) or not isinstance(other, (int, np.integer)) or not 0 <= other < len(system.planets):
        raise ValueError(f"other must be a planet name or an index in [0, {len(system.planets)}), got {other!r}")
    if other == system.tilted:
        raise ValueError(f"other = {other!r} is the tilted planet itself; alpha_limits needs the second planet of "
                         "the pair (default: the first untilted one)")
    pc = system.planets[other]
    bb, bc = float(abs(tb.impact)), float(abs(pc.impact))
    pb, pcr = float(tb.radius), float(pc.radius)

    def asin_deg(v: float) -> float:
        return math.degrees(math.asin(min(max(v, -1.0), 1.0)))

    alpha_a = abs(asin_deg(bc + pcr) - asin_deg(bb - pb)) - 1.0
    alpha_b = 180.0 - abs(asin_deg(bc - pcr) + asin_deg(bb - pb)) + 1.0
    return alpha_a, alpha_b, 360.0 - alpha_b, 360.0 - alpha_a


@dataclasses.dataclass(frozen=True)
class MultiTransit:
    """Two or more planets on the star at once: one event of ``multi_transits``.

    A frozen dataclass.

    Attributes
    ----------
    number : int
        Running number of the event in its list (from 1).
    planets : tuple of str
        The planets on the disk together (names, or indices as text), in
        planet order.
    start, end : float
        First contact of the earliest and last contact of the latest of the
        overlapping transits [d].
    mid : float
        Their midpoint [d].
    overlap_start, overlap_end : float
        When all of ``planets`` are on the star [d].
    transit_mid : tuple of float
        Each planet's mid-transit time [d], in the order of ``planets``.

    Examples
    --------
    >>> import jaxppo as jp
    >>> event = jp.multi_transits(jp.kepler20_system(), 330.0, 340.0)[0]
    >>> event.planets
    ('b', 'c')
    >>> print(f"{event.mid:.2f} d, both on the star for {24 * 60 * (event.overlap_end - event.overlap_start):.1f} min")
    334.02 d, both on the star for 27.7 min
    >>> sorted(event.as_dict())
    ['end', 'mid', 'number', 'overlap_end', 'overlap_start', 'planets', 'start', 'transit_mid']
    """

    number: int
    planets: tuple[str, ...]
    start: float
    end: float
    mid: float
    overlap_start: float
    overlap_end: float
    transit_mid: tuple[float, ...]

    def as_dict(self) -> dict:
        """The event as a plain dict (field name: value), e.g. for JSON or a table row.

        Returns
        -------
        dict
            The fields of ``MultiTransit``.
        """
        return dataclasses.asdict(self)


def planet_label(system: System, i: int) -> str:
    """The planet's name, or its index as a string when it has none."""
    return system.planets[i].name or str(i)


def transit_windows(system: System, idx, t_start: float, t_end: float) -> list:
    """(first contact, last contact, planet index, mid-transit) [d] of every
    transit that touches [t_start, t_end], sorted by first contact.
    A system with moons is refused: the windows are the planets' own
    contacts, and a moon, up to a_m (1 + e_m) from its planet (which
    recoils from it), crosses the star outside them."""
    if any(pl.moons for pl in system.planets):
        raise ValueError("multi-transit windows (multi_transits, multi_transit_counts) come from each planet's own "
                         "contacts and do not follow moons (a moon reaches a_m (1 + e_m) from its planet, which "
                         "recoils from it): events would be missed or misplaced; find them from system.positions")
    windows = []
    nbody = None
    if system.orbits == "nbody":
        # mid-times from the integrated orbits; contacts from each planet's osculating Keplerian orbit
        from ._nbody import nbody_transit_times

        pad = max(float(np.max(np.abs(system.planets[i].contacts()))) for i in idx) if len(idx) else 0.0
        nbody = nbody_transit_times(system, t_start - pad, t_end + pad)
    for i in idx:
        pl = system.planets[i]
        # first and last contact about conjunction (asymmetric for e > 0)
        t1, t4 = (float(v) for v in pl.contacts())
        if t4 <= t1:
            continue
        half = max(-t1, t4)
        mids = _epochs_between(pl, t_start, t_end, pad=half) if nbody is None else \
            [(n, tc) for j, n, tc in nbody if j == i]
        for _, mid in mids:
            if mid + t4 >= t_start and mid + t1 <= t_end:
                windows.append((mid + t1, mid + t4, i, mid))
    windows.sort()
    return windows


def simultaneous_sets(windows: list) -> list[list]:
    """Maximal sets of transit windows that share a common time (all those
    planets on the stellar disk at once): the maximal cliques of the interval
    overlap graph, found by sweeping the contact times. Windows that only
    touch (last contact = first contact) do not overlap."""
    points = [(w[0], 1, k) for k, w in enumerate(windows)] + [(w[1], 0, k) for k, w in enumerate(windows)]
    points.sort()  # at equal times, ends (0) before starts (1)
    active: set[int] = set()
    grew = False
    out = []
    for _, is_start, k in points:
        if is_start:
            active.add(k)
            grew = True
        else:
            if grew and len(active) >= 2:
                out.append([windows[j] for j in sorted(active)])
            grew = False
            active.discard(k)
    return out


def multi_transits(
    system: System, t_start: float, t_end: float, planets: tuple | None = None
) -> list[MultiTransit]:
    """Find the events in [t_start, t_end] with two or more planets on the stellar disk at once.

    Two planets are on the disk at once when their first-to-last-contact
    windows share a common time. An event lists exactly the planets that are
    all on the disk at once: a triple needs a moment with all three in
    transit; a chain b-c then c-d with no common time is two double
    transits, not a triple. Windows come from the orbits' contact times
    (``Planet.contacts``), so events that fall in data gaps are listed
    too (see ``multi_transit_counts`` for observed ones).

    Parameters
    ----------
    system : System
        The planets.
    t_start, t_end : float or Quantity or TimeDelta
        The time span [d] (a time Quantity or TimeDelta is converted); an
        event counts when some transit of it touches the span.
    planets : sequence of str or int, optional
        Restrict to these planets (names or indices); default all.

    Returns
    -------
    list of MultiTransit
        The events, sorted by time and numbered from 1.

    Raises
    ------
    ValueError
        When t_start or t_end is not finite, t_end <= t_start, or a name in
        ``planets`` is not a planet's.

    Examples
    --------
    The double transits of Kepler-20 b and c in 300..700 d (Mueller et al.
    2021, Table 2, lists those observed):

    >>> import jaxppo as jp
    >>> for e in jp.multi_transits(jp.kepler20_system(), 300.0, 700.0):
    ...     print(e.number, e.planets, f"{e.mid:.2f}")
    1 ('b', 'c') 323.08
    2 ('b', 'c') 334.02
    3 ('b', 'c') 496.77
    4 ('b', 'c') 670.46
    """
    # a time Quantity or TimeDelta in days; a string, bool or length refused by name
    t_start, t_end = (_one_time(n, v) for n, v in (("t_start", t_start), ("t_end", t_end)))
    for name, v in (("t_start", t_start), ("t_end", t_end)):
        if not np.isfinite(v):
            raise ValueError(f"{name} must be finite, got {v!r}")
    if t_end <= t_start:
        raise ValueError(f"t_end must be after t_start, got {t_start} .. {t_end}")
    idx = range(len(system.planets)) if planets is None else [
        system.index(p) if isinstance(p, str) else int(p) for p in planets
    ]
    events: list[MultiTransit] = []
    for group in simultaneous_sets(transit_windows(system, idx, t_start, t_end)):
        group = sorted(group, key=lambda w: w[2])
        start = min(w[0] for w in group)
        end = max(w[1] for w in group)
        events.append(MultiTransit(
            number=len(events) + 1,
            planets=tuple(planet_label(system, w[2]) for w in group),
            start=start, end=end, mid=0.5 * (start + end),
            overlap_start=max(w[0] for w in group), overlap_end=min(w[1] for w in group),
            transit_mid=tuple(w[3] for w in group),
        ))
    return events


def multi_transit_counts(
    system: System, times, exposure: float | None = None, planets: tuple | None = None
) -> dict[tuple[str, ...], int]:
    """Count the observed multi-transits of each set of planets.

    As in Mueller et al. (2021), Table 2: each event counted once, under all
    the planets on the disk at once, so a triple is not also counted as
    three doubles. An event (``multi_transits``) counts as observed when
    some cadence covers part of the time during which all its planets are on
    the disk (``overlap_start`` .. ``overlap_end``); events in data gaps do
    not count.

    Parameters
    ----------
    system : System
        The planets.
    times : array_like
        Observation time stamps [d] (e.g. the cadence mid-times of the light
        curve) [n_times].
    exposure : float or None, optional
        Cadence length [d]; a cadence covers t +- exposure / 2. None
        (default): the time stamps are instants.
    planets : sequence of str or int, optional
        Restrict to these planets (names or indices); default all.

    Returns
    -------
    dict
        Planet-name tuple (e.g. ``("b", "c")``) -> number of observed events,
        ordered by the number of planets, then by name; sets never observed
        are absent.

    Raises
    ------
    ValueError
        When ``times`` is empty or not finite, or ``exposure`` is negative.

    Examples
    --------
    Kepler-20 b + c with Kepler long cadence (29.4 min) from 300 to 1600 d:

    >>> import numpy as np
    >>> import jaxppo as jp
    >>> times = np.arange(300.0, 1600.0, 0.0204)
    >>> jp.multi_transit_counts(jp.kepler20_system(), times, exposure=0.0204)
    {('b', 'c'): 9}
    """
    t = np.sort(np.asarray(times, float).ravel())
    if t.size == 0:
        raise ValueError("times must hold at least one time stamp")
    if not np.all(np.isfinite(t)):
        raise ValueError(f"times must be finite, got {float(t[~np.isfinite(t)][0])}")
    half = 0.0 if exposure is None else 0.5 * float(exposure)
    if not half >= 0:
        raise ValueError(f"exposure must be >= 0 days, got {exposure!r}")
    counts: dict[tuple[str, ...], int] = {}
    # one day of padding: a single time stamp is a valid (empty-width) span
    for e in multi_transits(system, float(t[0]) - half - 1.0, float(t[-1]) + half + 1.0, planets):
        # first cadence ending after the overlap starts: does it begin before the overlap ends?
        j = np.searchsorted(t, e.overlap_start - half, side="right")
        if j < t.size and t[j] - half < e.overlap_end:
            counts[e.planets] = counts.get(e.planets, 0) + 1
    return dict(sorted(counts.items(), key=lambda kv: (len(kv[0]), kv[0])))
