"""The coordinates every posterior of jaxppo is sampled in, and its priors.

One system for ``sample`` (NUTS over any free parameters) and for the
transit posterior of the marginal scan and the joint sampler
(``._posterior.TransitPosterior``):

- the priors are stated on the prior parameters q (``Coordinates``: t0, P,
  a, the impact parameter b / (1 + p), p, star and light-curve terms in
  ``Model.slots`` order), with the defaults of ``default_priors``;
- each q is reached from an unconstrained coordinate u through numpyro's
  bijection onto its prior's support (a logistic map for a bounded
  interval, so a posterior that fills its prior meets no wall);
- the impact parameter is folded (q = |s|, s signed: the light curve
  depends on |cos i| only, so one smooth mode through b = 0);
- when a and i of a planet are both free (and a keeps its default prior),
  u places log T14 in place of a (Winn 2010, eq. 14), where the data
  constrain T14 and b nearly independently; its map covers a in
  (1 + p, a_max), so a's uniform prior is taken on that range (orbits
  that graze the star at every phase are left out);
- with a stellar density prior (``density``), every free a/R* follows
  from one coordinate log rho* by Kepler's third law (``a_from_density``);
- the log-density in u is the log-likelihood plus the priors' log-density
  plus log |det dq/du| (``Coordinates.log_prior``), so the posterior is the
  one the physical priors define, whatever the coordinates.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..model._system import System
from ._ecc import ECC_PARAMS, ecc_cap
from ._params import inc_sign_matters, is_moon, is_tc, planet_value, star_value

__all__ = ["Coordinates", "default_priors", "start_q", "a_from_density", "density_from_a", "check_density",
           "default_density", "window_priors", "priors_from_text", "PRIOR_KINDS"]

G_CGS = 6.67430e-8  # [cm^3 g^-1 s^-2] (CODATA 2018)
DAY_S = 86400.0
DENSITY = ("star", "density")
"""The slot name of the stellar-density coordinate (log rho* in u)."""


# ---- the stellar density that ties a/R* of several planets ---------------------
#
# a / R* = (G rho* P^2 / (3 pi))^(1/3) for a circular orbit and M_p << M*
# (Seager & Mallen-Ornelas 2003, eq. 30): the a/R* of all planets move
# together and a literature density bounds them. Sampling a/R* of each
# planet with a flat prior lets long-cadence transits (which barely
# separate a/R* from b) drift to grazing orbits.

def a_from_density(rho, period, xp=np):
    """a/R* [stellar radii] from the stellar density rho [g/cm^3] and the
    period [d]: Kepler's third law, circular orbit, M_p << M*
    (Seager & Mallen-Ornelas 2003, eq. 30)."""
    return (G_CGS * rho * (period * DAY_S) ** 2 / (3.0 * xp.pi)) ** (1.0 / 3.0)


def density_from_a(a, period) -> float:
    """The stellar density [g/cm^3] that puts a planet of period [d] at a/R*
    ``a`` (the inverse of ``a_from_density``)."""
    return float(3.0 * np.pi * a**3 / (G_CGS * (period * DAY_S) ** 2))


def check_density(density, where="stellar_density"):
    """(mean, sd) [g/cm^3] of a stellar-density prior as floats; a
    ValueError naming ``where`` unless both are finite and positive."""
    try:
        m, s = (float(v) for v in density)
    except (TypeError, ValueError):
        raise ValueError(f"{where} must be (mean, sd) in g/cm^3, got {density!r}") from None
    if not (np.isfinite(m) and np.isfinite(s) and m > 0 and s > 0):
        raise ValueError(f"{where} must be (mean, sd) with mean > 0 and sd > 0 [g/cm^3], got {density!r}")
    return m, s


def default_density(system: System, tied) -> tuple[float, float, str]:
    """With no literature value: the density the configuration's own a/R*
    imply (geometric mean over the tied planets), 10 % wide."""
    rho = np.exp(np.mean([np.log(density_from_a(float(system.planets[i].a), float(system.planets[i].period)))
                          for i in tied]))
    return float(rho), 0.1 * float(rho), "the configuration's a/R* (Kepler's third law), 10 % (no stellar_density given)"


# ---- priors -----------------------------------------------------------------

def default_priors(model, user=None):
    """Physical priors, one per free parameter of ``model`` (a
    ``._model.Model``; inclinations through b / (1 + p)): the defaults
    around the starting system (see ``jaxppo.sample``), replaced by
    ``user[name]`` where given (a numpyro distribution on the parameter in
    its public units)."""
    import numpyro.distributions as dist

    user = dict(user or {})
    unknown = sorted(set(user) - set(model.free))
    if unknown:
        raise ValueError(f"priors: {unknown} are not free parameters; free: {list(model.free)}")
    for name, pr in user.items():
        if not isinstance(pr, dist.Distribution) or pr.batch_shape or pr.event_shape:
            raise ValueError(f"priors[{name!r}] must be a scalar numpyro distribution, got {pr!r}")
        if name.endswith(".inc") and not is_moon(model.slots[model.free.index(name)][1]):
            raise ValueError(f"priors[{name!r}]: a prior on the inclination is not supported (the default is uniform "
                             "in the impact parameter b / (1 + p), |b| < 1 + p); put priors on the other parameters")
    sigma = float(np.median(np.asarray(model.sigma)))
    out = []
    for name, (owner, par) in zip(model.free, model.slots):
        if name in user:
            out.append(user[name])
        elif par in ("q1", "q2"):
            out.append(dist.Uniform(0.0, 1.0))  # Kipping (2013): uniform q samples every physical profile
        elif par == "jitter":
            out.append(dist.LogUniform(1e-3 * sigma, 10.0 * sigma))
        elif owner == "lc":  # offset and baseline coefficients: relative flux
            out.append(dist.Uniform(-0.05, 0.05))
        elif owner == "star" and par in ("mass", "radius"):  # N-body star: within a factor 2 of the start
            v = float(star_value(model.system, par))
            out.append(dist.LogUniform(0.5 * v, 2.0 * v))
        elif owner == "star":
            v = float(model.system.star.params[par])
            out.append(dist.Uniform(v - 1.0, v + 1.0))
        elif par in ECC_PARAMS:  # uniform in the disk e < e_cap: ``Coordinates.log_prior`` cuts the corners
            c = float(np.sqrt(ecc_cap(model.system, owner)))
            out.append(dist.Uniform(-c, c))
        else:
            out.append(_planet_prior(model.system.planets[owner], par))
    return out


# the kinds of ``--prior NAME KIND A B``: numpyro's distribution and its two numbers
PRIOR_KINDS = {"normal": ("Normal", "MEAN SD"), "uniform": ("Uniform", "LOW HIGH"),
               "loguniform": ("LogUniform", "LOW HIGH")}


def priors_from_text(specs) -> dict:
    """``jaxppo sample --prior NAME KIND A B`` (each a tuple of four
    strings) -> {name: numpyro distribution}; ValueError naming the option,
    the prior and what is wrong."""
    import numpyro.distributions as dist

    out = {}
    for name, kind, a, b in specs:
        if kind.lower() not in PRIOR_KINDS:
            raise ValueError(f"--prior {name}: unknown kind {kind!r}; use one of {sorted(PRIOR_KINDS)}")
        vals = []
        for text in (a, b):
            try:
                vals.append(float(text))
            except ValueError:
                raise ValueError(f"--prior {name} {kind}: not a number: {text!r}") from None
            if not np.isfinite(vals[-1]):
                raise ValueError(f"--prior {name} {kind}: must be a finite number, got {text!r}")
        x, y = vals
        if kind.lower() == "normal" and not y > 0:
            raise ValueError(f"--prior {name} normal: SD must be > 0, got {b}")
        if kind.lower() != "normal" and not (y > x and (kind.lower() == "uniform" or x > 0)):
            raise ValueError(f"--prior {name} {kind}: need 0 < LOW < HIGH (uniform: LOW < HIGH), got {a} {b}")
        if name in out:
            raise ValueError(f"--prior {name} given twice")
        out[name] = getattr(dist, PRIOR_KINDS[kind.lower()][0])(x, y)
    return out


def window_priors(model, user=None) -> dict:
    """The free parameters whose prior is a default WINDOW about the start
    (not a physical bound), name -> (low, high): t0 and listed transit
    times (+-0.05 d), the period (+-0.1 %), a node (+-90 deg), the light
    curve's offset and baseline coefficients, the star's limb-darkening
    coefficients (+-1; not Kipping's q, whose [0, 1] is physical) and an
    N-body star's mass and radius (factor 2), a moon's t0 and period.
    A posterior against such a bound is the window's, not the data's
    (``jaxppo.sample`` warns). Parameters with a prior in ``user`` are the
    user's choice and not listed."""
    user = dict(user or {})
    out = {}
    for name, (owner, par), pr in zip(model.free, model.slots, default_priors(model, user)):
        moon_window = is_moon(par) and par[2] in ("t0", "period")
        window = (par in ("t0", "period", "lnode") or is_tc(par) or moon_window
                  or (owner == "lc" and par != "jitter") or (owner == "star" and par not in ("q1", "q2")))
        if window and name not in user:
            out[name] = (float(pr.support.lower_bound), float(pr.support.upper_bound))
    return out


def _planet_prior(pl, par):
    """The default prior of a planet parameter (see ``jaxppo.sample``)."""
    import numpyro.distributions as dist

    if is_moon(par):
        return _moon_prior(pl, pl.moons[par[1]], par[2])
    if par == "mass":  # N-body: from a thousandth of an Earth mass to ten Jupiter masses
        return dist.LogUniform(3e-9, 1e-2)
    if par == "lnode":
        v = float(pl.lnode)
        return dist.Uniform(v - 90.0, v + 90.0)
    if par == "t0" or is_tc(par):
        t = float(planet_value(pl, par))
        return dist.Uniform(t - 0.05, t + 0.05)
    if par == "period":
        p = float(pl.period)
        return dist.Uniform(p * (1 - 1e-3), p * (1 + 1e-3))
    if par == "a":
        return dist.Uniform(1.0, 4.0 * float(pl.a))
    if par == "radius":
        return dist.LogUniform(1e-4, 0.5)
    return dist.Uniform(-1.0, 1.0)  # inc through the impact parameter in units of (1 + p)


def _moon_prior(pl, moon, element):
    """The default prior of a moon's element (see ``jaxppo.sample``)."""
    import numpyro.distributions as dist

    v = float(getattr(moon, element))
    if element == "period":
        return dist.LogUniform(0.5 * v, 2.0 * v)
    if element == "t0":
        return dist.Uniform(v - 0.5 * float(moon.period), v + 0.5 * float(moon.period))
    if element == "a":  # from touching the planet to 4 times the start
        return dist.LogUniform(float(pl.radius) + float(moon.radius), 4.0 * v)
    if element == "radius":
        return dist.LogUniform(1e-4, 0.5)
    if element == "mass_ratio":
        return dist.LogUniform(1e-6, 1.0)
    if element == "inc":
        return dist.Uniform(0.0, 180.0)
    return dist.Uniform(v - 180.0, v + 180.0)  # lnode


def start_q(model, system: System, what: str = "sample") -> np.ndarray:
    """The prior parameters q (``Coordinates``) of ``system``: the
    inclination as the signed b / (1 + p) (``Coordinates`` folds it). A
    ValueError starting with ``what`` when a planet with a free
    inclination does not transit."""
    q = []
    phys = np.asarray(model.physical(model.to_theta(system)), float)  # q1, q2, lc.* at the start
    for k, (owner, par) in enumerate(model.slots):
        if owner == "lc" or par in ("q1", "q2"):
            q.append(phys[k])
        elif owner == "star":
            q.append(float(star_value(system, par)))
        elif par == "inc":
            pl = system.planets[owner]
            b = float(pl.impact)
            if not abs(b) < 1.0 + float(pl.radius) or not float(pl.a) > 1.0 + float(pl.radius):
                raise ValueError(f"{what}: planet {pl.name or owner} does not transit at the start (impact parameter "
                                 f"{b:.3g}, a {float(pl.a):.3g} R*, radius {float(pl.radius):.3g} R*)")
            q.append(b / (1.0 + float(pl.radius)))
        else:
            q.append(float(planet_value(system.planets[owner], par)))
    return np.asarray(q)


# ---- the coordinates ----------------------------------------------------------

class Coordinates:
    """Maps the sampling coordinates u to the prior parameters q of
    ``model.slots`` and back (module docstring).

    ``coords``: what each entry of u is, a slot of ``model.slots`` or
    ``("star", "density")`` (log rho*, last); without ``density`` u has one
    entry per slot. ``priors``: one numpyro distribution per slot
    (``default_priors``); a tied a's entry is not used. ``user``: the free
    names whose prior the user gave (a user prior on a keeps plain
    coordinates for that planet). ``fold``: the inclination's q is |s|
    (except where the sign of cos i changes the light curve:
    ``inc_sign_matters``).
    ``density``: (mean, sd) [g/cm^3] of a Gaussian prior (truncated at 0)
    on rho*, which then sets every free a/R*."""

    def __init__(self, model, priors, user=(), fold: bool = True, density=None):
        from numpyro.distributions.transforms import biject_to

        self.model = model
        self.slots = list(model.slots)
        self.index = {s: k for k, s in enumerate(self.slots)}
        self.user = {k for k, n in enumerate(model.free) if n in user}
        self.density = None if density is None else check_density(density)
        self.tied = sorted(o for (o, par) in self.slots if par == "a") if density is not None else []
        self.coords = [s for s in self.slots if not self._is_tied(s)] + ([DENSITY] if self.tied else [])
        self.at = {s: j for j, s in enumerate(self.coords)}
        # the T14 coordinate replaces a only under the default prior on a
        # (its map covers the default's support); a user prior on a keeps
        # plain coordinates for that planet
        both = {o for (o, par) in self.slots if par == "a" and (o, "inc") in self.index and o not in self.tied}
        self.duration = {o for o in both if self.index[(o, "a")] not in self.user}
        self.plain = sorted(both - self.duration)
        self.maps = [biject_to(pr.support) for pr in priors]
        self.folded = [k for k, (owner, par) in enumerate(self.slots)
                       if fold and par == "inc" and not inc_sign_matters(model.system, owner)]
        self.priors = list(priors)
        # (secosw, sesinw) slot pairs: the prior is the disk e < e_cap
        self.ecc = [(self.index[(o, "secosw")], self.index[(o, "sesinw")], float(ecc_cap(model.system, o)))
                    for o, par in self.slots if par == "secosw" and (o, "sesinw") in self.index]
        self.a_max = {k: float(np.asarray(pr.support.upper_bound)) for k, pr in enumerate(priors)
                      if self.slots[k][1] == "a" and self.slots[k][0] in self.duration}

    def _is_tied(self, slot) -> bool:
        return slot[1] == "a" and slot[0] in self.tied

    def _is_duration(self, k) -> bool:
        owner, par = self.slots[k]
        return par == "a" and owner in self.duration

    @staticmethod
    def _log_t14_range(p, b, period, a_max, xp):
        """log T14 [d] at a = a_max and at a = 1 + p (T14 = P / 2): the
        logistic map between them covers a in (1 + p, a_max) without walls."""
        lo = xp.log(period / np.pi * xp.arcsin(xp.sqrt(((1.0 + p) ** 2 - b**2) / (a_max**2 - b**2))))
        return lo, xp.log(0.5 * period)

    def _other(self, q, owner, par):
        k = self.index.get((owner, par))
        return q[k] if k is not None else float(getattr(self.model.system.planets[owner], par))

    def density_of(self, u):
        """rho* [g/cm^3] at u (only with ``density``)."""
        return jnp.exp(u[self.at[DENSITY]])

    def to_q(self, u):
        """u -> q (one per slot; traceable)."""
        q = [None if (self._is_duration(k) or self._is_tied(s)) else self.maps[k](u[self.at[s]])
             for k, s in enumerate(self.slots)]
        for k in self.folded:
            # |s| with the derivative -1 or +1 (jnp.abs has 0 at s = 0, which
            # would put log |det dq/du| = -inf at a head-on start)
            q[k] = jnp.where(q[k] < 0, -q[k], q[k])
        if self.tied:
            rho = self.density_of(u)
            for owner in self.tied:
                q[self.index[(owner, "a")]] = a_from_density(rho, self._other(q, owner, "period"), jnp)
        for owner in self.duration:
            ka, kb = self.index[(owner, "a")], self.index[(owner, "inc")]
            p, period = self._other(q, owner, "radius"), self._other(q, owner, "period")
            b = q[kb] * (1.0 + p)
            lo, hi = self._log_t14_range(p, b, period, self.a_max[ka], jnp)
            x = jnp.pi * jnp.exp(lo + (hi - lo) * jax.nn.sigmoid(u[self.at[(owner, "a")]])) / period
            # a sin i = sqrt((1 + p)^2 - b^2) / sin(pi T14 / P) (Winn 2010, eq. 14)
            q[ka] = jnp.sqrt(((1.0 + p) ** 2 - b**2) / jnp.sin(x) ** 2 + b**2)
        return jnp.stack([jnp.asarray(v, float) for v in q])

    def from_q(self, q, rho=None) -> np.ndarray:
        """q -> u; with ``density``, rho* [g/cm^3] (default: the prior's mean)."""
        q = np.asarray(q, float).copy()
        q[self.folded] = np.abs(q[self.folded])
        u = np.zeros(len(self.coords))
        for k, s in enumerate(self.slots):
            if not (self._is_duration(k) or self._is_tied(s)):
                u[self.at[s]] = float(self.maps[k].inv(q[k]))
        if self.tied:
            u[self.at[DENSITY]] = np.log(self.density[0] if rho is None else float(rho))
        for owner in self.duration:
            ka, kb = self.index[(owner, "a")], self.index[(owner, "inc")]
            p, period = self._other(q, owner, "radius"), self._other(q, owner, "period")
            a, b = q[ka], q[kb] * (1.0 + p)
            lo, hi = self._log_t14_range(p, b, period, self.a_max[ka], np)
            s = (np.log(period / np.pi * np.arcsin(np.sqrt(((1.0 + p) ** 2 - b**2) / (a**2 - b**2)))) - lo) / (hi - lo)
            u[self.at[(owner, "a")]] = np.log(s / (1.0 - s))
        return u

    def _values(self, u):
        """The values the priors are on, one per entry of u: q of every
        slot that is not a tied a, then rho* (a bijection of u)."""
        q = self.to_q(u)
        v = [q[k] for k, s in enumerate(self.slots) if not self._is_tied(s)]
        if self.tied:
            v.append(self.density_of(u))
        return jnp.stack(v)

    def log_prior(self, u):
        """log prior density in u: the priors' log-densities at q (and the
        truncated Gaussian of rho*; a T14 coordinate's a uniform on
        (1 + p, a_max)), plus log |det dq/du|; -inf outside a prior's
        support."""
        import numpyro.distributions as dist

        v = self._values(u)
        pri = [pr for k, pr in enumerate(self.priors) if not self._is_tied(self.slots[k])]
        if self.tied:
            pri.append(dist.TruncatedNormal(self.density[0], self.density[1], low=0.0))
        # numpyro does not check supports unless asked: outside it is -inf
        inside = jnp.all(jnp.stack([pr.support(v[j]) for j, pr in enumerate(pri)]))
        lp = sum(pr.log_prob(v[j]) for j, pr in enumerate(pri))
        q = self.to_q(u)
        for kx, ky, cap in self.ecc:  # uniform e, omega: the square's prior, cut to the disk e < e_cap
            inside = inside & (q[kx] ** 2 + q[ky] ** 2 < cap)
            lp = lp + np.log(4.0 / np.pi)  # normalised on the disk
        for owner in self.duration:
            # the T14 map covers a in (1 + p, a_max): a's Uniform(1, a_max)
            # renormalised on that range, so the prior in u integrates to one
            ka = self.index[(owner, "a")]
            lp = lp - jnp.log1p(-self._other(q, owner, "radius") / (self.a_max[ka] - 1.0))
        lp = lp + jnp.linalg.slogdet(jax.jacfwd(self._values)(u))[1]
        return jnp.where(inside, lp, -jnp.inf)

    def prior_widths(self, u0) -> np.ndarray:
        """Rough prior standard deviations in u: a uniform prior mapped by
        the logistic function has sd pi / sqrt(3); a user prior with a
        finite variance, its sd divided by |dq/du| at the start (so that an
        informative prior sets the Laplace widths); log rho*, sd / mean."""
        out = np.full(len(self.coords), np.pi / np.sqrt(3.0))
        for k in self.user:
            if self._is_tied(self.slots[k]):
                continue
            try:
                var = float(np.asarray(self.priors[k].variance))
            except (NotImplementedError, AttributeError, TypeError):
                continue
            j = self.at[self.slots[k]]
            slope = abs(float(jax.grad(lambda x: self.maps[k](x))(float(u0[j]))))
            if np.isfinite(var) and var > 0 and slope > 0:
                out[j] = np.sqrt(var) / slope
        if self.tied:
            out[self.at[DENSITY]] = self.density[1] / self.density[0]
        return out
