"""The transit model of fits and samplers: a vector theta of unconstrained
coordinates (``._params`` names them) -> a System -> the light curve at
the data times, the residuals and the likelihood.

The model functions are jitted module-level functions of theta and a
``ModelData`` pytree (the arrays traced, the structure static), so
every Model of the same structure and frame counts shares one compilation.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..model._lightcurve import LightCurve
from ..model._overlap import on_star, pairs_in_contact
from ..model._planet import Planet
from ..model._programs import stored
from ..model._system import System
from ..model._units import from_quantity
from ._ecc import ECC_PARAMS, conjunction_factor, e_omega, ecc_cap, pair_from_theta, pair_of, periastron_ok, theta_from_pair
from ._params import (as_lightcurve, expand_free, is_moon, is_tc, is_trend, jitter_start, kipping_q, kipping_u,
                      logit, planet_value, star_value)


def _check_span(system: System, t_model) -> None:
    """Refuse data outside an N-body System's given ``span`` by more than
    ``dt``: the traced model is NaN there (and a fit failed with "chi^2 at
    the start is nan ... flux_err ... overflow", which does not name it)."""
    if system.orbits != "nbody" or system.span is None:
        return
    lo, hi = float(np.min(t_model)), float(np.max(t_model))
    dt = float(system.dt)
    if lo < system.span[0] - dt or hi > system.span[1] + dt:
        raise ValueError(f"span = ({system.span[0]:g}, {system.span[1]:g}) [d] of the N-body System does not cover "
                         f"the data (model times {lo:.3f}-{hi:.3f} d; more than dt = {dt:.3g} d outside the span the "
                         "positions are NaN): widen span, or leave it None (fits and samplers then take the data's)")


# moon elements whose coordinate is the logarithm (the others: identity)
_MOON_LOG = ("period", "a", "radius", "mass_ratio")

__all__ = ["UNION_MARGIN", "ACTIVE_MARGIN", "Model", "ModelData", "system_at", "residuals",
           "pointwise_loglike", "chi2_batch", "residuals_batch", "physical_jacobian", "theta_of"]

UNION_MARGIN = 0.05
"""[R*] Two disks within this distance of touching at the start run the
exact union integral (fits move less; ``fit`` and ``sample`` widen it)."""
ACTIVE_MARGIN = 0.25
"""[R*] Frames with a disk within this distance of the star at the start are
computed; the rest are exactly 1."""


class Model(eqx.Module):
    """Maps an unconstrained vector theta to a System and a light curve.

    An immutable ``eqx.Module``: ``with_frames`` and ``widened`` return new
    Models. The exposure of the data (if any) is modelled by averaging the
    flux over ``nsub`` sub-exposures. The arrays the compiled model
    functions take (``data``) are built with the Model.
    """

    system: System
    lc: LightCurve
    alpha: float
    jitter0: float
    basis: np.ndarray
    t_model: jax.Array
    y: jax.Array
    sigma: jax.Array
    union_idx: np.ndarray
    active_idx: np.ndarray
    model_data: "ModelData"
    requested: tuple = eqx.field(static=True)
    free: tuple = eqx.field(static=True)
    slots: tuple = eqx.field(static=True)
    case: object = eqx.field(static=True)
    union_floor: int = eqx.field(static=True)
    nsub: int = eqx.field(static=True)
    user_span: object = eqx.field(static=True)

    # Compared and hashed by identity, as a plain object: a bound method
    # (``jax.jit(model.residuals)``) is then hashable like any method, where
    # equinox's field-wise hash would meet the arrays among the fields.
    __hash__ = object.__hash__

    def __eq__(self, other) -> bool:
        return self is other

    def __init__(self, system: System, lc: LightCurve, free, alpha: float = 0.0, case: str = "same", *,
                 active_margin: float = ACTIVE_MARGIN, union_floor: int = 0):
        """``system``: the start (and the values of every parameter not in
        ``free``); ``lc``: a ``LightCurve`` or a lightkurve LightCurve;
        ``free``: names from ``parameter_names``; ``alpha`` [deg] and
        ``case``: the tilt and hemisphere case of the geometry;
        ``active_margin`` [R*]: the frames computed are those with a disk
        within this distance of the star at the start (a sampler, whose
        posterior spreads further than a fit moves, asks for 1);
        ``union_floor``: pad the union-integral frames to a power of two of
        at least this many (``fit``: widenings then rarely recompile)."""
        free = (free,) if isinstance(free, str) else tuple(free)
        if not free:
            raise ValueError("free must name at least one parameter, e.g. ('b.t0', 'b.radius')")
        if len(set(free)) != len(free):
            raise ValueError(f"free parameters repeat: {free}")
        if not (np.isfinite(active_margin) and active_margin >= 0):
            raise ValueError(f"active_margin must be a finite distance >= 0 [R*], got {active_margin!r}")
        if int(union_floor) != union_floor or union_floor < 0:
            raise ValueError(f"union_floor must be an integer >= 0, got {union_floor!r}")
        alpha = from_quantity("alpha", alpha, "deg")  # one tilt: NaN read as "no planet transits" before
        if not isinstance(alpha, jax.core.Tracer) and (np.ndim(alpha) != 0 or not np.isfinite(alpha)):
            raise ValueError(f"alpha must be one finite angle [deg], got {alpha!r}")
        lc = as_lightcurve(lc)
        self.user_span = system.span  # results get it back (``result_system``)
        if system.orbits == "nbody" and system.span is None:
            # the N-body grid is fixed once: the compiled model takes traced times
            tl = np.asarray(lc.time, float)
            pad = 0.5 * float(np.max(np.asarray(lc.exposure))) + 1.0 if lc.exposure is not None else 1.0
            system = system.replace(span=(float(tl.min()) - pad, float(tl.max()) + pad))
        self.system, self.lc, self.requested = system, lc, free
        self.alpha, self.case = alpha, (tuple(case) if isinstance(case, list) else case)
        self.union_floor = int(union_floor)  # see ModelData.build
        # ``free``: the names of the fitted values (baseline expanded)
        names, slots, self.basis = expand_free(free, system, np.asarray(lc.time))
        self.free, self.slots = tuple(names), tuple(slots)
        self.jitter0 = jitter_start(lc.flux_err)
        t_model, self.nsub = lc.supersampled_times()
        _check_span(system, t_model)
        self.t_model = jnp.asarray(t_model)
        # Frames where two disks are on the star and within UNION_MARGIN
        # [R*] of touching at the starting parameters run the exact union
        # integral; all others are a sum of one-disk terms. The split is
        # fixed for the fit (the margin covers the parameter changes of a
        # fit; ``fit`` checks the final geometry and refits with a wider
        # split if needed).
        self.union_idx = self.union_frames_of(system)
        # Likewise, only frames where a disk is on the star or within
        # ``active_margin`` [R*] of its limb at the start are computed; the
        # others are exactly 1 (and widened like the union frames).
        self.active_idx = self.active_frames_of(system, margin=active_margin)
        self.y = jnp.asarray(lc.flux)
        self.sigma = jnp.asarray(lc.flux_err)
        self.model_data = _build(self)
        _check_precision(self.model_data, lc)

    def _positions(self, system: System, t=None):
        t = np.asarray(self.t_model if t is None else t)
        return system.positions(t, self.alpha, self.case, xp=np)

    def union_frames_of(self, system: System, t=None, margin: float = UNION_MARGIN) -> np.ndarray:
        """Indices of the frames (model times, or ``t`` [d]) in which two
        disks of ``system`` are on the star and within ``margin`` [R*] of
        touching, at this Model's alpha and case."""
        return np.nonzero(pairs_in_contact(*self._positions(system, t), margin))[0]

    def active_frames_of(self, system: System, t=None, margin: float = ACTIVE_MARGIN) -> np.ndarray:
        """Indices of the frames (model times, or ``t`` [d]) in which a disk
        of ``system`` is within ``margin`` [R*] of the stellar disk."""
        return np.nonzero(on_star(*self._positions(system, t), margin).any(-1))[0]

    def with_frames(self, union=(), active=()) -> "Model":
        """A copy (traced anew) whose union-integral frames also include
        ``union`` and whose computed frames also include ``active`` and every
        union frame (indices into the model times)."""
        union = np.union1d(self.union_idx, np.asarray(union, np.int64))
        active = np.union1d(np.union1d(self.active_idx, np.asarray(active, np.int64)), union)
        new = eqx.tree_at(lambda m: (m.union_idx, m.active_idx), self, (union, active))
        return eqx.tree_at(lambda m: m.model_data, new, _build(new))

    def widened(self, systems) -> "Model | None":
        """A new Model (traced anew) whose union-integral frames also cover
        the frames where any of ``systems`` brings disks within the margin of
        touching, and whose computed frames cover every frame where they put
        a disk within 0.05 R* of the star; None when the current frames
        cover them already."""
        needed = np.concatenate([self.union_frames_of(s) for s in systems] or [np.zeros(0, np.int64)])
        active = np.concatenate([self.active_frames_of(s, margin=0.05) for s in systems] or [np.zeros(0, np.int64)])
        return self._widened_to(needed, active)

    def widened_at(self, thetas, batch: int = 32) -> "Model | None":
        """``widened`` for many parameter vectors ``thetas`` [n, k] at once:
        their positions in one compiled, vmapped call per ``batch`` (fewer
        for long light curves: at most ~4e6 model times a call)."""
        thetas = np.atleast_2d(np.asarray(thetas, float))
        if thetas.shape[0] == 0:
            return None
        t = self.t_model
        batch = int(max(1, min(batch, 4_000_000 // max(1, t.shape[0]))))
        pos = jax.jit(jax.vmap(lambda th: self.to_system(th).positions(t, self.alpha, self.case)))
        n = thetas.shape[0]
        pad = -(-n // batch) * batch
        thetas = np.concatenate([thetas, np.repeat(thetas[-1:], pad - n, axis=0)])
        union, active = np.zeros(t.shape[0], bool), np.zeros(t.shape[0], bool)
        for i in range(0, pad, batch):
            x, y, r = (np.asarray(v) for v in pos(jnp.asarray(thetas[i:i + batch])))
            union |= pairs_in_contact(x, y, r, UNION_MARGIN).any(0)
            active |= on_star(x, y, r, 0.05).any(-1).any(0)
        return self._widened_to(np.nonzero(union)[0], np.nonzero(active)[0])

    def _widened_to(self, union, active) -> "Model | None":
        """``with_frames(union, active)``, or None when the current frames
        hold them already."""
        if np.all(np.isin(union, self.union_idx)) and np.all(np.isin(active, self.active_idx)):
            return None
        return self.with_frames(union, active)

    # ---- coordinates ----------------------------------------------------------
    def to_theta(self, system: System) -> jnp.ndarray:
        """theta (the unconstrained fit coordinates, ``self.slots`` order) of
        ``system``'s values; light-curve terms at their starts (one compiled
        program, ``theta_of``: eagerly its dozen operations were a program
        each, a tenth of a second of a new process's fit)."""
        return theta_of(system, self.system, tuple(self.slots), jnp.asarray(self.jitter0, float))

    def to_system(self, theta) -> System:
        """The System that theta describes (traceable; one compiled program)."""
        return _system_program(jnp.asarray(theta), self.system, tuple(self.slots))

    def result_system(self, theta, system: System | None = None) -> System:
        """The System at theta as a result hands it to the user: an N-body
        system's integration span as the user gave it (the span this Model
        fixed covers only the data; outside it a traced time gives NaN).
        ``system``: ``to_system(theta)`` where the caller has it already."""
        system = self.to_system(theta) if system is None else system
        if system.orbits == "nbody" and system.span != self.user_span:
            system = system.replace(span=self.user_span)
        return system

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
            if is_moon(par):
                out.append(jnp.log(v) if par[2] in _MOON_LOG else v)
            elif par in ("q1", "q2"):
                out.append(logit(v))
            elif par in ("jitter", "period", "mass", "radius"):  # star mass/radius too
                out.append(jnp.log(v))
            elif owner in ("star", "lc") or par in ("t0", "lnode") or is_tc(par):
                out.append(v)
            elif par == "a":
                out.append(jnp.log(v - 1.0))
            elif par in ECC_PARAMS:
                pair = (named[(owner, "secosw")], named[(owner, "sesinw")])
                out.append(theta_from_pair(*pair, ecc_cap(self.system, owner))[ECC_PARAMS.index(par)])
            elif ref is None:
                out.append(jnp.arctanh(jnp.clip(v, -1 + 1e-12, 1 - 1e-12)))
            else:
                pl = ref.planets[owner]
                a = named.get((owner, "a"), pl.a)
                p = named.get((owner, "radius"), pl.radius)
                e, w = (e_omega(named[(owner, "secosw")], named[(owner, "sesinw")]) if (owner, "secosw") in named
                        else (pl.e, pl.omega))
                out.append(jnp.arctanh(a * jnp.cos(jnp.deg2rad(v)) * conjunction_factor(e, w) / (1.0 + p)))
        return jnp.stack(out)

    def physical(self, theta) -> jnp.ndarray:
        """The free parameters in physical units (days, degrees, R*;
        q1, q2; offset, jitter [relative flux], baseline coefficients)."""
        return _physical(theta, self.to_system(theta), self.slots, self.system)

    def derived_names(self) -> tuple:
        """Quantities implied by the free parameters: "star.u1", "star.u2"
        when Kipping's q1 or q2 is free; "<p>.e", "<p>.omega" [deg] of each
        planet whose secosw, sesinw are free."""
        names = ("star.u1", "star.u2") if any(p in ("q1", "q2") for _, p in self.slots) else ()
        return names + tuple(f"{self.system.planets[o].name or o}.{x}" for o in _ecc_planets(self.slots)
                             for x in ("e", "omega"))

    def derived(self, theta) -> jnp.ndarray:
        """Values of ``derived_names`` at theta."""
        return _derived(self.to_system(theta), self.slots)

    def physical_jacobian(self, theta):
        """(d q / d theta, q) of q = ``physical`` followed by ``derived``:
        one stored program (eager differentiation cost 0.3 s of every new
        process's fit)."""
        return physical_jacobian(theta, self.data())

    # ---- model ----------------------------------------------------------------
    def data(self) -> "ModelData":
        """The arrays the compiled model functions take as traced inputs
        (built with the Model's frame sets). Every Model with the same
        structure and frame counts reuses one compilation."""
        return self.model_data

    def flux(self, theta) -> jnp.ndarray:
        """Model flux at the data times, with the offset / baseline trend."""
        d = self.data()
        return _flux(theta, d) * _trend(theta, d)

    def pointwise_loglike(self, theta) -> jnp.ndarray:
        """Gaussian log-likelihood of each data point (jitter included)."""
        return pointwise_loglike(theta, self.data())

    def residuals(self, theta, args=None) -> jnp.ndarray:
        """The residuals whose sum of squares is the objective (see
        ``residuals``); ``args`` is ignored (optimistix's signature)."""
        return residuals(theta, self.data())

    def residuals_at(self, theta, alpha) -> jnp.ndarray:
        """``residuals`` at the tilt ``alpha`` [deg] instead of the
        Model's (alpha is traced: one compilation serves every tilt)."""
        return residuals(theta, eqx.tree_at(lambda d: d.alpha, self.data(), jnp.asarray(alpha, float)))

    def chi2_batch(self, thetas):
        """chi^2 at each row of ``thetas`` (one compiled program)."""
        return chi2_batch(thetas, self.data())

    def residuals_batch(self, thetas, count=None):
        """``residuals`` at each row of ``thetas`` (one compiled program for
        every ``count``): at its first ``count`` rows only (the others
        zero; all by default). Forward-mode derivatives only (``jvp``,
        ``jacfwd``; the loop stops at a traced count). ValueError unless
        ``count`` is a whole number from 0 to the number of rows."""
        thetas = jnp.asarray(thetas)
        rows = thetas.shape[0]
        if count is None:
            count = rows
        elif isinstance(count, bool) or not isinstance(count, (int, np.integer)) or not 0 <= count <= rows:
            raise ValueError(f"count must be a whole number from 0 to the {rows} rows of thetas, got {count!r}")
        return residuals_batch(thetas, self.data(), jnp.asarray(count, jnp.int32))


def _check_precision(d: "ModelData", lc: LightCurve) -> None:
    """RuntimeError where float64 data became float32 arrays with JAX's
    float64 on: JAX 0.10's ``jax.enable_x64`` context in one thread leaks
    into others (``jnp.asarray`` of a float64 array gave float32 in ~30 %
    of the calls of a thread beside one inside ``enable_x64(False)``), and a
    fit of those arrays converged, "successfully", to another point."""
    if not jax.config.jax_enable_x64:
        return
    for name, data, arr in (("flux", lc.flux, d.y), ("flux_err", lc.flux_err, d.sigma), ("time", lc.time, d.t)):
        if np.asarray(data).dtype == np.float64 and arr.dtype != jnp.float64:
            raise RuntimeError(
                f"the light curve's {name} (float64) became a {arr.dtype} array although JAX's float64 is on: "
                "most likely another thread inside a jax.enable_x64 context changed this thread's arrays (JAX's "
                "context leaks into other threads); run float32 and float64 work in separate processes")


def _build(model: "Model") -> "ModelData":
    """``ModelData.build`` as concrete arrays even inside a trace (a tracer
    kept in the Model would leak into later calls)."""
    with jax.ensure_compile_time_eval():
        return ModelData.build(model)


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


class ModelData(eqx.Module):
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
    def build(model: "Model") -> "ModelData":
        """The arrays the compiled model needs, from ``model``: the computed
        and union frames padded to power-of-two buckets (fewer recompiles)."""
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
        return ModelData(system, jnp.asarray(np.asarray(model.t_model)[act]), jnp.asarray(act), jnp.asarray(union),
                     model.y, model.sigma, jnp.asarray(model.alpha, float), jnp.asarray(model.basis, float),
                     tuple(model.slots), int(model.nsub),
                     int(model.t_model.size), case,
                     tuple(not pl.circular or k in _ecc_planets(model.slots) for k, pl in enumerate(model.system.planets)))


def system_at(theta, base: System, slots, eccentric=None) -> System:
    """The system at theta. ``eccentric`` (static flags per planet; None: take
    e and omega of every planet, for a concrete ``base``) says which planets
    keep their e and omega: inside a traced program ``base``'s leaves are
    tracers, so a circular planet given its traced e = 0 would take the
    slower Keplerian path."""
    # listed transit times: as given, except the free ones ("b.tc[12]")
    nbody = base.orbits == "nbody"
    planets = [dict(period=p.period, t0=p.t0, a=p.a, inc=p.inc, radius=p.radius, name=p.name,
                    transit_times=p.transit_times, transit_epochs=p.transit_epochs, lnode=p.lnode, mass=p.mass,
                    moons=p.moons)
               for p in base.planets]
    for k, p in enumerate(base.planets):
        if eccentric is None or eccentric[k]:
            planets[k].update(e=p.e, omega=p.omega)
    star_params = base.star.params
    options = base.nbody_options()
    b_theta, q, ecc = {}, {}, {}
    for k, (owner, par) in enumerate(slots):
        v = theta[k]
        if owner == "lc":
            continue
        if par in ("q1", "q2"):
            q[par] = jax.nn.sigmoid(v)
        elif owner == "star" and par in ("mass", "radius"):
            options["star_" + par] = jnp.exp(v)
        elif is_moon(par):
            _, m, element = par
            moons = list(planets[owner]["moons"])
            moons[m] = eqx.tree_at(lambda mo: getattr(mo, element), moons[m],
                                   jnp.exp(v) if element in _MOON_LOG else v)
            planets[owner]["moons"] = tuple(moons)
        elif par == "mass":
            planets[owner]["mass"] = jnp.exp(v)
        elif par == "lnode":
            planets[owner]["lnode"] = v
        elif owner == "star":
            star_params = star_params.at[par].set(v)
        elif is_tc(par):
            planets[owner]["transit_times"] = jnp.asarray(planets[owner]["transit_times"], float).at[par[1]].set(v)
        elif par == "t0":
            planets[owner]["t0"] = v
        elif par == "period":
            planets[owner]["period"] = jnp.exp(v)
        elif par == "a":
            planets[owner]["a"] = 1.0 + jnp.exp(v)
        elif par == "radius":
            planets[owner]["radius"] = jnp.exp(v)
        elif par in ECC_PARAMS:
            ecc.setdefault(owner, {})[par] = v
        else:
            b_theta[owner] = v
    for owner, xy in ecc.items():  # (secosw, sesinw) in the disk e < e_cap (._ecc)
        e, w = e_omega(*pair_from_theta(xy["secosw"], xy["sesinw"], ecc_cap(base, owner)))
        planets[owner].update(e=e, omega=w)
    if nbody:  # a is derived (Kepler's third law, Jacobi masses): from the masses at theta
        from ..model._nbody import semi_major_axis

        inner = 0.0
        for pl in planets:
            inner = inner + pl["mass"]
            pl["a"] = semi_major_axis(pl["period"], options["star_mass"] + inner, options["star_radius"])
    for owner, v in b_theta.items():  # the impact parameter b -> inc at this e, omega
        pl = planets[owner]
        b = (1.0 + pl["radius"]) * jnp.tanh(v)
        f = conjunction_factor(pl["e"], pl["omega"]) if "e" in pl else 1.0
        pl["inc"] = jnp.rad2deg(jnp.arccos(b / (pl["a"] * f)))
    if nbody:
        for pl in planets:
            pl["a"] = None
    if q:
        q1_0, q2_0 = kipping_q(star_params[0], star_params[1])
        u1, u2 = kipping_u(q.get("q1", q1_0), q.get("q2", q2_0))
        star_params = jnp.stack([u1, u2])
    star = dataclasses.replace(base.star, params=star_params)
    return System(star, [Planet(**p) for p in planets], base.tilted, **options)


@eqx.filter_jit
def theta_of(system: System, start: System, slots: tuple, jitter0) -> jnp.ndarray:
    """theta (the unconstrained coordinates, in the order of ``slots``) of
    ``system``'s values, for a Model of ``start`` (whose eccentricity caps
    apply) with jitter start ``jitter0``: ``Model.to_theta`` in one program."""
    out = []
    for (owner, par) in slots:
        if owner == "lc":
            out.append(jnp.log(jitter0) if par == "jitter" else 0.0)
            continue
        if owner == "star":
            if par in ("mass", "radius"):
                out.append(jnp.log(system.star_mass if par == "mass" else system.star_radius))
            elif par in ("q1", "q2"):
                q = kipping_q(system.star.params[0], system.star.params[1])[0 if par == "q1" else 1]
                out.append(logit(q))
            else:
                out.append(system.star.params[par])
            continue
        pl = system.planets[owner]
        if is_moon(par):
            v = planet_value(pl, par)
            out.append(jnp.log(v) if par[2] in _MOON_LOG else v)
        elif par in ("t0", "lnode") or is_tc(par):
            out.append(planet_value(pl, par))
        elif par in ("period", "mass"):
            out.append(jnp.log(getattr(pl, par)))
        elif par == "a":
            out.append(jnp.log(pl.a - 1.0))
        elif par == "radius":
            out.append(jnp.log(pl.radius))
        elif par in ECC_PARAMS:
            x = theta_from_pair(*pair_of(pl.e, pl.omega), ecc_cap(start, owner))
            out.append(x[ECC_PARAMS.index(par)])
        else:  # inc -> b = (1 + p) tanh(theta), b the impact parameter
            b = pl.impact
            out.append(jnp.arctanh(jnp.clip(b / (1.0 + pl.radius), -0.999999, 0.999999)))
    return jnp.stack([jnp.asarray(v, float) for v in out])


# Model.to_system in one program (traced inside others as it is)
_system_program = eqx.filter_jit(system_at)


def _flux(theta, d: ModelData) -> jnp.ndarray:
    from ..model._terms import separate_frames

    sysm = system_at(theta, d.system, d.slots, d.eccentric)
    x, y, r = sysm.positions(d.t, d.alpha, d.case)
    for o in _ecc_planets(d.slots):  # an orbit through the star: NaN (._ecc)
        x = jnp.where(periastron_ok(sysm.planets[o]), x, jnp.nan)
    fa = separate_frames(sysm.star, x, y, r, 24)
    if d.union.size:
        u = d.union
        fa = fa.at[u].set(union_frames(sysm.star, x[u], y[u], r[u], fa[u]))
    f = jnp.ones((d.n_model,), fa.dtype).at[d.act].set(fa)
    return f.reshape(-1, d.nsub).mean(-1)


UNION_BLOCK = 16  # union-integral frames per block of ``union_frames``


def union_frames(star, x, y, r, separate) -> jnp.ndarray:
    """The flux of frames ([frame, disk] x, y, r [R*]) where two disks may
    meet: the exact union integral in each block of ``UNION_BLOCK``
    consecutive frames where some pair of disks on the star overlaps, and
    ``separate`` (the one-disk sum of those frames, which the union integral
    equals where no disks overlap) in the others. The blocks run one after
    another (``jax.lax.map``) with ``jax.lax.cond``, so at a tilt or
    parameters where the planets do not meet in a block its union integral
    is not computed; under ``jax.vmap`` the cond computes both and selects
    (the same values)."""
    from ..model._terms import exact_frames

    n, k = x.shape
    pad = -n % UNION_BLOCK
    if pad:
        x, y, r, separate = (jnp.concatenate([v, jnp.repeat(v[-1:], pad, axis=0)]) for v in (x, y, r, separate))
    nb = (n + pad) // UNION_BLOCK
    xb, yb, rb = (v.reshape(nb, UNION_BLOCK, k) for v in (x, y, r))
    sb = separate.reshape(nb, UNION_BLOCK)

    def block(args):
        xs, ys, rs, ss = args
        on = (rs > 0) & (jnp.hypot(xs, ys) < 1.0 + rs)
        touch = jnp.zeros((), bool)
        for i in range(k):
            for j in range(i + 1, k):
                dij = jnp.hypot(xs[:, i] - xs[:, j], ys[:, i] - ys[:, j])
                touch = touch | jnp.any(on[:, i] & on[:, j] & (dij < rs[:, i] + rs[:, j]))
        return jax.lax.cond(touch, lambda: exact_frames(star, xs, ys, rs, 24), lambda: ss)

    return jax.lax.map(block, (xb, yb, rb, sb)).reshape(-1)[:n]


def _trend(theta, d: ModelData) -> jnp.ndarray:
    """Multiplicative trend 1 + basis @ c of the offset / baseline slots."""
    idx = [k for k, slot in enumerate(d.slots) if is_trend(slot)]
    if not idx:
        return jnp.ones(())
    return 1.0 + d.basis @ jnp.stack([theta[k] for k in idx])


def _variance(theta, d: ModelData):
    """(sigma^2 + s^2, s^2) with the jitter s when it is free, else (sigma^2, None)."""
    for k, (owner, par) in enumerate(d.slots):
        if par == "jitter":
            s2 = jnp.exp(2.0 * theta[k])
            return d.sigma**2 + s2, s2
    return d.sigma**2, None


@stored(filtered=True)
def residuals(theta, d: ModelData) -> jnp.ndarray:
    """Residuals whose sum of squares is the objective: (y - model) /
    sigma, and with a free jitter s also sqrt(ln(1 + s^2 / sigma_i^2)) per
    point, so that the sum of squares is -2 ln L - sum ln(2 pi sigma_i^2):
    the full likelihood, whose log-variance term keeps s from growing
    without bound (chi^2 alone would be minimised by s -> infinity)."""
    var, s2 = _variance(theta, d)
    model = _flux(theta, d)
    if any(is_trend(slot) for slot in d.slots):
        model = model * _trend(theta, d)
    if s2 is None:
        return (d.y - model) / d.sigma
    return jnp.concatenate([(d.y - model) / jnp.sqrt(var), jnp.sqrt(jnp.log1p(s2 / d.sigma**2))])


@stored(filtered=True)
def pointwise_loglike(theta, d: ModelData) -> jnp.ndarray:
    """Gaussian log-likelihood of each data point (jitter included)."""
    var, _ = _variance(theta, d)
    r = d.y - _flux(theta, d) * _trend(theta, d)
    return -0.5 * r**2 / var - 0.5 * jnp.log(2.0 * jnp.pi * var)


@stored(filtered=True)
def chi2_batch(thetas, d: ModelData):
    """Sum of squared residuals at each row of ``thetas`` (lax.map)."""
    return jax.lax.map(lambda t: jnp.sum(residuals(t, d) ** 2), thetas)


@stored(filtered=True)
def residuals_batch(thetas, d: ModelData, count):
    """Residuals at the first ``count`` rows of ``thetas``, the other rows
    zero (a loop that stops there: a batch padded to the program's rows
    costs only its own)."""
    shape = jax.eval_shape(lambda t: residuals(t, d), thetas[0])
    out = jnp.zeros((thetas.shape[0],) + shape.shape, shape.dtype)
    return jax.lax.fori_loop(0, jnp.minimum(count, thetas.shape[0]),
                             lambda i, acc: acc.at[i].set(residuals(thetas[i], d)), out)


def _ecc_planets(slots) -> list:
    """The planets whose secosw, sesinw are free, in slot order."""
    return list(dict.fromkeys(o for o, p in slots if p in ECC_PARAMS))


def _derived(system: System, slots) -> jnp.ndarray:
    """``Model.derived`` of ``system``, the system at theta."""
    out = [system.star.params[:2]] if any(p in ("q1", "q2") for _, p in slots) else []
    out += [jnp.stack([system.planets[o].e, system.planets[o].omega]) for o in _ecc_planets(slots)]
    return jnp.concatenate(out) if out else jnp.zeros(0)


def _physical(theta, system: System, slots, base: System) -> jnp.ndarray:
    """The free parameters in physical units (``Model.physical``) of
    ``system``, the system at theta (``base``: the start)."""
    out = []
    index = {slot: k for k, slot in enumerate(slots)}
    for k, (owner, par) in enumerate(slots):
        if par in ECC_PARAMS:  # from theta: sqrt(e) has no derivative at e = 0
            xy = (theta[index[(owner, "secosw")]], theta[index[(owner, "sesinw")]])
            out.append(pair_from_theta(*xy, ecc_cap(base, owner))[ECC_PARAMS.index(par)])
        elif par in ("q1", "q2"):
            out.append(jax.nn.sigmoid(theta[k]))
        elif par == "jitter":
            out.append(jnp.exp(theta[k]))
        elif owner == "lc":
            out.append(theta[k])
        else:
            out.append(star_value(system, par) if owner == "star" else planet_value(system.planets[owner], par))
    return jnp.stack(out)


@stored(filtered=True)
def physical_jacobian(theta, d: ModelData):
    """(d q / d theta, q): q the free parameters in physical units, then
    the derived quantities (``Model.derived``)."""
    def values(th):
        system = system_at(th, d.system, d.slots, d.eccentric)
        q = jnp.concatenate([_physical(th, system, d.slots, d.system), _derived(system, d.slots)])
        return q, q

    return jax.jacfwd(values, has_aux=True)(theta)
