"""Transit fits: optimistix Levenberg-Marquardt and numpyro NUTS over named
free parameters ("b.t0", "c.radius", "star.u1", ...), in coordinates that keep
the physics valid: a = 1 + exp(.), p = exp(.), P = exp(.), and the impact
parameter b = (1 + p) tanh(.) (so |b| < 1 + p and the planet always transits),
with i = arccos(b / a).

Besides the planets' and the star's parameters:

* ``"star.q1"``, ``"star.q2"`` (quadratic star): Kipping (2013, eqs. 15-16)
  limb darkening, u1 = 2 sqrt(q1) q2, u2 = sqrt(q1) (1 - 2 q2); q in (0, 1)
  through a logistic map, so that every draw is a physical profile;
* ``"lc.offset"``: a multiplicative flux normalisation c, model = (1 + c) F;
* ``"lc.jitter"``: s [relative flux] added in quadrature to every error,
  sigma_i^2 -> sigma_i^2 + s^2 (coordinate log s); the objective is then the
  full -2 ln L, not chi^2;
* ``"lc.baseline"`` / ``"lc.baseline2"``: a linear / quadratic polynomial per
  data window (windows: runs of points separated by gaps > ``BASELINE_GAP``),
  multiplicative, model = F (1 + c0 + c1 x + c2 x^2) with x in [-1, 1] across
  the window; expands to the names "lc.baseline.w<window>.c<power>".
"""

from __future__ import annotations

import dataclasses
import json
import sys
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..model._lightcurve import LightCurve
from ..model._system import Planet, System

__all__ = ["fit", "FitResult", "Model", "parameter_names", "kipping_u", "kipping_q"]

_PLANET_PARAMS = ("t0", "period", "a", "inc", "radius")
_STAR_PARAMS = {"quadratic": ("u1", "u2"), "nonlinear": ("c1", "c2", "c3", "c4"), "power2": ("c", "alpha")}
_LC_PARAMS = ("offset", "jitter", "baseline", "baseline2")
# [d] a gap longer than this starts a new baseline window (Kepler quarters,
# the multi-transit windows of a scan)
BASELINE_GAP = 0.5
# fit warns when the condition number of the scaled Fisher matrix exceeds
# this: some combination of the free parameters is 1e3 times less determined
# than the parameters one by one, and the linearised errors mislead
CONDITION_WARN = 1e6


def kipping_u(q1, q2):
    """(u1, u2) of the quadratic law from Kipping's (2013, eqs. 15-16)
    q1, q2 in [0, 1]: u1 = 2 sqrt(q1) q2, u2 = sqrt(q1) (1 - 2 q2)."""
    s = jnp.sqrt(q1)
    return 2.0 * s * q2, s * (1.0 - 2.0 * q2)


def kipping_q(u1, u2):
    """Inverse of :func:`kipping_u`: q1 = (u1 + u2)^2, q2 = u1 / (2 (u1 + u2))
    (Kipping 2013, eqs. 17-18); q2 = 0.5 when u1 + u2 = 0."""
    s = u1 + u2
    return s**2, jnp.where(s == 0, 0.5, u1 / (2.0 * jnp.where(s == 0, 1.0, s)))


def _as_lightcurve(lightcurve) -> LightCurve:
    """A jaxppo LightCurve from a LightCurve or a lightkurve LightCurve."""
    if isinstance(lightcurve, LightCurve):
        return lightcurve
    from ..model._lightcurve import is_lightkurve

    if is_lightkurve(lightcurve):
        return LightCurve.from_lightkurve(lightcurve)
    raise ValueError(f"lightcurve must be a jaxppo.LightCurve or a lightkurve LightCurve, got "
                     f"{type(lightcurve).__name__} (arrays and astropy Time/Quantity columns: "
                     "jaxppo.LightCurve(time, flux, flux_err) or LightCurve.from_arrays)")


def parameter_names(system: System) -> list[str]:
    """All names ``fit`` and ``sample`` accept for this system ("lc.baseline"
    and "lc.baseline2" expand to one name per window and power)."""
    names = []
    for i, pl in enumerate(system.planets):
        label = pl.name or str(i)
        names += [f"{label}.{p}" for p in _PLANET_PARAMS]
    names += [f"star.{p}" for p in _STAR_PARAMS.get(system.star.law, ())]
    if system.star.law == "quadratic":
        names += ["star.q1", "star.q2"]
    names += [f"lc.{p}" for p in _LC_PARAMS]
    return names


def _split(name: str, system: System):
    if not isinstance(name, str) or "." not in name:
        raise ValueError(f"free parameter {name!r} must look like 'b.t0' or 'star.u1'")
    owner, par = name.split(".", 1)
    if owner == "star":
        pars = _STAR_PARAMS.get(system.star.law, ())
        if par in ("q1", "q2"):
            if system.star.law != "quadratic":
                raise ValueError(f"free parameter {name!r}: Kipping's q1, q2 need a quadratic star, "
                                 f"this one is {system.star.law}")
            return "star", par
        if par not in pars:
            extra = " (or q1, q2)" if system.star.law == "quadratic" else ""
            raise ValueError(f"free parameter {name!r}: a {system.star.law} star has {pars}{extra}")
        return "star", pars.index(par)
    if owner == "lc":
        if par not in _LC_PARAMS:
            raise ValueError(f"free parameter {name!r}: light-curve parameters are {_LC_PARAMS}")
        return "lc", par
    idx = None
    for i, pl in enumerate(system.planets):
        if (pl.name or str(i)) == owner:
            idx = i
    if idx is None:
        raise ValueError(f"free parameter {name!r}: no planet named {owner!r}; names are {[p.name for p in system.planets]}")
    if par not in _PLANET_PARAMS:
        raise ValueError(f"free parameter {name!r}: planet parameters are {_PLANET_PARAMS}")
    return idx, par


def _baseline_windows(time: np.ndarray) -> list[np.ndarray]:
    """Index arrays of the runs of points separated by gaps > BASELINE_GAP."""
    cuts = np.nonzero(np.diff(time) > BASELINE_GAP)[0] + 1
    return np.split(np.arange(time.size), cuts)


def _expand(free, system: System, time: np.ndarray):
    """(names, slots, basis): "lc.baseline[2]" expanded per window and
    power; ``basis`` [n, m] holds the columns of the multiplicative trend
    (offset: ones; baseline: x^k per window) in the order of the trend
    slots."""
    names, slots, cols = [], [], []
    windows = None
    for n in free:
        owner, par = _split(n, system)
        if owner == "lc" and par in ("baseline", "baseline2"):
            windows = _baseline_windows(time) if windows is None else windows
            order = 1 if par == "baseline" else 2
            for w, idx in enumerate(windows):
                tw = time[idx]
                mid, half = 0.5 * (tw[0] + tw[-1]), 0.5 * (tw[-1] - tw[0])
                x = (tw - mid) / half if half > 0 else np.zeros(tw.size)
                for k in range(order + 1):
                    col = np.zeros(time.size)
                    col[idx] = x**k
                    names.append(f"lc.baseline.w{w}.c{k}")
                    slots.append(("lc", ("baseline", w, k)))
                    cols.append(col)
        else:
            names.append(n)
            slots.append((owner, par))
            if (owner, par) == ("lc", "offset"):
                cols.append(np.ones(time.size))
    pars = {p for o, p in slots if o == "lc" and not isinstance(p, tuple)}
    if "offset" in pars and any(isinstance(p, tuple) for o, p in slots if o == "lc"):
        raise ValueError("free parameters 'lc.offset' and 'lc.baseline' are degenerate (each window's baseline "
                         "has its own constant term c0): name one of them")
    if sum(1 for n in free if n.startswith("lc.baseline")) > 1:
        raise ValueError(f"free parameters name the baseline twice: {[n for n in free if n.startswith('lc.baseline')]}")
    star = {p for o, p in slots if o == "star"}
    if star & {"q1", "q2"} and star & {0, 1}:
        raise ValueError("free parameters name both u1/u2 and q1/q2 of the star: name one pair "
                         "(q1, q2 is Kipping's 2013 reparameterisation of u1, u2)")
    basis = np.stack(cols, axis=1) if cols else np.zeros((time.size, 0))
    return tuple(names), slots, basis


def _is_trend(slot) -> bool:
    owner, par = slot
    return owner == "lc" and (par == "offset" or isinstance(par, tuple))


def _jitter_start(sigma) -> float:
    """Starting jitter [relative flux]: a tenth of the median error (the
    coordinate is log s, so it cannot start at 0)."""
    return 0.1 * float(np.median(np.asarray(sigma)))


class Model:
    """Maps an unconstrained vector theta to a System and a light curve.

    The exposure of the data (if any) is modelled by averaging the flux over
    ``nsub`` sub-exposures.
    """

    def __init__(self, system: System, lc: LightCurve, free, alpha: float = 0.0, case: str = "same"):
        free = (free,) if isinstance(free, str) else tuple(free)
        if not free:
            raise ValueError("free must name at least one parameter, e.g. ('b.t0', 'b.radius')")
        if len(set(free)) != len(free):
            raise ValueError(f"free parameters repeat: {free}")
        lc = _as_lightcurve(lc)
        self.system, self.lc, self.requested = system, lc, free
        self.alpha, self.case = alpha, case
        self.union_floor = 0  # see _Data.build
        # ``free``: the names of the fitted values (baseline expanded)
        self.free, self.slots, self.basis = _expand(free, system, np.asarray(lc.time))
        self.jitter0 = _jitter_start(lc.flux_err)
        t_model, self.nsub = lc.supersampled_times()
        self.t_model = jnp.asarray(t_model)
        # Frames where two disks are on the star and within `margin` [R*] of
        # touching at the starting parameters run the exact union integral;
        # all others are a sum of one-disk terms. The split is fixed for the
        # fit (the margin covers the parameter changes of a fit; ``fit``
        # checks the final geometry and refits with a wider split if needed).
        self.union_idx = self._union_frames(system, t_model)
        # Likewise, only frames where a disk is on the star or within
        # `margin` [R*] of its limb at the start are computed; the others
        # are exactly 1 (and widened like the union frames).
        self.active_idx = self._active_frames(system, t_model)
        self.y = jnp.asarray(lc.flux)
        self.sigma = jnp.asarray(lc.flux_err)

    def _union_frames(self, system, t_model, margin: float = 0.05):
        x, y, r = system.positions(t_model, self.alpha, self.case, xp=np)
        k = x.shape[-1]
        on = np.hypot(x, y) - r < 1.0 + margin
        near = np.zeros(t_model.size, bool)
        for i in range(k):
            for j in range(i + 1, k):
                d = np.hypot(x[:, i] - x[:, j], y[:, i] - y[:, j])
                near |= on[:, i] & on[:, j] & (d < r[:, i] + r[:, j] + margin)
        return np.nonzero(near)[0]

    def _active_frames(self, system, t_model, margin: float = 0.25):
        x, y, r = system.positions(t_model, self.alpha, self.case, xp=np)
        return np.nonzero(np.any((r > 0) & (np.hypot(x, y) < 1.0 + r + margin), axis=-1))[0]

    def widened(self, systems) -> "Model | None":
        """A new Model (traced anew) whose union-integral frames also cover
        the frames where any of ``systems`` brings disks within the margin of
        touching, and whose computed frames cover every frame where they put
        a disk within 0.05 R* of the star; None when the current frames
        cover them already."""
        t = np.asarray(self.t_model)
        needed = np.unique(np.concatenate([self.union_idx] + [self._union_frames(s, t) for s in systems]))
        active = np.unique(np.concatenate([self.active_idx] + [self._active_frames(s, t, 0.05) for s in systems]))
        if np.all(np.isin(needed, self.union_idx)) and np.all(np.isin(active, self.active_idx)):
            return None
        wider = Model(self.system, self.lc, self.requested, self.alpha, self.case)
        wider.union_floor = self.union_floor
        wider.union_idx = np.union1d(wider.union_idx, needed)
        wider.active_idx = np.union1d(np.union1d(wider.active_idx, active), wider.union_idx)
        return wider

    # ---- coordinates ----------------------------------------------------------
    def to_theta(self, system: System) -> jnp.ndarray:
        out = []
        for (owner, par) in self.slots:
            if owner == "lc":
                out.append(jnp.log(self.jitter0) if par == "jitter" else 0.0)
                continue
            if owner == "star":
                if par in ("q1", "q2"):
                    q = kipping_q(system.star.params[0], system.star.params[1])[0 if par == "q1" else 1]
                    out.append(_logit(q))
                else:
                    out.append(system.star.params[par])
                continue
            pl = system.planets[owner]
            if par == "t0":
                out.append(pl.t0)
            elif par == "period":
                out.append(jnp.log(pl.period))
            elif par == "a":
                out.append(jnp.log(pl.a - 1.0))
            elif par == "radius":
                out.append(jnp.log(pl.radius))
            else:  # inc -> b = (1 + p) tanh(theta)
                b = pl.a * jnp.cos(jnp.deg2rad(pl.inc))
                out.append(jnp.arctanh(jnp.clip(b / (1.0 + pl.radius), -0.999999, 0.999999)))
        return jnp.stack([jnp.asarray(v, float) for v in out])

    def to_system(self, theta) -> System:
        return _to_system(theta, self.system, tuple(self.slots))

    def theta_from(self, values, theta_ref=None) -> jnp.ndarray:
        """Unconstrained theta from parameter values in physical units, except
        that an inclination may be given either in degrees (``theta_ref``
        supplies a and p when they are not free) or, with ``theta_ref=None``,
        as the impact parameter in units of (1 + p) (what ``sample`` draws)."""
        ref = self.to_system(theta_ref) if theta_ref is not None else None
        named = {slot: values[k] for k, slot in enumerate(self.slots)}
        out = []
        for k, (owner, par) in enumerate(self.slots):
            v = values[k]
            if par in ("q1", "q2"):
                out.append(_logit(v))
            elif par == "jitter":
                out.append(jnp.log(v))
            elif owner in ("star", "lc") or par == "t0":
                out.append(v)
            elif par == "period":
                out.append(jnp.log(v))
            elif par == "a":
                out.append(jnp.log(v - 1.0))
            elif par == "radius":
                out.append(jnp.log(v))
            elif ref is None:
                out.append(jnp.arctanh(jnp.clip(v, -1 + 1e-12, 1 - 1e-12)))
            else:
                pl = ref.planets[owner]
                a = named.get((owner, "a"), pl.a)
                p = named.get((owner, "radius"), pl.radius)
                out.append(jnp.arctanh(a * jnp.cos(jnp.deg2rad(v)) / (1.0 + p)))
        return jnp.stack(out)

    def physical(self, theta) -> jnp.ndarray:
        """The free parameters in physical units (days, degrees, R*;
        q1, q2; offset, jitter [relative flux], baseline coefficients)."""
        sysm = self.to_system(theta)
        out = []
        for k, (owner, par) in enumerate(self.slots):
            if par in ("q1", "q2"):
                out.append(jax.nn.sigmoid(theta[k]))
            elif par == "jitter":
                out.append(jnp.exp(theta[k]))
            elif owner == "lc":
                out.append(theta[k])
            else:
                out.append(sysm.star.params[par] if owner == "star" else getattr(sysm.planets[owner], par))
        return jnp.stack(out)

    def derived_names(self) -> tuple:
        """Quantities implied by the free parameters: "star.u1", "star.u2"
        when Kipping's q1 or q2 is free."""
        return ("star.u1", "star.u2") if any(p in ("q1", "q2") for _, p in self.slots) else ()

    def derived(self, theta) -> jnp.ndarray:
        """Values of :meth:`derived_names` at theta."""
        if not self.derived_names():
            return jnp.zeros(0)
        return self.to_system(theta).star.params[:2]

    # ---- model ----------------------------------------------------------------
    def data(self) -> "_Data":
        """The arrays the compiled model functions take as traced inputs
        (rebuilt when the frame sets change). Every Model with the same
        structure and frame counts reuses one compilation."""
        key = (self.union_idx, self.active_idx)
        cached = getattr(self, "_data_cache", None)
        if cached is None or cached[0][0] is not key[0] or cached[0][1] is not key[1]:
            # concrete arrays even when first asked for inside a trace (a
            # tracer kept here would leak into later calls)
            with jax.ensure_compile_time_eval():
                cached = (key, _Data.build(self))
            self._data_cache = cached
        return cached[1]

    def flux(self, theta) -> jnp.ndarray:
        """Model flux at the data times, with the offset / baseline trend."""
        d = self.data()
        return _flux(theta, d) * _trend(theta, d)

    def pointwise_loglike(self, theta) -> jnp.ndarray:
        """Gaussian log-likelihood of each data point (jitter included)."""
        return _pointwise_loglike(theta, self.data())

    def residuals(self, theta, args=None) -> jnp.ndarray:
        return _residuals(theta, self.data())

    def scaled_residuals(self, z, args) -> jnp.ndarray:
        """Residuals at theta = theta_ref + z / scale, ``args = (theta_ref,
        scale)``."""
        theta_ref, scale = args
        return _residuals(theta_ref + z / scale, self.data())

    def chi2_batch(self, thetas):
        """chi^2 at each row of ``thetas`` (one compiled program)."""
        return _chi2_batch(thetas, self.data())

    def jacobian(self, theta):
        """(d residuals / d theta, residuals), compiled once per structure."""
        return _jacobian(theta, self.data())


def _bucket(n: int) -> int:
    """Padded length for n computed frames: steps of 1/16 of a power of two
    (at most ~6 % extra work), so that widening the frame sets by a few
    frames usually keeps the compiled programs."""
    if n <= 64:
        return max(n, 1)
    step = 1 << max(int(np.floor(np.log2(n))) - 4, 0)
    return int(-(-n // step) * step)


def _pad(idx: np.ndarray, size: int) -> np.ndarray:
    # repeat the last entry: a repeated frame is computed twice and written
    # twice with the same value
    return np.concatenate([idx, np.full(size - idx.size, idx[-1], idx.dtype)]) if idx.size else idx


class _Data(eqx.Module):
    """Everything the model flux needs, as a pytree: arrays are traced (so a
    new light curve, start or frame set of the same sizes does not
    recompile); the structure is static."""

    system: System
    t: jax.Array          # model times of the computed frames [d]
    act: jax.Array        # their positions in the supersampled time grid
    union: jax.Array      # positions (in ``t``) of the union-integral frames
    y: jax.Array
    sigma: jax.Array
    alpha: jax.Array
    basis: jax.Array      # [n, m] columns of the multiplicative trend
    slots: tuple = eqx.field(static=True)
    nsub: int = eqx.field(static=True)
    n_model: int = eqx.field(static=True)
    case: object = eqx.field(static=True)
    eccentric: tuple = eqx.field(static=True, default=())

    @staticmethod
    def build(model: "Model") -> "_Data":
        act = np.union1d(model.active_idx, model.union_idx).astype(np.int64)
        union = np.searchsorted(act, model.union_idx).astype(np.int64)
        act = _pad(act, _bucket(act.size))
        if model.union_floor and act.size:
            # ``fit`` pads the union frames to a power of two (at least
            # ``union_floor``, even when there are none: the union integral
            # is exact, with exact derivatives, for any frame): they are a
            # small share of the work, and a fit that brings disks together
            # adds them at its widenings, which would each recompile
            size = max(model.union_floor, 1 << int(np.ceil(np.log2(max(union.size, 1)))))
            union = np.concatenate([union, np.full(size - union.size, union[-1] if union.size else 0, np.int64)])
        else:
            union = _pad(union, _bucket(union.size))
        case = tuple(model.case) if isinstance(model.case, list) else model.case
        system = jax.tree.map(lambda v: jnp.asarray(v, float) if not isinstance(v, jax.Array) else v, model.system)
        return _Data(system, jnp.asarray(np.asarray(model.t_model)[act]), jnp.asarray(act), jnp.asarray(union),
                     model.y, model.sigma, jnp.asarray(model.alpha, float), jnp.asarray(model.basis, float),
                     tuple(model.slots), int(model.nsub),
                     int(model.t_model.size), case, tuple(not pl.circular for pl in model.system.planets))


def _to_system(theta, base: System, slots, eccentric=None) -> System:
    """The system at theta. ``eccentric`` (static flags per planet; None: take
    e and omega of every planet, for a concrete ``base``) says which planets
    keep their e and omega: inside a traced program ``base``'s leaves are
    tracers, so a circular planet given its traced e = 0 would take the
    slower Keplerian path."""
    planets = [dict(period=p.period, t0=p.t0, a=p.a, inc=p.inc, radius=p.radius, name=p.name) for p in base.planets]
    for k, p in enumerate(base.planets):
        if eccentric is None or eccentric[k]:
            planets[k].update(e=p.e, omega=p.omega)
    star_params = base.star.params
    b_theta, q = {}, {}
    for k, (owner, par) in enumerate(slots):
        v = theta[k]
        if owner == "lc":
            continue
        if par in ("q1", "q2"):
            q[par] = jax.nn.sigmoid(v)
        elif owner == "star":
            star_params = star_params.at[par].set(v)
        elif par == "t0":
            planets[owner]["t0"] = v
        elif par == "period":
            planets[owner]["period"] = jnp.exp(v)
        elif par == "a":
            planets[owner]["a"] = 1.0 + jnp.exp(v)
        elif par == "radius":
            planets[owner]["radius"] = jnp.exp(v)
        else:
            b_theta[owner] = v
    for owner, v in b_theta.items():
        pl = planets[owner]
        b = (1.0 + pl["radius"]) * jnp.tanh(v)
        pl["inc"] = jnp.rad2deg(jnp.arccos(b / pl["a"]))
    if q:
        q1_0, q2_0 = kipping_q(star_params[0], star_params[1])
        u1, u2 = kipping_u(q.get("q1", q1_0), q.get("q2", q2_0))
        star_params = jnp.stack([u1, u2])
    star = dataclasses.replace(base.star, params=star_params)
    return System(star, [Planet(**p) for p in planets], base.tilted)


def _flux(theta, d: _Data) -> jnp.ndarray:
    from ..model._terms import exact_frames, separate_frames

    sysm = _to_system(theta, d.system, d.slots, d.eccentric)
    x, y, r = sysm.positions(d.t, d.alpha, d.case)
    fa = separate_frames(sysm.star, x, y, r, 24)
    if d.union.size:
        u = d.union
        fa = fa.at[u].set(exact_frames(sysm.star, x[u], y[u], r[u], 24))
    f = jnp.ones((d.n_model,), fa.dtype).at[d.act].set(fa)
    return f.reshape(-1, d.nsub).mean(-1)


def _logit(q):
    # q clipped into (0, 1): a start outside Kipping's triangle begins at its edge
    q = jnp.clip(jnp.asarray(q, float), 1e-9, 1.0 - 1e-9)
    return jnp.log(q) - jnp.log1p(-q)


def _trend(theta, d: _Data) -> jnp.ndarray:
    """Multiplicative trend 1 + basis @ c of the offset / baseline slots."""
    idx = [k for k, slot in enumerate(d.slots) if _is_trend(slot)]
    if not idx:
        return jnp.ones(())
    return 1.0 + d.basis @ jnp.stack([theta[k] for k in idx])


def _variance(theta, d: _Data):
    """(sigma^2 + s^2, s^2) with the jitter s when it is free, else (sigma^2, None)."""
    for k, (owner, par) in enumerate(d.slots):
        if par == "jitter":
            s2 = jnp.exp(2.0 * theta[k])
            return d.sigma**2 + s2, s2
    return d.sigma**2, None


@eqx.filter_jit
def _residuals(theta, d: _Data) -> jnp.ndarray:
    """Residuals whose sum of squares is the objective: (y - model) /
    sigma, and with a free jitter s also sqrt(ln(1 + s^2 / sigma_i^2)) per
    point, so that the sum of squares is -2 ln L - sum ln(2 pi sigma_i^2):
    the full likelihood, whose log-variance term keeps s from growing
    without bound (chi^2 alone would be minimised by s -> infinity)."""
    var, s2 = _variance(theta, d)
    model = _flux(theta, d)
    if any(_is_trend(slot) for slot in d.slots):
        model = model * _trend(theta, d)
    if s2 is None:
        return (d.y - model) / d.sigma
    return jnp.concatenate([(d.y - model) / jnp.sqrt(var), jnp.sqrt(jnp.log1p(s2 / d.sigma**2))])


@eqx.filter_jit
def _pointwise_loglike(theta, d: _Data) -> jnp.ndarray:
    var, _ = _variance(theta, d)
    r = d.y - _flux(theta, d) * _trend(theta, d)
    return -0.5 * r**2 / var - 0.5 * jnp.log(2.0 * jnp.pi * var)


def _scaled_residuals(z, args) -> jnp.ndarray:
    """Residuals at theta = theta_ref + z / scale, ``args = (theta_ref,
    scale, data)``: a module-level function with the data as traced inputs,
    so optimistix compiles it once per model structure and frame counts
    (not once per fit, restart or Model)."""
    theta_ref, scale, d = args
    return _residuals(theta_ref + z / scale, d)


@eqx.filter_jit
def _chi2_batch(thetas, d: _Data):
    return jax.lax.map(lambda t: jnp.sum(_residuals(t, d) ** 2), thetas)


@eqx.filter_jit
def _jacobian(theta, d: _Data):
    return jax.jacfwd(lambda th: (_residuals(th, d),) * 2, has_aux=True)(theta)


@dataclasses.dataclass
class FitResult:
    """Best-fit ``system``, ``chi2``, ``covariance`` of the free parameters in
    physical units (``names`` order; "lc.baseline" expanded per window and
    power), ``errors`` (1 sigma), ``success`` and ``message``;
    ``reduced_chi2`` = chi^2 / (N - k). With ``"lc.jitter"`` free, ``chi2``
    is the minimised objective -2 ln L - sum ln(2 pi sigma_i^2) (chi^2 with
    the inflated errors plus sum ln(1 + s^2 / sigma_i^2)), ``reduced_chi2``
    its chi^2 part / (N - k), and the covariance is twice the inverse
    Hessian of the objective (the Gauss-Newton form misses the jitter's
    curvature). ``derived``: name -> (value, 1-sigma error) of implied
    quantities (u1, u2 from Kipping's q1, q2). ``condition``: condition
    number of the Fisher matrix scaled to unit diagonal (above
    ``CONDITION_WARN`` fit warns: the linearised errors are unreliable,
    use :func:`jaxppo.sample`). ``union_frames``: the model frames
    integrated by the exact union integral (overlapping disks at the start
    or at the solution, with a margin)."""

    system: System
    chi2: float
    covariance: np.ndarray
    success: bool
    message: str
    names: tuple
    values: np.ndarray
    errors: np.ndarray
    reduced_chi2: float
    steps: int
    union_frames: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, int))
    derived: dict = dataclasses.field(default_factory=dict)
    condition: float = float("nan")

    def table(self) -> str:
        rows = [f"{n:14s} {v:16.8f} +- {e:.2e}" for n, v, e in zip(self.names, self.values, self.errors)]
        rows += [f"{n:14s} {v:16.8f} +- {e:.2e} (derived)" for n, (v, e) in self.derived.items()]
        return "\n".join(rows + [f"chi2 = {self.chi2:.2f}, reduced {self.reduced_chi2:.3f}, {self.message}"])

    def save(self, path) -> str:
        """Write the result as JSON (format "jaxppo.FitResult", the jaxppo
        version, free names, values, errors, covariance, the fitted system);
        :meth:`load` reads it back exactly (floats are written with 17
        significant digits; NaN as null). Returns the path."""
        from .._version import __version__

        out = {"format": "jaxppo.FitResult", "version": __version__, "names": list(self.names),
               "values": to_jsonable(self.values), "errors": to_jsonable(self.errors),
               "covariance": to_jsonable(self.covariance), "chi2": to_jsonable(self.chi2),
               "reduced_chi2": to_jsonable(self.reduced_chi2), "success": bool(self.success),
               "message": self.message, "steps": int(self.steps),
               "union_frames": [int(i) for i in np.asarray(self.union_frames)],
               "derived": {k: to_jsonable(list(v)) for k, v in self.derived.items()},
               "condition": to_jsonable(self.condition), "system": system_to_dict(self.system)}
        with open(path, "w") as fh:
            json.dump(out, fh, indent=1, allow_nan=False)
        return str(path)

    @classmethod
    def load(cls, path) -> "FitResult":
        """Read a result written by :meth:`save` (or ``jaxppo fit --out``)."""
        try:
            with open(path) as fh:
                d = json.load(fh)
        except json.JSONDecodeError as err:
            raise ValueError(f"{path}: not a JSON file written by FitResult.save ({err})") from None
        if not isinstance(d, dict) or d.get("format") != "jaxppo.FitResult":
            raise ValueError(f"{path}: not a FitResult file (format {d.get('format') if isinstance(d, dict) else None!r})")
        arr = lambda v: np.asarray(from_jsonable(v), float)  # noqa: E731
        return cls(system_from_dict(d["system"]), float(from_jsonable(d["chi2"])), arr(d["covariance"]).reshape(
            len(d["names"]), len(d["names"])), bool(d["success"]), d["message"], tuple(d["names"]), arr(d["values"]),
            arr(d["errors"]), float(from_jsonable(d["reduced_chi2"])), int(d["steps"]),
            np.asarray(d["union_frames"], int), {k: tuple(from_jsonable(v)) for k, v in d["derived"].items()},
            float(from_jsonable(d["condition"])))


def to_jsonable(v):
    """Floats (nested lists) for strict JSON: NaN -> None, +-inf -> "inf"/"-inf"."""
    v = np.asarray(v, float) if not isinstance(v, list) else v
    if isinstance(v, list):
        return [to_jsonable(x) for x in v]
    if v.ndim:
        return [to_jsonable(x) for x in v]
    x = float(v)
    return None if np.isnan(x) else ("inf" if x == np.inf else "-inf" if x == -np.inf else x)


def from_jsonable(v):
    if isinstance(v, list):
        return [from_jsonable(x) for x in v]
    return np.nan if v is None else float(v)


def system_to_dict(system: System) -> dict:
    """A System as plain JSON-ready values (every field of Star and Planet;
    :func:`system_from_dict` inverts it exactly)."""
    star = {}
    for f in dataclasses.fields(system.star):
        v = getattr(system.star, f.name)
        if f.name == "surface" and v is not None:
            raise ValueError("a Star built from a tabulated surface object cannot be saved as JSON")
        star[f.name] = v if v is None or isinstance(v, str) else to_jsonable(v)
    planets = []
    for pl in system.planets:
        planets.append({f.name: (getattr(pl, f.name) if f.name == "name" else to_jsonable(getattr(pl, f.name)))
                        for f in dataclasses.fields(pl)})
    return {"star": star, "planets": planets, "tilted": int(system.tilted)}


def system_from_dict(d: dict) -> System:
    from ..model._star import Star

    kw = {}
    for f in dataclasses.fields(Star):
        if f.name not in d["star"]:
            continue
        v = d["star"][f.name]
        if f.name in ("law", "interpolation") or v is None:
            kw[f.name] = v
        elif f.name == "degree":
            kw[f.name] = int(v)
        elif f.name == "table_residual":
            kw[f.name] = float(from_jsonable(v))
        else:
            kw[f.name] = jnp.asarray(from_jsonable(v), float)
    star = Star(**kw)
    planets = [Planet(**{k: (v if k == "name" else from_jsonable(v)) for k, v in p.items()}) for p in d["planets"]]
    return System(star, planets, d["tilted"])


def fit(system: System, lightcurve: LightCurve, free=("b.t0", "b.radius"), alpha: float = 0.0, case: str = "same",
        max_steps: int = 200, rtol: float = 1e-6, atol: float = 1e-6, progress: bool = False) -> FitResult:
    """Least-squares fit (optimistix Levenberg-Marquardt) of the named free
    parameters to the light curve; limb darkening stays fixed unless named
    (``"star.u1"``, or Kipping's ``"star.q1"``, ``"star.q2"``); the
    light-curve nuisance parameters ``"lc.offset"``, ``"lc.jitter"``,
    ``"lc.baseline"`` / ``"lc.baseline2"`` are described in the module
    docstring. ``lightcurve``: a :class:`LightCurve` or a lightkurve
    LightCurve. ``progress``: one line per stage on stderr. Never raises for
    a failed fit: ``success`` is False and ``message`` says why.

    ``success`` means more points than free parameters, a start and a
    solution at which every planet with a free parameter transits in the
    data, a finite chi^2, and a solution that is a minimum: the Hessian of
    chi^2 there is positive definite and a Newton step from it would lower
    chi^2 by less than 0.01. When optimistix stops elsewhere (its step
    criteria are met where chi^2 is flat, e.g. from a start with a tiny
    radius), the fit restarts from there in coordinates scaled by the
    Jacobian's columns before it reports failure. A UserWarning (not a
    failure) says when the linearised covariance is degenerate or
    ill-conditioned: ``FitResult.condition`` > ``CONDITION_WARN``, or chi^2
    at 1 sigma along a principal axis of the covariance differs from
    chi^2_min + 1 by more than a factor 4 (e.g. a and inc of a grazing or
    single transit): the posterior is then far from Gaussian and
    :func:`jaxppo.sample` gives the errors.
    """
    import time as _time

    import optimistix as optx

    clock = _time.perf_counter()

    def say(text):
        if progress:
            print(f"fit: {text} ({_time.perf_counter() - clock:.1f} s)", file=sys.stderr, flush=True)

    lightcurve = _as_lightcurve(lightcurve)
    model = Model(system, lightcurve, free, alpha, case)
    model.union_floor = 128
    free = model.free
    theta = model.to_theta(system)
    n, k = lightcurve.time.size, len(free)
    problems = _start_problems(model, system, n, k)
    say(f"{n} points, {k} free parameters; compiling the model")
    # from the Jacobian's program, which the minimum check compiles anyway
    # (a separate residual program would cost a compilation of its own)
    chi2_start = float(np.sum(np.asarray(model.jacobian(theta)[1]) ** 2))
    if not np.isfinite(chi2_start):
        problems.append(f"chi^2 at the start is {chi2_start} (flux_err as small as {np.min(lightcurve.flux_err):.3g} "
                        "makes the residuals overflow float64, or the model is not finite)")
    if problems:
        nan = np.full((k, k), np.nan)
        # the start as given (the coordinates would clip an impossible inclination)
        ph = np.asarray(model.physical(theta), float)
        start = np.array([ph[i] if owner == "lc" or par in ("q1", "q2") else float(
            system.star.params[par] if owner == "star" else getattr(system.planets[owner], par))
            for i, (owner, par) in enumerate(model.slots)])
        return FitResult(system, chi2_start, nan, False, "failed: " + "; ".join(problems), tuple(free),
                         start, np.full(k, np.nan), chi2_start / max(n - k, 1) if n > k else np.nan,
                         0, model.union_idx)
    say(f"chi^2 at the start {chi2_start:.6g}")
    solver = optx.LevenbergMarquardt(rtol=rtol, atol=atol)
    steps, restarts = 0, 0
    scale = jnp.ones_like(theta)
    # The frames that take the union integral are fixed from the starting
    # parameters (with a margin). If the solution brings disks together in
    # other frames, refit from it with those frames added (a new Model, so
    # the residuals are traced anew). Levenberg-Marquardt damps with the
    # identity, so where chi^2 is nearly flat in theta (a radius of 1e-6
    # R*) its steps are tiny and its step criteria are met far from the
    # minimum; then restart in theta scaled by the Jacobian's columns
    # (same residual function, so no recompilation).
    verdict = None
    for stage in range(10):
        sol = optx.least_squares(_scaled_residuals, solver, jnp.zeros_like(theta), args=(theta, scale, model.data()),
                                 max_steps=max_steps, throw=False)
        theta = theta + sol.value / scale
        steps += int(sol.stats.get("num_steps", -1))
        say(f"Levenberg-Marquardt pass {stage + 1}: {steps} steps in all")
        verdict = None
        wider = model.widened([model.to_system(theta)])
        if wider is not None:
            model = wider
            say(f"the solution brings disks together or onto the star in new frames: refitting with "
                f"{model.union_idx.size} union and {model.active_idx.size} computed frames")
            continue
        verdict = _assess(model, theta)
        say(f"checked the minimum: chi^2 {verdict['chi2']:.6g}"
            + ("" if verdict["optimum"] else "; not a minimum yet" if verdict["scale"] is not None else ""))
        if verdict["optimum"] or verdict["scale"] is None or restarts == 3:
            break
        scale, restarts = verdict["scale"], restarts + 1
    optx_ok = bool(sol.result == optx.RESULTS.successful)
    if verdict is None:
        verdict = _assess(model, theta)
    chi2 = verdict["chi2"]
    problems = []
    if not optx_ok:
        problems.append(str(optx.RESULTS[sol.result]) if hasattr(optx.RESULTS, "__getitem__") else str(sol.result))
    problems += verdict["problems"]
    problems += [p.replace("at the start", "at the solution") for p in _transit_problems(model, model.to_system(theta))]
    ok = not problems
    message = ("converged: " + verdict["summary"]) if ok else "failed: " + "; ".join(problems)
    phys = model.physical(theta)
    cov = np.full((k, k), np.nan)
    derived = {}
    if verdict["cov_theta"] is not None:
        # covariance in physical units: q = q(theta), cov_q = D cov_theta D^T
        d = np.asarray(jax.jacfwd(model.physical)(theta))
        cov = d @ verdict["cov_theta"] @ d.T
        if model.derived_names():
            dd = np.asarray(jax.jacfwd(model.derived)(theta))
            dcov = dd @ verdict["cov_theta"] @ dd.T
            derived = {nm: (float(v), float(np.sqrt(max(dcov[i, i], 0.0))))
                       for i, (nm, v) in enumerate(zip(model.derived_names(), np.asarray(model.derived(theta))))}
    elif model.derived_names():
        derived = {nm: (float(v), np.nan) for nm, v in zip(model.derived_names(), np.asarray(model.derived(theta)))}
    errors = np.sqrt(np.clip(np.diag(cov), 0, None))
    if ok and not np.all(np.isfinite(errors)):
        ok = False
        message = "failed: covariance not finite"
    condition, dchi2 = verdict["condition"], verdict["dchi2_1sigma"]
    why = []
    if condition > CONDITION_WARN:
        why.append(f"condition number {condition:.3g} of the scaled Fisher matrix, most degenerate combination "
                   f"{verdict['weakest']}")
    # Delta chi^2 at the linearised 1 sigma outside [1/4, 4]: the error along
    # that axis is off by more than a factor 2 (a milder mismatch is common:
    # chi^2(t0) of 1-min data has kinks where samples cross contact points)
    if dchi2 is not None and not np.all((dchi2 > 0.25) & (dchi2 < 4.0)):
        worst = dchi2[np.argmax(np.abs(np.log(np.where(dchi2 > 0, dchi2, 1e-300))))]
        why.append(f"chi^2 rises by {worst:.3g} instead of 1 at 1 sigma along a principal axis of the covariance")
    if why:
        warnings.warn(
            f"jaxppo.fit: the linearised covariance of {list(free)} is degenerate or ill-conditioned ("
            + "; ".join(why) + "): the errors and correlations from the curvature are not reliable (e.g. a and inc "
            "of a grazing or single transit); jaxppo.sample gives the posterior", UserWarning, stacklevel=2)
    chi2_data = float(np.sum(verdict["residuals"][:n] ** 2)) if verdict["residuals"] is not None else np.nan
    say("done")
    return FitResult(model.to_system(theta), chi2, cov, ok, message, tuple(free), np.asarray(phys), errors,
                     chi2_data / (n - k), steps, model.union_idx, derived, condition)


def _transit_problems(model: Model, system: System) -> list:
    """Planets with a free parameter that do not transit in any model frame."""
    x, y, r = system.positions(np.asarray(model.t_model), model.alpha, model.case, xp=np)
    owners = sorted({o for o, _ in model.slots if o not in ("star", "lc")})
    if not owners:
        owners = list(range(len(system.planets)))
        need_all = False
    else:
        need_all = True
    missing = []
    for i in owners:
        on = (r[:, i] > 0) & (np.hypot(x[:, i], y[:, i]) < 1.0 + r[:, i])
        if not np.any(on):
            pl = system.planets[i]
            b = float(pl.impact)
            missing.append(f"planet {pl.name or i} does not transit in the data at the start "
                           f"(impact parameter {b:.3g}, t0 {float(pl.t0):.6f} d, radius {float(pl.radius):.3g} R*)")
    if not need_all and len(missing) < len(owners):
        return []
    return missing


def _start_problems(model: Model, system: System, n: int, k: int) -> list:
    out = []
    if n <= k:
        out.append(f"{n} data points for {k} free parameters {model.free}: a fit needs more points than free parameters")
    return out + _transit_problems(model, system)


def _assess(model: Model, theta) -> dict:
    """Is theta a minimum of chi^2? From the residuals' Jacobian J and the
    full Hessian H of chi^2, both with theta scaled by J's column norms (so
    the verdict does not depend on units): H positive definite and the
    Newton decrement g^T H^-1 g / 2 (the chi^2 a Newton step would gain)
    below 0.01. Also the covariance (J^T J)^-1 in theta."""
    jac, r = (np.asarray(v) for v in model.jacobian(theta))
    chi2 = float(np.sum(r**2))
    out = {"chi2": chi2, "problems": [], "optimum": False, "scale": None, "cov_theta": None, "summary": "",
           "condition": np.nan, "weakest": "", "dchi2_1sigma": None, "residuals": r}
    if not np.isfinite(chi2):
        out["problems"].append(f"chi^2 at the solution is {chi2}")
        return out
    c = np.sqrt(np.sum(jac**2, axis=0))
    flat = [n for n, ci in zip(model.free, c) if not ci > 0]
    if flat or not np.all(np.isfinite(jac)):
        out["problems"].append(f"the data do not constrain {flat} (zero or non-finite derivative at the solution)")
        out["condition"], out["weakest"] = np.inf, f"{flat} alone"
        return out
    out["scale"] = jnp.asarray(c)
    grad = 2.0 * (jac.T @ r) / c
    # Hessian of chi^2 in the scaled coordinates by second differences of
    # chi^2 itself (2 k^2 forward evaluations in one program; a traced
    # jax.hessian costs ~8 s of compilation here). The step, 0.3, is a
    # fraction of the scale on which chi^2 changes by 1: the light curve's
    # second derivative jumps at contact points, and differences of the
    # gradient over tiny steps read a 10-parameter Kepler-20 minimum as a
    # saddle.
    h, k = 0.3, c.size
    eye = np.eye(k) * h
    pts = [np.zeros(k)] + [s * eye[i] for i in range(k) for s in (1.0, -1.0)]
    pairs = [(i, j) for i in range(k) for j in range(i + 1, k)]
    pts += [si * eye[i] + sj * eye[j] for i, j in pairs for si in (1.0, -1.0) for sj in (1.0, -1.0)]
    n_hess = len(pts)
    jtj = (jac / c).T @ (jac / c)
    jitter = any(par == "jitter" for _, par in model.slots)
    try:
        cov_gn = np.linalg.inv(jtj) / np.outer(c, c)
    except np.linalg.LinAlgError:
        cov_gn = None
    # the same batch also evaluates chi^2 at +-1 sigma along the principal
    # axes of the linearised covariance (see _axis_steps)
    axes = None if jitter else _axis_steps(cov_gn)
    if axes is not None:
        pts += list(axes * c)
    f = np.asarray(model.chi2_batch(jnp.asarray(theta) + jnp.asarray(np.array(pts)) / c))
    hess = np.empty((k, k))
    for i in range(k):
        hess[i, i] = (f[1 + 2 * i] - 2 * f[0] + f[2 + 2 * i]) / h**2
    base = 1 + 2 * k
    for n, (i, j) in enumerate(pairs):
        fpp, fpm, fmp, fmm = f[base + 4 * n: base + 4 * n + 4]
        hess[i, j] = hess[j, i] = (fpp - fpm - fmp + fmm) / (4 * h**2)
    if not np.all(np.isfinite(hess)):
        out["problems"].append("the Hessian of chi^2 at the solution is not finite")
        return out
    w = np.linalg.eigvalsh(0.5 * (hess + hess.T))
    # scaled so that the Gauss-Newton part has unit diagonal: eigenvalues
    # near 2 for well-determined parameters; 1e-9 of that is degenerate
    if w[0] <= 2e-9 * max(w[-1], 1.0):
        out["problems"].append(f"not a minimum: the Hessian of chi^2 is not positive definite (scaled eigenvalues "
                               f"{w[0]:.3g} .. {w[-1]:.3g}, gradient norm {np.linalg.norm(grad):.3g}); the free parameters are "
                               "degenerate, or the fit stopped on a slope or a saddle")
    else:
        decrement = 0.5 * float(grad @ np.linalg.solve(hess, grad))
        out["summary"] = f"Newton step would lower chi^2 by {decrement:.2g}"
        if decrement > 0.01:
            out["problems"].append(f"not a minimum: a Newton step would lower chi^2 by {decrement:.3g}")
        else:
            out["optimum"] = True
    # conditioning of the scaled Fisher matrix (unit diagonal): its smallest
    # eigenvalue is 1 / (the variance inflation of the worst-determined
    # combination of parameters over the parameters one at a time)
    wj, vj = np.linalg.eigh(jtj)
    out["condition"] = float(wj[-1] / wj[0]) if wj[0] > 0 else np.inf
    v0 = vj[:, 0]
    top = np.argsort(-np.abs(v0))[:3]
    out["weakest"] = " ".join(f"{v0[i]:+.2f} {model.free[i]}" for i in top if abs(v0[i]) > 0.1)
    if not jitter:
        out["cov_theta"] = cov_gn
        if axes is not None:
            out["dchi2_1sigma"] = f[n_hess:] - chi2
        return out
    try:
        # Laplace: -2 ln L ~ const + dtheta^T H dtheta, cov = 2 H^-1 (in
        # scaled coordinates, back to theta by the column scales); the
        # Gauss-Newton form of the augmented residuals misses the jitter's
        # curvature
        out["cov_theta"] = 2.0 * np.linalg.inv(0.5 * (hess + hess.T)) / np.outer(c, c)
    except np.linalg.LinAlgError:
        return out
    axes = _axis_steps(out["cov_theta"])
    if axes is not None:
        # padded to the Hessian's batch size: the compiled program is reused
        steps = list(axes) + [np.zeros(k)] * max(n_hess - len(axes), 0)
        g = np.asarray(model.chi2_batch(jnp.asarray(theta) + jnp.asarray(np.array(steps))))
        out["dchi2_1sigma"] = g[: len(axes)] - chi2
    return out


def _axis_steps(cov_theta):
    """Steps in theta to +-1 sigma along each principal axis of the
    linearised covariance, where chi^2 - chi^2_min is exactly 1 if the
    Laplace approximation holds; None without a finite, positive-definite
    covariance."""
    if cov_theta is None or not np.all(np.isfinite(cov_theta)):
        return None
    w, v = np.linalg.eigh(0.5 * (cov_theta + cov_theta.T))
    if w[0] <= 0:
        return None
    return np.array([s * np.sqrt(w[i]) * v[:, i] for i in range(w.size) for s in (1.0, -1.0)])
