"""Transit fits: optimistix Levenberg-Marquardt and numpyro NUTS over named
free parameters ("b.t0", "c.radius", "star.u1", ...), in coordinates that keep
the physics valid: a = 1 + exp(.), p = exp(.), P = exp(.), and the impact
parameter b = (1 + p) tanh(.) (so |b| < 1 + p and the planet always transits),
with i = arccos(b / a).
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._lightcurve import LightCurve
from ._system import Planet, System

__all__ = ["fit", "FitResult", "Model", "parameter_names"]

_PLANET_PARAMS = ("t0", "period", "a", "inc", "radius")
_STAR_PARAMS = {"quadratic": ("u1", "u2"), "nonlinear": ("c1", "c2", "c3", "c4"), "power2": ("c", "alpha")}


def parameter_names(system: System) -> list[str]:
    """All names ``fit`` and ``sample`` accept for this system."""
    names = []
    for i, pl in enumerate(system.planets):
        label = pl.name or str(i)
        names += [f"{label}.{p}" for p in _PLANET_PARAMS]
    names += [f"star.{p}" for p in _STAR_PARAMS.get(system.star.law, ())]
    return names


def _split(name: str, system: System):
    if "." not in name:
        raise ValueError(f"free parameter {name!r} must look like 'b.t0' or 'star.u1'")
    owner, par = name.split(".", 1)
    if owner == "star":
        pars = _STAR_PARAMS.get(system.star.law, ())
        if par not in pars:
            raise ValueError(f"free parameter {name!r}: a {system.star.law} star has {pars}")
        return "star", pars.index(par)
    idx = None
    for i, pl in enumerate(system.planets):
        if (pl.name or str(i)) == owner:
            idx = i
    if idx is None:
        raise ValueError(f"free parameter {name!r}: no planet named {owner!r}; names are {[p.name for p in system.planets]}")
    if par not in _PLANET_PARAMS:
        raise ValueError(f"free parameter {name!r}: planet parameters are {_PLANET_PARAMS}")
    return idx, par


class Model:
    """Maps an unconstrained vector theta to a System and a light curve.

    The exposure of the data (if any) is modelled by averaging the flux over
    ``nsub`` sub-exposures.
    """

    def __init__(self, system: System, lc: LightCurve, free, alpha: float = 0.0, case: str = "same"):
        free = tuple(free)
        if not free:
            raise ValueError("free must name at least one parameter, e.g. ('b.t0', 'b.radius')")
        if len(set(free)) != len(free):
            raise ValueError(f"free parameters repeat: {free}")
        self.system, self.lc, self.free = system, lc, free
        self.alpha, self.case = alpha, case
        self.union_floor = 0  # see _Data.build
        self.slots = [_split(n, system) for n in free]
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
        wider = Model(self.system, self.lc, self.free, self.alpha, self.case)
        wider.union_floor = self.union_floor
        wider.union_idx = np.union1d(wider.union_idx, needed)
        wider.active_idx = np.union1d(np.union1d(wider.active_idx, active), wider.union_idx)
        return wider

    # ---- coordinates ----------------------------------------------------------
    def to_theta(self, system: System) -> jnp.ndarray:
        out = []
        for (owner, par) in self.slots:
            if owner == "star":
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
            if owner == "star" or par == "t0":
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
        """The free parameters in physical units (days, degrees, R*)."""
        sysm = self.to_system(theta)
        out = []
        for (owner, par) in self.slots:
            out.append(sysm.star.params[par] if owner == "star" else getattr(sysm.planets[owner], par))
        return jnp.stack(out)

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
        return _flux(theta, self.data())

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
    slots: tuple = eqx.field(static=True)
    nsub: int = eqx.field(static=True)
    n_model: int = eqx.field(static=True)
    case: object = eqx.field(static=True)

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
                     model.y, model.sigma, jnp.asarray(model.alpha, float), tuple(model.slots), int(model.nsub),
                     int(model.t_model.size), case)


def _to_system(theta, base: System, slots) -> System:
    planets = [dict(period=p.period, t0=p.t0, a=p.a, inc=p.inc, radius=p.radius, name=p.name) for p in base.planets]
    star_params = base.star.params
    b_theta = {}
    for k, (owner, par) in enumerate(slots):
        v = theta[k]
        if owner == "star":
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
    star = dataclasses.replace(base.star, params=star_params)
    return System(star, [Planet(**p) for p in planets], base.tilted)


def _flux(theta, d: _Data) -> jnp.ndarray:
    from ._flux import _exact_frames, _separate_frames

    sysm = _to_system(theta, d.system, d.slots)
    x, y, r = sysm.positions(d.t, d.alpha, d.case)
    fa = _separate_frames(sysm.star, x, y, r, 24)
    if d.union.size:
        u = d.union
        fa = fa.at[u].set(_exact_frames(sysm.star, x[u], y[u], r[u], 24))
    f = jnp.ones((d.n_model,), fa.dtype).at[d.act].set(fa)
    return f.reshape(-1, d.nsub).mean(-1)


@eqx.filter_jit
def _residuals(theta, d: _Data) -> jnp.ndarray:
    return (d.y - _flux(theta, d)) / d.sigma


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
    physical units (``names`` order), ``errors`` (1 sigma), ``success`` and
    ``message``; ``reduced_chi2`` = chi2 / (N - k); ``union_frames``: the
    model frames integrated by the exact union integral (overlapping disks
    at the start or at the solution, with a margin)."""

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

    def table(self) -> str:
        rows = [f"{n:14s} {v:16.8f} +- {e:.2e}" for n, v, e in zip(self.names, self.values, self.errors)]
        return "\n".join(rows + [f"chi2 = {self.chi2:.2f}, reduced {self.reduced_chi2:.3f}, {self.message}"])


def fit(system: System, lightcurve: LightCurve, free=("b.t0", "b.radius"), alpha: float = 0.0, case: str = "same",
        max_steps: int = 200, rtol: float = 1e-6, atol: float = 1e-6) -> FitResult:
    """Least-squares fit (optimistix Levenberg-Marquardt) of the named free
    parameters to the light curve; limb darkening stays fixed unless named
    (``"star.u1"``). Never raises for a failed fit: ``success`` is False and
    ``message`` says why.

    ``success`` means more points than free parameters, a start and a
    solution at which every planet with a free parameter transits in the
    data, a finite chi^2, and a solution that is a minimum: the Hessian of
    chi^2 there is positive definite and a Newton step from it would lower
    chi^2 by less than 0.01. When optimistix stops elsewhere (its step
    criteria are met where chi^2 is flat, e.g. from a start with a tiny
    radius), the fit restarts from there in coordinates scaled by the
    Jacobian's columns before it reports failure.
    """
    import optimistix as optx

    model = Model(system, lightcurve, free, alpha, case)
    model.union_floor = 128
    theta = model.to_theta(system)
    n, k = lightcurve.time.size, len(free)
    problems = _start_problems(model, system, n, k)
    chi2_start = float(jnp.sum(model.residuals(theta) ** 2))
    if not np.isfinite(chi2_start):
        problems.append(f"chi^2 at the start is {chi2_start} (flux_err as small as {np.min(lightcurve.flux_err):.3g} "
                        "makes the residuals overflow float64, or the model is not finite)")
    if problems:
        nan = np.full((k, k), np.nan)
        start = [system.star.params[par] if owner == "star" else getattr(system.planets[owner], par) for owner, par in model.slots]
        return FitResult(system, chi2_start, nan, False, "failed: " + "; ".join(problems), tuple(free),
                         np.asarray(start, float), np.full(k, np.nan), chi2_start / max(n - k, 1) if n > k else np.nan,
                         0, model.union_idx)
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
    for _ in range(10):
        sol = optx.least_squares(_scaled_residuals, solver, jnp.zeros_like(theta), args=(theta, scale, model.data()),
                                 max_steps=max_steps, throw=False)
        theta = theta + sol.value / scale
        steps += int(sol.stats.get("num_steps", -1))
        verdict = None
        wider = model.widened([model.to_system(theta)])
        if wider is not None:
            model = wider
            continue
        verdict = _assess(model, theta)
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
    if verdict["cov_theta"] is not None:
        # covariance in physical units: q = q(theta), cov_q = D cov_theta D^T
        d = np.asarray(jax.jacfwd(model.physical)(theta))
        cov = d @ verdict["cov_theta"] @ d.T
    errors = np.sqrt(np.clip(np.diag(cov), 0, None))
    if ok and not np.all(np.isfinite(errors)):
        ok = False
        message = "failed: covariance not finite"
    return FitResult(model.to_system(theta), chi2, cov, ok, message, tuple(free), np.asarray(phys), errors,
                     chi2 / (n - k), steps, model.union_idx)


def _transit_problems(model: Model, system: System) -> list:
    """Planets with a free parameter that do not transit in any model frame."""
    x, y, r = system.positions(np.asarray(model.t_model), model.alpha, model.case, xp=np)
    owners = sorted({o for o, _ in model.slots if o != "star"})
    if any(o == "star" for o, _ in model.slots) and not owners:
        owners = list(range(len(system.planets)))
        need_all = False
    else:
        need_all = True
    missing = []
    for i in owners:
        on = (r[:, i] > 0) & (np.hypot(x[:, i], y[:, i]) < 1.0 + r[:, i])
        if not np.any(on):
            pl = system.planets[i]
            b = float(pl.a * np.cos(np.deg2rad(pl.inc)))
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
    out = {"chi2": chi2, "problems": [], "optimum": False, "scale": None, "cov_theta": None, "summary": ""}
    if not np.isfinite(chi2):
        out["problems"].append(f"chi^2 at the solution is {chi2}")
        return out
    c = np.sqrt(np.sum(jac**2, axis=0))
    flat = [n for n, ci in zip(model.free, c) if not ci > 0]
    if flat or not np.all(np.isfinite(jac)):
        out["problems"].append(f"the data do not constrain {flat} (zero or non-finite derivative at the solution)")
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
    jtj = (jac / c).T @ (jac / c)
    try:
        out["cov_theta"] = np.linalg.inv(jtj) / np.outer(c, c)
    except np.linalg.LinAlgError:
        pass
    return out
