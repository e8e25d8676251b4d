"""The posterior of the transit parameters that the marginalised obliquity
scan draws from, and alpha sampled jointly with them.

NUTS over t0, P, p and b / (1 + p) of every planet and ONE stellar density
rho* for all planets (see ``TransitPosterior``), started at the mode
with the Laplace covariance there as the mass matrix.
"""

from __future__ import annotations

import time

import jax
import numpy as np

from ..model._lightcurve import LightCurve
from ..model._overlap import may_touch
from ..model._system import System
from ._diagnostics import rank_diagnostics
from ._coords import Coordinates, default_priors, start_q
from ._mapped import mapped, mapped_over_devices
from ._model import Model
from ._params import check_ttv_free, expand_tc

__all__ = ["PLANET_PARAMS", "posterior_slot", "TransitPosterior", "mode_and_cov", "nuts_draws"]

PLANET_PARAMS = ("t0", "period", "a", "inc", "radius")
"""The planet parameters the transit posterior samples."""


def posterior_slot(system: System, name: str, what: str):
    """(planet index, par) of a name the transit posterior samples: one of
    ``PLANET_PARAMS`` ("b.t0") or a listed transit time ("b.tc[12]", par
    ("tc", k), k its position in ``transit_times``). A ValueError starting
    with ``what`` for any other name."""
    labels = [pl.name or str(i) for i, pl in enumerate(system.planets)]
    owner, _, par = name.partition(".")
    if owner in labels:
        idx = labels.index(owner)
        tc = check_ttv_free(system, idx, par, name if what == "free" else f"{what}: {name}")
        if tc is not None or par in PLANET_PARAMS:
            return idx, tc if tc is not None else par
    raise ValueError(f"{what}: {name!r} is not a planet parameter the marginal scan samples; names look like "
                     f"'b.t0' (planets {labels}, parameters {PLANET_PARAMS}, and listed transit times 'b.tc[12]')")


class TransitPosterior:
    """The log-posterior of the transit parameters ``free`` (names from
    ``PLANET_PARAMS``, and listed transit times "b.tc[12]", "b.tc" for
    every listed epoch, each uniform within +-0.05 d of its value) at a tilt, in the coordinates u of
    ``._coords.Coordinates`` (those of ``jaxppo.sample``): t0, P, p and the
    folded impact parameter b / (1 + p) of each planet through the
    bijections onto their default priors' supports (t0 within +-0.05 d and P
    within +-0.1 % of the start, p log-uniform in [1e-4, 0.5], b / (1 + p)
    uniform in [0, 1)), and, when any a/R* is free, ONE stellar density
    rho* for all of them (log rho* last in u; a/R* from Kepler's third law)
    with the Gaussian prior ``density`` = (mean, sd) [g/cm^3] truncated at
    0. b >= 0 loses nothing: the scan's cases enumerate the hemispheres of
    the untilted planets (case "opposite" mirrors them) and alpha turns the
    tilted one through 360 deg. The likelihood is
    ``jaxppo.inference._model.Model``'s (the windows' Gaussian chi^2) at the
    tilt ``alpha``; ``log_density`` leaves out its normalisation
    (-sum ln sigma - N ln(2 pi) / 2, the same at every tilt and case)."""

    def __init__(self, system, data, free, density, alpha, case):
        free = tuple(expand_tc(tuple(free), system))  # "b.tc": every listed epoch of b
        for name in free:
            posterior_slot(system, name, "free")
        if len(set(free)) != len(free):
            raise ValueError(f"free parameters repeat: {list(free)}")
        self.system, self.density = system, density
        # a posterior spreads further than a fit moves: compute every frame
        # within 1 R* of the limb at the start
        self.model = Model(system, data, free, alpha, case, active_margin=1.0)
        self.free = tuple(self.model.free)
        self.slots = list(self.model.slots)
        tie = density if any(p == "a" for _, p in self.slots) else None
        self.coordinates = Coordinates(self.model, default_priors(self.model), fold=True, density=tie)
        self.coords, self.tied = self.coordinates.coords, self.coordinates.tied
        q = start_q(self.model, system, "the transit posterior")
        # a grazing start: from b / (1 + p) = 0.95 at most, where the
        # logistic map still has a slope
        for k, (_, p) in enumerate(self.slots):
            if p == "inc":
                q[k] = min(abs(q[k]), 0.95)
        self.u_start = self.coordinates.from_q(q)
        # rough prior widths in u (the Laplace matrix's prior curvature, so
        # that a parameter the data do not constrain keeps a finite width)
        self.prior_sd = self.coordinates.prior_widths(self.u_start)

    def physical(self, u):
        """u -> (the values of ``free`` in physical units (d, d, R*, deg,
        R*), rho* [g/cm^3] or None)."""
        theta = self.model.theta_from(self.coordinates.to_q(u))
        return self.model.physical(theta), (self.coordinates.density_of(u) if self.tied else None)

    def model_q(self, u):
        """u -> the Model's values (physical, but inc as b / (1 + p))."""
        return self.coordinates.to_q(u)

    def data_residuals(self, u, alpha=None):
        """The data's residuals at the tilt ``alpha`` [deg] when given, else
        the Model's."""
        theta = self.model.theta_from(self.model_q(u))
        return self.model.residuals(theta) if alpha is None else self.model.residuals_at(theta, alpha)

    def residuals(self, u, alpha=None):
        """``data_residuals``, and (rho* - mean) / sd appended (the Gaussian
        prior as one more residual) when rho* is sampled: what least squares
        (``mode_and_cov``, the joint mode search) minimise."""
        import jax.numpy as jnp

        r = self.data_residuals(u, alpha)
        if self.tied:
            m, s = self.coordinates.density
            r = jnp.concatenate([r, ((self.coordinates.density_of(u) - m) / s)[None]])
        return r

    def exact_overlaps_anywhere(self, margin: float = 0.05, us=()) -> bool:
        """Compute by the exact union integral every frame in which two
        disks could touch at some tilt, within ``margin`` [R*], at the start
        (without ``us``) or at each coordinate vector of ``us`` (``jaxppo.model._overlap.
        may_touch`` of the untilted geometry: the tilt turns an orbit about
        the star's centre); for sampling alpha (``joint_case_smc``). Returns whether the frames grew."""
        import jax.numpy as jnp

        t = np.asarray(self.model.t_model)
        if not len(us):
            need = may_touch(*self.system.positions(t, 0.0, "same", xp=np), margin)
        else:
            # the untilted positions at every u at once (jit, vmap), 32 at a time
            if getattr(self, "_positions", None) is None or self._positions[0] is not self.model.t_model:
                tj = jnp.asarray(t)
                self._positions = (self.model.t_model, jax.jit(jax.vmap(
                    lambda u: self.model.to_system(self.model.theta_from(self.model_q(u))).positions(tj, 0.0,
                                                                                                     "same"))))
            us = np.atleast_2d(np.asarray(us, float))
            pad = -(-us.shape[0] // 32) * 32
            us = np.concatenate([us, np.repeat(us[-1:], pad - us.shape[0], axis=0)])
            need = np.zeros(t.size, bool)
            for i in range(0, pad, 32):
                x, y, r = (np.asarray(v) for v in self._positions[1](jnp.asarray(us[i:i + 32])))
                need |= np.any(may_touch(x, y, r, margin), axis=0)
        idx = np.nonzero(need)[0]
        if np.all(np.isin(idx, self.model.union_idx)):
            return False
        self.model = self.model.with_frames(union=idx)
        return True

    def log_density(self, u, alpha=None):
        """log posterior in u (up to the likelihood's normalisation): -chi^2
        / 2 of the data plus ``Coordinates.log_prior`` (the priors, rho*'s
        truncated Gaussian and log |det dq/du|)."""
        import jax.numpy as jnp

        return -0.5 * jnp.sum(self.data_residuals(u, alpha) ** 2) + self.coordinates.log_prior(u)


def mode_and_cov(post: TransitPosterior, max_steps: int = 256, tol: float = 1e-9):
    """The mode of the transit posterior and the Laplace covariance there:
    optimistix Levenberg-Marquardt on the residuals (data and rho* prior)
    from the start, then the
    covariance from the Jacobian with the prior widths as curvature. NUTS
    moves in w with u = u_mode + L w, L L^T = that covariance, so its mass
    matrix starts close to the identity.

    Returns (u_mode, L, chi^2 at the mode). ``tol``: optimistix's rtol and
    atol, on parameters in units of their Laplace width at the start and
    on chi^2 / 2."""
    import jax.numpy as jnp
    import optimistix as optx

    jac = jax.jit(lambda v: (post.residuals(v), jax.jacfwd(post.residuals)(v)))
    u0 = jnp.asarray(post.u_start, float)
    r, J = (np.asarray(x) for x in jac(u0))
    cost = float(r @ r)
    if not np.isfinite(cost):
        raise ValueError(f"the transit model is not finite at the start (chi^2 = {cost})")
    # LM damps with the identity: solve in z = (u - u_start) c, c the
    # Laplace precision of each coordinate at the start, so that a step of 1
    # is about one posterior width in every direction (t0 is known to
    # 1e-4 d, log p to 1e-2)
    c = jnp.asarray(np.sqrt(np.sum(J**2, axis=0) + 1.0 / post.prior_sd**2))

    def to_u(z):
        return u0 + z / c

    sol = optx.least_squares(lambda z, _: post.residuals(to_u(z)), optx.LevenbergMarquardt(rtol=tol, atol=tol),
                             jnp.zeros_like(u0), max_steps=max_steps, throw=False)
    u = np.asarray(to_u(sol.value))
    r, J = (np.asarray(x) for x in jac(jnp.asarray(u)))
    info = J.T @ J + np.diag(1.0 / post.prior_sd**2)
    cov = np.linalg.inv(info)
    cov = 0.5 * (cov + cov.T)
    return u, np.linalg.cholesky(cov), float(r @ r)


def nuts_draws(system: System, data: LightCurve, free, density, alpha: float, case: str, draws: int,
               num_warmup: int = 300, thin: int = 1, seed: int = 0, chains: int = 4, progress: bool = False):
    """Draws of the transit parameters ``free`` from their posterior at tilt
    ``alpha`` [deg] (numpyro NUTS, ``chains`` chains vectorised; the mass
    matrix is the Laplace covariance at the posterior mode, found first by
    Levenberg-Marquardt (optimistix); ``TransitPosterior`` for coordinates and priors). a/R* of every
    planet with "P.a" in ``free`` is tied to one stellar density with the
    Gaussian prior ``density`` = (mean, sd) [g/cm^3].

    Returns (samples: name -> array [draws] in physical units (d, R*, deg),
    with "star.density" [g/cm^3] when sampled; info: settings, R-hat and
    ESS per parameter, divergences, tree depths, seconds)."""
    import jax
    import jax.numpy as jnp
    from numpyro.infer import MCMC, NUTS

    post = TransitPosterior(system, data, free, density, alpha, case)
    t0 = time.perf_counter()
    u_mode, L, chi2_mode = mode_and_cov(post)
    uj, Lj = jnp.asarray(u_mode), jnp.asarray(L)

    @jax.jit
    def potential(w):
        v = -post.log_density(uj + Lj @ w)
        return jnp.where(jnp.isnan(v), jnp.inf, v)

    k = len(post.coords)
    per_chain = -(-draws * thin // chains)
    # The Laplace map u = u_mode + L w is the dense mass matrix (the
    # posterior in w has Hessian eigenvalues ~0.5-2 on the bundled data), so
    # warmup adapts the step size only: a dense matrix estimated per chain
    # from a few dozen correlated warmup draws can be near-singular, and
    # then every tree runs to its maximum depth (1023 steps).
    mcmc = MCMC(NUTS(potential_fn=potential, adapt_mass_matrix=False), num_warmup=num_warmup, num_samples=per_chain,
                num_chains=chains, chain_method="vectorized", progress_bar=progress)
    init = 0.3 * np.random.default_rng(seed).standard_normal((chains, k))
    mcmc.run(jax.random.PRNGKey(seed), init_params=jnp.asarray(init),
             extra_fields=("diverging", "num_steps"))
    w = np.asarray(mcmc.get_samples(group_by_chain=True)).reshape(chains, per_chain, k)[:, ::thin]
    u = u_mode + w @ L.T
    phys, rho = jax.jit(jax.vmap(post.physical))(jnp.asarray(u.reshape(-1, k)))
    n_kept = u.shape[1]
    chains_of = {n: np.asarray(phys)[:, j].reshape(chains, n_kept) for j, n in enumerate(post.free)}
    if post.tied:
        chains_of["star.density"] = np.asarray(rho).reshape(chains, n_kept)
    # every chain contributes equally: take draws round-robin over chains
    samples = {n: v.T.reshape(-1)[:draws] for n, v in chains_of.items()}
    extra = mcmc.get_extra_fields(group_by_chain=True)
    steps = np.asarray(extra["num_steps"])
    info = {"method": "numpyro NUTS (jaxppo.inference._posterior.nuts_draws): t0, P, p, b/(1+p) per planet"
                      + (", one stellar density for all a/R*" if post.tied else ""),
            "chains": chains, "num_warmup": num_warmup, "num_samples_per_chain": per_chain, "thin": thin,
            "seed": seed, "start_chi2": float(chi2_mode),
            "divergences": int(np.sum(np.asarray(extra["diverging"]))),
            "mean_steps_per_draw": float(np.mean(steps)), "max_steps_per_draw": int(np.max(steps)),
            "diagnostics": {n: {kk: (float(vv) if np.isfinite(vv) else None) for kk, vv in rank_diagnostics(v).items()}
                            for n, v in chains_of.items()},
            "seconds": time.perf_counter() - t0}
    return samples, info


def _arc(d):
    """|d| [deg] on the circle, in [0, 180]."""
    return abs((d + 180.0) % 360.0 - 180.0)


def joint_modes(post: TransitPosterior, u_mode, L, step: float = 4.0, keep: float = 30.0, best: int = 16,
                rounds: int = 4):
    """The modes of the joint posterior of (transit parameters, alpha) in
    the coordinates (w, alpha) of the joint sampler (u = u_mode + L w, alpha
    [deg]), for ``post``'s case, with their Laplace covariances.

    The profile of the log posterior over alpha at w = 0 (every 0.5 deg)
    shows the tilts where a PPO changes the likelihood; Levenberg-Marquardt
    (optimistix, one start after another, 40 steps) moves (w,
    alpha) jointly from a start every ``step`` deg over those tilts (widened
    by 4 deg) and from each local maximum of the profile 1 above its quiet
    level: the PPO ties alpha to the planets' t0, so a mode lies along a
    ridge the profile at fixed w does not see (on a high-SNR injection 26
    whitened widths from the no-PPO mode); starts whose conditional mode
    lies on the no-PPO plateau (the PPO leaves the likelihood as at the
    quiet tilt, so it does not depend on alpha there) are not fitted
    jointly. The best ``best`` solutions at
    distinct tilts go on for up to ``rounds`` more rounds of 40 steps.
    Solutions where the PPO does not change the likelihood are the no-PPO
    mode (the plateau) and are dropped; solutions within 0.3 deg and 0.5 in
    log density are one mode; modes more than ``keep`` below the best are
    dropped.

    Returns (modes: [(log Laplace mass, mean [dim + 1], chol [dim + 1,
    dim + 1])] (mean and chol in (w, alpha [deg])), plateau: log Laplace mass
    of the no-PPO mode spread over the tilts without a PPO, info dict)."""
    t_begin = time.perf_counter()
    dim = L.shape[0]
    starts, loud, quiet = _starts(post, u_mode, step)
    info = {"profile_quiet": quiet, "starts": int(starts.size), "joint_starts": 0, "ridges": []}
    modes, ridge = [], []
    if starts.size:
        search = _ModeSearch(post, u_mode, L, best)
        # joint fits from the conditional mode at each start's tilt (a joint
        # fit from the no-PPO mode can slide along the alpha-t0 ridge to
        # another optimum before w has moved to where the PPO needs it)
        z0 = np.column_stack([search.at_tilts(starts), starts / search.a_unit])
        # a start whose conditional mode the PPO leaves as at the quiet tilt
        # lies on the plateau, where the log density does not depend on
        # alpha: a joint fit from there cannot move, and ``laplace`` would
        # drop it
        z0 = z0[~search.on_plateau(z0)]
        info["joint_starts"] = int(z0.shape[0])
        if z0.shape[0]:
            z, logd = search.run(z0)
            z, logd = search.refine(z, logd, rounds)
            modes = search.laplace(z, logd, keep)
            ridge, nodes = search.ridge(modes, quiet, keep)
            info["ridges"] = nodes  # [first tilt, last tilt, nodes] per ridge
    # the no-PPO mode over the quiet tilts: w ~ N(0, I) in the whitening
    plateau = quiet + 0.5 * dim * np.log(2 * np.pi) + np.log(360.0 * max(float(np.mean(~loud)), 1e-3))
    info.update({"modes": [{"alpha": float(m[1][-1]), "log_mass": float(m[0]), "log_density": m[3]} for m in modes],
                 "plateau_log_mass": float(plateau), "seconds": time.perf_counter() - t_begin})
    return [m[:3] for m in modes + ridge], plateau, info


def _starts(post: TransitPosterior, u_mode, step: float):
    """The tilts [deg] the mode search starts from (every ``step`` deg
    within 4 deg of a tilt where a PPO changes the log density at the no-PPO
    mode, and that profile's maxima 1 above its quiet level), the loud mask
    on a 0.5-deg grid and the quiet level (the log density at the
    posterior's own quiet tilt, not a median over tilts, which is a PPO
    level when most tilts have one)."""
    import jax.numpy as jnp

    uj = jnp.asarray(u_mode)
    grid = np.arange(0.0, 360.0, 0.5)
    prof = np.asarray(mapped_over_devices(lambda a: post.log_density(uj, a))(grid), float)
    quiet = float(post.log_density(uj))
    if not np.isfinite(quiet):
        raise ValueError(f"the transit posterior is not finite at its no-PPO mode (log density {quiet})")
    prof = np.where(np.isfinite(prof), prof, -np.inf)
    loud = ~(np.abs(prof - quiet) <= 1e-6)
    near = np.zeros(grid.size, bool)
    for k in np.nonzero(loud)[0]:
        near[(k + np.arange(-8, 9)) % grid.size] = True
    starts = [a for a in np.arange(0.0, 360.0, step) if near[int(round(a / 0.5)) % grid.size]]
    peaks = (prof >= np.roll(prof, 1)) & (prof >= np.roll(prof, -1)) & (prof > quiet + 1.0)
    return np.array(sorted(set(starts) | set(grid[peaks].tolist())), float), loud, quiet


class _ModeSearch:
    """Batched Levenberg-Marquardt (optimistix) in z = (w, alpha / 10 deg)
    for ``joint_modes``: u = u_mode + L w, a weak pull (10 whitened widths) on
    directions the data leave free, 40 steps per solve; the solves of a
    call run one after another (``mapped``: each stops when it converges),
    ``chunk`` per compiled call."""

    a_unit = 10.0  # alpha in units of 10 deg, so LM's identity damping treats w and alpha alike
    chunk = 4  # solves per compiled call (a padded call repeats its last row: kept short)
    ahead = 8  # tilts solved ahead per step along a ridge

    def __init__(self, post, u_mode, L, best):
        import jax.numpy as jnp
        import optimistix as optx

        self.post, self.u_mode, self.L, self.best, self.dim = post, np.asarray(u_mode), np.asarray(L), best, L.shape[0]
        uj, Lj = jnp.asarray(u_mode), jnp.asarray(L)
        a_unit = self.a_unit

        def res(z, _):
            u = uj + Lj @ z[:-1]
            return jnp.concatenate([post.residuals(u, a_unit * z[-1]), 0.1 * z[:-1]])

        lm = optx.LevenbergMarquardt(rtol=1e-8, atol=1e-8)

        def solve(z0):
            return optx.least_squares(res, lm, z0, max_steps=40, throw=False).value

        def solve_at(zw0, a, steps):  # w alone at the fixed tilt a [deg]
            return optx.least_squares(lambda zw, _: res(jnp.concatenate([zw, (a / a_unit)[None]]), None), lm, zw0,
                                      max_steps=steps, throw=False).value

        # one solve after another (``mapped``): each stops when it converges.
        # The solves run whole in every JAX process: optimistix's linear
        # solve inside jax.shard_map failed to trace ("pytree does not match
        # out_structure"); the log densities are split over every device
        self.solve = mapped(solve)
        self.solve_at = mapped(lambda zw0, a: solve_at(zw0, a, 40))
        # along a ridge, from the line through the last nodes: a few steps
        self.follow = mapped(lambda zw0, a: solve_at(zw0, a, 8))
        self.logd = mapped_over_devices(lambda v, a: post.log_density(uj + Lj @ v[:-1], a))
        self.jac = jax.jit(jax.jacfwd(lambda v: res(v, None)))

    def _chunks(self, fn, *arrays):
        """``fn`` over the rows of ``arrays`` in calls of ``self.chunk``
        rows (one compilation; the last call padded with its last row)."""
        import jax.numpy as jnp

        n = arrays[0].shape[0]
        pad = -(-n // self.chunk) * self.chunk
        full = [np.concatenate([x, np.repeat(x[-1:], pad - n, axis=0)]) for x in arrays]
        return np.concatenate([np.asarray(fn(*(jnp.asarray(x[i:i + self.chunk]) for x in full)))
                               for i in range(0, pad, self.chunk)])[:n]

    def on_plateau(self, z):
        """Whether the log density at each row of z equals that at the quiet
        tilt (within 1e-6): no PPO changes the likelihood there."""
        a_quiet = np.full(z.shape[0], float(self.post.model.alpha))
        at = self._chunks(self.logd, z, self.a_unit * z[:, -1])
        at_quiet = self._chunks(self.logd, z, a_quiet)
        return np.isfinite(at) & (np.abs(at - at_quiet) <= 1e-6)

    def at_tilts(self, a):
        """w at each tilt of a [deg]: 40 LM steps from w = 0."""
        return self._chunks(self.solve_at, np.zeros((a.size, self.dim)), a)

    def run(self, z0):
        """40 joint LM steps from each row of z0: (z, log density)."""
        import jax.numpy as jnp

        z = self._chunks(self.solve, z0)
        z[:, -1] = np.mod(z[:, -1] * self.a_unit, 360.0) / self.a_unit
        ld = np.asarray(self.logd(jnp.asarray(z), jnp.asarray(self.a_unit * z[:, -1])), float)
        return z, np.where(np.isfinite(ld), ld, -np.inf)

    def refine(self, z, logd, rounds):
        """The ``best`` solutions at distinct tilts (over 1 deg apart)
        go on for up to ``rounds`` more runs, until their log density stops
        moving (0.01)."""
        for _ in range(rounds):
            best = []
            for k in np.argsort(logd)[::-1]:
                if len(best) == self.best or not np.isfinite(logd[k]):
                    break
                if all(_arc(self.a_unit * (z[k, -1] - z[j, -1])) > 1.0 for j in best):
                    best.append(k)
            if not best:
                break
            z2, ld2 = self.run(z[best])
            moved = np.max(np.abs(ld2 - logd[best]))
            z[best], logd[best] = z2, ld2
            if moved < 0.01:
                break
        return z, logd

    def laplace(self, z, logd, keep):
        """The distinct modes among the solutions (the plateau, where the PPO
        leaves the likelihood as at the quiet tilt, dropped; within 0.3 deg
        and 0.5 in log density one mode; more than ``keep`` below the best
        dropped) with their Laplace covariances in (w, alpha [deg]):
        [(log mass, mean, chol, log density)]."""
        import jax.numpy as jnp

        ok = np.isfinite(logd) & ~self.on_plateau(z)
        z, logd = z[ok], logd[ok]
        kept = []
        for k in np.argsort(logd)[::-1]:
            if logd[k] < logd.max() - keep:
                break
            if not any(_arc(self.a_unit * (z[k, -1] - z[j, -1])) < 0.3 and abs(logd[k] - logd[j]) < 0.5
                       for j in kept):
                kept.append(k)
        scale = np.r_[np.ones(self.dim), self.a_unit]
        modes = []
        for k in kept:
            J = np.asarray(self.jac(jnp.asarray(z[k])), float)
            # prior curvature: a unit width in w, 30 deg in alpha
            info_z = J.T @ J + np.diag(np.r_[np.full(self.dim, 1e-2), (self.a_unit / 30.0) ** 2])
            cov = np.diag(scale) @ np.linalg.inv(info_z) @ np.diag(scale)
            try:
                chol = np.linalg.cholesky(0.5 * (cov + cov.T))
            except np.linalg.LinAlgError:
                continue
            log_mass = float(logd[k]) + float(np.sum(np.log(np.diag(chol)))) + 0.5 * (self.dim + 1) * np.log(2 * np.pi)
            modes.append((log_mass, z[k] * scale, chol, float(logd[k])))
        return modes

    def ridge(self, modes, quiet, keep, max_nodes: int = 400):
        """The ridge through each mode 1 above the plateau, traced by
        continuation: the conditional mode w*(alpha) at fixed tilts stepping
        away from the mode both ways (steps of half its alpha width, 0.05-1
        deg; each step solves ``ahead`` tilts ahead from the line through
        the last two nodes and keeps them while they stay on one branch),
        until the PPO no longer lifts the conditional mode 0.5 above the
        plateau or it falls 12 (or ``keep``) below the best mode. Along a PPO's
        alpha-t0 ridge the posterior can be flat over tens of degrees and
        curved in w (a mode's Gaussian covers its middle only: particles
        piled up there, and calibration runs put the truth in the tails).
        Each node becomes a Gaussian in (w, alpha [deg]): alpha within 0.6
        step of the node, w about w* + (alpha - node) dw*/dalpha with the
        conditional Laplace covariance, weighted by the posterior mass of
        its slice. Returns [(log mass, mean, chol, log density)] as
        ``laplace``, and the number of nodes per ridge."""
        import jax.numpy as jnp

        best = max([m[3] for m in modes], default=-np.inf)
        # a tilt whose conditional mode is 12 below the best holds < 1e-5 of
        # its mass per degree: the ridge ends there, or where the PPO no
        # longer lifts it above the plateau
        floor = max(quiet + 0.5, best - min(keep, 12.0))
        traced, counts, comps = [], [], []  # traced: (alpha nodes, w nodes) per ridge
        for log_mass, mean, chol, logd0 in sorted(modes, key=lambda m: -m[3]):
            if logd0 < quiet + 1.0:
                continue
            a0, w0 = float(mean[-1]), np.asarray(mean[:-1])
            if any(np.min(_arc(ra - a0)) < 1.0 and np.min(np.linalg.norm(rw - w0, axis=1)) < 3.0 for ra, rw in traced):
                continue  # on a ridge already traced
            sd = float(np.sqrt(np.sum(chol[-1] ** 2)))
            step = float(np.clip(0.5 * sd, 0.05, 1.0))
            # nodes: tilt -> (w*, log density); each step solves ``ahead``
            # tilts ahead (spacing h) from the line through the last two
            # nodes and keeps them while they stay on the branch; a call that
            # keeps none solves again at a quarter of h, and the ridge ends
            # where even h = step / 16 leaves it
            nodes = {a0: (w0, logd0)}
            ahead = np.arange(1, self.ahead + 1)
            for d in (-1, 1):
                a, h, slope = a0, step, np.zeros(self.dim)
                while len(nodes) < max_nodes and abs(a - a0) < 180.0 and h >= step / 16:
                    w_cur, ld_cur = nodes[a]
                    tilts = a + d * h * ahead
                    zw = self._chunks(self.follow, w_cur + np.outer(tilts - a, slope), tilts)
                    ld = np.asarray(self.logd(jnp.asarray(np.column_stack([zw, tilts / self.a_unit])),
                                              jnp.asarray(tilts)), float)
                    moved = 0
                    for j in range(self.ahead):
                        w_last, ld_last = nodes[a]
                        expect = w_last + slope * (tilts[j] - a)
                        if (not np.isfinite(ld[j]) or ld[j] < floor
                                or abs(ld[j] - ld_last) > 3.0
                                or np.linalg.norm(zw[j] - expect) > 1.0 + 0.5 * np.linalg.norm(expect - w_last)):
                            break
                        slope = (zw[j] - w_last) / (tilts[j] - a)
                        a, moved = float(tilts[j]), moved + 1
                        nodes[a] = (zw[j], float(ld[j]))
                    h = h / 4 if not moved else min(step, 2 * h) if moved == self.ahead else h
            ks = sorted(nodes)
            alphas = np.array(ks, float)
            ws = np.array([nodes[i][0] for i in ks])
            lds = np.array([nodes[i][1] for i in ks])
            traced.append((alphas, ws))
            counts.append([float(np.mod(alphas[0], 360.0)), float(np.mod(alphas[-1], 360.0)), len(ks)])
            slopes = np.gradient(ws, alphas, axis=0) if len(ks) > 1 else np.zeros_like(ws)
            # each node stands for the slice of tilts nearer to it than to its neighbours
            edges = np.r_[alphas[0] - 0.5 * step, 0.5 * (alphas[1:] + alphas[:-1]), alphas[-1] + 0.5 * step]
            for a, w, g, ld_, width in zip(alphas, ws, slopes, lds, np.diff(edges)):
                s = 0.6 * width
                J = np.asarray(self.jac(jnp.asarray(np.r_[w, a / self.a_unit])), float)[:, :-1]
                cov_w = np.linalg.inv(J.T @ J + 1e-2 * np.eye(self.dim))
                gg = np.r_[g, 1.0]  # (w, alpha) = (w* + g x, node + x), x ~ N(0, s^2)
                cov = s**2 * np.outer(gg, gg)
                cov[:-1, :-1] += cov_w
                try:
                    ch = np.linalg.cholesky(0.5 * (cov + cov.T))
                except np.linalg.LinAlgError:
                    continue
                # the posterior mass of the slice of width ``step`` about the node (conditional Laplace)
                lm = ld_ + 0.5 * np.linalg.slogdet(2 * np.pi * cov_w)[1] + np.log(width)
                comps.append((float(lm), np.r_[w, np.mod(a, 360.0)], ch, float(ld_)))
        return comps, counts
