""""auto"'s planner: which frames need which rule (``_survey``), the host
plan over concrete frames (``auto_frames``, ``one_disk_sum``), the padded,
sharded calls that run it (``run_padded``, ``_shard``), and the plan that
traced code carries (``traced_auto_frames``). Used by ``occultation_flux``
and by the sweep."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

from ._programs import stored
from ._star import Star
from ._terms import column_terms, exact_frames, lens_rho_jit, lens_terms
from ..core.centre import centre_split
from ..core.geometry import safe_hypot
from ..core.occult import INNER_MARGIN, LENS_RULES, MAX_RADIUS, disk_deficit, inner_disk_deficit, lens_deficit, lens_rho, union_deficit


def is_concrete(*arrays) -> bool:
    """True when none of ``arrays`` is a JAX tracer (the call is eager, so
    the host can plan on their values)."""
    return not any(isinstance(a, jax.core.Tracer) for a in arrays)


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
    for mask, is_inner in ((inner, True), (rest, False)):
        idx = np.nonzero(mask)[0]
        if idx.size:
            terms[idx] = _per_disk(is_inner, star, flat_d[idx], flat_r[idx], order, chunk)
    return 1.0 - terms.reshape(d.shape).sum(-1)


def _per_disk(is_inner: bool, star: Star, d: np.ndarray, p: np.ndarray, order: int, chunk: int) -> np.ndarray:
    """One-disk terms (the midpoint rule where ``is_inner``, else the
    general rule) over host arrays of disks, in the padded calls of
    ``run_padded`` (padding disks lie off the star; ``column_terms`` gets d
    in the x slot, and the y slot is unused)."""
    col = d[:, None]
    kernel = functools.partial(column_terms, inner=is_inner)
    return run_padded(kernel, star, col, col, p[:, None], order, chunk)


@functools.lru_cache(maxsize=None)
def _pairs(k: int) -> np.ndarray:
    """The unordered pairs (i < j) of k disks, [pair, 2]."""
    return np.array([(i, j) for i in range(k) for j in range(i + 1, k)], int).reshape(-1, 2)


@stored
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
    d = safe_hypot(x, y)  # finite gradient for a disk centred on the star
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
    # disks outside the rule's domain get a harmless (d, p) = (0.5, 0), so
    # that under grad their masked-out terms (possibly NaN off the star)
    # cannot turn a zero cotangent into NaN
    # centred disks: d = 0 here, their curvature is added by traced_auto_frames
    # (centre_split; the host plan takes no derivatives)
    d_in, _ = centre_split(x, y, r, star.radial_intensity())
    terms = inner_disk_deficit(jnp.where(inner, d_in, 0.5), jnp.where(inner, r, 0.0), g) / (2.0 * jnp.pi * phi1)
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
    survey = run_padded(lambda s, a, b, c, o: _survey(s, a, b, c), star, x, y, r, 0, chunk)
    multiple, counts, inner, inner_sum, cross = survey
    n, k = x.shape
    general = multiple.astype(bool)
    out = 1.0 - inner_sum
    fp, pp = np.nonzero(cross)
    if fp.size and (not star.smooth or fp.size < LENS_MIN_PAIRS):
        general[fp] = True
    elif fp.size:
        pair = _gather_pairs((x, y, r), fp, pp, k)
        rho = run_padded(lambda s, a, b, c, o: lens_rho_jit(a, b, c), None, *pair, 0, chunk)
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
                lens[lo:hi] = run_padded(lens_terms, star, *(v[lo:hi] for v in pair), nodes, chunk)
        out += np.bincount(fp[order_], weights=lens, minlength=n)
    # counting disks outside the midpoint rule's domain: the general one-disk rule
    fd, kd = np.nonzero(counts & ~inner & ~general[:, None])
    if fd.size:
        terms = _per_disk(False, star, np.hypot(x[fd, kd], y[fd, kd]), r[fd, kd], order, chunk)
        out -= np.bincount(fd, weights=terms, minlength=n)
    idx = np.nonzero(general)[0]
    if idx.size:
        out[idx] = run_padded(exact_frames, star, x[idx], y[idx], r[idx], order, chunk)
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


def to_host(v) -> np.ndarray:
    """A result as a numpy array on this process. With several JAX
    processes (``jax.distributed.initialize``) the frames of a sharded
    result lie on other processes' devices too: every process gathers the
    whole array (``multihost_utils.process_allgather``), so each holds the
    same numbers as one process would."""
    if isinstance(v, jax.Array) and not v.is_fully_addressable:
        from jax.experimental import multihost_utils

        return np.asarray(multihost_utils.process_allgather(v, tiled=True))
    return np.asarray(v)


def run_padded(fn, star, x, y, r, order, chunk: int):
    """Run a frame kernel over [frame, disk] arrays in calls of a few fixed
    sizes (``_padded_calls``: so repeated calls reuse compilations), padded to
    a multiple of the device count and sharded over devices."""
    n = x.shape[0]
    if n == 0:
        return jnp.zeros(0, x.dtype)
    concrete = is_concrete(x, y, r, *jax.tree_util.tree_leaves(star))
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
        # host arrays go to the program as they are (jnp.asarray would run
        # one device program per array on an eager call)
        xs, ys, rs = _shard((xs, ys, rs) if concrete else tuple(jnp.asarray(v) for v in (xs, ys, rs)))
        res = fn(star, xs, ys, rs, order)
        outs.append(jax.tree_util.tree_map(lambda v: to_host(v)[:m] if concrete else v[:m], res))
    cat = np.concatenate if concrete else jnp.concatenate
    return jax.tree_util.tree_map(lambda *v: cat(v), *outs)


# Overlap frames per call below which the sweep and the marginalised scan
# send them all to the union integral, in calls of OVERLAP_CALL frames: one
# compiled program serves every call (the scan's blocks included), where the
# lens path's programs (survey, lens_rho, three lens tiers, one-disk rule, at
# each padded size) cost ~0.1-1 s each to trace and compile per process, and
# would save ~3 us per frame.
OVERLAP_LENS_MIN = 65536
OVERLAP_CALL = 1024


def overlap_flux(star, x, y, r, order: int, chunk: int) -> np.ndarray:
    """Flux of frames known to contain an overlapping pair: fewer than
    OVERLAP_LENS_MIN (a grid of one system has hundreds to tens of
    thousands) go to the union integral in calls of one padded size, more
    through "auto"."""
    n = x.shape[0]
    if n >= OVERLAP_LENS_MIN:
        return auto_frames(star, x, y, r, order, chunk)
    if n == 0:
        return np.zeros(0, x.dtype)
    size = min(OVERLAP_CALL, chunk)
    pad = -n % size
    if pad:
        # padding frames: disks far off the star (cost the same, dropped)
        k = x.shape[1]
        x = np.concatenate([x, np.full((pad, k), 10.0) + np.arange(k)])
        y = np.concatenate([y, np.zeros((pad, k))])
        r = np.concatenate([r, np.full((pad, k), 0.1)])
    return np.asarray(run_padded(exact_frames, star, x, y, r, order, size))[:n]


# Entries per block of the compacted calls of ``traced_auto_frames``: the
# union integral (~3.5 us per frame) in blocks of 256 frames, the cheaper
# one-disk and lens rules in blocks of 1024; at most one block's padding is
# wasted per call.
UNION_BLOCK = 256
TERM_BLOCK = 1024


@jax.custom_batching.custom_vmap
def shared_branch(branch: Array) -> Array:
    """The rule each block of ``_compacted`` runs ([block] ints). Batched by
    ``vmap``, every member of the batch runs, per block, the highest rule
    any member needs (the rules are ordered so that a higher one is also
    exact where a lower one is; free slots hold harmless pads): the switch
    index stays unbatched, so ``lax.switch`` stays a switch (a batched index
    would turn it into a select that runs every rule on every block, and
    one whose derivative JAX cannot transpose, jax-ml/jax#39219)."""
    return branch


@shared_branch.def_vmap
def _shared_branch_batched(axis_size, in_batched, branch):
    del axis_size, in_batched
    return jnp.max(branch, axis=0), False


def _compacted(fns, level: Array, args, pads, block: int, dtype) -> Array:
    """``fns[level](*args)`` ([entry, ...] arrays -> [entry]) at the entries
    with ``level`` >= 0 (traced [entry] ints), 0 elsewhere, with static
    shapes: the entries are packed to the front in order of level (cumulative
    sums, no sort) into blocks of ``block`` entries, and each block runs,
    by ``lax.switch``, the rule of the highest level it holds (the rules are
    ordered so that a higher one is also exact where a lower one is), or
    nothing past the last entry. Free slots take the harmless ``pads``
    entries (never another entry's value, so that no NaN can leak into a
    gradient). Under ``vmap`` every member runs the highest rule any member
    needs in that block (``shared_branch``)."""
    m = level.shape[0]
    block = max(1, min(block, m))
    nb = -(-m // block)
    slots = nb * block
    pos = jnp.full(m, slots, jnp.int32)
    offset = jnp.zeros((), jnp.int32)
    for lv in range(len(fns)):
        hit = level == lv
        run = jnp.cumsum(hit.astype(jnp.int32))
        pos = jnp.where(hit, offset + run - 1, pos)
        offset = offset + run[-1]
    idx = jnp.full(slots, m, jnp.int32).at[pos].set(jnp.arange(m, dtype=jnp.int32), mode="drop")
    valid = idx < m
    take = jnp.minimum(idx, m - 1)
    packed = []
    for a, pad in zip(args, pads):
        v = jnp.where(valid.reshape((-1,) + (1,) * (a.ndim - 1)), a[take], jnp.asarray(pad, a.dtype))
        packed.append(v.reshape((nb, block) + a.shape[1:]))
    branch = shared_branch(jnp.max(jnp.where(valid, level[take], -1).reshape(nb, block), axis=1) + 1)
    branches = [lambda b: jnp.zeros(block, dtype)] + [lambda b, f=f: f(*b).astype(dtype) for f in fns]

    def body(_, xs):
        return None, jax.lax.switch(xs[0], branches, xs[1:])

    _, vals = jax.lax.scan(body, None, (branch, *packed))
    return jnp.zeros(m, dtype).at[idx].set(vals.reshape(-1), mode="drop")


@functools.partial(jax.jit, static_argnames=("order",))
def traced_auto_frames(star: Star, x: Array, y: Array, r: Array, order: int) -> Array:
    """``auto_frames`` for traced [frame, disk] arrays (inside ``jit``,
    ``grad``, ``vmap``): the same rules on the same frames, planned on the
    device. ``_survey`` classifies every frame and sums the midpoint-rule
    terms; the general one-disk rule, each lens tier (LENS_RULES, by
    ``lens_rho``) and the union integral then run only on the entries that
    need them (``_compacted``), so a frame costs what its cheapest exact
    rule costs plus a few passes over the frame axis. Bad input (non-finite,
    negative radius, radius above MAX_RADIUS) goes to the union integral,
    which makes that frame NaN.

    Jitted: ``grad``, ``vmap`` and ``jvp`` of a caller then transform this
    plan's jaxpr (traced once per shape, star and order) instead of running
    its Python again under each transformation; a new caller's first trace
    and lowering took half the time (the same numbers, bit for bit)."""
    n, k = x.shape
    dtype = x.dtype
    g, phi1 = star.radial_kernel()
    inten = star.radial_intensity()
    norm = 2.0 * jnp.pi * phi1
    # optimization barriers: each stage's masks are computed once (XLA would
    # otherwise fuse, say, lens_rho into each of its consumers and evaluate
    # it several times: measured 1.5x the whole cost)
    multiple, counts, inner, inner_sum, cross = jax.lax.optimization_barrier(_survey(star, x, y, r))
    d_in, centre = centre_split(x, y, r, inten)
    ok = jnp.isfinite(x) & jnp.isfinite(y) & jnp.isfinite(r) & (r >= 0) & (r <= MAX_RADIUS)
    union = multiple | ~jnp.all(ok, axis=-1)
    out = 1.0 - inner_sum
    pairs = _pairs(k)
    if pairs.size:
        px, py, pr = (v[:, pairs].reshape(-1, 2) for v in (x, y, r))  # [frame * pair, 2]
        flat_cross = cross.reshape(-1)
        if star.smooth:
            # a crossing pair well inside the star fills the free slots
            pad = (np.array([0.0, 0.01]), np.zeros(2), np.full(2, 0.01))
            rho = _compacted([lens_rho], jnp.where(flat_cross, 0, -1), (px, py, pr), pad, TERM_BLOCK, dtype)
            tier = jnp.select([rho >= rho_min for _, rho_min in LENS_RULES], list(range(len(LENS_RULES))), -1)
            union = union | jnp.any((cross & (tier < 0).reshape(n, -1)), axis=-1)
            tier, union = jax.lax.optimization_barrier((tier, union))
            use = flat_cross & ~jnp.repeat(union, len(pairs))
            lens = _compacted(
                [lambda a, b, c, nodes=nodes: lens_deficit(a, b, c, g, nodes, inten) / norm for nodes, _ in LENS_RULES],
                jnp.where(use, tier, -1), (px, py, pr), pad, TERM_BLOCK, dtype,
            )
            out = jax.lax.optimization_barrier(out + lens.reshape(n, -1).sum(-1))
        else:
            # kinks of a piecewise table: every overlap by the union integral
            union = union | jnp.any(cross, axis=-1)
    general = (counts & ~inner & ~union[:, None]).reshape(-1)
    one = _compacted(
        [lambda dd, pp: jax.vmap(lambda a, b: disk_deficit(a, b, g, phi1, order, inten))(dd, pp) / norm],
        jnp.where(general, 0, -1), (d_in.reshape(-1), r.reshape(-1)), (10.0, 0.1), TERM_BLOCK, dtype,
    )
    # one-disk terms see the centre through d alone: at and next to d = 0
    # their second derivatives come from centre_split's extra term
    out = out - jnp.sum(jnp.where(counts & ~union[:, None], centre, 0.0), axis=-1) / norm
    out = jax.lax.optimization_barrier(out - one.reshape(n, k).sum(-1))
    pad = (10.0 + np.arange(k), np.zeros(k), np.full(k, 0.1))
    whole = _compacted(
        [lambda a, b, c: 1.0 - jax.vmap(lambda u, v, w: union_deficit(u, v, w, g, phi1, order, inten))(a, b, c) / norm],
        jnp.where(union, 0, -1), (x, y, r), pad, UNION_BLOCK, dtype,
    )
    return jnp.where(union, whole, out)
