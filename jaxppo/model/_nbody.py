"""Sky positions of planets moved by their mutual gravity (photodynamics).

The orbits are integrated by the differentiable N-body code ``jnkepler``
(Masuda et al.; the symplectic Wisdom-Holman map with TTVFast's third-order
corrector, in Jacobi coordinates, with a fixed step), not by an integrator
of jaxppo's own; jaxppo only reads its states at the requested times and
puts them in its sky frame (docs/conventions.md).

Initial conditions: osculating Jacobi elements at the time ``epoch`` (the
convention of jnkepler, TTVFast and REBOUND's default ``primary``): planet j
orbits the centre of mass of the star and planets 0..j-1 with
GM = G (M_star + m_0 + ... + m_j); its period, eccentricity e, argument of
periastron omega, inclination i, longitude of the ascending node Omega and
the time of inferior conjunction (mid-transit) ``tic`` of that osculating
orbit fix its state at ``epoch``.

Positions at arbitrary times: the map is run once on the grid
t_k = epoch + k dt (forward, and backward in the same compiled call when a
time precedes ``epoch``); each state is brought back from the map's
half-step offset to t_k (a Kepler drift of -dt/2, as jnkepler's transit
finders do). The state at the grid point nearest to t is then advanced by
tau = t - t_k with one drift-kick-drift step of size tau (jnkepler's
``kepler_kick_kepler_map``, the step its fast transit finder takes to reach
a transit time); |tau| <= dt/2, and <= dt within dt/2 of ``epoch`` (the
state at k = 0 is not stored). The positions are the map's (mapping)
coordinates, like jnkepler's transit times: TTVFast's corrector is not
undone at output. Measured against REBOUND's IAS15 for Kepler-51
(benchmarks/nbody_vs_rebound.py; P_b = 45 d): the error is the map's, a
bounded oscillation proportional to dt^2 and the planet/star mass ratios
(no secular growth over 1450 d), 3e-6 R* at the default dt = P_min / 40
(0.6e-6 at P_min / 90, 1.3e-5 at P_min / 20), the same at grid points and
half-way between them, so the read-out step adds nothing measurable;
mid-transit times within 0.0004 min (0.03 s). The positions are smooth in
the parameters; in t they jump at the half-way points t_k + dt/2 by up to
0.6e-6 R* (default dt), and are continuous at ``epoch``.

Frame: jnkepler (like REBOUND) puts the observer on +z and a transiting
planet moves towards -x at conjunction; jaxppo's planets move towards +x.
Gravity is symmetric under the mirror x -> -x, so jaxppo's sky position of
a planet is (-x, y, z) of its astrocentric position divided by the stellar
radius. Then Omega is exactly jaxppo's tilt alpha (x' = x cos a + y sin a,
y' = -x sin a + y cos a) and the orbit of a planet with Omega = 0 is
:meth:`jaxppo.Planet.position` of the same elements: i < 90 deg crosses
y > 0. Unlike :meth:`jaxppo.System.positions`, the sign of cos i is kept
(mutual inclinations act on the dynamics): i and 180 - i differ here, and
(i, Omega) -> (180 - i, -Omega) for every planet mirrors y -> -y.

jnkepler switches JAX to float64 when it is imported; jaxppo never flips
that switch for its user, so jnkepler is imported on first use and the
user's setting is put back afterwards (N-body positions in float32 warn).
"""

from __future__ import annotations

import math
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike

from ._planet import check_periastron, never_transits, warn_if_never_transits

__all__ = ["nbody_positions", "nbody_xyz", "semi_major_axis", "default_dt", "check_reliable", "ENERGY_TOLERANCE",
           "ENERGY_TOLERANCE_32", "energy_tolerance",
           "HILL_TOLERANCE", "R_SUN_AU", "G_AU_DAY"]

#: Nominal solar radius (IAU 2015 B3, 695 700 km) in au (IAU 2012, 149 597 870.7 km).
R_SUN_AU = 695700.0 / 149597870.7
#: G in au^3 / (M_sun d^2): the Gaussian constant squared, as in jnkepler and TTVFast.
G_AU_DAY = 2.959122082855911e-4

_JNKEPLER: dict = {}


def _jnkepler() -> dict:
    """jnkepler's functions, imported once with the user's float64 setting kept."""
    if not _JNKEPLER:
        x64 = bool(jax.config.jax_enable_x64)
        try:
            with warnings.catch_warnings():
                # its advice on XLA_FLAGS for CPU speed (see benchmarks/nbody_vs_rebound.py)
                warnings.filterwarnings("ignore", message="For CPU performance", category=UserWarning)
                from jnkepler.jaxttv.conversion import G, jacobi_to_astrocentric
                from jnkepler.jaxttv.symplectic import integrate_xv, kepler_kick_kepler_map, kepler_step_map
                from jnkepler.jaxttv.utils import initialize_jacobi_xv
        except ImportError as err:  # pragma: no cover - depends on the environment
            raise ImportError("N-body orbits need the package jnkepler: pip install jnkepler") from err
        finally:
            jax.config.update("jax_enable_x64", x64)
        if not math.isclose(G, G_AU_DAY, rel_tol=1e-12):  # pragma: no cover - a future jnkepler
            raise ImportError(f"jnkepler's G = {G} differs from jaxppo's G_AU_DAY = {G_AU_DAY}")
        _JNKEPLER.update(integrate_xv=integrate_xv, kkk=kepler_kick_kepler_map, drift=kepler_step_map,
                         init=initialize_jacobi_xv, to_astro=jacobi_to_astrocentric)
    return _JNKEPLER


def semi_major_axis(period: ArrayLike, mass: ArrayLike, star_radius: ArrayLike) -> Array:
    """Semi-major axis [R*] of a Keplerian orbit of period P about mass M.

    Kepler's third law a^3 = G M P^2 / (4 pi^2) with :data:`G_AU_DAY`,
    divided by the stellar radius (:data:`R_SUN_AU`). For the Jacobi orbit
    of planet j, M is the star's mass plus the masses of planets 0..j.

    Parameters
    ----------
    period : array_like
        Orbital period P [d].
    mass : array_like
        Total mass M the orbit feels [M_sun].
    star_radius : array_like
        Stellar radius [R_sun].

    Returns
    -------
    jax.Array
        a [R*], the broadcast shape of the inputs.

    Examples
    --------
    >>> from jaxppo.model._nbody import semi_major_axis
    >>> print(f"{float(semi_major_axis(365.256363, 1.0, 1.0)):.2f}")  # the Earth, in R_sun
    215.03
    """
    period, mass = jnp.asarray(period, float), jnp.asarray(mass, float)
    a_au = (G_AU_DAY * mass * period**2 / (4.0 * np.pi**2)) ** (1.0 / 3.0)
    return a_au / (jnp.asarray(star_radius, float) * R_SUN_AU)


_Q_REF = 1e-4  # the mass ratio up to which default_dt is P (1 - e)^1.5 / 40


def default_dt(periods, eccs, mass_ratios=None) -> float:
    """The default step [d] of the map: min over planets of P (1 - e)^1.5 /
    40, times sqrt(1e-4 / q_max) where the largest planet-to-star mass ratio
    q_max exceeds 1e-4.

    P / 40 for circular orbits (Kepler-51: 3e-6 R* from REBOUND's IAS15);
    the factor (1 - e)^1.5 keeps about 40 steps per periastron passage of an
    eccentric orbit (its time scale there is P (1 - e)^1.5). The map's error
    grows as q dt^2 (the planets' pulls on each other are what it
    approximates): against IAS15 over 2000 d, a planet at P = 8 d beside a
    companion of q = 1.2e-4, 1.2e-3 and 2.5e-2 was off by 0.07, 0.9 and 25 s
    in its transit times at P (1 - e)^1.5 / 40; the factor holds them near
    0.1 s for well-separated planets (more steps for a heavier system: 3.2
    times for a Jupiter around the Sun). Near a resonance the error grows
    faster than q (a Jupiter-mass companion near 5:3: 3.7 s, 44.5 s
    before): halve dt there until the times stop moving. ``mass_ratios``:
    m_planet / M_star of each planet (None: no factor)."""
    periods, eccs = np.atleast_1d(np.asarray(periods, float)), np.atleast_1d(np.asarray(eccs, float))
    dt = float(np.min(periods * (1.0 - eccs) ** 1.5)) / 40.0
    if mass_ratios is not None and np.size(mass_ratios):
        q_max = float(np.max(np.asarray(mass_ratios, float)))
        if q_max > _Q_REF:
            dt *= math.sqrt(_Q_REF / q_max)
    return dt


def _concrete(value, name: str, why: str) -> np.ndarray:
    try:
        return np.asarray(value, dtype=float)
    except (jax.errors.TracerArrayConversionError, jax.errors.ConcretizationTypeError):
        raise ValueError(f"{name} must be concrete ({why})") from None


def _grid(t, epoch: float, dt: float, t_range) -> tuple[int, int, float, float]:
    """Numbers of forward and backward map steps that cover the times (rounded up by :func:`_bucket`), and
    the span (t_min, t_max) they must cover."""
    if t_range is None:
        tc = _concrete(t, "t", "it fixes the integration grid; under jit pass t_range=(t_min, t_max)")
        if tc.size == 0 or not np.all(np.isfinite(tc)):
            raise ValueError("t must be a non-empty array of finite times [d]")
        lo, hi = float(tc.min()), float(tc.max())
    else:
        lo, hi = (float(v) for v in t_range)
        if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
            raise ValueError(f"t_range must be finite (t_min, t_max) with t_min <= t_max, got {t_range!r}")
    n_fwd = _bucket(max(1, int(np.floor((hi - epoch) / dt + 0.5)) + 1))
    n_bwd = _bucket(int(np.floor((epoch - lo) / dt + 0.5)) + 1) if lo < epoch else 0
    return n_fwd, n_bwd, lo, hi


def _bucket(n: int) -> int:
    """n rounded up to a power of two (at least 64): spans of similar length share one compiled program."""
    return max(64, 1 << (int(n) - 1).bit_length())


def _grid_states(elements, epoch, dt: float, n_fwd: int, n_bwd: int) -> tuple[Array, Array, tuple]:
    """The map's states at t_k = epoch + k dt for k = -n_bwd..-1, 1..n_fwd: [n_bwd + n_fwd, 2, n_planets, 3]
    (Jacobi positions and velocities [au, au/d]), the masses [M_sun] (star first) and the states'
    :func:`_reliability` (energy error, closest pair in mutual Hill radii, that pair), each [n_bwd + n_fwd].

    jnkepler's ``integrate_xv`` returns each state dt/2 past t_k (after the
    closing half drift); a drift of -dt/2 brings it back. A backward run
    (step -dt) is batched with the forward one: one compiled integration."""
    jk = _jnkepler()
    x0, v0, masses = jk["init"](elements, epoch)
    if not n_bwd:
        _, xv = jk["integrate_xv"](x0, v0, masses, epoch + dt * jnp.arange(n_fwd + 1))
        states = jnp.stack(jk["drift"](xv[:, 0], xv[:, 1], masses, -0.5 * dt), axis=1)
        return states, masses, _reliability(x0, v0, states, masses)
    n = max(n_fwd, n_bwd)
    sign = jnp.array([1.0, -1.0])
    times = epoch + dt * sign[:, None] * jnp.arange(n + 1)
    _, xv = jax.vmap(jk["integrate_xv"], (None, None, None, 0))(x0, v0, masses, times)
    xv = jnp.stack(jax.vmap(jk["drift"], (0, 0, None, 0))(xv[:, :, 0], xv[:, :, 1], masses, -0.5 * dt * sign), axis=2)
    states = jnp.concatenate([xv[1, :n_bwd][::-1], xv[0, :n_fwd]], axis=0)
    return states, masses, _reliability(x0, v0, states, masses)


#: The largest relative change |E / E_0 - 1| of the total energy (in the
#: centre-of-mass frame) over the integrated span that a System accepts.
#: Stable systems at the default step stay far below it (docs/photodynamics.md:
#: Kepler-51 3.6e-8, two Jupiters near 2:1 2.4e-7, near 5:3 4.3e-7 over
#: 1,500-2,850 d, each falling as dt^2); planets that scatter exceed it.
ENERGY_TOLERANCE = 1e-5
#: The same in float32 (x64 off), whose round-off alone drifts the energy by
#: 1e-5 over Kepler-51's 9,000 d: the energy test then catches only gross
#: failures, the Hill test (precision-free) the close encounters.
ENERGY_TOLERANCE_32 = 1e-3


def energy_tolerance() -> float:
    """The energy tolerance of the current precision: ``ENERGY_TOLERANCE``
    with float64 (x64 on), ``ENERGY_TOLERANCE_32`` without."""
    return ENERGY_TOLERANCE if jax.config.jax_enable_x64 else ENERGY_TOLERANCE_32


#: The least separation of two planets, in mutual Hill radii, that a System
#: accepts: closer, their pull on each other exceeds the star's tidal pull
#: (a close encounter), which the Wisdom-Holman map in Jacobi coordinates
#: cannot follow at a fixed step. Stable systems keep well above it (2.2 for
#: a planet at 8 d inside a brown dwarf at 17.6 d; 3.4-13 for the others above).
HILL_TOLERANCE = 1.0


def _reliability(x0, v0, states, masses) -> tuple[Array, Array, Array]:
    """Per grid state [n]: the relative change of the total energy from the
    initial state (x0, v0), the least separation of two planets in mutual
    Hill radii ((m_i + m_j) / (3 M*))^(1/3) (r_i + r_j) / 2 (r: astrocentric
    distances), and the index of that pair in ``np.triu_indices(n_planets, 1)``.
    Not differentiated (they only decide whether the result is kept)."""
    jk = _jnkepler()
    xj = jax.lax.stop_gradient(jnp.concatenate([x0[None], states[:, 0]]))
    vj = jax.lax.stop_gradient(jnp.concatenate([v0[None], states[:, 1]]))
    m = jax.lax.stop_gradient(masses)
    xa, va = jk["to_astro"](xj, vj, m)  # [n + 1, n_planets, 3]
    mp, ms = m[1:], m[0]
    v_cm = jnp.sum(mp[:, None] * va, axis=1) / jnp.sum(m)  # the barycentre's velocity, astrocentric
    kinetic = 0.5 * ms * jnp.sum(v_cm**2, -1) + 0.5 * jnp.sum(mp * jnp.sum((va - v_cm[:, None]) ** 2, -1), -1)
    r = jnp.sqrt(jnp.sum(xa**2, -1))
    potential = -G_AU_DAY * ms * jnp.sum(mp / r, -1)
    i, j = np.triu_indices(mp.size, 1)
    if i.size:
        d = jnp.sqrt(jnp.sum((xa[:, i] - xa[:, j]) ** 2, -1))
        potential = potential - G_AU_DAY * jnp.sum(mp[i] * mp[j] / d, -1)
        hill = d / (((mp[i] + mp[j]) / (3.0 * ms)) ** (1.0 / 3.0) * 0.5 * (r[:, i] + r[:, j]))
        closest, pair = jnp.min(hill[1:], -1), jnp.argmin(hill[1:], -1)
    else:
        closest, pair = jnp.full(states.shape[0], jnp.inf), jnp.zeros(states.shape[0], int)
    energy = kinetic + potential
    return jnp.abs(energy[1:] / energy[0] - 1.0), closest, pair


def _read_out(t, states, masses, epoch, dt: float, n_fwd: int, n_bwd: int) -> Array:
    """Astrocentric positions [au] in jnkepler's frame at times t (1D): [n_times, n_planets, 3].

    The grid state nearest to t (k = 0 is not stored: times within dt/2 of
    the epoch start from k = +-1, |tau| <= dt) is advanced by one
    drift-kick-drift step of size tau = t - t_k."""
    jk = _jnkepler()
    k = jnp.round((t - epoch) / dt)
    k = jnp.where((t >= epoch) | (n_bwd == 0), jnp.clip(k, 1, n_fwd), jnp.clip(k, -n_bwd, -1))
    idx = jnp.where(k > 0, k - 1 + n_bwd, k + n_bwd).astype(jnp.int32)
    xj, vj = jk["kkk"](states[idx, 0], states[idx, 1], masses, t - (epoch + k * dt))
    return jk["to_astro"](xj, vj, masses)[0]


_states_jit = jax.jit(_grid_states, static_argnames=("dt", "n_fwd", "n_bwd"))
_read_out_jit = jax.jit(_read_out, static_argnames=("dt", "n_fwd", "n_bwd"))


def nbody_xyz(t: ArrayLike, *, periods, eccs, omegas, incs, lnodes, tics, masses, star_mass, star_radius,
              epoch: float, dt: float | None = None, t_range=None) -> tuple[Array, Array, Array]:
    """Sky positions (x, y, z) [R*] of N-body planets at times t [d].

    The orbits from osculating Jacobi elements at ``epoch``, integrated by
    jnkepler and read at every time (module docstring: the method and its
    error); jaxppo's sky frame (docs/conventions.md): x right, y up, z
    towards the observer, the star at the origin. Jit-able and
    differentiable in t, the elements and the masses (the grid is static:
    ``dt``, ``epoch`` and the span of the times must be concrete).

    Parameters
    ----------
    t : array_like
        Times [d], any shape.
    periods : array_like
        Osculating Jacobi periods [d], [n_planets].
    eccs, omegas : array_like
        Eccentricities and arguments of periastron [deg] (docs/conventions.md:
        omega = 90 deg puts periastron at transit), [n_planets].
    incs : array_like
        Inclinations [deg] in [0, 180] (the sign of cos i is kept), [n_planets].
    lnodes : array_like
        Longitudes of the ascending node Omega [deg], jaxppo's tilt alpha of
        each orbit, [n_planets].
    tics : array_like
        Times of inferior conjunction (mid-transit) of the osculating orbits [d], [n_planets].
    masses : array_like
        Planet masses [M_sun], [n_planets].
    star_mass : float
        Stellar mass [M_sun].
    star_radius : float
        Stellar radius [R_sun] (the unit of x, y, z).
    epoch : float
        Time [d] at which the elements osculate (concrete).
    dt : float, optional
        Step of the map [d] (concrete). Default :func:`default_dt`, the
        shortest P (1 - e)^1.5 / 40, shorter for planets heavier than 1e-4
        of the star (needs concrete periods, e and masses).
    t_range : tuple of float, optional
        (t_min, t_max) [d] the grid must cover; needed when ``t`` is traced,
        default the span of ``t``. Times outside it are still evaluated, with
        a step tau larger than dt / 2 and so a larger error.

    Returns
    -------
    x, y, z : jax.Array
        Coordinates [R*], each [*t.shape, n_planets]; z > 0 in front of the star. The
        integration's reliability is not checked here (an N-body System checks
        it: :func:`check_reliable`).

    Raises
    ------
    ValueError
        When ``t`` (without ``t_range``), ``epoch`` or ``dt`` (or the periods,
        without ``dt``) is traced, ``t`` is empty or not finite, the element
        arrays differ in length, or ``dt`` is not positive.

    Examples
    --------
    >>> import jax
    >>> jax.config.update("jax_enable_x64", True)
    >>> from jaxppo.model._nbody import nbody_xyz
    >>> x, y, z = nbody_xyz([100.0], periods=[10.0], eccs=[0.0], omegas=[90.0], incs=[89.0], lnodes=[0.0],
    ...                     tics=[100.0], masses=[1e-10], star_mass=1.0, star_radius=1.0, epoch=95.0)
    >>> print(f"|x| = {abs(float(x[0, 0])):.6f}, y = {float(y[0, 0]):.4f}")  # mid-transit: x = 0, y = b = a cos i
    |x| = 0.000000, y = 0.3409
    """
    return _integrate(t, periods=periods, eccs=eccs, omegas=omegas, incs=incs, lnodes=lnodes, tics=tics,
                      masses=masses, star_mass=star_mass, star_radius=star_radius, epoch=epoch, dt=dt,
                      t_range=t_range)[:3]


def _integrate(t, *, periods, eccs, omegas, incs, lnodes, tics, masses, star_mass, star_radius, epoch, dt,
               t_range):
    """:func:`nbody_xyz`'s (x, y, z) and the integration's reliability on the grid points within a step of
    the span: (t_k, energy error, closest pair in mutual Hill radii, that pair), each [n_k] (see
    :func:`_reliability`; :func:`check_reliable` reads them)."""
    if dt is None:
        dt = default_dt(_concrete(periods, "periods", "the default dt depends on the periods; pass dt"),
                        _concrete(eccs, "eccs", "the default dt depends on the eccentricities; pass dt"),
                        _concrete(masses, "masses", "the default dt depends on the masses; pass dt")
                        / _concrete(star_mass, "star_mass", "the default dt depends on the masses; pass dt"))
    cols = [jnp.atleast_1d(jnp.asarray(v, float)) for v in (periods, eccs, omegas, incs, lnodes, tics, masses)]
    if len({c.shape for c in cols}) != 1 or cols[0].ndim != 1:
        raise ValueError(f"the element arrays must all be 1D of one length, got shapes {[c.shape for c in cols]}")
    period, ecc, omega, inc, lnode, tic, mass = cols
    epoch = float(_concrete(epoch, "epoch", "it fixes the integration grid"))
    dt = float(_concrete(dt, "dt", "it fixes the integration grid"))
    if not dt > 0:
        raise ValueError(f"dt must be > 0 [d], got {dt}")
    if not jax.config.jax_enable_x64:
        warnings.warn("N-body orbits in float32 drift (Kepler-51 over 1450 d: 0.04 R*, 3e-6 R* in float64); "
                      'enable float64: jax.config.update("jax_enable_x64", True)', UserWarning, stacklevel=2)
    n_fwd, n_bwd, lo, hi = _grid(t, epoch, dt, t_range)
    elements = {"period": period, "ecc": ecc, "omega": jnp.deg2rad(omega), "cosi": jnp.cos(jnp.deg2rad(inc)),
                "lnode": jnp.deg2rad(lnode), "tic": tic, "pmass": mass, "smass": jnp.asarray(star_mass, float)}
    t = jnp.asarray(t, float)
    states, masses_all, (err, hill, pair) = _states_jit(elements, epoch, dt=dt, n_fwd=n_fwd, n_bwd=n_bwd)
    xa = _read_out_jit(t.reshape(-1), states, masses_all, epoch, dt=dt, n_fwd=n_fwd, n_bwd=n_bwd)
    xa = xa.reshape(t.shape + xa.shape[1:]) / (jnp.asarray(star_radius, float) * R_SUN_AU)
    tk = epoch + dt * np.concatenate([np.arange(-n_bwd, 0), np.arange(1, n_fwd + 1)])
    sel = (tk >= lo - dt) & (tk <= hi + dt)  # the grid runs on to a power of two: that part is not used
    return -xa[..., 0], xa[..., 1], xa[..., 2], (jnp.asarray(tk[sel]), err[sel], hill[sel], pair[sel])


def nbody_positions(t: ArrayLike, *, periods, eccs, omegas, incs, lnodes, tics, masses, radii, star_mass,
                    star_radius, epoch: float, dt: float | None = None, t_range=None) -> tuple[Array, Array, Array]:
    """Disk centres and radii (x, y, r) [R*] of N-body planets at times t [d].

    The layout of :meth:`jaxppo.System.positions` (r = 0 for a planet
    behind the star, z < 0), ready for :func:`jaxppo.occultation_flux`; the
    positions are those of :func:`nbody_xyz` (the same parameters, and the
    radii).

    Parameters
    ----------
    t : array_like
        Times [d], any shape.
    periods, eccs, omegas, incs, lnodes, tics, masses : array_like
        Osculating Jacobi elements at ``epoch`` and planet masses, each
        [n_planets]; units and meaning as in :func:`nbody_xyz`.
    radii : array_like
        Radius ratios R_p / R* [n_planets].
    star_mass, star_radius : float
        Stellar mass [M_sun] and radius [R_sun].
    epoch : float
        Time [d] at which the elements osculate (concrete).
    dt : float, optional
        Step of the map [d]; default :func:`default_dt`.
    t_range : tuple of float, optional
        (t_min, t_max) the grid covers, needed when ``t`` is traced.

    Returns
    -------
    x, y, r : jax.Array
        Disk centres and radii [R*], each [*t.shape, n_planets].

    Raises
    ------
    ValueError
        As :func:`nbody_xyz`.

    Examples
    --------
    >>> import jax
    >>> jax.config.update("jax_enable_x64", True)
    >>> from jaxppo.model._nbody import nbody_positions
    >>> x, y, r = nbody_positions([100.0, 105.0], periods=[10.0], eccs=[0.0], omegas=[90.0], incs=[89.0],
    ...                           lnodes=[0.0], tics=[100.0], masses=[1e-10], radii=[0.05], star_mass=1.0,
    ...                           star_radius=1.0, epoch=95.0)
    >>> print(r[:, 0])  # in front at mid-transit, behind half a period later
    [0.05 0.  ]
    """
    x, y, z = nbody_xyz(t, periods=periods, eccs=eccs, omegas=omegas, incs=incs, lnodes=lnodes, tics=tics,
                        masses=masses, star_mass=star_mass, star_radius=star_radius, epoch=epoch, dt=dt,
                        t_range=t_range)
    r = jnp.where(z > 0, jnp.atleast_1d(jnp.asarray(radii, float)), 0.0)
    return x, y, r


# ---- an N-body System (jaxppo.System(..., orbits="nbody")) -------------------------------------------------


def _concrete_or_none(value):
    """The value as a numpy array, or None when it is traced."""
    return None if isinstance(value, jax.core.Tracer) else np.asarray(value, float)


def nbody_setup(planets, epoch, star_mass, star_radius, dt, span):
    """Check an N-body System's keywords and derive its planets' a.

    Returns (planets with ``a`` set to the osculating Jacobi semi-major
    axis, star_mass, star_radius, epoch, dt, span); raises ValueError naming
    the keyword and value that is missing or out of range."""
    from ._units import from_quantity

    for name, value in (("epoch", epoch), ("star_mass", star_mass), ("star_radius", star_radius)):
        if value is None:
            raise ValueError(f"orbits='nbody' needs {name} (epoch: the time [d] at which the elements osculate; "
                             "star_mass [M_sun]; star_radius [R_sun])")
    epoch = float(_concrete(from_quantity("epoch", epoch, "d"), "epoch", "it fixes the integration grid"))
    if not math.isfinite(epoch):
        raise ValueError(f"epoch must be a finite time [d], got {epoch!r}")
    star_mass = from_quantity("star_mass", star_mass, "M_sun")
    mass_given = _concrete_or_none(star_mass)  # before jnp.asarray: under jit that is traced
    star_mass = jnp.asarray(star_mass, float)
    star_radius = jnp.asarray(from_quantity("star_radius", star_radius, "R_sun"), float)
    for name, value in (("star_mass", star_mass), ("star_radius", star_radius)):
        v = _concrete_or_none(value)
        if v is not None and not (v.ndim == 0 and np.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
        lo, hi, unit = STAR_RANGES[name]
        if v is not None and not lo <= v <= hi:
            raise ValueError(f"{name} = {float(v):.6g} {unit} is outside {lo:g}..{hi:g} {unit}: {name} is in {unit} "
                             "(a Quantity in other units is converted)")
    periods = [_concrete_or_none(pl.period) for pl in planets]
    if all(p is not None for p in periods):
        if np.any(np.diff(np.asarray(periods, float)) <= 0):
            raise ValueError(f"N-body planets are listed from the inside out (Jacobi coordinates: each orbits the "
                             f"star and the planets inside it), so their periods must increase; got {periods}")
    eccs = [_concrete_or_none(pl.e) for pl in planets]
    masses = [_concrete_or_none(pl.mass) for pl in planets] + [mass_given]
    if dt is None:
        if any(p is None for p in periods + eccs + masses):
            raise ValueError("dt (the N-body step [d]) is needed when the periods, eccentricities or masses are "
                             "traced")
        dt = default_dt(periods, eccs, np.asarray(masses[:-1], float) / masses[-1])
    dt = float(_concrete(from_quantity("dt", dt, "d"), "dt", "it fixes the integration grid"))
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a finite step > 0 [d], got {dt!r}")
    if span is not None:
        try:
            # each end a number of days, a time Quantity or a TimeDelta (or a
            # time Quantity of two values)
            ends = list(span)
            if len(ends) != 2:
                raise ValueError
            lo, hi = (float(from_quantity("span", v, "d")) for v in ends)
        except (TypeError, ValueError, IndexError):
            raise ValueError(f"span must be (t_min, t_max) [d], got {span!r}") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise ValueError(f"span must be finite (t_min, t_max) with t_min <= t_max [d], got {span!r}")
        span = (lo, hi)
    out, inner = [], 0.0
    for pl in planets:
        if pl.transit_times is not None:
            raise ValueError(f"planet {pl.name!r}: N-body orbits make their own transit times; drop transit_times")
        m = _concrete_or_none(pl.mass)
        if m is not None and not m > 0:
            raise ValueError(f"planet {pl.name!r}: an N-body planet needs mass > 0 [M_sun], got {float(m)!r} (the "
                             "integrator divides by the masses; a test particle: 1e-12)")
        inner = inner + pl.mass
        a = semi_major_axis(pl.period, star_mass + inner, star_radius)
        given, derived = _concrete_or_none(pl.a), _concrete_or_none(a)
        if given is not None and derived is not None and not np.isnan(given) and abs(given / derived - 1) > 0.01:
            raise ValueError(
                f"planet {pl.name!r}: a = {float(given):.6g} R* disagrees with Kepler's third law for its period, "
                f"the masses and star_radius ({float(derived):.6g} R*); an N-body System derives a: give a=None")
        out.append(eqx.tree_at(lambda p: p.a, pl, jnp.asarray(a, float)))  # no re-check: a may be traced
        # the derived orbit's checks of a Keplerian Planet (traced values pass):
        # a unit slip in star_radius or star_mass shows here
        why = " (Kepler's third law from its period, the masses and star_radius)"
        check_periastron(pl.name, out[-1].a, pl.e, pl.radius, why)
    _warn_far_epoch(planets, epoch)
    # a planet that does not transit is a perturber, as N-body systems have;
    # none transiting is an inclination in radians or a unit slip
    if all(never_transits(p) is not None for p in out):
        for p in out:
            warn_if_never_transits(p, orbit=f" (its osculating orbit at epoch {epoch:g}, a by Kepler's third law "
                                            "from its period, the masses and star_radius; no planet transits)")
    return tuple(out), star_mass, star_radius, epoch, dt, span


#: The most orbits between ``epoch`` and a planet's t0 an N-body System
#: accepts without a warning: the elements osculate at the epoch and place
#: the planet by t0, so they are usually within a few orbits; an epoch in
#: BJD beside t0 in BKJD (2,454,833 d apart) integrated 6,700 years and put
#: Kepler-51's transits 6 to 43 days off, silently.
FAR_EPOCH_ORBITS = 1000.0


def _warn_far_epoch(planets, epoch: float) -> None:
    """UserWarning naming the planets whose t0 lies more than
    ``FAR_EPOCH_ORBITS`` periods from ``epoch`` (traced values pass)."""
    far = []
    for pl in planets:
        t0, period = _concrete_or_none(pl.t0), _concrete_or_none(pl.period)
        if t0 is not None and period is not None and abs(float(t0) - epoch) > FAR_EPOCH_ORBITS * float(period):
            far.append(f"{pl.name} (t0 = {float(t0):.6g} d, {abs(float(t0) - epoch) / float(period):.3g} orbits)")
    if far:
        warnings.warn(f"N-body planets {', '.join(far)} are more than {FAR_EPOCH_ORBITS:g} orbits from epoch = "
                      f"{epoch:.10g} d, where their elements osculate: are epoch and t0 on one time scale (BJD = "
                      "BKJD + 2454833, BTJD + 2457000)? The orbits are integrated over that whole time",
                      UserWarning, stacklevel=4)


# star_mass [M_sun] and star_radius [R_sun] outside these are a unit slip
# (kg, km, metres), not a star: brown dwarfs and white dwarfs to supergiants
STAR_RANGES = {"star_mass": (1e-3, 1e3, "M_sun"), "star_radius": (1e-3, 1e4, "R_sun")}


def _elements(system, signs, extra_node):
    """jnkepler's element arrays of an N-body System: the tilted planet's
    node turned by ``extra_node`` [deg], and planets of a mirrored hemisphere
    (sign -1) at 180 - inc (their orbit mirrored about its line of nodes)."""
    pls = system.planets
    inc = jnp.stack([jnp.where(signs[i] < 0 and i != system.tilted, 180.0 - p.inc, p.inc)
                     for i, p in enumerate(pls)])
    lnode = jnp.stack([p.lnode + (extra_node if i == system.tilted else 0.0) for i, p in enumerate(pls)])
    return dict(periods=jnp.stack([p.period for p in pls]), eccs=jnp.stack([p.e for p in pls]),
                omegas=jnp.stack([p.omega for p in pls]), incs=inc, lnodes=lnode,
                tics=jnp.stack([p.t0 for p in pls]), masses=jnp.stack([p.mass for p in pls]),
                star_mass=system.star_mass, star_radius=system.star_radius)


def system_xyz(system, t, alpha, signs, t_range=None, checks=False):
    """Sky positions (x, y, z) [R*] of an N-body System's planets at times t,
    the tilted planet's node turned by alpha [deg] (each tilt is its own
    integration: the tilt changes the mutual inclinations and so the
    dynamics). ``alpha`` is a scalar, or [n_alpha, 1, ...] against t of
    shape [1, ...] (one light curve per tilt). ``t_range``: the span the
    grid covers (default the System's ``span``, else that of t).

    The integration's reliability (:func:`check_reliable`): concrete
    results of an unreliable integration raise ValueError; traced ones
    (jit, grad: a fit's or a sampler's model) are NaN, so that the fit
    refuses the step and NUTS the proposal. ``checks=True`` applies neither
    and returns ((x, y, z), the reliability) for the caller to check."""
    t_range = system.span if t_range is None else t_range
    if isinstance(t, jax.core.Tracer) and t_range is None:
        raise ValueError("an N-body System evaluated at traced times (jit) needs span=(t_min, t_max) [d]: "
                         "System(..., orbits='nbody', span=...) fixes the integration grid")
    if not isinstance(t, jax.core.Tracer):  # concrete times: the grid covers them all
        tc = np.asarray(t, float)
        if tc.size:
            lo, hi = float(tc.min()), float(tc.max())
            t_range = (lo, hi) if t_range is None else (min(lo, t_range[0]), max(hi, t_range[1]))
    xyz, rel = _xyz(system, t, alpha, signs, dict(epoch=system.epoch, dt=system.dt, t_range=t_range))
    if checks:
        return xyz, rel
    if not any(isinstance(v, jax.core.Tracer) for v in (t, *xyz, *rel)):
        check_reliable(system, rel)
        return xyz
    # the traced policy: an unreliable integration, or a time beyond the grid (more than a step outside the
    # span), gets NaN positions, never the error of a long read-out step or a scattered orbit
    bad = jnp.any(rel[1] > energy_tolerance()) | jnp.any(rel[2] < HILL_TOLERANCE)
    if t_range is None:
        outside = bad
    else:
        outside = bad | (jnp.asarray(t) < t_range[0] - system.dt) | (jnp.asarray(t) > t_range[1] + system.dt)
    return tuple(jnp.where(jnp.broadcast_to(outside, v.shape[:-1])[..., None], jnp.nan, v) for v in xyz)


def _xyz(system, t, alpha, signs, opts):
    """``system_xyz``'s positions on its grid ``opts`` (epoch, dt, t_range), and the reliability."""
    if jnp.ndim(alpha) == 0 or jnp.size(alpha) == 1:
        x, y, z, rel = _integrate(t, **_elements(system, signs, jnp.reshape(alpha, ())), **opts)
        return (x, y, z), rel
    alpha = jnp.asarray(alpha)
    if any(n != 1 for n in alpha.shape[1:]) or (jnp.ndim(t) >= alpha.ndim and jnp.shape(t)[jnp.ndim(t) - alpha.ndim] != 1):
        raise ValueError(f"an N-body System takes one tilt, or tilts [n_alpha, 1, ...] against times [1, ...]; got "
                         f"alpha of shape {alpha.shape} and t of shape {jnp.shape(t)}")
    t_in = jnp.asarray(t)
    lead = t_in.ndim - alpha.ndim
    if lead >= 0:
        t_in = t_in.reshape(t_in.shape[:lead] + t_in.shape[lead + 1:])
    x, y, z, rel = jax.vmap(lambda a: _integrate(t_in, **_elements(system, signs, a), **opts))(alpha.reshape(-1))
    shape = np.broadcast_shapes(jnp.shape(t), alpha.shape)
    return tuple(v.reshape(shape + (len(system.planets),)) for v in (x, y, z)), rel


def check_reliable(system, reliability) -> None:
    """Raise ValueError when a concrete N-body integration is not reliable.

    Two checks on the map's states at every grid point t_k = epoch + k dt
    within a step of the span (as N-body codes do: REBOUND reports the
    relative energy error; a close encounter breaks a Wisdom-Holman map in
    Jacobi coordinates): the total energy in the centre-of-mass frame
    changed by more than :data:`ENERGY_TOLERANCE` (float32:
    :data:`ENERGY_TOLERANCE_32`) relative to its value at the epoch, or two planets came closer than :data:`HILL_TOLERANCE`
    mutual Hill radii ((m_i + m_j) / (3 M*))^(1/3) (r_i + r_j) / 2.

    Parameters
    ----------
    system : jaxppo.System
        The N-body System (its planets' names and masses, star mass, ``dt``).
    reliability : tuple of array_like
        (t_k [d], relative energy error, least pair separation [mutual Hill
        radii], that pair's index in ``np.triu_indices(n_planets, 1)``), as
        ``system_xyz(..., checks=True)`` returns them.

    Raises
    ------
    ValueError
        Naming the planets that met, when and how close, the largest energy
        error and when it first passed the tolerance, and the step dt: the
        system is unstable, or dt too large.

    Examples
    --------
    >>> import numpy as np
    >>> from jaxppo.model._nbody import check_reliable
    >>> check_reliable(None, (np.array([1.0]), np.array([1e-9]), np.array([5.0]), np.array([0])))  # reliable
    """
    # under a vmap over tilts each is [n_alpha, n_k] (t_k repeated): flat, they stay aligned
    tk, err, hill, pair = (np.asarray(v).reshape(-1) for v in reliability)
    tol = energy_tolerance()
    with np.errstate(invalid="ignore"):
        hot, close = err > tol, hill < HILL_TOLERANCE
    if not (hot.any() or close.any()):
        return
    names = [p.name or str(k) for k, p in enumerate(system.planets)]
    i, j = np.triu_indices(len(names), 1)
    why = []
    if close.any():
        k = int(np.nanargmin(hill))
        first = int(np.argmax(close))
        why.append(f"planets {names[i[pair[k]]]} and {names[j[pair[k]]]} came within {hill[k]:.3g} mutual Hill "
                   f"radii of each other at t = {tk[k]:.6g} d (closer than {HILL_TOLERANCE:g} first at t = "
                   f"{tk[first]:.6g} d: a close encounter, which the Wisdom-Holman map cannot follow)")
    if hot.any():
        k, first = int(np.nanargmax(err)), int(np.argmax(hot))
        why.append(f"the total energy changed by {err[k]:.3g} (relative, at t = {tk[k]:.6g} d; more than "
                   f"{tol:g} first at t = {tk[first]:.6g} d{'' if tol == ENERGY_TOLERANCE else ', float32'})")
    ratios = ", ".join(f"{p.name or k}: {float(p.mass) / float(system.star_mass):.3g}"
                       for k, p in enumerate(system.planets))
    raise ValueError(f"the N-body integration is not reliable over t = {np.min(tk):.6g}..{np.max(tk):.6g} d: "
                     + "; ".join(why) + f". The system is unstable (its planets scatter: no N-body step gives "
                     f"meaningful transit times or fluxes), or the step dt = {system.dt:.4g} d is too large for "
                     f"these planets (planet-to-star mass ratios {ratios}): a stable system's energy error "
                     f"falls as dt^2, so try dt / 4" + _mass_unit_hint(system))


#: A planet-to-star mass ratio above which an N-body error adds that masses
#: are in M_sun (a brown dwarf's is below 0.08; jnkepler's ``pmass``, Earth
#: masses, read as M_sun gives 3 to 5 for Kepler-51).
MASS_RATIO_HINT = 0.1


def _mass_unit_hint(system) -> str:
    """A sentence for N-body errors where a planet outweighs a tenth of its
    star: masses in Earth or Jupiter masses given as M_sun."""
    ratios = [float(p.mass) / float(system.star_mass) for p in system.planets]
    if max(ratios) <= MASS_RATIO_HINT:
        return ""
    return (f". A planet above {MASS_RATIO_HINT:g} of its star's mass: mass is in M_sun (an Earth mass is 3.0e-6 "
            "M_sun, a Jupiter mass 9.55e-4; a Quantity, mass=3.3 * u.M_earth, is converted)")


def _check_finite(system, t, xyz) -> None:
    """ValueError where concrete times inside the integration's span got
    non-finite positions: the map diverged (planets too heavy for the
    star, or an unstable system), named with the mass ratios."""
    if any(isinstance(v, jax.core.Tracer) for v in (t, *xyz)):
        return
    if all(np.all(np.isfinite(np.asarray(v))) for v in xyz):
        return
    ratios = ", ".join(f"{p.name or k}: {float(p.mass) / float(system.star_mass):.3g}"
                       for k, p in enumerate(system.planets))
    raise ValueError(f"the N-body integration diverged (non-finite positions; planet-to-star mass ratios {ratios}): "
                     "the system is unstable, or planets this heavy need a smaller dt than "
                     f"{system.dt:.4g} d (the map assumes planets much lighter than the star)"
                     + _mass_unit_hint(system))


def system_positions(system, t, alpha, signs, xp):
    """The disks (x, y, r) [R*] of ``System.positions`` for N-body orbits
    (r = 0 behind the star); ``xp=numpy`` returns host arrays."""
    x, y, z = system_xyz(system, t, alpha, signs)
    _check_finite(system, t, (x, y, z))
    if any(p.moons for p in system.planets):
        from ._moon import add_moons

        x, y, r = add_moons(system, jnp.asarray(t), alpha, signs, (x, y, z), jnp, kepler=False)
    else:
        r = jnp.where(z > 0, jnp.stack([p.radius for p in system.planets]), 0.0)
    if xp is np:
        return np.asarray(x), np.asarray(y), np.asarray(r)
    return x, y, r


def nbody_transit_times(system, t_start: float, t_end: float) -> list[tuple[int, int, float]]:
    """(planet index, epoch, tc) of every transit of an N-body System's
    planets in [t_start, t_end].

    Mid-transit is the time of least sky-projected distance from the star's
    centre, g = d/dt (x^2 + y^2) / 2 = 0 (jnkepler's and TTVFast's
    definition). g is sampled on a grid of step min P (1 - e)^1.5 / 24 (a
    dozen points per half orbit, so every extremum of the sky distance is
    bracketed, however far the TTVs take the transits from a linear
    ephemeris); each rise of g through 0 with the planet in front (z > 0)
    is an inferior conjunction, refined by Newton steps kept inside its
    bracket (the derivatives by forward differentiation of the positions).
    Conjunctions are numbered consecutively, epoch 0 the one nearest to the
    planet's t0; a conjunction is a transit when its least distance is
    below 1 + radius."""
    n_pl = len(system.planets)
    signs = np.ones(n_pl)
    periods = np.array([float(p.period) for p in system.planets])
    eccs = np.array([float(p.e) for p in system.planets])
    tics = np.array([float(p.t0) for p in system.planets])
    radius = np.array([float(p.radius) for p in system.planets])
    lo = min(t_start, float(tics.min())) - 0.6 * periods.max()
    hi = max(t_end, float(tics.max())) + 0.6 * periods.max()
    h = float(np.min(periods * (1.0 - eccs) ** 1.5)) / 24.0
    grid = lo + h * np.arange(int(np.ceil((hi - lo) / h)) + 1)
    span = (float(grid[0]) - 1.0, float(grid[-1]) + 1.0)

    def state(t):  # (x, y, z), the sky-plane g = x vx + y vy, [n_times, n_planets], and the reliability
        (x, y, z), (vx, vy, _), rel = jax.jvp(lambda tt: system_xyz(system, tt, 0.0, signs, span, checks=True),
                                              (t,), (jnp.ones_like(t),), has_aux=True)
        return x, y, z, x * vx + y * vy, rel

    state_jit = jax.jit(state)
    *out, rel = state_jit(jnp.asarray(grid))
    x, y, z, g = (np.asarray(v) for v in out)
    _check_finite(system, grid, (x, y, z))  # a diverged integration finds a few transits, then none
    check_reliable(system, rel)  # one that scattered its planets finds meaningless ones
    k, j = np.nonzero((g[:-1] < 0) & (g[1:] >= 0) & (z[:-1] + z[1:] > 0))
    if k.size == 0:
        return []
    left, right = grid[k], grid[k + 1]
    g0, g1 = g[k, j], g[k + 1, j]
    t = left + (right - left) * g0 / (g0 - g1)  # the secant root, then Newton inside the bracket
    pick = jnp.asarray(j)

    @jax.jit
    def newton(t):
        def gj(tt):
            return jnp.take_along_axis(state(tt)[3], pick[:, None], 1)[:, 0]

        val, der = jax.jvp(gj, (t,), (jnp.ones_like(t),))
        return t - val / der

    for _ in range(6):
        t_new = np.clip(np.asarray(newton(jnp.asarray(t))), left, right)
        done = np.max(np.abs(t_new - t)) < 1e-10
        t = t_new
        if done:
            break
    x, y, z, _ = (np.asarray(v) for v in state_jit(jnp.asarray(t))[:4])
    rows = []
    for planet in range(n_pl):
        mine = np.nonzero(j == planet)[0]
        mine = mine[np.argsort(t[mine])]
        if mine.size == 0:
            continue
        zero = int(np.argmin(np.abs(t[mine] - tics[planet])))
        for count, m in enumerate(mine):
            d = math.hypot(x[m, planet], y[m, planet])
            if t_start <= t[m] <= t_end and z[m, planet] > 0 and d < 1.0 + radius[planet]:
                rows.append((planet, count - zero, float(t[m])))
    return rows
