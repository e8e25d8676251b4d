"""occultation_flux: relative flux of a star behind any number of disks."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike

from ._star import Star
from .core.geometry import float_dtype
from .core.occult import INNER_MARGIN, disk_deficit, inner_disk_deficit, inner_pair_deficit, union_deficit

__all__ = ["occultation_flux", "METHODS"]

METHODS = ("auto", "exact", "raster")


def _is_concrete(*arrays) -> bool:
    return not any(isinstance(a, jax.core.Tracer) for a in arrays)


def _prepare(x, y, r):
    try:
        x, y, r = jnp.broadcast_arrays(jnp.asarray(x), jnp.asarray(y), jnp.asarray(r))
    except ValueError as err:
        raise ValueError(
            f"x, y and r must broadcast together, got shapes {jnp.shape(x)}, {jnp.shape(y)}, {jnp.shape(r)}"
        ) from err
    if x.ndim == 0:
        x, y, r = x[None], y[None], r[None]
    dtype = float_dtype(x, y, r)
    return x.astype(dtype), y.astype(dtype), r.astype(dtype)


def _validate_concrete(x, y, r) -> None:
    for name, v in (("x", x), ("y", y), ("r", r)):
        arr = np.asarray(v)
        if not np.all(np.isfinite(arr)):
            bad = arr[~np.isfinite(arr)].ravel()[0]
            raise ValueError(f"{name} must be finite, found {bad}")
    rr = np.asarray(r)
    if np.any(rr < 0):
        raise ValueError(f"r (disk radius) must be >= 0, found {rr[rr < 0].ravel()[0]}")


@functools.partial(jax.jit, static_argnames=("order",))
def _exact_frames(star: Star, x: Array, y: Array, r: Array, order: int) -> Array:
    g, phi1 = star.radial_kernel()
    deficit = jax.vmap(lambda a, b, c: union_deficit(a, b, c, g, phi1, order))(x, y, r)
    return 1.0 - deficit / (2.0 * jnp.pi * phi1)


@functools.partial(jax.jit, static_argnames=("order",))
def _separate_frames(star: Star, x: Array, y: Array, r: Array, order: int) -> Array:
    """Frames whose disks do not overlap each other: a sum of one-disk terms."""
    g, phi1 = star.radial_kernel()
    d = jnp.hypot(x, y)
    one = jax.vmap(lambda dd, rr: disk_deficit(dd, rr, g, phi1, order))
    deficit = one(d.reshape(-1), r.reshape(-1)).reshape(d.shape).sum(-1)
    return 1.0 - deficit / (2.0 * jnp.pi * phi1)


@functools.partial(jax.jit, static_argnames=("order",))
def _disk_terms(star: Star, d: Array, p: Array, order: int) -> Array:
    """Relative deficits of single disks (general rule, any position)."""
    g, phi1 = star.radial_kernel()
    return jax.vmap(lambda dd, rr: disk_deficit(dd, rr, g, phi1, order))(d, p) / (2.0 * jnp.pi * phi1)


@jax.jit
def _inner_disk_terms(star: Star, d: Array, p: Array) -> Array:
    """Relative deficits of single disks well inside the star (midpoint rule)."""
    g, phi1 = star.radial_kernel()
    return inner_disk_deficit(d, p, g) / (2.0 * jnp.pi * phi1)


def one_disk_sum(star: Star, d: np.ndarray, r: np.ndarray, order: int, chunk: int) -> np.ndarray:
    """1 - sum of one-disk deficits per frame ([frame, disk] host arrays): each
    disk well inside the star (1 - d - p >= INNER_MARGIN p) takes the cheap
    midpoint rule, every other disk on the star the general rule."""
    d = np.asarray(d)
    r = np.asarray(r)
    flat_d, flat_r = d.reshape(-1), r.reshape(-1)
    terms = np.zeros(flat_d.size, d.dtype)
    on = (flat_r > 0) & (flat_d - flat_r < 1.0)
    inner = on & (1.0 - flat_d - flat_r >= INNER_MARGIN * flat_r)
    rest = on & ~inner
    for mask, kernel in ((inner, lambda s, a, b, o: _inner_disk_terms(s, a, b)), (rest, _disk_terms)):
        idx = np.nonzero(mask)[0]
        for start in range(0, idx.size, chunk):
            sel = idx[start:start + chunk]
            size = _bucket(sel.size)
            a = np.zeros(size, d.dtype)
            b = np.zeros(size, d.dtype)
            a[: sel.size], b[: sel.size] = flat_d[sel], flat_r[sel]
            terms[sel] = np.asarray(kernel(star, jnp.asarray(a), jnp.asarray(b), order))[: sel.size]
    return 1.0 - terms.reshape(d.shape).sum(-1)


@functools.partial(jax.jit, static_argnames=("order",))
def _inner_pair_frames(star: Star, x: Array, y: Array, r: Array, order: int) -> Array:
    """Two overlapping disks, both well inside the star (inclusion-exclusion)."""
    g, phi1 = star.radial_kernel()
    return 1.0 - inner_pair_deficit(x, y, r, g) / (2.0 * jnp.pi * phi1)


def overlap_frames(star: Star, x: np.ndarray, y: np.ndarray, r: np.ndarray, order: int, chunk: int) -> np.ndarray:
    """Flux of frames in which disks overlap ([frame, disk] host arrays): pairs
    of disks well inside the star (1 - d - p >= INNER_MARGIN p) take the
    inclusion-exclusion kernel, everything else the general union integral."""
    out = np.empty(x.shape[0], x.dtype)
    inner = np.zeros(x.shape[0], bool)
    if x.shape[1] == 2:
        d = np.hypot(x, y)
        inner = np.all((r > 0) & (1.0 - d - r >= INNER_MARGIN * r), axis=1)
    for mask, fn in ((inner, _inner_pair_frames), (~inner, _exact_frames)):
        idx = np.nonzero(mask)[0]
        if idx.size:
            out[idx] = _run_padded(fn, star, x[idx], y[idx], r[idx], order, chunk)
    return out


def _bucket(n: int) -> int:
    """Pad batch sizes to a few shapes (1024 x 4^k) so that repeated calls
    reuse compilations: at most a handful of programs per kernel."""
    size = 1024
    while size < n:
        size *= 4
    return size


def _shard(arrays):
    """Place the frame axis across all devices (a no-op on one device)."""
    devices = jax.devices()
    if len(devices) == 1:
        return arrays
    from jax.sharding import Mesh, NamedSharding, PartitionSpec

    mesh = Mesh(np.array(devices), ("frames",))
    spec = NamedSharding(mesh, PartitionSpec("frames"))
    return tuple(jax.device_put(a, spec) for a in arrays)


def _run_padded(fn, star, x, y, r, order, chunk: int):
    """Run a frame kernel over [frame, disk] arrays in chunks of at most
    ``chunk`` frames, padded to a few bucket sizes (so repeated calls reuse
    compilations) and to a multiple of the device count, sharded over devices."""
    n = x.shape[0]
    if n == 0:
        return jnp.zeros(0, x.dtype)
    ndev = len(jax.devices())
    concrete = _is_concrete(x, y, r, *jax.tree_util.tree_leaves(star))
    x, y, r = (np.asarray(v) for v in (x, y, r)) if concrete else (x, y, r)
    xp = np if concrete else jnp
    outs = []
    for start in range(0, n, chunk):
        xs, ys, rs = x[start:start + chunk], y[start:start + chunk], r[start:start + chunk]
        m = xs.shape[0]
        size = min(_bucket(m), chunk) if m <= chunk else m
        size = -(-size // ndev) * ndev
        pad = size - m
        if pad:
            # Padding frames: disks far off the star cost nothing and are dropped.
            kk = xs.shape[1]
            xs = xp.concatenate([xs, xp.full((pad, kk), 10.0, xs.dtype) + xp.arange(kk, dtype=xs.dtype)], 0)
            ys = xp.concatenate([ys, xp.zeros((pad, kk), ys.dtype)], 0)
            rs = xp.concatenate([rs, xp.full((pad, kk), 0.1, rs.dtype)], 0)
        xs, ys, rs = _shard(tuple(jnp.asarray(v) for v in (xs, ys, rs)))
        outs.append(np.asarray(fn(star, xs, ys, rs, order))[:m] if concrete else fn(star, xs, ys, rs, order)[:m])
    return np.concatenate(outs) if concrete else jnp.concatenate(outs)


def scene_classes(x: np.ndarray, y: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per frame: (any disk on the star, any two disks on the star overlapping).

    Tangent disks (distance = sum of radii) do not overlap: their union has the
    area of the sum, so the one-disk sum is exact for them.
    """
    d = np.hypot(x, y)
    on = (d - r < 1.0) & (r > 0)
    k = x.shape[-1]
    overlap = np.zeros(x.shape[:-1], dtype=bool)
    for i in range(k):
        for j in range(i + 1, k):
            dist = np.hypot(x[..., i] - x[..., j], y[..., i] - y[..., j])
            overlap |= on[..., i] & on[..., j] & (dist < r[..., i] + r[..., j])
    return on.any(-1), overlap


def occultation_flux(
    star: Star,
    x: ArrayLike,
    y: ArrayLike,
    r: ArrayLike,
    method: str = "auto",
    order: int = 24,
    chunk: int = 65536,
    raster=None,
) -> Array:
    """Relative flux of ``star`` behind opaque disks.

    Args:
        star: a :class:`Star`.
        x, y, r: disk centres and radii [R*]; the last axis indexes the disks
            (any number, overlapping or not), leading axes broadcast. All disks
            are in front of the star; a disk of radius 0 is absent.
        method: ``"exact"`` integrates the union of the disks exactly (Green's
            theorem, ``jaxppo.core.occult``); ``"auto"`` (default) models no
            more than each frame needs: frames with no disk on the star cost
            nothing, frames whose disks do not overlap use one-disk terms, and
            only frames with overlapping disks run the union integral. It
            equals ``"exact"`` to rounding. Under ``jit``/``grad`` (traced
            inputs) ``"auto"`` evaluates the union integral for every frame.
            ``"raster"`` is the pixel-grid method.
        order: Gauss-Legendre nodes per arc piece (24: worst measured error
            ~1e-11 in float64 over adversarial scenes; 20 is ~5e-11).
        chunk: frames per compiled batch (bounds memory).
        raster: ``RasterSettings`` for ``method="raster"`` (default: windowed,
            pixel scale = smallest radius / 24, 4 x 4 supersampling).

    Returns:
        Relative flux, shape = the broadcast leading axes.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if not isinstance(star, Star):
        raise ValueError(f"star must be a jaxppo.Star, got {type(star).__name__}")
    x, y, r = _prepare(x, y, r)
    lead = x.shape[:-1]
    k = x.shape[-1]
    if not star.symmetric:
        if method == "exact":
            raise ValueError(
                "method='exact' needs a radially symmetric star; this star has a surface map: use method='raster'"
            )
        method = "raster"
    if method == "raster":
        from ._raster import raster_flux

        return raster_flux(star, x, y, r, raster)
    concrete = _is_concrete(x, y, r, *jax.tree_util.tree_leaves(star))
    if _is_concrete(x, y, r):
        _validate_concrete(x, y, r)
    xf, yf, rf = (v.reshape(-1, k) for v in (x, y, r))
    if method == "exact" or not concrete:
        if concrete:
            return jnp.asarray(_run_padded(_exact_frames, star, xf, yf, rf, order, chunk).reshape(lead))
        return _exact_frames(star, xf, yf, rf, order).reshape(lead)
    xf, yf, rf = (np.asarray(v) for v in (xf, yf, rf))
    any_on, overlap = scene_classes(xf, yf, rf)
    out = np.ones(xf.shape[0], xf.dtype)
    single = np.nonzero(any_on & ~overlap)[0]
    multi = np.nonzero(overlap)[0]
    if single.size:
        out[single] = one_disk_sum(star, np.hypot(xf[single], yf[single]), rf[single], order, chunk)
    if multi.size:
        out[multi] = overlap_frames(star, xf[multi], yf[multi], rf[multi], order, chunk)
    return jnp.asarray(out.reshape(lead))

