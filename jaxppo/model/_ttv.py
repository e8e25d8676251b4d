"""Transit times of a planet that does not follow a linear ephemeris
(transit-timing variations): the listed mid-times, the time offset they
put on the Keplerian orbit, and the predicted mid-time of any epoch.

The rule (docs/conventions.md, "Transit times"; that of exoplanet's and
jaxoplanet's ``TTVOrbit``): at time t the planet is where its Keplerian
orbit (period P, conjunction t0) puts it at t - dt_k, where
dt_k = tc_k - t0 - k P is the offset of the listed transit k NEAREST to t
in time. Ties (t exactly half-way between two listed transits) go to the
later one. So the conjunction of every listed epoch k is at tc_k exactly.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["check_transit_times", "shifted_time", "offsets", "mid_time", "epochs_text"]


def _concrete(*values) -> bool:
    return not any(isinstance(v, jax.core.Tracer) for v in values)


def check_transit_times(times, epochs, period, t0, name: str):
    """(times [n] as a float array, epochs as a tuple of ints) after the
    checks: both given together or times alone (epochs 0..n-1), the same
    length >= 1, finite times, distinct integer epochs, and every time
    within half a period of its linear-ephemeris time t0 + k P (a time
    further off belongs to another epoch). Epochs are sorted ascending
    (times with them). Returns (None, None) without times."""
    label = f"planet {name!r}: " if name else ""
    if times is None:
        if epochs is not None:
            raise ValueError(f"{label}transit_epochs = {epochs!r} needs transit_times (the mid-times [d] of those "
                             "epochs)")
        return None, None
    if isinstance(times, (str, bytes)):
        raise ValueError(f"{label}transit_times must be a 1D list of mid-times [d], got {times!r}")
    traced = not _concrete(times)
    try:
        arr = times if traced else np.asarray(times, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{label}transit_times must be a 1D list of mid-times [d] (numbers), got {times!r}") from None
    if arr.ndim != 1 or arr.shape[0] < 1:
        raise ValueError(f"{label}transit_times must be a non-empty 1D list of mid-times [d], got shape {arr.shape}")
    n = arr.shape[0]
    if epochs is None:
        epochs = tuple(range(n))
    else:
        if isinstance(epochs, (str, bytes)) or np.ndim(epochs) != 1:
            raise ValueError(f"{label}transit_epochs must be a 1D list of integers, got {epochs!r}")
        out = []
        for e in epochs:
            if isinstance(e, (bool, np.bool_)) or not float(e) == math.floor(float(e)):
                raise ValueError(f"{label}transit_epochs must be integers (0 is the transit at t0), got {e!r}")
            out.append(int(e))
        epochs = tuple(out)
        if len(epochs) != n:
            raise ValueError(f"{label}transit_epochs has {len(epochs)} entries but transit_times has {n}: they "
                             "must pair up (one epoch per mid-time)")
        dup = sorted({e for e in epochs if epochs.count(e) > 1})
        if dup:
            raise ValueError(f"{label}transit_epochs must be distinct, epoch(s) {dup} are listed twice")
    order = np.argsort(epochs, kind="stable")
    if np.any(order != np.arange(n)):
        epochs = tuple(epochs[i] for i in order)
        arr = arr[jnp.asarray(order)] if traced else arr[order]
    if traced:
        return arr, epochs
    if not np.all(np.isfinite(arr)):
        k = int(np.argmin(np.isfinite(arr)))
        raise ValueError(f"{label}transit_times must be finite, got {float(arr[k])} for epoch {epochs[k]}")
    if _concrete(period, t0):
        p, t = float(np.asarray(period, float)), float(np.asarray(t0, float))
        off = arr - (t + p * np.asarray(epochs, float))
        bad = np.nonzero(~(np.abs(off) < 0.5 * p))[0]
        if bad.size:
            k = int(bad[0])
            raise ValueError(
                f"{label}transit time {float(arr[k])!r} d of epoch {epochs[k]} is {off[k]:+.6g} d from its linear "
                f"ephemeris t0 + {epochs[k]} P = {t + p * epochs[k]!r} d; every listed time must lie within half a "
                f"period ({0.5 * p:.6g} d) of it (is the epoch number right? epoch 0 is the transit at t0)")
    return jnp.asarray(arr, float), epochs


def offsets(times, epochs, period, t0, xp=jnp):
    """dt_k = tc_k - t0 - k P [d] of the listed transits."""
    return xp.asarray(times) - xp.asarray(t0) - xp.asarray(period) * xp.asarray(np.asarray(epochs, float))


def _nearest(t, times, xp):
    """Index of the listed transit nearest to each t (ties: the later)."""
    times = xp.asarray(times)
    if times.shape[0] == 1:
        return xp.zeros(xp.shape(t), int)
    # the listed times increase with epoch (each lies within P/2 of t0 + k P),
    # so the bins of "nearest" are cut at the midpoints; side="right" puts a
    # t at a midpoint into the later bin
    edges = 0.5 * (times[1:] + times[:-1])
    return xp.searchsorted(edges, t, side="right")


def shifted_time(t, times, epochs, period, t0, xp=jnp):
    """t - dt_k(t) [d]: the time at which the Keplerian orbit is evaluated."""
    t = xp.asarray(t)
    dt = offsets(times, epochs, period, t0, xp)
    return t - dt[_nearest(t, times, xp)]


def mid_time(epoch: int, times, epochs, period, t0) -> float:
    """Predicted mid-time [d] of ``epoch`` (concrete values): the listed
    time of a listed epoch; otherwise t0 + n P plus the offset of the
    nearest listed EPOCH (ties: the later)."""
    ep = [int(v) for v in epochs]
    k = min(range(len(ep)), key=lambda j: (abs(ep[j] - epoch), -ep[j]))
    tc = float(np.asarray(times, float)[k])
    if ep[k] == epoch:
        return tc
    return float(t0) + epoch * float(period) + (tc - float(t0) - float(period) * ep[k])


def epochs_text(epochs) -> str:
    """Short text of a list of epochs for repr: "0..5" or "0, 2, 7"."""
    e = list(epochs)
    if e == list(range(e[0], e[-1] + 1)) and len(e) > 2:
        return f"{e[0]}..{e[-1]}"
    return ", ".join(str(v) for v in e) if len(e) <= 6 else f"{e[0]}, {e[1]}, ..., {e[-1]}"
