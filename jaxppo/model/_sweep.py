"""sweep: light curves on a [case, alpha, time] grid, modelling no more than
the scene needs.

Rotating the tilted planet about the star's centre does not change its
distance from the centre, and mirroring the other planets into the other
hemisphere (the hemisphere case) does not change theirs. So wherever no two disks overlap, the flux is the sum
of one-disk terms that depend on neither alpha nor the case: they are computed
once per time. Only the (case, alpha, time) frames in which two disks overlap
run the exact union integral, in bounded chunks, sharded over all devices.
"""

from __future__ import annotations

import dataclasses
import warnings

import jax.numpy as jnp
import numpy as np

from ._flux import occultation_flux
from ._overlap import case_xy, contact_frames, on_star, untilted_geometry
from ._plan import one_disk_sum, overlap_flux
from ._cases import CASES, case_signs
from ._system import System, require_keplerian
from ._units import from_quantity

__all__ = ["sweep", "SweepStats"]


@dataclasses.dataclass(frozen=True)
class SweepStats:
    """What a sweep computed.

    Attributes:
        frames: frames in the [case, alpha, time] grid.
        single: one-disk evaluations (alpha- and case-independent).
        union: frames that ran the union integral.
    """

    frames: int
    single: int
    union: int

    def __getitem__(self, key: str) -> int:
        """``stats["frames"]``: the dict access of jaxppo 0.3, kept one
        release; use ``stats.frames``."""
        if key not in ("frames", "single", "union"):
            raise KeyError(key)
        warnings.warn(
            f"SweepStats is a dataclass now: use stats.{key} instead of stats[{key!r}] "
            "(dict access is deprecated and will be removed in 1.0)",
            DeprecationWarning,
            stacklevel=2,
        )
        return getattr(self, key)


def sweep(
    system: System,
    t,
    alpha,
    cases=CASES,
    method: str = "auto",
    order: int = 24,
    chunk: int = 65536,
    return_stats: bool = False,
    no_overlap: bool = False,
):
    """Compute the relative flux on the grid [case, alpha, time].

    Rotating the tilted planet about the star's centre does not change its
    distance from the centre, and mirroring the other planets into the other
    hemisphere does not change theirs. So with ``method="auto"`` every frame
    in which no two disks overlap is a sum of one-disk terms computed once per
    time; only the (case, alpha, time) frames in which two disks overlap run
    the exact union integral, in bounded chunks. Other methods, and stars
    that are not radially symmetric, evaluate ``System.flux`` on the
    whole grid.

    Parameters
    ----------
    system : System
        The star and planets; ``system.tilted`` is rotated by alpha.
    t : array_like
        Times [d], [n_times] (a time Quantity or TimeDelta is converted; an
        absolute astropy Time is refused, see ``System.flux``).
    alpha : array_like
        Tilt angles [deg], a scalar or [n_alpha] (an angle Quantity is
        converted).
    cases : str or sequence, optional
        Hemisphere cases: "same", "opposite" or tuples of +-1 signs of the
        untilted planets (see ``hemisphere_cases``); one string is one
        case (default ("same", "opposite")).
    method : {"auto", "exact", "raster"}, optional
        "auto" (default; as above), "exact" (union integral for every
        frame) or "raster".
    order : int, optional
        Gauss-Legendre nodes per arc piece (default 24; as in
        ``occultation_flux``).
    chunk : int, optional
        Frames per compiled batch (default 65536).
    return_stats : bool, optional
        Also return a ``SweepStats`` (default False).
    no_overlap : bool, optional
        Model every frame as if no two disks overlapped (the null model of
        the obliquity scan: each planet's own transit only; default False).

    Returns
    -------
    flux : numpy.ndarray
        Relative flux, [n_cases, n_alpha, n_times].
    stats : SweepStats
        Only with ``return_stats=True``: ``frames`` (the grid's size),
        ``single`` (one-disk evaluations, alpha- and case-independent) and
        ``union`` (frames that ran the union integral).

    Raises
    ------
    ValueError
        When ``t`` is not 1D or ``alpha`` more than 1D, a value is not finite,
        or a case is invalid for the system (and as ``System.flux`` for
        other methods).

    Examples
    --------
    Two planets in transit together at t = 0: along the same chord
    (alpha = 0) the disks overlap at both times, at alpha = 90 deg only at
    t = 0, where they are concentric:

    >>> import jaxppo as jp
    >>> b = jp.Planet(period=3.0, t0=0.0, a=10.0, inc=90.0, radius=0.1, name="b")
    >>> c = jp.Planet(period=10.0, t0=0.0, a=20.0, inc=90.0, radius=0.1, name="c")
    >>> system = jp.System(jp.Star.quadratic(0.4, 0.25), [b, c], tilted="b")
    >>> flux, stats = jp.sweep(system, t=[0.0, 0.02], alpha=[0.0, 90.0], cases="same", return_stats=True)
    >>> flux.shape
    (1, 2, 2)
    >>> print(flux.round(6))
    [[[0.987891 0.97733 ]
      [0.987891 0.97642 ]]]
    >>> stats
    SweepStats(frames=4, single=4, union=3)
    """
    require_keplerian(system, "sweep")  # its plans take every tilt from one geometry
    t = np.asarray(from_quantity("t", t, "d"), float)
    alpha = np.atleast_1d(np.asarray(from_quantity("alpha", alpha, "deg"), float))
    if t.ndim != 1 or alpha.ndim != 1:
        raise ValueError(f"t and alpha must be 1D, got shapes {t.shape} and {alpha.shape}")
    if not np.all(np.isfinite(t)) or not np.all(np.isfinite(alpha)):
        raise ValueError("t and alpha must be finite")
    if isinstance(cases, str):
        cases = (cases,)
    cases = tuple(cases)
    signs_of = [case_signs(len(system.planets), system.tilted, c) for c in cases]  # validates
    n_c, n_a, n_t = len(cases), alpha.size, t.size
    if method != "auto" or not system.star.symmetric:
        flux = _each_disk_alone if no_overlap else _all_disks
        out = [flux(system, t, alpha, c, method, order, chunk) for c in cases]
        res = np.stack(out).reshape(n_c, n_a, n_t)
        stats = SweepStats(frames=n_c * n_a * n_t, single=0, union=0 if no_overlap else n_c * n_a * n_t)
        return (res, stats) if return_stats else res

    tilted = system.tilted
    # Untilted positions (case "same"; radius 0 behind the star) and the
    # tilted planet at every alpha
    geometry = untilted_geometry(system, t, alpha)
    x0, y0, r0, xt, yt = geometry
    d = np.hypot(x0, y0)
    # One-disk terms: alpha- and case-independent, computed once.
    on = on_star(x0, y0, r0)
    base = np.ones(n_t)
    frames = np.nonzero(on.any(-1))[0]
    n_single = 0
    if frames.size:
        base[frames] = one_disk_sum(system.star, d[frames], r0[frames], order, chunk)
        n_single = int(on.sum())
    out = np.broadcast_to(base, (n_c, n_a, n_t)).copy()

    if no_overlap:
        stats = SweepStats(frames=n_c * n_a * n_t, single=n_single, union=0)
        return (out, stats) if return_stats else out
    # Frames where some pair of disks on the star overlaps (the one contact test)
    hits = contact_frames(system, t, alpha, cases, geometry=geometry)
    jobs = []  # (case index, alpha index, time index)
    for ci, signs in enumerate(signs_of):
        ai, ti = np.nonzero(hits[ci])
        if ai.size:
            jobs.append((ci, ai, ti, signs))
    n_union = 0
    for ci, ai, ti, signs in jobs:
        X, Y = (np.array(v) for v in case_xy(system, x0[ti], y0[ti], signs))
        X[:, tilted] = xt[ai, ti]
        Y[:, tilted] = yt[ai, ti]
        vals = overlap_flux(system.star, X, Y, r0[ti], order, chunk)
        out[ci, ai, ti] = np.asarray(vals)
        n_union += ai.size
    stats = SweepStats(frames=n_c * n_a * n_t, single=n_single, union=n_union)
    return (out, stats) if return_stats else out


def _all_disks(system: System, t, alpha, case, method: str, order, chunk) -> np.ndarray:
    """``system.flux`` at [alpha, t] with ``method``: every disk, overlaps included."""
    return np.asarray(system.flux(t, alpha, case=case, method=method, order=order, chunk=chunk))


def _each_disk_alone(system: System, t, alpha, case, method: str, order, chunk) -> np.ndarray:
    """The flux without planet-planet overlaps, at [alpha, t] with ``method``
    (any star, spotted ones included): the star's own flux F_0 (no disk;
    a spotted star's varies with time) plus each disk's own dip,
    F_0 + sum_k (F_k - F_0), F_k the flux with disk k alone."""
    alpha = jnp.asarray(alpha, float)
    tt, aa = jnp.asarray(t, float)[None], alpha.reshape(-1, 1)
    x, y, r = system.positions(tt, aa, case=case)
    k = r.shape[-1]
    # one call over [no disk, disk 1 alone, ..., disk k alone]: one
    # program, not k + 1 (a spotted star's raster compiles per call)
    radii = jnp.stack([jnp.zeros_like(r)] + [jnp.zeros_like(r).at[..., j].set(r[..., j]) for j in range(k)])
    xs, ys = (jnp.broadcast_to(v, radii.shape) for v in (x, y))
    kw = dict(method=method, order=order, chunk=chunk)
    if getattr(system.star, "spots", None) is not None:
        kw["times"] = jnp.broadcast_to(tt, radii.shape[:-1])
    f = np.asarray(occultation_flux(system.star, xs, ys, radii, **kw))
    return f[0] + np.sum(f[1:] - f[0], axis=0)
