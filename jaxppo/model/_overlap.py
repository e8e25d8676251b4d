"""Which frames put two disks in contact on the star, and which times are in
transit: ONE home for the contact test and the in-transit mask.

Every workflow that needs to know where a planet-planet occultation can
happen asks here: the sweep (which frames run the union integral), the
marginal scan (the same, for every draw), the scan's PPO tables, the fit
model and the transit posterior (which frames take the exact union
integral). The geometry comes from ``System.positions``, the one place
the tilt convention lives.
"""

from __future__ import annotations

import numpy as np

from ._cases import case_signs
from ._system import System, require_keplerian

__all__ = ["on_star", "pairs_in_contact", "untilted_geometry", "case_xy", "quiet_model", "no_ppo_model", "contact_frames", "ppo_table", "may_touch",
           "in_transit_mask"]


def on_star(x, y, r, margin: float = 0.0) -> np.ndarray:
    """[..., disk]: the disk (radius r > 0; r = 0 marks a planet behind the
    star) reaches within ``margin`` [R*] of the stellar disk."""
    return (np.asarray(r) > 0) & (np.hypot(x, y) - r < 1.0 + margin)


def pairs_in_contact(x, y, r, margin: float = 0.0, only: int | None = None) -> np.ndarray:
    """[...]: some pair of disks (positions [..., disk]), both on the star,
    whose centres are closer than the sum of their radii plus ``margin``
    [R*]; with ``only``, the pairs that include disk ``only``."""
    x, y, r = (np.asarray(v, float) for v in (x, y, r))
    on = on_star(x, y, r, margin)
    k = x.shape[-1]
    hit = np.zeros(np.broadcast_shapes(x.shape, y.shape, r.shape)[:-1], bool)
    for i in range(k):
        for j in range(i + 1, k):
            if only is not None and only not in (i, j):
                continue
            d = np.hypot(x[..., i] - x[..., j], y[..., i] - y[..., j])
            hit |= on[..., i] & on[..., j] & (d < r[..., i] + r[..., j] + margin)
    return hit


def untilted_geometry(system: System, t, alpha):
    """The positions a [case, alpha, time] grid is built from: the untilted
    planets at ``t`` (case "same"; x0, y0, r0 [time, disk], r = 0 behind the
    star) and the tilted planet at every alpha (xt, yt [alpha, time])."""
    t = np.asarray(t, float)
    x0, y0, r0 = system.positions(t, 0.0, "same", xp=np)
    xa, ya, _ = system.positions(t[None, :], np.asarray(alpha, float)[:, None], "same", xp=np)
    return x0, y0, r0, xa[..., system.tilted], ya[..., system.tilted]


def case_xy(system: System, x0, y0, signs):
    """The untilted planets' sky positions in a hemisphere case, from those
    of case "same" (``untilted_geometry``; the disks on the last axis).

    ``System.positions`` mirrors a planet (y -> -y, inc -> 180 - inc)
    before turning it by its node ``lnode``; mirroring the turned position
    instead (y' -> -y') put a planet with a nonzero node elsewhere (the scan
    of case "opposite" then differed from ``System.flux`` by 1 %). With
    (x', y') the node-turned position, the mirrored one is
    (x' cos 2W - y' sin 2W, -x' sin 2W - y' cos 2W), W the node."""
    signs = np.asarray(signs, float)
    node = np.deg2rad(np.array([float(pl.lnode) for pl in system.planets]))
    c2, s2 = np.cos(2.0 * node), np.sin(2.0 * node)
    x0, y0 = np.asarray(x0), np.asarray(y0)
    mirror = signs < 0
    x = np.where(mirror, x0 * c2 - y0 * s2, x0)
    y = np.where(mirror, -x0 * s2 - y0 * c2, y0)
    return x, y


def quiet_model(system: System, t, case) -> np.ndarray:
    """The light curve of a tilt at which the tilted planet touches no other
    disk, in hemisphere case ``case``: the untilted planets' union (their
    own overlaps exact) and the tilted planet's one-disk deficit; what a
    scan's quiet alpha computes, also where the grid has none (the sum of
    one-disk terms left out overlaps of two untilted planets). Any star: a
    spotted one gets each frame's time, and the tilted planet's dip is
    taken from the star's own flux F_0(t) (union + F_tilted - F_0)."""
    from ._flux import occultation_flux

    t = np.asarray(t, float)
    x, y, r = system.positions(t, 0.0, case, xp=np)
    i = system.tilted
    r_untilted = np.array(r)
    r_untilted[..., i] = 0.0
    r_tilted = np.zeros_like(r_untilted)
    r_tilted[..., i] = r[..., i]
    kw = {"times": t} if getattr(system.star, "spots", None) is not None else {}

    def flux(radii):
        return np.asarray(occultation_flux(system.star, x, y, radii, **kw))

    star = flux(np.zeros_like(r_untilted)) if kw or not system.star.symmetric else 1.0
    return flux(r_untilted) + flux(r_tilted) - star


def no_ppo_model(system: System, t, case) -> np.ndarray:
    """The no-PPO light curve [time] at times ``t`` [d] in ``case``: each
    disk's own dip (``sweep``'s ``no_overlap``) and, in the frames where two
    untilted planets overlap each other (at every tilt), ``quiet_model``,
    which counts that overlap once: the scan's ground level."""
    from ._sweep import sweep

    t = np.asarray(t, float)
    out = np.array(sweep(system, t, np.zeros(1), cases=(case,), no_overlap=True)[0, 0])
    x, y, r = system.positions(t, 0.0, case, xp=np)
    r = np.array(r)
    r[..., system.tilted] = 0.0
    both = pairs_in_contact(x, y, r)
    if both.any():
        out[both] = quiet_model(system, t[both], case)
    return out


def contact_frames(system: System, t, alpha, cases, margin: float = 0.0, tilted_only: bool = False,
                   geometry=None) -> np.ndarray:
    """[case, alpha, time]: the frames in which two disks overlap on the star
    (centres closer than the sum of the radii plus ``margin`` [R*], both
    disks within ``margin`` of the stellar disk). The tilted planet turns
    with alpha; the untilted ones are mirrored per hemisphere case, so a
    pair of untilted planets may touch in one case and not the other.

    Args:
        tilted_only: only pairs with the tilted planet (a PPO of the tilted
            planet, as the scan's tables count them).
        geometry: ``untilted_geometry`` of the same arguments, when
            already computed.
    """
    alpha = np.atleast_1d(np.asarray(alpha, float))
    x0, y0, r0, xt, yt = untilted_geometry(system, t, alpha) if geometry is None else geometry
    k, i = x0.shape[-1], system.tilted
    on = on_star(x0, y0, r0, margin)
    out = np.zeros((len(cases), alpha.size, x0.shape[0]), bool)
    for ci, case in enumerate(cases):
        signs = case_signs(k, i, case)
        xc, yc = case_xy(system, x0, y0, signs)
        hit = out[ci]
        for j in range(k):
            if j == i:
                continue
            both = on[:, i] & on[:, j]
            dist2 = (xt - xc[:, j]) ** 2 + (yt - yc[:, j]) ** 2
            hit |= both[None, :] & (dist2 < (r0[:, i] + r0[:, j] + margin)[None, :] ** 2)
            if tilted_only:
                continue
            for m in range(j + 1, k):
                if m == i:
                    continue
                dd = np.hypot(xc[:, j] - xc[:, m], yc[:, j] - yc[:, m])
                hit |= (on[:, j] & on[:, m] & (dd < r0[:, j] + r0[:, m] + margin))[None, :]
    return out


def ppo_table(system: System, times_per_event, alpha, case) -> np.ndarray:
    """[alpha, event]: does the tilted planet overlap another planet on the
    star in any of the event's frames?"""
    alpha = np.atleast_1d(np.asarray(alpha, float))
    out = np.zeros((alpha.size, len(times_per_event)), bool)
    for ei, t in enumerate(times_per_event):
        out[:, ei] = contact_frames(system, t, alpha, (case,), tilted_only=True)[0].any(-1)
    return out


def may_touch(x, y, r, margin: float = 0.0) -> np.ndarray:
    """[time]: frames (untilted positions [time, disk]) in which two disks on
    the star could touch at SOME tilt: turning an orbit about the star's
    centre keeps each disk's distance from the centre, so two disks can meet
    only if those distances differ by less than the sum of their radii (plus
    ``margin`` [R*]). A superset of ``contact_frames`` over all alphas
    and cases."""
    x, y, r = (np.asarray(v, float) for v in (x, y, r))
    d, on = np.hypot(x, y), on_star(x, y, r, margin)
    k = x.shape[-1]
    hit = np.zeros(x.shape[:-1], bool)
    for i in range(k):
        for j in range(i + 1, k):
            hit |= on[..., i] & on[..., j] & (np.abs(d[..., i] - d[..., j]) < r[..., i] + r[..., j] + margin)
    return hit


def in_transit_mask(system: System, t, pad: float = 0.0) -> np.ndarray:
    """True where any planet of ``system`` is between its first and last
    contact, widened by ``pad`` [d] on both sides (e.g. half an exposure,
    which smears a transit by that much). Alpha rotates the tilted orbit
    about the star's centre, which keeps every contact time: the mask holds
    for all alpha and both cases."""
    t = np.asarray(t, float)
    mask = np.zeros(t.shape, bool)
    if t.size == 0:
        return mask
    if any(pl.moons for pl in system.planets):
        require_keplerian(system, "in_transit_mask")
    if system.orbits == "nbody":  # the windows of the integrated transit times
        from ._transits import transit_windows

        for t1, t4, _, _ in transit_windows(system, range(len(system.planets)), float(t.min()) - pad,
                                            float(t.max()) + pad):
            mask |= (t > t1 - pad) & (t < t4 + pad)
        return mask
    for pl in system.planets:
        half = float(pl.half_duration())
        if half <= 0:  # never transits: nothing to mask
            continue
        period, t0 = float(pl.period), float(pl.t0)
        # a planet with transit times is where its orbit is at the shifted time
        ts = pl.orbit_time(t, np)
        n = np.round((ts - t0) / period)
        mask |= np.abs(ts - (t0 + n * period)) < half + pad
    return mask
