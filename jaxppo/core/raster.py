"""Pixel-grid rasterizer kernels (one frame).

Two modes, both with supersampled anti-aliasing (``ss x ss`` points per pixel,
placed on a regular sub-grid) or the analytic edge approximation:

* full disk: an N x N grid over [-1, 1]^2, the way Mueller et al. (2021)
  rendered with Blender (500 x 500); flux = sum over visible pixels / sum over
  all pixels of the star, so the stellar edge's own aliasing cancels as in a
  Blender frame normalised by an unocculted frame;
* windowed: pixels only in a square window around each disk, at a pixel scale
  ``scale`` [R*]; a point is charged to the first disk that covers it, so
  overlaps count once; the unocculted flux F0 is exact.

Each sample's weight is the star's intensity at its mu, times an optional
surface map m(x, y) (spots, faculae) for stars that are not radially
symmetric. Rotating circular spots (``spot_surface``, ``spot_deficit``)
give a map that depends on the frame's time.
"""

from __future__ import annotations

from typing import Callable

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

__all__ = [
    "subsample_offsets", "full_disk_flux", "windowed_deficit", "edge_coverage", "pixel_disk_area",
    "spot_centres", "spot_profile", "spot_surface", "spot_deficit",
]


def subsample_offsets(ss: int) -> np.ndarray:
    """Offsets (in pixels) of ss x ss samples centred in a pixel."""
    o = (np.arange(ss) + 0.5) / ss - 0.5
    ox, oy = np.meshgrid(o, o, indexing="xy")
    return np.stack([ox.ravel(), oy.ravel()], axis=-1)


def edge_coverage(dist: Array, radius: Array, pixel: float) -> Array:
    """Analytic anti-aliasing: fraction of a pixel inside a disk edge,
    linear in the signed distance to the edge (exact for a straight edge
    crossing the pixel centre along an axis)."""
    return jnp.clip((radius - dist) / pixel + 0.5, 0.0, 1.0)


def _star_weight(px: Array, py: Array, intensity: Callable, surface: Callable | None) -> Array:
    r2 = px * px + py * py
    inside = r2 < 1.0
    mu = jnp.sqrt(jnp.where(inside, 1.0 - r2, 1.0))
    w = jnp.where(inside, intensity(mu), 0.0)
    if surface is not None:
        w = w * surface(px, py)
    return w


def full_disk_flux(
    x: Array, y: Array, r: Array, intensity: Callable, n: int, ss: int = 1,
    surface: Callable | None = None, analytic: bool = False, unspotted_norm: bool = False,
) -> Array:
    """Relative flux from an n x n raster of the whole star (one frame):
    relative to the same raster of the unocculted star with its surface map,
    or, with ``unspotted_norm``, without it (rotating spots: the flux
    relative to the unspotted star, like a Blender frame divided by a frame
    of the bare star)."""
    pix = 2.0 / n
    c = -1.0 + (np.arange(n) + 0.5) * pix
    cx, cy = np.meshgrid(c, c, indexing="xy")
    if analytic:
        px, py = jnp.asarray(cx.ravel()), jnp.asarray(cy.ravel())
        w = _star_weight(px, py, intensity, surface)
        dist = jnp.sqrt((px[:, None] - x) ** 2 + (py[:, None] - y) ** 2)
        cov = edge_coverage(dist, r, pix)
        visible = jnp.prod(1.0 - cov, axis=-1)
        w0 = _star_weight(px, py, intensity, None) if unspotted_norm else w
        return jnp.sum(w * visible) / jnp.sum(w0)
    off = subsample_offsets(ss) * pix
    px = jnp.asarray((cx.ravel()[:, None] + off[None, :, 0]).ravel())
    py = jnp.asarray((cy.ravel()[:, None] + off[None, :, 1]).ravel())
    w = _star_weight(px, py, intensity, surface)
    hidden = jnp.any((px[:, None] - x) ** 2 + (py[:, None] - y) ** 2 < r * r, axis=-1)
    w0 = _star_weight(px, py, intensity, None) if unspotted_norm else w
    return jnp.sum(jnp.where(hidden, 0.0, w)) / jnp.sum(w0)


def windowed_deficit(
    x: Array, y: Array, r: Array, intensity: Callable, scale: Array, window: int, ss: int = 2,
    surface: Callable | None = None,
) -> Array:
    """Occulted flux (same units as F0) from per-disk windows of
    ``window x window`` pixels, disk i's of side ``scale[i]`` [R*] (one frame).

    Each window is anchored on its own lattice (pixel edges at multiples of
    ``scale[i]``) around the centre of ``visible_box``, so sampling is the same wherever
    a disk sits.
    """
    k = x.shape[-1]
    _, cx, cy = visible_box(x, y, r)
    off = subsample_offsets(ss)  # pixels
    idx = np.arange(window) - window // 2
    gx, gy = np.meshgrid(idx, idx, indexing="xy")
    base = (gx.ravel()[:, None] + 0.5 + off[None, :, 0]).ravel()  # in pixels
    basey = (gy.ravel()[:, None] + 0.5 + off[None, :, 1]).ravel()
    base, basey = jnp.asarray(base), jnp.asarray(basey)
    total = 0.0
    for i in range(k):
        h = scale[i]
        px = jnp.floor(cx[i] / h) * h + base * h
        py = jnp.floor(cy[i] / h) * h + basey * h
        w = _star_weight(px, py, intensity, surface)
        mine = (px - x[i]) ** 2 + (py - y[i]) ** 2 < r[i] ** 2
        for j in range(i):
            mine = mine & ~((px - x[j]) ** 2 + (py - y[j]) ** 2 < r[j] ** 2)
        total = total + jnp.sum(jnp.where(mine, w, 0.0)) * (h / ss) ** 2
    return total


def visible_box(x, y, r, xp=jnp):
    """Side [R*] of the square that holds the bounding box of each disk's
    part on the star (box of the disk clipped to [-1, 1]^2), and its centre;
    0 for a disk off the star or of zero radius. ``xp``: jnp or numpy."""
    x0, x1 = xp.maximum(x - r, -1.0), xp.minimum(x + r, 1.0)
    y0, y1 = xp.maximum(y - r, -1.0), xp.minimum(y + r, 1.0)
    side = xp.maximum(xp.maximum(x1 - x0, y1 - y0), 0.0)
    return side, 0.5 * (x0 + x1), 0.5 * (y0 + y1)


def _w_integral(t: Array, r: Array) -> Array:
    """int_{-r}^{t} sqrt(r^2 - s^2) ds for t in [-r, r]."""
    t = jnp.clip(t, -r, r)
    w = jnp.sqrt(jnp.maximum(r * r - t * t, 0.0))
    ratio = jnp.clip(t / jnp.where(r > 0, r, 1.0), -1.0, 1.0)
    return 0.5 * (t * w + r * r * jnp.arcsin(ratio)) + 0.25 * jnp.pi * r * r


def _corner_area(x: Array, y: Array, r: Array) -> Array:
    """Area of the disk of radius r at the origin with x' <= x and y' <= y."""
    h = jnp.sqrt(jnp.maximum(r * r - x * x, 0.0))
    W = lambda t: _w_integral(t, r)
    yc = jnp.clip(y, -r, r)
    # |t| > h: the whole chord (x >= 0) or nothing (x < 0); |t| < h: x + w.
    lower = jnp.where(x >= 0, 2.0 * (W(jnp.minimum(yc, -h)) - W(-r)), 0.0)
    mid_top = jnp.clip(yc, -h, h)
    middle = jnp.where(yc > -h, x * (mid_top + h) + W(mid_top) - W(-h), 0.0)
    upper = jnp.where((x >= 0) & (yc > h), 2.0 * (W(yc) - W(h)), 0.0)
    inside = lower + middle + upper
    full = 2.0 * (W(yc) - W(-r))
    return jnp.where(x >= r, full, jnp.where(x <= -r, 0.0, inside))


def pixel_disk_area(x0: Array, x1: Array, y0: Array, y1: Array, xc: Array, yc: Array, r: Array) -> Array:
    """Exact area of the rectangle [x0, x1] x [y0, y1] inside the disk
    (xc, yc, r), by inclusion-exclusion of corner areas (closed form)."""
    a, b, c, d = x0 - xc, x1 - xc, y0 - yc, y1 - yc
    return (_corner_area(b, d, r) - _corner_area(a, d, r) - _corner_area(b, c, r) + _corner_area(a, c, r))


_SUB = subsample_offsets(16)


def windowed_deficit_exact_coverage(
    x: Array, y: Array, r: Array, intensity: Callable, scale: Array, window: int, ss: int = 1,
    surface: Callable | None = None,
) -> Array:
    """Windowed raster with exact pixel-disk coverage (closed-form area of
    each pixel inside the disk); disk i's window has ``window x window``
    pixels of side ``scale[i]`` [R*] around the centre of ``visible_box``;
    the intensity is sampled at ss x ss points per pixel.

    Two kinds of pixel are refined on a 16 x 16 sub-grid: pixels on the edges
    of two disks at once (the part already charged to an earlier disk is
    counted there; elsewhere the product of the exact fractions is exact, one
    of them being 0 or 1), and pixels on the stellar limb: the exact fraction
    on the star times the mean intensity of the sub-points on the star where
    no disk edge crosses the pixel, the sub-points on the star, in disk i and
    in no earlier disk where one does (a product of the two fractions would
    count a disk edge just inside the limb as if it were spread over the
    pixel). At most ``8 * window + 8`` such pixels per disk are refined (a
    convex curve crosses at most 4 * window + 4 of them); the rest keep the
    product rule.
    """
    k = x.shape[-1]
    _, cx, cy = visible_box(x, y, r)
    idx = np.arange(window) - window // 2
    gx, gy = np.meshgrid(idx, idx, indexing="xy")
    gx, gy = jnp.asarray(gx.ravel(), float), jnp.asarray(gy.ravel(), float)
    off = jnp.asarray(subsample_offsets(ss))
    n_refine = min(8 * window + 8, window * window)
    total = 0.0
    for i in range(k):
        h = scale[i]
        area = h * h
        x0, y0 = jnp.floor(cx[i] / h) * h + gx * h, jnp.floor(cy[i] / h) * h + gy * h
        x1, y1 = x0 + h, y0 + h
        # Which circles cross each pixel, decided geometrically (nearest and
        # farthest point of the pixel from the centre): robust, unlike testing
        # the closed-form areas, whose inclusion-exclusion leaves rounding of
        # the size of the whole disk's area.
        crosses_i = _edge_in_pixel(x0, x1, y0, y1, x[i], y[i], r[i])
        inside_i = _pixel_inside(x0, x1, y0, y1, x[i], y[i], r[i])
        frac = _fraction(x0, x1, y0, y1, x[i], y[i], r[i], crosses_i, inside_i, n_refine, area)
        keep = frac
        partial = jnp.zeros_like(crosses_i)
        any_edge = crosses_i
        for j in range(i):
            crosses_j = _edge_in_pixel(x0, x1, y0, y1, x[j], y[j], r[j])
            inside_j = _pixel_inside(x0, x1, y0, y1, x[j], y[j], r[j])
            fj = _fraction(x0, x1, y0, y1, x[j], y[j], r[j], crosses_j, inside_j, n_refine, area)
            keep = keep * (1.0 - fj)
            partial = partial | (crosses_i & crosses_j)
            any_edge = any_edge | crosses_j
        limb = _edge_in_pixel(x0, x1, y0, y1, 0.0, 0.0, 1.0) & (frac > 0)
        star_in = _pixel_inside(x0, x1, y0, y1, 0.0, 0.0, 1.0)
        on_star = _fraction(x0, x1, y0, y1, 0.0, 0.0, 1.0, limb, star_in, n_refine, area)
        px = (x0 + 0.5 * h)[:, None] + off[None, :, 0] * h
        py = (y0 + 0.5 * h)[:, None] + off[None, :, 1] * h
        w = jnp.mean(_star_weight(px, py, intensity, surface), axis=-1)
        cover = jnp.where(limb, keep * on_star, keep)
        mixed = limb & any_edge
        flags = (partial, limb, mixed)
        fine = _refine(x, y, r, i, x0, y0, h, frac, keep, on_star, flags, intensity, surface, n_refine)
        sel, valid, f_ref, w_limb, w_mixed = fine
        c_ref = jnp.where(mixed[sel], 1.0, jnp.where(limb[sel], f_ref * on_star[sel], f_ref))
        w_ref = jnp.where(mixed[sel], w_mixed, jnp.where(limb[sel], w_limb, w[sel]))
        contrib = jnp.sum(cover * w)
        contrib = contrib + jnp.sum(jnp.where(valid, c_ref * w_ref - cover[sel] * w[sel], 0.0))
        total = total + contrib * area
    return total


def _refine(x, y, r, i, x0, y0, h, frac, keep, on_star, flags, intensity, surface, n_refine):
    """Coverage and mean intensity of the flagged pixels (a fixed count, so it
    stays jittable) from a 16 x 16 sub-grid: see
    ``windowed_deficit_exact_coverage``."""
    partial, limb, mixed = flags
    sub = jnp.asarray(_SUB) + 0.5
    sel = jnp.nonzero(partial | limb, size=n_refine, fill_value=0)[0]
    valid = jnp.arange(n_refine) < jnp.sum(partial | limb)
    sx = x0[sel][:, None] + sub[None, :, 0] * h
    sy = y0[sel][:, None] + sub[None, :, 1] * h
    in_i = (sx - x[i]) ** 2 + (sy - y[i]) ** 2 < r[i] ** 2
    taken = jnp.zeros_like(in_i)
    for j in range(i):
        taken = taken | ((sx - x[j]) ** 2 + (sy - y[j]) ** 2 < r[j] ** 2)
    f_ref = jnp.where(partial[sel], jnp.maximum(frac[sel] - jnp.mean(in_i & taken, axis=-1), 0.0), keep[sel])
    sub_w = _star_weight(sx, sy, intensity, surface)  # 0 off the star
    n_in = jnp.sum(sx * sx + sy * sy < 1.0, axis=-1)
    w_limb = jnp.sum(sub_w, axis=-1) / jnp.maximum(n_in, 1)
    # limb and a disk edge in one pixel: what the sub-grid sees of the three
    w_mixed = jnp.mean(jnp.where(in_i & ~taken, sub_w, 0.0), axis=-1)
    return sel, valid, f_ref, w_limb, w_mixed


def _edge_in_pixel(x0, x1, y0, y1, xc, yc, r):
    """Does the circle (xc, yc, r) pass through the pixel?"""
    nx = jnp.clip(xc, x0, x1) - xc
    ny = jnp.clip(yc, y0, y1) - yc
    fx = jnp.maximum(jnp.abs(x0 - xc), jnp.abs(x1 - xc))
    fy = jnp.maximum(jnp.abs(y0 - yc), jnp.abs(y1 - yc))
    return (nx * nx + ny * ny < r * r) & (fx * fx + fy * fy > r * r)


def _pixel_inside(x0, x1, y0, y1, xc, yc, r):
    """Is the whole pixel inside the disk?"""
    fx = jnp.maximum(jnp.abs(x0 - xc), jnp.abs(x1 - xc))
    fy = jnp.maximum(jnp.abs(y0 - yc), jnp.abs(y1 - yc))
    return fx * fx + fy * fy <= r * r


def _fraction(x0, x1, y0, y1, xc, yc, r, crosses, inside, n_edge, area):
    """Fraction of each pixel inside the disk: 0 or 1 away from its edge, the
    closed-form area on the (at most n_edge) pixels the edge crosses, which
    are gathered so that only they pay for the area formula."""
    sel = jnp.nonzero(crosses, size=n_edge, fill_value=0)[0]
    valid = jnp.arange(n_edge) < jnp.sum(crosses)
    vals = pixel_disk_area(x0[sel], x1[sel], y0[sel], y1[sel], xc, yc, r) / area
    base = jnp.where(inside, 1.0, 0.0)
    return base.at[sel].set(jnp.where(valid, vals, base[sel]))


# ---- rotating circular spots -------------------------------------------------


def spot_centres(spots, t: Array) -> tuple[Array, Array, Array]:
    """Unit vectors (x, y, z) [R*] of the spot centres at time t [d]
    (z towards the observer), each of shape t.shape + (spots,).

    The rotation axis is a = (0, sin i, cos i) before the sky rotation by the
    obliquity; a spot at latitude phi and longitude lambda sits at
    sin(phi) a + cos(phi) [cos(dl) e1 + sin(dl) x], e1 = (0, -cos i, sin i),
    dl = 2 pi (t - t_ref) / P - lambda, so that z = mu is the small-spot
    formula's mu (``jaxppo.activity.spot_flux``).
    """
    t = jnp.asarray(t)[..., None]
    lat, lon = jnp.deg2rad(spots.lat), jnp.deg2rad(spots.lon)
    inc, psi = jnp.deg2rad(spots.inc), jnp.deg2rad(spots.obliquity)
    dl = 2.0 * jnp.pi * (t - spots.t_ref) / spots.period - lon
    cl, sl = jnp.cos(lat), jnp.sin(lat)
    vx = cl * jnp.sin(dl)
    vy = sl * jnp.sin(inc) - cl * jnp.cos(dl) * jnp.cos(inc)
    vz = sl * jnp.cos(inc) + cl * jnp.cos(dl) * jnp.sin(inc)
    # sky rotation by the obliquity, the same sense as System's alpha
    cp, sp = jnp.cos(psi), jnp.sin(psi)
    return vx * cp + vy * sp, -vx * sp + vy * cp, vz


def spot_profile(theta: Array, radius: Array, edge: float) -> Array:
    """Fraction of full contrast at angular distance theta [rad] from a
    spot's centre: 1 inside radius - edge/2, 0 outside radius + edge/2, a C1
    cubic smoothstep between (radius and edge [rad]); symmetric about the
    radius, so the spot's area equals a hard-edged one's to O(edge^2)."""
    s = jnp.clip((radius - theta) / edge + 0.5, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def _angular_distance(chord2: Array) -> Array:
    # 2 arcsin(chord / 2), guarded so that neither the centre (chord 0: the
    # derivative of sqrt) nor the antipode (arcsin' at 1) gives a NaN gradient
    chord = jnp.sqrt(chord2 + 1e-24)
    return 2.0 * jnp.arcsin(jnp.minimum(0.5 * chord, 1.0 - 1e-12))


def spot_surface(spots, t: Array) -> Callable:
    """The surface map m(x, y) = 1 - sum_k c_k S_k at time t [d] (scalar):
    a function of sky coordinates [R*] on the visible hemisphere."""
    vx, vy, vz = spot_centres(spots, t)
    rho, edge = jnp.deg2rad(spots.radius), np.deg2rad(spots.edge)

    def surface(px, py):
        pz = jnp.sqrt(jnp.maximum(1.0 - px * px - py * py, 0.0))
        d2 = (px[..., None] - vx) ** 2 + (py[..., None] - vy) ** 2 + (pz[..., None] - vz) ** 2
        prof = spot_profile(_angular_distance(d2), rho, edge)
        return 1.0 - jnp.sum(spots.contrast * prof, axis=-1)

    return surface


_THETA_IN = np.polynomial.legendre.leggauss(24)
_THETA_EDGE = np.polynomial.legendre.leggauss(16)


def spot_deficit(spots, t: Array, intensity: Callable, n_psi: int = 128) -> Array:
    """Flux the spots remove from the unocculted star at time t [d]
    (scalar), sum_k c_k int S_k I(mu) mu dOmega over the visible hemisphere,
    in the units of the star's total flux F0 = int I dA.

    Each spot is integrated on its own cap in polar coordinates (theta,
    psi) about its centre v: mu = cos(theta) v_z + sin(theta) cos(psi)
    sqrt(1 - v_z^2) (the azimuth measured from the direction towards the
    observer), Gauss-Legendre in theta on [0, radius - edge/2] and across the
    edge (24 + 16 nodes: the profile is smooth on each piece), midpoints in
    psi on [0, pi] (the integrand is even in psi). The only kink left is the
    limb (mu = 0) where I mu goes to zero continuously.
    """
    _, _, vz = spot_centres(spots, t)
    rho, edge = jnp.deg2rad(spots.radius), np.deg2rad(spots.edge)
    a = jnp.maximum(rho - 0.5 * edge, 0.0)
    b = rho + 0.5 * edge
    pieces = []
    for (nodes, weights), lo, hi in ((_THETA_IN, 0.0, a), (_THETA_EDGE, a, b)):
        half = 0.5 * (hi - lo)
        theta = (lo + half * (1.0 + jnp.asarray(nodes)[:, None]))  # [node, spot]
        pieces.append((theta, half * jnp.asarray(weights)[:, None]))
    theta = jnp.concatenate([p[0] for p in pieces])
    wt = jnp.concatenate([p[1] for p in pieces])
    psi = (np.arange(n_psi) + 0.5) * np.pi / n_psi
    sinv = jnp.sqrt(jnp.maximum(1.0 - vz * vz, 0.0) + 1e-30)
    cpsi = jnp.asarray(np.cos(psi))
    # [node, spot, psi]
    mu = jnp.cos(theta)[..., None] * vz[None, :, None] + (jnp.sin(theta) * sinv)[..., None] * cpsi
    vis = mu > 0
    mu_v = jnp.where(vis, mu, 0.0)
    f = jnp.where(vis, intensity(mu_v) * mu_v, 0.0)
    per_node = jnp.sum(f, axis=-1) * (2.0 * np.pi / n_psi)
    prof = spot_profile(theta, rho, edge)
    per_spot = jnp.sum(wt * jnp.sin(theta) * prof * per_node, axis=0)
    return jnp.sum(spots.contrast * per_spot)
