"""Transit fits: optimistix Levenberg-Marquardt and numpyro NUTS over named
free parameters ("b.t0", "c.radius", "star.u1", ...), in coordinates that keep
the physics valid: a = 1 + exp(.), p = exp(.), P = exp(.), and the impact
parameter b = (1 + p) tanh(.) (so |b| < 1 + p and the planet always transits),
with i = arccos(b / a).
"""

from __future__ import annotations

import dataclasses

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
        self.slots = [_split(n, system) for n in free]
        t_model, self.nsub = lc.supersampled_times()
        self.t_model = jnp.asarray(t_model)
        # Frames where two disks are on the star and within `margin` [R*] of
        # touching at the starting parameters run the exact union integral;
        # all others are a sum of one-disk terms. The split is fixed for the
        # fit (the margin covers the parameter changes of a fit; ``fit``
        # checks the final geometry and refits with a wider split if needed).
        self.union_idx = self._union_frames(system, t_model)
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

    def widened(self, systems) -> "Model | None":
        """A new Model (traced anew) whose union-integral frames also cover
        the frames where any of ``systems`` brings disks within the margin of
        touching; None when the current frames cover them already."""
        t = np.asarray(self.t_model)
        needed = np.unique(np.concatenate([self.union_idx] + [self._union_frames(s, t) for s in systems]))
        if np.all(np.isin(needed, self.union_idx)):
            return None
        wider = Model(self.system, self.lc, self.free, self.alpha, self.case)
        wider.union_idx = np.union1d(wider.union_idx, needed)
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
        planets = [dict(period=p.period, t0=p.t0, a=p.a, inc=p.inc, radius=p.radius, name=p.name) for p in self.system.planets]
        star_params = self.system.star.params
        b_theta = {}
        for k, (owner, par) in enumerate(self.slots):
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
        star = dataclasses.replace(self.system.star, params=star_params)
        return System(star, [Planet(**p) for p in planets], self.system.tilted)

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
    def flux(self, theta) -> jnp.ndarray:
        from ._flux import _exact_frames, _separate_frames

        sysm = self.to_system(theta)
        x, y, r = sysm.positions(self.t_model, self.alpha, self.case)
        f = _separate_frames(sysm.star, x, y, r, 24)
        if self.union_idx.size:
            idx = self.union_idx
            f = f.at[idx].set(_exact_frames(sysm.star, x[idx], y[idx], r[idx], 24))
        return f.reshape(-1, self.nsub).mean(-1)

    def residuals(self, theta, args=None) -> jnp.ndarray:
        return (self.y - self.flux(theta)) / self.sigma


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
    ``message`` says why."""
    import optimistix as optx

    model = Model(system, lightcurve, free, alpha, case)
    theta = model.to_theta(system)
    solver = optx.LevenbergMarquardt(rtol=rtol, atol=atol)
    # The frames that take the union integral are fixed from the starting
    # parameters (with a margin). If the solution brings disks together in
    # other frames, refit from it with those frames added (a new Model, so
    # the residuals are traced anew).
    for _ in range(4):
        sol = optx.least_squares(model.residuals, solver, theta, max_steps=max_steps, throw=False)
        theta = sol.value
        wider = model.widened([model.to_system(theta)])
        if wider is None:
            break
        model = wider
    res = model.residuals(theta)
    chi2 = float(jnp.sum(res**2))
    ok = bool(sol.result == optx.RESULTS.successful) and bool(np.isfinite(chi2))
    message = "converged" if ok else f"failed: {optx.RESULTS[sol.result] if hasattr(optx.RESULTS, '__getitem__') else sol.result}"
    # Covariance in physical units from the Jacobian of the residuals.
    phys = model.physical(theta)

    def res_phys(q):
        return model.residuals(model.theta_from(q, theta))

    try:
        jac = np.asarray(jax.jacfwd(res_phys)(phys))
        cov = np.linalg.pinv(jac.T @ jac)
        flat = [n for n, col in zip(free, np.abs(jac).max(0)) if not col > 0]
        if flat:
            ok = False
            message = f"failed: the data do not constrain {flat} (zero derivative at the solution)"
    except Exception as err:  # a singular or non-finite Jacobian: report, don't raise
        cov = np.full((len(free), len(free)), np.nan)
        message += f"; no covariance ({err})"
    errors = np.sqrt(np.clip(np.diag(cov), 0, None))
    if not np.all(np.isfinite(errors)):
        ok = False
        message += "; covariance not finite"
    dof = max(lightcurve.time.size - len(free), 1)
    steps = int(sol.stats.get("num_steps", -1)) if hasattr(sol, "stats") else -1
    return FitResult(model.to_system(theta), chi2, cov, ok, message, tuple(free), np.asarray(phys), errors, chi2 / dof, steps,
                     model.union_idx)

