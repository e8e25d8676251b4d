"""occultation_flux: relative flux of a star behind any number of disks."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike

from ._star import Star
from .core.geometry import float_dtype, safe_hypot
from .core.occult import (
    INNER_MARGIN,
    MAX_RADIUS,
    LENS_RULES,
    disk_deficit,
    inner_disk_deficit,
    lens_deficit,
    lens_rho,
    union_deficit,
)

__all__ = ["occultation_flux", "METHODS"]

METHODS = ("auto", "exact", "raster")


_FLOAT32_WARNED = False
FLOAT32_MESSAGE = (
    "jaxppo: float32: JAX's float64 is off (jax_enable_x64 is False), so every flux is computed in float32. "
    "The flux kernel alone then errs by ~1e-7, but float32 times and positions put a light curve off by up to "
    "~20 ppm (Kepler-20 near a planet-planet occultation; docs/methods.md). For science, call "
    "jax.config.update('jax_enable_x64', True) at startup; to keep float32 deliberately, silence this with "
    "warnings.filterwarnings('ignore', message='jaxppo: float32')."
)


def _warn_float32_once() -> None:
    """The float32 policy (docs/methods.md): the library never flips JAX's
    global x64 switch, but a user cannot miss that it is off."""
    global _FLOAT32_WARNED
    if not _FLOAT32_WARNED and not jax.config.jax_enable_x64:
        _FLOAT32_WARNED = True
        import warnings

        warnings.warn(FLOAT32_MESSAGE, UserWarning, stacklevel=3)


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
    if np.any(rr > MAX_RADIUS):
        raise ValueError(
            f"r (disk radius) must be <= {MAX_RADIUS:g} stellar radii (beyond it the rounding of the disk's "
            f"distance alone exceeds 1e-10 of the flux), found {rr[rr > MAX_RADIUS].ravel()[0]}"
        )


@functools.partial(jax.jit, static_argnames=("order",))
def _exact_frames(star: Star, x: Array, y: Array, r: Array, order: int) -> Array:
    g, phi1 = star.radial_kernel()
    inten = star.radial_intensity()
    deficit = jax.vmap(lambda a, b, c: union_deficit(a, b, c, g, phi1, order, inten))(x, y, r)
    return 1.0 - deficit / (2.0 * jnp.pi * phi1)


@functools.partial(jax.jit, static_argnames=("order",))
def _separate_frames(star: Star, x: Array, y: Array, r: Array, order: int) -> Array:
    """Frames whose disks do not overlap each other: a sum of one-disk terms."""
    g, phi1 = star.radial_kernel()
    inten = star.radial_intensity()
    d = safe_hypot(x, y)
    one = jax.vmap(lambda dd, rr: disk_deficit(dd, rr, g, phi1, order, inten))
    deficit = one(d.reshape(-1), r.reshape(-1)).reshape(d.shape).sum(-1)
    return 1.0 - deficit / (2.0 * jnp.pi * phi1)


@functools.partial(jax.jit, static_argnames=("order",))
def _disk_terms(star: Star, d: Array, p: Array, order: int) -> Array:
    """Relative deficits of single disks (general rule, any position)."""
    g, phi1 = star.radial_kernel()
    inten = star.radial_intensity()
    return jax.vmap(lambda dd, rr: disk_deficit(dd, rr, g, phi1, order, inten))(d, p) / (2.0 * jnp.pi * phi1)


@jax.jit
def _inner_disk_terms(star: Star, d: Array, p: Array) -> Array:
    """Relative deficits of single disks well inside the star (midpoint rule)."""
    g, phi1 = star.radial_kernel()
    return inner_disk_deficit(d, p, g) / (2.0 * jnp.pi * phi1)


@functools.partial(jax.jit, static_argnames=("order",))
def _lens_terms(star: Star, x: Array, y: Array, r: Array, order: int) -> Array:
    """Relative flux of the lens of each crossing pair ([pair, 2] arrays),
    ``order`` Gauss-Legendre nodes per arc."""
    g, phi1 = star.radial_kernel()
    return lens_deficit(x, y, r, g, order) / (2.0 * jnp.pi * phi1)


_lens_rho = jax.jit(lens_rho)

# Below this many crossing pairs in one call, "auto" integrates their frames
# by the union integral: compiling the lens kernels (~1 s on the CPU, once per
# process and batch size) would cost more than they save (~2.5 us per pair).
LENS_MIN_PAIRS = 2048


def _gather_pairs(arrays, fp: np.ndarray, pp: np.ndarray, k: int):
    """[pair, 2] arrays of the disks of crossing pairs (frame fp, pair pp)."""
    if k == 2:  # one pair per frame: rows, and no copy when every frame has it
        return tuple(v if fp.size == v.shape[0] else v[fp] for v in arrays)
    ij = _pairs(k)[pp]
    return tuple(np.take_along_axis(v[fp], ij, 1) for v in arrays)


def _padded_calls(n: int, chunk: int):
    """Split n frames into calls of a few fixed sizes, 1024 x 2^k <= chunk, so
    that repeated calls reuse at most a handful of compiled programs and the
    padding is below 1024 frames: yields (start, stop, padded size)."""
    ndev = len(jax.devices())
    top = max(1024, 1 << (max(chunk, 1).bit_length() - 1)) if chunk >= 1024 else max(chunk, 1)
    start = 0
    while start < n:
        rest = n - start
        size = top if top < 1024 else max(min(top, 1 << (rest.bit_length() - 1)), 1024)
        stop = min(start + size, n)
        yield start, stop, -(-size // ndev) * ndev
        start = stop


def one_disk_sum(star: Star, d: np.ndarray, r: np.ndarray, order: int, chunk: int) -> np.ndarray:
    """1 - sum of one-disk deficits per frame ([frame, disk] host arrays): for
    a smooth profile each disk well inside the star (1 - d - p >= INNER_MARGIN p)
    takes the cheap midpoint rule, every other disk on the star the general
    rule."""
    d = np.asarray(d)
    r = np.asarray(r)
    flat_d, flat_r = d.reshape(-1), r.reshape(-1)
    terms = np.zeros(flat_d.size, d.dtype)
    on = (flat_r > 0) & (flat_d - flat_r < 1.0)
    inner = on & (1.0 - flat_d - flat_r >= INNER_MARGIN * flat_r) & star.smooth
    rest = on & ~inner
    for mask, kernel in ((inner, lambda s, a, b, o: _inner_disk_terms(s, a, b)), (rest, _disk_terms)):
        idx = np.nonzero(mask)[0]
        if idx.size:
            terms[idx] = _per_disk(kernel, star, flat_d[idx], flat_r[idx], order, chunk)
    return 1.0 - terms.reshape(d.shape).sum(-1)


def _per_disk(kernel, star: Star, d: np.ndarray, p: np.ndarray, order: int, chunk: int) -> np.ndarray:
    """A one-disk kernel(star, d, p, order) over host arrays of disks, in the
    padded calls of ``_run_padded`` (padding disks lie off the star; the
    kernel gets d in the x slot, and the y slot is unused)."""
    col = d[:, None]
    return _run_padded(lambda s, a, b, c, o: kernel(s, a[:, 0], c[:, 0], o), star, col, col, p[:, None], order, chunk)


@functools.lru_cache(maxsize=None)
def _pairs(k: int) -> np.ndarray:
    """The unordered pairs (i < j) of k disks, [pair, 2]."""
    return np.array([(i, j) for i in range(k) for j in range(i + 1, k)], int).reshape(-1, 2)


@jax.jit
def _survey(star: Star, x: Array, y: Array, r: Array) -> tuple[Array, Array, Array, Array, Array]:
    """One pass over [frame, disk] arrays that decides how each frame is
    modelled, and does the cheapest part of it.

    A disk that lies off the star or inside another disk adds nothing to the
    union and does not count (of identical disks the first counts). Where
    each counting disk crosses at most one other, the union is, exactly, the
    sum of the one-disk terms minus the lens of each crossing pair.

    Returns ``(multiple, counts, inner, inner_sum, cross)``: frames with a
    disk crossing two or more others (they need the union integral); the
    counting disks; those well inside the star (1 - d - p >= INNER_MARGIN p,
    smooth profiles only), whose relative deficits, by the midpoint rule,
    are summed in ``inner_sum``; and the crossing pairs [frame, pair] in
    ``_pairs(k)`` order.
    """
    k = x.shape[-1]
    d = jnp.hypot(x, y)
    counts = [(r[..., i] > 0) & (d[..., i] - r[..., i] < 1.0) for i in range(k)]
    dist = {}
    for i, j in _pairs(k):
        dist[i, j] = jnp.hypot(x[..., i] - x[..., j], y[..., i] - y[..., j])
        i_in_j = (r[..., j] > 0) & (dist[i, j] + r[..., i] <= r[..., j])  # disk i in closed disk j
        j_in_i = (r[..., i] > 0) & (dist[i, j] + r[..., j] <= r[..., i])
        counts[i] = counts[i] & ~(i_in_j & ~j_in_i)
        counts[j] = counts[j] & ~j_in_i
    crossings = [jnp.zeros(x.shape[:-1], jnp.int32) for _ in range(k)]
    cross = []
    for i, j in _pairs(k):
        cij = counts[i] & counts[j] & (dist[i, j] < r[..., i] + r[..., j])
        crossings[i] = crossings[i] + cij
        crossings[j] = crossings[j] + cij
        cross.append(cij)
    counts = jnp.stack(counts, -1)
    multiple = jnp.any(jnp.stack(crossings, -1) > 1, axis=-1)
    inner = counts & (1.0 - d - r >= INNER_MARGIN * r) & star.smooth
    g, phi1 = star.radial_kernel()
    terms = inner_disk_deficit(d, jnp.where(inner, r, 0.0), g) / (2.0 * jnp.pi * phi1)
    inner_sum = jnp.sum(jnp.where(inner, terms, 0.0), axis=-1)
    cross = jnp.stack(cross, -1) if cross else jnp.zeros(x.shape[:-1] + (0,), bool)
    return multiple, counts, inner, inner_sum, cross


def auto_frames(star: Star, x: np.ndarray, y: np.ndarray, r: np.ndarray, order: int, chunk: int) -> np.ndarray:
    """Relative flux of frames ([frame, disk] host arrays) modelling no more
    than each needs (``_survey``): one-disk terms (the midpoint rule well
    inside the star, the general rule elsewhere), the lens of each crossing
    pair by the fewest Gauss-Legendre nodes that converge at its ``lens_rho``
    (LENS_RULES), and the union integral only for the frames left: a disk
    crossing two others, a lens at the limb, or any overlap on a star with a
    piecewise (kinked) table. Calls with fewer than LENS_MIN_PAIRS crossing
    pairs send those frames to the union integral as well (compilation)."""
    survey = _run_padded(lambda s, a, b, c, o: _survey(s, a, b, c), star, x, y, r, 0, chunk)
    multiple, counts, inner, inner_sum, cross = survey
    n, k = x.shape
    general = multiple.astype(bool)
    out = 1.0 - inner_sum
    fp, pp = np.nonzero(cross)
    if fp.size and (not star.smooth or fp.size < LENS_MIN_PAIRS):
        general[fp] = True
    elif fp.size:
        pair = _gather_pairs((x, y, r), fp, pp, k)
        rho = _run_padded(lambda s, a, b, c, o: _lens_rho(a, b, c), None, *pair, 0, chunk)
        # the fewest nodes whose rule converges at this rho; -1: none does
        tier = np.select([rho >= rho_min for _, rho_min in LENS_RULES], list(range(len(LENS_RULES))), -1)
        general[fp[tier < 0]] = True
        # one gather puts the pairs of each tier next to each other
        order_ = np.argsort(tier, kind="stable")
        edges = np.searchsorted(tier[order_], np.arange(-1, len(LENS_RULES) + 1))
        pair = tuple(v[order_] for v in pair)
        lens = np.zeros(fp.size, x.dtype)
        for t, (nodes, _) in enumerate(LENS_RULES):
            lo, hi = edges[t + 1], edges[t + 2]
            if hi > lo:
                lens[lo:hi] = _run_padded(_lens_terms, star, *(v[lo:hi] for v in pair), nodes, chunk)
        out += np.bincount(fp[order_], weights=lens, minlength=n)
    # counting disks outside the midpoint rule's domain: the general one-disk rule
    fd, kd = np.nonzero(counts & ~inner & ~general[:, None])
    if fd.size:
        terms = _per_disk(_disk_terms, star, np.hypot(x[fd, kd], y[fd, kd]), r[fd, kd], order, chunk)
        out -= np.bincount(fd, weights=terms, minlength=n)
    idx = np.nonzero(general)[0]
    if idx.size:
        out[idx] = _run_padded(_exact_frames, star, x[idx], y[idx], r[idx], order, chunk)
    return out


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
    """Run a frame kernel over [frame, disk] arrays in calls of a few fixed
    sizes (``_padded_calls``: so repeated calls reuse compilations), padded to
    a multiple of the device count and sharded over devices."""
    n = x.shape[0]
    if n == 0:
        return jnp.zeros(0, x.dtype)
    concrete = _is_concrete(x, y, r, *jax.tree_util.tree_leaves(star))
    x, y, r = (np.asarray(v) for v in (x, y, r)) if concrete else (x, y, r)
    xp = np if concrete else jnp
    outs = []
    for start, stop, size in _padded_calls(n, chunk):
        xs, ys, rs = x[start:stop], y[start:stop], r[start:stop]
        m = stop - start
        pad = size - m
        if pad:
            # Padding frames: disks far off the star cost nothing and are dropped.
            kk = xs.shape[1]
            xs = xp.concatenate([xs, xp.full((pad, kk), 10.0, xs.dtype) + xp.arange(kk, dtype=xs.dtype)], 0)
            ys = xp.concatenate([ys, xp.zeros((pad, kk), ys.dtype)], 0)
            rs = xp.concatenate([rs, xp.full((pad, kk), 0.1, rs.dtype)], 0)
        xs, ys, rs = _shard(tuple(jnp.asarray(v) for v in (xs, ys, rs)))
        res = fn(star, xs, ys, rs, order)
        outs.append(jax.tree_util.tree_map(lambda v: np.asarray(v)[:m] if concrete else v[:m], res))
    cat = np.concatenate if concrete else jnp.concatenate
    return jax.tree_util.tree_map(lambda *v: cat(v), *outs)


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
            nothing; disks off the star or inside another disk are dropped;
            where each disk crosses at most one other, the flux is the sum of
            one-disk terms minus the lens of each crossing pair (a midpoint
            rule for disks well inside the star, Gauss-Legendre on lenses
            where ``lens_rho`` says it converges); only the remaining frames
            (three disks meeting, lenses at the limb) run the union integral.
            Its error is the same as ``"exact"``'s (both ~4e-12 at worst,
            measured). Piecewise-table stars take the union integral for every
            overlap. Under ``jit``/``grad`` (traced
            inputs) ``"auto"`` evaluates the union integral for every frame.
            ``"raster"`` is the pixel-grid method.
        order: Gauss-Legendre nodes per arc piece (24: worst measured error
            ~1e-11 in float64 over adversarial scenes; 20 is ~5e-11).
        chunk: frames per compiled batch (bounds memory).
        raster: ``RasterSettings`` for ``method="raster"`` (default: windowed,
            pixel scale = smallest radius / 24, 4 x 4 supersampling).

    Returns:
        Relative flux, shape = the broadcast leading axes (1 per frame when
        the disk axis is empty; an empty array when there are no frames).

    float32: when JAX's x64 is off every input is float32; the first call
    in a process then warns once (docs/methods.md, float32 policy). With x64
    on, float32 inputs (explicitly float32 arrays and star) run in float32.

    Bad input: concrete arrays with a non-finite value, a negative radius or
    a radius above ``MAX_RADIUS`` (1e6) raise ``ValueError`` naming x, y or r.
    Under ``jit``/``grad``/``vmap`` (traced input) such a frame's flux is NaN
    (and so is its gradient), never a finite plausible value, so that an
    optimiser or sampler sees it; the exact and union methods do this per
    frame, so one bad frame does not poison a batch.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    _warn_float32_once()
    if not isinstance(star, Star):
        raise ValueError(f"star must be a jaxppo.Star, got {type(star).__name__}")
    for name, value in (("order", order), ("chunk", chunk)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"{name} must be a positive integer, got {value!r}")
    x, y, r = _prepare(x, y, r)
    lead = x.shape[:-1]
    k = x.shape[-1]
    if k == 0 or x.size == 0:
        # no disks: the star unocculted; no frames: nothing to compute
        if _is_concrete(x, y, r):
            _validate_concrete(x, y, r)
        return jnp.ones(lead, x.dtype)
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
    return jnp.asarray(auto_frames(star, xf, yf, rf, order, chunk).reshape(lead))
