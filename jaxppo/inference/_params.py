"""The named free parameters of fits and samplers ("b.t0", "c.radius",
"star.u1", ...) and the coordinates theta that ``._model.Model`` maps
them to, which keep the physics valid: a = 1 + exp(.), p = exp(.),
P = exp(.), and the impact parameter b = (1 + p) tanh(.) (so |b| < 1 + p and
the planet always transits), with i = arccos(b / (a f)), f = (1 - e^2) /
(1 + e sin omega) at the point's e and omega (``._ecc.conjunction_factor``;
1 for a circular orbit).

A planet with ``transit_times`` also has its listed mid-times as
parameters: ``"b.tc[12]"`` (epoch 12; coordinate: the time itself [d]) and
``"b.tc"`` for all of them.

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

import re

import jax.numpy as jnp
import numpy as np

from ..model._lightcurve import LightCurve, cadence_warning, is_lightkurve
from ..model._system import System
from ..model._ttv import epochs_text
from ._ecc import ECC_PARAMS, pair_of

__all__ = ["checked_lightcurve", "PLANET_PARAMS", "MOON_PARAMS", "NBODY_PARAMS", "PERTURBER_PARAMS", "inc_sign_matters", "is_moon", "moon_label", "star_value", "STAR_PARAMS", "LC_PARAMS", "BASELINE_GAP", "kipping_u", "kipping_q", "logit",
           "check_ttv_free", "expand_tc", "is_tc", "planet_value", "tc_name", "as_lightcurve", "parameter_names", "expand_free", "is_trend", "jitter_start"]

PLANET_PARAMS = ("t0", "period", "a", "inc", "radius")
"""The parameters of each planet a fit or a sampler may free."""
MOON_PARAMS = ("period", "t0", "a", "inc", "radius", "mass_ratio", "lnode")
"""The parameters of a moon a fit or a sampler may free, named
"<planet>.<moon>.<parameter>" (the moon's name, or "moon<k>" for the k-th
unnamed moon): coordinates log P, t0, log a, inc [deg], log radius,
log mass_ratio, lnode [deg]."""
NBODY_PARAMS = {"planet": ("mass", "lnode"), "star": ("mass", "radius")}
"""Parameters of N-body systems only: each planet's mass [M_sun] and
longitude of the ascending node [deg], the star's mass [M_sun] and radius
[R_sun] (coordinates: logarithms, except lnode); there a planet's ``a`` is
derived, not free."""
PERTURBER_PARAMS = ("mass", "lnode", "period", "t0")
"""The parameters of an N-body planet that a fit may free although the
planet does not transit (a perturber: the classic TTV inference of a
non-transiting planet's mass): each acts on the transiting planets through
gravity (t0, the time of inferior conjunction of its osculating orbit,
sets its orbital phase). Its radius and inclination stay under the rule
that a planet with a free parameter must transit: the radius acts on no
light then, and the fit's and NUTS's coordinate of the inclination is
the impact parameter of a transiting planet."""

STAR_PARAMS = {"quadratic": ("u1", "u2"), "nonlinear": ("c1", "c2", "c3", "c4"), "power2": ("c", "alpha")}
"""The limb-darkening coefficients of each law, in ``Star.params`` order."""
LC_PARAMS = ("offset", "jitter", "baseline", "baseline2")
"""The light curve's nuisance parameters (module docstring)."""
# [d] a gap longer than this starts a new baseline window (Kepler quarters,
# the multi-transit windows of a scan)
BASELINE_GAP = 0.5


def kipping_u(q1, q2):
    """Quadratic limb-darkening coefficients from Kipping's q1, q2.

    Kipping (2013, eqs. 15-16): u1 = 2 sqrt(q1) q2, u2 = sqrt(q1) (1 - 2 q2).
    Every (q1, q2) in the unit square gives a physical profile (positive
    everywhere, darkening towards the limb), which is why fits and samplers
    free ``"star.q1"``, ``"star.q2"`` rather than u1, u2. Inverse:
    ``kipping_q``.

    Parameters
    ----------
    q1, q2 : float or array_like
        Kipping's coefficients, in [0, 1] (any broadcastable shapes).

    Returns
    -------
    u1, u2 : jax.Array
        The linear and quadratic coefficients of the quadratic law,
        I(mu) / I(1) = 1 - u1 (1 - mu) - u2 (1 - mu)^2 (broadcast shape).

    Examples
    --------
    >>> import jaxppo as jp
    >>> u1, u2 = jp.kipping_u(0.36, 0.25)
    >>> print(f"u1 = {float(u1):.2f}, u2 = {float(u2):.2f}")
    u1 = 0.30, u2 = 0.30
    """
    s = jnp.sqrt(q1)
    return 2.0 * s * q2, s * (1.0 - 2.0 * q2)


def kipping_q(u1, u2):
    """Kipping's q1, q2 from quadratic limb-darkening coefficients.

    The inverse of ``kipping_u`` (Kipping 2013, eqs. 17-18):
    q1 = (u1 + u2)^2, q2 = u1 / (2 (u1 + u2)); q2 = 0.5 when u1 + u2 = 0
    (q1 = 0 then, and any q2 gives u1 = u2 = 0). Coefficients outside the
    physical region give q1 or q2 outside [0, 1].

    Parameters
    ----------
    u1, u2 : float or array_like
        Linear and quadratic coefficients of the quadratic law (any
        broadcastable shapes).

    Returns
    -------
    q1, q2 : jax.Array
        Kipping's coefficients (broadcast shape).

    Examples
    --------
    >>> import jaxppo as jp
    >>> q1, q2 = jp.kipping_q(0.4, 0.25)
    >>> print(f"q1 = {float(q1):.4f}, q2 = {float(q2):.4f}")
    q1 = 0.4225, q2 = 0.3077
    >>> u1, u2 = jp.kipping_u(q1, q2)  # and back
    >>> print(f"u1 = {float(u1):.4f}, u2 = {float(u2):.4f}")
    u1 = 0.4000, u2 = 0.2500
    """
    s = u1 + u2
    return s**2, jnp.where(s == 0, 0.5, u1 / (2.0 * jnp.where(s == 0, 1.0, s)))



def check_ttv_free(system: System, idx: int, par: str, name: str):
    """The slot of a planet parameter tied to transit times, or None for
    any other parameter: ``"b.tc[12]"`` is the listed mid-time of epoch 12
    (slot par ``("tc", k)``, k its position in ``transit_times``). Refused:
    a time of an epoch the planet does not list, and the t0 of a planet with
    ``transit_times`` (its orbit is shifted by tc_n - t0 - n P, so t0
    cancels: a free t0 would move nothing and the fit would be degenerate)."""
    pl = system.planets[idx]
    label = pl.name or str(idx)
    if par.startswith("tc"):
        m = re.fullmatch(r"tc\[\s*(-?\d+)\s*\]", par)
        if pl.transit_times is None and (m is not None or par == "tc"):
            raise ValueError(f"free parameter {name!r}: planet {label!r} has no transit_times; give it "
                             "Planet(..., transit_times=, transit_epochs=) (e.g. its predicted times from "
                             "system.transit_times, or use jaxppo.measure_transit_times)")
        if m is None:
            raise ValueError(f"free parameter {name!r}: a transit time is named like '{label}.tc[12]' (the listed "
                             f"epoch in brackets), or '{label}.tc' for every listed epoch")
        epoch = int(m.group(1))
        if epoch not in pl.transit_epochs:
            raise ValueError(f"free parameter {name!r}: planet {label!r} lists no epoch {epoch} (its transit_epochs "
                             f"are {epochs_text(pl.transit_epochs)})")
        return ("tc", pl.transit_epochs.index(epoch))
    if par == "t0" and pl.transit_times is not None:
        raise ValueError(
            f"free parameter {name!r}: planet {label!r} has transit_times, which fix its mid-times (the "
            "orbit is shifted by tc_n - t0 - n P, so t0 cancels and a free t0 would change nothing); leave t0 "
            f"fixed and free its times ('{label}.tc'), or drop transit_times to fit a linear ephemeris")
    return None


def is_tc(par) -> bool:
    """Whether a planet slot's par is a transit time ("tc", k)."""
    return isinstance(par, tuple) and par[0] == "tc"


def planet_value(pl, par):
    """The value of a planet slot: an attribute, the listed transit time
    of a ("tc", k) slot, or a moon's element of a ("moon", k, name) slot."""
    if is_moon(par):
        return getattr(pl.moons[par[1]], par[2])
    if par in ECC_PARAMS:
        return pair_of(pl.e, pl.omega)[ECC_PARAMS.index(par)]
    return pl.transit_times[par[1]] if is_tc(par) else getattr(pl, par)


def star_value(system: System, par):
    """The value of a star slot: a limb-darkening coefficient (its index),
    or the star's N-body mass / radius."""
    if par in NBODY_PARAMS["star"]:
        return system.star_mass if par == "mass" else system.star_radius
    return system.star.params[par]


def inc_sign_matters(system: System, owner) -> bool:
    """Whether the sign of cos i of planet ``owner`` changes the light
    curve, so that i and 180 deg - i must not be folded together: N-body
    orbits (mutual inclinations act on the dynamics) and a planet with
    moons (the moons' orbits are given on the sky: the planet's hemisphere
    mirror turns them over, docs/conventions.md). Keplerian planets without
    moons cross the star by |cos i| only."""
    return system.orbits == "nbody" or bool(system.planets[owner].moons)


def is_moon(par) -> bool:
    """Whether a planet slot's par is a moon's element ("moon", k, name)."""
    return isinstance(par, tuple) and par[0] == "moon"


def moon_label(moon, k: int) -> str:
    """A moon's label in parameter names: its name, or "moon<k>"."""
    return moon.name or f"moon{k}"


def _moon_slot(system: System, idx: int, par: str, name: str):
    """("moon", k, element) for "b.<moon>.<element>", or None when par names no moon."""
    pl = system.planets[idx]
    sub, _, element = par.partition(".")
    labels = [moon_label(m, k) for k, m in enumerate(pl.moons)]
    if not element or sub not in labels:
        if element:
            raise ValueError(f"free parameter {name!r}: planet {pl.name or idx!r} has no moon {sub!r} (its moons: "
                             f"{labels or 'none'})")
        return None
    if element not in MOON_PARAMS:
        raise ValueError(f"free parameter {name!r}: moon parameters are {MOON_PARAMS}")
    k = labels.index(sub)
    if element == "mass_ratio" and not float(np.asarray(pl.moons[k].mass_ratio)) > 0:
        raise ValueError(f"free parameter {name!r}: a free mass_ratio starts from a value > 0 (its coordinate is "
                         "its logarithm)")
    return ("moon", k, element)


def tc_name(pl, idx: int, k: int) -> str:
    """The public name "b.tc[12]" of the k-th listed time of a planet."""
    return f"{pl.name or idx}.tc[{pl.transit_epochs[k]}]"


def logit(q):
    """log(q / (1 - q)), q clipped into (0, 1): a start outside Kipping's
    triangle begins at its edge."""
    q = jnp.clip(jnp.asarray(q, float), 1e-9, 1.0 - 1e-9)
    return jnp.log(q) - jnp.log1p(-q)


def as_lightcurve(lightcurve) -> LightCurve:
    """A jaxppo LightCurve from a LightCurve or a lightkurve LightCurve."""
    if isinstance(lightcurve, LightCurve):
        return lightcurve
    if is_lightkurve(lightcurve):
        return LightCurve.from_lightkurve(lightcurve)
    raise ValueError(f"lightcurve must be a jaxppo.LightCurve or a lightkurve LightCurve, got "
                     f"{type(lightcurve).__name__} (arrays and astropy Time/Quantity columns: "
                     "jaxppo.LightCurve(time, flux, flux_err) or LightCurve.from_arrays)")


def checked_lightcurve(lightcurve, who: str) -> LightCurve:
    """``as_lightcurve``, with a UserWarning naming ``who`` where its points
    are more than 5 min apart without an exposure (``cadence_warning``;
    once per light curve); a ValueError where the flux's median is outside
    (0.5, 2): not relative flux (ppt, percent, electrons, or deviations
    from 1), which the model (1 = the star unocculted) cannot fit."""
    lc = as_lightcurve(lightcurve)
    level = float(np.median(lc.flux))
    if not 0.5 < level < 2.0:
        raise ValueError(
            f"{who}: the light curve's flux has median {level:.6g}, but the model is relative flux (1 = the star "
            "unocculted; docs/conventions.md): flux in ppt, percent or electrons, or deviations from 1, must be "
            "normalised first (divide flux and flux_err by the out-of-transit level, e.g. LightCurve.normalized)")
    note = cadence_warning(lc)
    if note is not None:
        import warnings

        warnings.warn(f"{who}: {note}", UserWarning, stacklevel=3)
    return lc


def parameter_names(system: System) -> list[str]:
    """List the free-parameter names that ``fit`` and ``sample`` accept for a system.

    Per planet (labelled by its name, or its index when it has none):
    ``"<p>.t0"`` [d], ``"<p>.period"`` [d], ``"<p>.a"`` [R*], ``"<p>.inc"``
    [deg], ``"<p>.radius"`` [R*], ``"<p>.secosw"``, ``"<p>.sesinw"``
    (sqrt(e) cos omega, sqrt(e) sin omega; freed together) (N-body systems: also ``"<p>.mass"``
    [M_sun] and ``"<p>.lnode"`` [deg], no ``a``, which is derived, and
    ``"star.mass"`` [M_sun], ``"star.radius"`` [R_sun]), each moon's
    ``"<p>.<moon>.<element>"`` (``MOON_PARAMS``; <moon> its name, or
    "moon<k>"), and for a planet with ``transit_times``
    one ``"<p>.tc[<epoch>]"`` [d] per listed epoch (``"<p>.tc"`` names them
    all at once) instead of ``"<p>.t0"`` (the listed times fix the orbit's
    phase, so its t0 cancels). Then the star's limb-darkening coefficients in
    ``Star.params`` order (u1, u2 of the quadratic law, c1-c4 of the
    non-linear law, c, alpha of the power-2 law; none for a uniform star),
    Kipping's ``"star.q1"``, ``"star.q2"`` for a quadratic star, and the
    light curve's nuisance parameters ``"lc.offset"``, ``"lc.jitter"``,
    ``"lc.baseline"``, ``"lc.baseline2"`` (the module docstring of
    ``jaxppo.inference._params`` defines them). "lc.baseline" and
    "lc.baseline2" expand to one name per data window and power
    (``"lc.baseline.w<window>.c<power>"``) when a fit is set up.

    Parameters
    ----------
    system : System
        The star and planets.

    Returns
    -------
    list of str
        The names, planets first, then the star, then the light curve.

    Examples
    --------
    >>> import jaxppo as jp
    >>> b = jp.Planet(period=3.0, t0=0.0, a=10.0, inc=89.0, radius=0.1, name="b")
    >>> jp.parameter_names(jp.System(jp.Star.quadratic(0.4, 0.25), [b]))
    ['b.t0', 'b.period', 'b.a', 'b.inc', 'b.radius', 'b.secosw', 'b.sesinw', 'star.u1', 'star.u2', 'star.q1', 'star.q2',
     'lc.offset', 'lc.jitter', 'lc.baseline', 'lc.baseline2']

    A planet with listed transit times has one name per epoch and no t0:

    >>> b = jp.Planet(period=3.0, t0=0.0, a=10.0, inc=89.0, radius=0.1, name="b",
    ...               transit_times=[0.001, 2.999], transit_epochs=[0, 1])
    >>> jp.parameter_names(jp.System(jp.Star.uniform(), [b]))[:8]
    ['b.period', 'b.a', 'b.inc', 'b.radius', 'b.secosw', 'b.sesinw', 'b.tc[0]', 'b.tc[1]']
    """
    names = []
    nbody = system.orbits == "nbody"
    for i, pl in enumerate(system.planets):
        label = pl.name or str(i)
        # a planet with transit times has no free t0: its listed mid-times
        # fix the orbit's phase and t0 cancels (check_ttv_free refuses it)
        names += [f"{label}.{p}" for p in PLANET_PARAMS if not (p == "t0" and pl.transit_times is not None)
                  and not (p == "a" and nbody)]
        names += [f"{label}.{p}" for p in ECC_PARAMS]
        names += [f"{label}.{p}" for p in NBODY_PARAMS["planet"] if nbody]
        names += [f"{label}.{moon_label(m, k)}.{p}" for k, m in enumerate(pl.moons) for p in MOON_PARAMS]
        if pl.transit_times is not None:
            names += [tc_name(pl, i, k) for k in range(len(pl.transit_epochs))]
    names += [f"star.{p}" for p in NBODY_PARAMS["star"] if nbody]
    names += [f"star.{p}" for p in STAR_PARAMS.get(system.star.law, ())]
    if system.star.law == "quadratic":
        names += ["star.q1", "star.q2"]
    names += [f"lc.{p}" for p in LC_PARAMS]
    return names


def _split(name: str, system: System):
    if not isinstance(name, str) or "." not in name:
        raise ValueError(f"free parameter {name!r} must look like 'b.t0' or 'star.u1'")
    for pl in system.planets:
        if pl.name and "." in pl.name and name.startswith(pl.name + "."):
            raise ValueError(f"free parameter {name!r}: the planet name {pl.name!r} contains '.', which parameter "
                             "names ('<planet>.<parameter>') cannot address; fits and samplers need planet names "
                             f"without one (e.g. {pl.name.replace('.', '_')!r})")
    owner, par = name.split(".", 1)
    nbody = system.orbits == "nbody"
    if owner == "star":
        pars = STAR_PARAMS.get(system.star.law, ())
        if par in NBODY_PARAMS["star"]:
            if not nbody:
                raise ValueError(f"free parameter {name!r}: the star's mass and radius are parameters of N-body "
                                 "orbits only (System(..., orbits='nbody')); Keplerian planets have a [R*]")
            return "star", par
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
        if par not in LC_PARAMS:
            raise ValueError(f"free parameter {name!r}: light-curve parameters are {LC_PARAMS}")
        return "lc", par
    idx = None
    for i, pl in enumerate(system.planets):
        if (pl.name or str(i)) == owner:
            idx = i
    if idx is None:
        raise ValueError(f"free parameter {name!r}: no planet named {owner!r}; names are {[p.name for p in system.planets]}")
    moon = _moon_slot(system, idx, par, name)
    if moon is not None:
        return idx, moon
    tc = check_ttv_free(system, idx, par, name)
    if tc is not None:
        return idx, tc
    if nbody and par == "a":
        raise ValueError(f"free parameter {name!r}: in an N-body system a planet's a is derived from its period and "
                         "the masses (free 'star.mass', 'star.radius' or the planets' masses instead)")
    if par in NBODY_PARAMS["planet"] and not nbody:
        what = "planet masses are parameters" if par == "mass" else "the node lnode is a parameter"
        raise ValueError(f"free parameter {name!r}: {what} of N-body orbits only (System(..., orbits='nbody'))")
    if par not in PLANET_PARAMS + ECC_PARAMS + NBODY_PARAMS["planet"]:
        raise ValueError(f"free parameter {name!r}: planet parameters are {PLANET_PARAMS + ECC_PARAMS} (N-body systems: also "
                         f"{NBODY_PARAMS['planet']}, and no 'a') and, for a planet with transit_times, its listed "
                         "mid-times 'tc[<epoch>]' (or 'tc' for all)")
    if par == "mass" and not float(np.asarray(system.planets[idx].mass)) > 0:
        raise ValueError(f"free parameter {name!r}: a free mass starts from a mass > 0 (its coordinate is log mass); "
                         f"planet {owner!r} has mass = {float(np.asarray(system.planets[idx].mass))!r} M_sun")
    return idx, par


def _baseline_windows(time: np.ndarray) -> list[np.ndarray]:
    """Index arrays of the runs of points separated by gaps > BASELINE_GAP."""
    cuts = np.nonzero(np.diff(time) > BASELINE_GAP)[0] + 1
    return np.split(np.arange(time.size), cuts)


def expand_tc(free, system: System) -> list:
    """"b.tc" -> "b.tc[e]" for every listed epoch e of planet b."""
    out = []
    for n in free:
        owner, _, par = n.partition(".") if isinstance(n, str) else (None, None, None)
        hit = [i for i, pl in enumerate(system.planets) if (pl.name or str(i)) == owner]
        if par == "tc" and hit and system.planets[hit[-1]].transit_times is not None:
            pl = system.planets[hit[-1]]
            out += [tc_name(pl, hit[-1], k) for k in range(len(pl.transit_epochs))]
        else:
            out.append(n)
    return out


def expand_free(free, system: System, time: np.ndarray):
    """(names, slots, basis): "lc.baseline[2]" expanded per window and
    power; ``basis`` [n, m] holds the columns of the multiplicative trend
    (offset: ones; baseline: x^k per window) in the order of the trend
    slots."""
    names, slots, cols = [], [], []
    windows = None
    for n in expand_tc(free, system):
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
    twice = sorted({names[k] for k, sl in enumerate(slots) if slots.count(sl) > 1})
    if twice:
        raise ValueError(f"free parameters repeat: {twice} named more than once (e.g. 'b.tc' already holds every "
                         "listed time of b)")
    pars = {p for o, p in slots if o == "lc" and not isinstance(p, tuple)}
    if "offset" in pars and any(isinstance(p, tuple) for o, p in slots if o == "lc"):
        raise ValueError("free parameters 'lc.offset' and 'lc.baseline' are degenerate (each window's baseline "
                         "has its own constant term c0): name one of them")
    if sum(1 for n in free if n.startswith("lc.baseline")) > 1:
        raise ValueError(f"free parameters name the baseline twice: {[n for n in free if n.startswith('lc.baseline')]}")
    for o in {o for o, p in slots if p in ECC_PARAMS}:
        if not all((o, p) in slots for p in ECC_PARAMS):
            label = system.planets[o].name or str(o)
            raise ValueError(f"free parameters name one of '{label}.secosw' and '{label}.sesinw': free both (together "
                             "they are e and omega) or neither")
    star = {p for o, p in slots if o == "star"}
    if star & {"q1", "q2"} and star & {0, 1}:
        raise ValueError("free parameters name both u1/u2 and q1/q2 of the star: name one pair "
                         "(q1, q2 is Kipping's 2013 reparameterisation of u1, u2)")
    basis = np.stack(cols, axis=1) if cols else np.zeros((time.size, 0))
    return tuple(names), slots, basis


def is_trend(slot) -> bool:
    """True for a light-curve offset or baseline-polynomial slot."""
    owner, par = slot
    return owner == "lc" and (par == "offset" or isinstance(par, tuple))


def jitter_start(sigma) -> float:
    """Starting jitter [relative flux]: a tenth of the median error (the
    coordinate is log s, so it cannot start at 0)."""
    return 0.1 * float(np.median(np.asarray(sigma)))
