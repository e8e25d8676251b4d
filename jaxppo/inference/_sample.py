"""MCMC with numpyro NUTS over the same model and free parameters as ``fit``.

The priors are stated on the physical parameters and NUTS moves in the
coordinates of ``._coords`` (the one coordinate system of jaxppo's
posteriors: each prior parameter through numpyro's bijection onto its
prior's support, T14 in place of a where a and i are both free, the impact
parameter folded), then

- shifted by the posterior mode (found from the user's start) and
  whitened by the Cholesky factor of the Laplace covariance there, so
  that NUTS's dense mass matrix starts right (numpyro starts it at the
  identity and regularises it towards 1e-3 x identity, far too wide for a
  mid-time known to 1e-4 d), and warm-up starts at the mode instead of
  fighting a metric taken on a slope.

The impact parameter is folded: the light curve depends on |cos i| only
(docs/conventions.md), so i and 180 deg - i are two identical modes, and a
chain that visits both reports an interval of i that straddles 90 deg
around neither. NUTS moves a signed coordinate s = b / (1 + p) in (-1, 1)
and the model takes |s|: the density is symmetric in s, so a posterior
piled up at b = 0 is one smooth mode through s = 0, and every reported
inclination is in [0, 90] deg. ``fold_inc=False`` keeps the signed s
(inc in (0, 180) deg, the two mirrored modes). N-body orbits and planets
with moons keep the signed s always: for them the sign of cos i changes
the light curve (``._params.inc_sign_matters``).

The log-density in these coordinates is the likelihood plus
``Coordinates.log_prior`` (the prior plus log |det d(prior
parameters)/d(coordinates)|), so the posterior is the one the physical
priors define.
"""

from __future__ import annotations

import dataclasses
import json
import warnings

import jax
import jax.numpy as jnp
import numpy as np

from ..model._lightcurve import LightCurve
from ..model._system import System
from ._diagnostics import rank_diagnostics
from ._model import Model
from ._ecc import off_circular
from ._coords import Coordinates, default_priors, start_q, window_priors
from ._start import find_mode, laplace_factor
from ._fit import misfit_note
from ._params import checked_lightcurve
from ._serialise import from_jsonable, system_from_dict, system_to_dict, to_jsonable

__all__ = ["sample", "SampleResult"]


@dataclasses.dataclass
class SampleResult:
    """Result of ``jaxppo.sample``: the posterior draws, intervals and convergence diagnostics.

    Draws are in physical units (days, degrees, R*, relative flux) under
    the public names of the free parameters (e.g. "b.inc" [deg]).
    ``save`` and ``load`` write and read it as a numpy ``.npz``
    file; ``to_arviz`` and ``to_netcdf`` export it to arviz.

    Attributes
    ----------
    samples : dict
        Name -> draws [n_chains * n_draws] (chains concatenated); with
        Kipping's q1 or q2 free also the implied "star.u1", "star.u2".
    best : System
        The lowest-deviance draw as a System (as the paper reports).
    intervals : dict
        Name -> (median, lower, upper) of the central 68.3 %. An angle
        ("<p>.omega" [deg]) is summarised on the circle: its draws taken
        on the branch around their circular mean, the median in
        (-180, 180], the bounds beside it (they may pass +-180, e.g.
        (179.5, 178.4, 180.6)); its diagnostics too.
    diagnostics : dict
        Name -> {"r_hat", "ess_bulk", "ess_tail", "n_eff"}: rank-normalised
        split R-hat and effective sample sizes (Vehtari et al. 2021;
        n_eff = ess_bulk).
    deviance_min : float
        The lowest deviance of the draws, -2 ln L without the normalisation
        of the Gaussian likelihood (chi^2 of the best draw; with a free
        jitter, fit's objective).
    mcmc : numpyro.infer.MCMC or None
        The numpyro MCMC object (its samples are the internal coordinates,
        see the module docstring of ``jaxppo.inference._sample``); None
        for a loaded result.
    union_frames : numpy.ndarray
        Indices of the model frames integrated exactly as overlaps (from the
        start with a margin, widened and sampled again when the posterior
        brings disks together elsewhere).
    chains : dict
        Name -> draws [n_chains, n_draws] (the names of ``samples``).
    log_likelihood : numpy.ndarray or None
        Gaussian log-likelihood of each draw, with its normalisation
        [n_chains, n_draws].
    stats : dict
        Sample statistics, name -> [n_chains, n_draws]: "diverging",
        "step_size", "tree_depth", "n_steps", "energy", "lp",
        "acceptance_rate".
    time, flux, flux_err : numpy.ndarray or None
        The data: times [d], relative flux and its errors [n_times].
    pointwise : callable or None
        Physical free parameters [n, k] -> log-likelihood of each data point
        [n, n_times] (used by ``to_arviz``; None for a loaded result).
    names : tuple of str
        The free parameters (``chains`` also holds the derived u1, u2).
    start : dict
        Where the chains started: {"optimised": bool, "converged": bool or
        None, "message": str} (``converged`` False: the optimiser did not
        find the posterior mode from the given system, and a UserWarning
        said so), and "prior_bound": the free parameters whose posterior
        lies against a bound of its default prior window (t0 +-0.05 d, P
        +-0.1 % ... about the start; a UserWarning says so). ``problems()``
        lists what a user should look at before using the draws.

    Examples
    --------
    A short chain for the radius of a simulated planet (far too short for
    science: check ``diagnostics``):

    >>> import numpy as np
    >>> import jaxppo as jp
    >>> star = jp.Star.quadratic(0.4, 0.25)
    >>> system = jp.System(star, [jp.Planet(period=3.0, t0=0.0, a=10.0, inc=89.0, radius=0.1, name="b")])
    >>> lc = jp.simulate(system, np.linspace(-0.15, 0.15, 200), noise=1e-3, seed=1)
    >>> result = jp.sample(system, lc, free=("b.radius",), num_warmup=30, num_samples=20, num_chains=1,
    ...                    progress_bar=False)
    >>> result.samples["b.radius"].shape, result.chains["b.radius"].shape
    ((20,), (1, 20))
    >>> median, lower, upper = result.intervals["b.radius"]
    >>> print(f"radius {median:.2f} R*")
    radius 0.10 R*
    >>> sorted(result.diagnostics["b.radius"])
    ['ess_bulk', 'ess_tail', 'n_eff', 'r_hat']
    >>> sorted(result.stats)
    ['acceptance_rate', 'diverging', 'energy', 'lp', 'n_steps', 'step_size', 'tree_depth']
    >>> same = jp.SampleResult.load(result.save("draws.npz"))
    >>> bool(np.array_equal(same.samples["b.radius"], result.samples["b.radius"]))
    True
    """

    samples: dict
    best: System
    intervals: dict
    diagnostics: dict
    deviance_min: float
    mcmc: object
    union_frames: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, int))
    chains: dict = dataclasses.field(default_factory=dict)
    log_likelihood: np.ndarray | None = None
    stats: dict = dataclasses.field(default_factory=dict)
    time: np.ndarray | None = None
    flux: np.ndarray | None = None
    flux_err: np.ndarray | None = None
    pointwise: object = None  # callable: [draw, k] physical -> [draw, time] log-likelihood
    names: tuple = ()  # the free parameters (``chains`` also holds derived u1, u2)
    start: dict = dataclasses.field(default_factory=dict)  # how the start was found (see ``sample``)

    def problems(self, r_hat_max: float = 1.01, ess_per_chain: float = 100.0) -> list:
        """What to look at before using the draws, one line each (empty: none).

        Rank-normalised R-hat above ``r_hat_max`` or not finite, bulk or
        tail ESS below ``ess_per_chain`` per chain (Vehtari et al. 2021:
        1.01 and 100), divergent transitions, a posterior against a bound
        of its default prior window (``start["prior_bound"]``), an
        optimiser that did not find the mode, chi^2 / (N - k) at the mode
        that says flux_err under- or overstates the scatter
        (``start["misfit"]``, ``jaxppo.inference._fit.misfit_note``), and
        draws that reached frames the model did not compute.

        Parameters
        ----------
        r_hat_max : float, optional
            Largest acceptable R-hat (default 1.01).
        ess_per_chain : float, optional
            Smallest acceptable bulk and tail ESS per chain (default 100).

        Returns
        -------
        list of str
            One line per problem.
        """
        chains = max(len(next(iter(self.chains.values()))) if self.chains else 1, 1)
        out = []
        names = list(self.diagnostics)
        bad_r = [n for n in names if not self.diagnostics[n]["r_hat"] <= r_hat_max]
        if bad_r:
            out.append(f"R-hat above {r_hat_max} (or not finite) for {bad_r}: the chains disagree; run longer")
        ess = {n: min(self.diagnostics[n]["ess_bulk"], self.diagnostics[n]["ess_tail"]) for n in names}
        low = [n for n in names if not ess[n] >= ess_per_chain * chains]
        if low:
            out.append(f"ESS below {ess_per_chain:g} per chain ({ess_per_chain * chains:g}) for {low} (lowest "
                       f"{min(ess[n] for n in low):.0f}): intervals are uncertain; run longer")
        div = int(np.sum(self.stats["diverging"])) if "diverging" in self.stats else 0
        if div:
            out.append(f"{div} divergent transitions: the sampler missed part of the posterior")
        if self.start.get("prior_bound"):
            out.append(f"posterior against its default prior window for {list(self.start['prior_bound'])}: the "
                       "window, not the data, sets that edge; start nearer the solution (jp.fit) or give priors")
        if self.start.get("misfit"):
            out.append(f"at the posterior mode {self.start['misfit']}")
        if self.start.get("converged") is False:
            out.append(f"the optimiser did not find the posterior mode ({self.start.get('message', '')})")
        if self.start.get("frames_complete") is False:
            out.append("draws reached frames the model did not compute (see the warning of jaxppo.sample)")
        return out

    def save(self, path) -> str:
        """Write the result to a numpy ``.npz`` file (no pickle).

        The file holds the draws, log-likelihood, sample stats, data,
        intervals, diagnostics and the best system; ``load`` reads it
        back exactly. The MCMC object and the pointwise log-likelihood
        function are not saved: ``to_arviz`` of a loaded result gives the
        total log-likelihood.

        Parameters
        ----------
        path : str or os.PathLike
            The file to write (overwritten; no ".npz" is appended).

        Returns
        -------
        str
            ``path``.
        """
        from .._version import __version__

        meta = {"format": "jaxppo.SampleResult", "version": __version__, "names": list(self.names or self.chains),
                "chains": list(self.chains), "stats": list(self.stats), "deviance_min": to_jsonable(self.deviance_min),
                "intervals": {k: to_jsonable(list(v)) for k, v in self.intervals.items()},
                "diagnostics": {k: {m: to_jsonable(x) for m, x in v.items()} for k, v in self.diagnostics.items()},
                "best": system_to_dict(self.best), "start": dict(self.start)}
        arrays = {f"chain_{i}": np.asarray(v) for i, v in enumerate(self.chains.values())}
        arrays.update({f"stat_{i}": np.asarray(v) for i, v in enumerate(self.stats.values())})
        for k in ("log_likelihood", "time", "flux", "flux_err", "union_frames"):
            if getattr(self, k) is not None:
                arrays[k] = np.asarray(getattr(self, k))
        path = str(path)
        with open(path, "wb") as fh:  # a file object: numpy appends no ".npz" to the name
            np.savez(fh, meta=np.array(json.dumps(meta, allow_nan=False)), **arrays)
        return path

    @classmethod
    def load(cls, path) -> "SampleResult":
        """Read a result written by ``save`` (or ``jaxppo sample --out``).

        Parameters
        ----------
        path : str or os.PathLike
            The ``.npz`` file.

        Returns
        -------
        SampleResult
            The result as saved, with ``mcmc`` and ``pointwise`` None.

        Raises
        ------
        ValueError
            When the file cannot be read as an ``.npz`` file with the
            result's metadata, or was not written by ``save``.
        """
        try:
            z = np.load(path, allow_pickle=False)
            meta = json.loads(str(z["meta"]))
        except (ValueError, KeyError, OSError) as err:
            raise ValueError(f"{path}: not a file written by SampleResult.save ({err})") from None
        if meta.get("format") != "jaxppo.SampleResult":
            raise ValueError(f"{path}: not a SampleResult file (format {meta.get('format')!r})")
        chains = {n: z[f"chain_{i}"] for i, n in enumerate(meta["chains"])}
        opt = {k: (z[k] if k in z.files else None) for k in ("log_likelihood", "time", "flux", "flux_err")}
        return cls({n: v.reshape(-1) for n, v in chains.items()}, system_from_dict(meta["best"]),
                   {k: tuple(from_jsonable(v)) for k, v in meta["intervals"].items()},
                   {k: {m: from_jsonable(x) for m, x in v.items()} for k, v in meta["diagnostics"].items()},
                   from_jsonable(meta["deviance_min"]), None,
                   union_frames=z["union_frames"] if "union_frames" in z.files else np.zeros(0, int), chains=chains,
                   stats={n: z[f"stat_{i}"] for i, n in enumerate(meta["stats"])}, names=tuple(meta["names"]),
                   start=dict(meta.get("start", {})), **opt)

    def to_arviz(self, pointwise: bool = True):
        """Convert the run to arviz's data structure.

        The groups: ``posterior`` (the free parameters in physical units
        under their public names, e.g. "b.inc" [deg]), ``log_likelihood``
        ("obs", per data point when ``pointwise``, else the total),
        ``sample_stats``, ``observed_data`` ("obs" at "time") and
        ``constant_data`` (flux_err at "time").

        Parameters
        ----------
        pointwise : bool, optional
            The log-likelihood of every data point [chain, draw, n_times]
            (default; needs the run's model, so not after ``load``) or the
            total per draw [chain, draw] (what PSIS-LOO cannot use).

        Returns
        -------
        arviz.InferenceData or xarray.DataTree
            An ``InferenceData`` with arviz 0.x, a ``DataTree`` with arviz
            1.x (the same groups and variables).

        Raises
        ------
        ImportError
            When arviz is not installed (``pip install 'jaxppo[arviz]'``).
        ValueError
            When ``pointwise`` is asked of a loaded result (no model).
        """
        try:
            import arviz as az
        except ImportError as err:  # pragma: no cover - depends on the environment
            raise ImportError("to_arviz needs arviz: pip install 'jaxppo[arviz]'") from err
        names = list(self.names or self.chains)
        nc, nd = self.chains[names[0]].shape
        if pointwise and self.pointwise is None:
            # a loaded result has no model: the total per draw under the
            # pointwise name made az.loo report "1 observation" silently
            raise ValueError("to_arviz(pointwise=True) needs the model of the run, which a loaded SampleResult does "
                             "not have: use to_arviz(pointwise=False) (the total log-likelihood per draw), or "
                             "re-run jp.sample")
        if pointwise:
            vals = np.stack([self.chains[n].reshape(-1) for n in names], axis=1)
            ll = {"obs": np.asarray(self.pointwise(vals)).reshape(nc, nd, -1)}
            ll_dims = {"obs": ["time"]}
        else:
            ll = {"obs": self.log_likelihood}
            ll_dims = {}
        groups = {
            "posterior": {n: np.asarray(v) for n, v in self.chains.items()},
            "log_likelihood": ll,
            "sample_stats": {k: np.asarray(v) for k, v in self.stats.items()},
            "observed_data": {"obs": np.asarray(self.flux)},
            "constant_data": {"flux_err": np.asarray(self.flux_err)},
        }
        attrs = {"inference_library": "numpyro", "creator": "jaxppo.sample"}
        kw = dict(coords={"time": np.asarray(self.time)}, dims={"obs": ["time"], "flux_err": ["time"], **ll_dims})
        if arviz_major(az) >= 1:  # an xarray DataTree; attributes per group
            return az.from_dict(groups, attrs={g: dict(attrs) for g in groups}, **kw)
        return az.from_dict(**groups, attrs=attrs, **kw)  # arviz 0.x: an InferenceData

    def to_netcdf(self, path) -> str:
        """Write ``to_arviz`` to a netCDF file.

        ``arviz.from_netcdf`` reads it back (arviz 0.x or 1.x; the groups
        are written with h5netcdf).

        Parameters
        ----------
        path : str or path-like
            The file to write (its folder must exist).

        Returns
        -------
        str
            The path written.
        """
        # arviz 0.x's InferenceData and 1.x's DataTree take the same call
        self.to_arviz().to_netcdf(str(path), engine="h5netcdf")
        return str(path)


def arviz_major(az) -> int:
    """The major version of the arviz module ``az`` (0 or 1: their
    ``from_dict`` signatures and return types differ)."""
    return int(str(az.__version__).split(".")[0])


def sample(system: System, lightcurve: LightCurve, free=("b.t0", "b.radius"), num_warmup: int = 1000,
           num_samples: int = 1000, seed: int = 0, num_chains: int = 4, alpha: float = 0.0, case: str = "same",
           progress_bar: bool = True, dense_mass: bool = True, priors: dict | None = None, optimise: bool = True,
           fold_inc: bool = True) -> SampleResult:
    """Sample the posterior of the named free parameters with NUTS (numpyro).

    The same model and free-parameter names as ``jaxppo.fit``
    (``jaxppo.parameter_names``), with physical priors. The defaults:
    t0 (and listed transit times) within +-0.05 d and P within +-0.1 % of
    the start, a in [1, 4 a], p log-uniform in [1e-4, 0.5], the impact
    parameter uniform in 0 <= |b| < 1 + p, limb-darkening coefficients
    within +-1 of the start, Kipping's q1, q2 uniform in [0, 1],
    "lc.offset" and baseline coefficients uniform in [-0.05, 0.05], the
    jitter log-uniform in [1e-3, 10] x the median error. The chains run
    vectorised (one program), with a dense mass matrix (``dense_mass``) in
    the coordinates of the module docstring of
    ``jaxppo.inference._sample``.

    Parameters
    ----------
    system : System
        The start: the free parameters' starting values (the default priors
        are centred on them) and every fixed one.
    lightcurve : LightCurve or lightkurve.LightCurve
        The data (its ``exposure`` is integrated).
    free : sequence of str, optional
        Names of the free parameters (default ``("b.t0", "b.radius")``).
    num_warmup : int, optional
        Warm-up (adaptation) steps per chain (default 1000), >= 1.
    num_samples : int, optional
        Draws kept per chain (default 1000), >= 1.
    seed : int, optional
        Random seed of the chains and their starting points (default 0).
    num_chains : int, optional
        Number of chains (default 4), >= 1.
    alpha : float, optional
        Tilt of the tilted planet's orbit [deg] (default 0).
    case : str or tuple of int, optional
        Hemisphere case (default "same"; see ``System.flux``).
    progress_bar : bool, optional
        Show numpyro's progress bar (default True).
    dense_mass : bool, optional
        Adapt a dense mass matrix (default True); False: a diagonal one.
    priors : dict or None, optional
        Name -> scalar numpyro distribution replacing the default prior of
        that parameter, in its public units (e.g.
        ``{"b.t0": dist.Normal(131.5, 1e-4)}``); not for inclinations. A
        prior on a keeps plain coordinates (a, b) for that planet instead of
        (T14, b), and a UserWarning says so.
    optimise : bool, optional
        First find the posterior mode from ``system`` (optimistix BFGS in
        NUTS's coordinates; the priors stay centred on ``system``) and start
        the chains there, in coordinates whitened by the Laplace covariance
        at the mode (``jaxppo.inference._start``); when the mode is not
        found a UserWarning says so and the chains start at the better of
        ``system`` and the optimiser's last point. False: start at
        ``system`` with the Laplace covariance there. Default True.
    fold_inc : bool, optional
        The sign of cos i cannot be measured (the model uses |cos i|,
        docs/conventions.md), so inclinations are reported folded into
        [0, 90] deg. False samples the signed b (the old behaviour): the
        posterior of inc is then two mirrored modes, i and 180 deg - i, of
        equal height, and its intervals mean nothing. Default True. An
        N-body system (``orbits="nbody"``) keeps the sign (it acts on the
        dynamics) and is never folded, nor is a planet with moons (their
        orbits are given on the sky: i and 180 deg - i turn them over
        against the planet's path, another light curve).

    Returns
    -------
    SampleResult
        The draws (and the implied u1, u2 when q1 or q2 is free), the
        lowest-deviance solution (as the paper reports), 68.3 % intervals,
        rank-normalised R-hat and bulk / tail ESS, the sample statistics,
        and ``start``: how the chains started, {"optimised", "converged",
        "message", "frames_complete"} (the last False when, after four
        runs, the draws still reached frames the model did not compute:
        a UserWarning says so).

    Raises
    ------
    ValueError
        When ``num_warmup``, ``num_samples`` or ``num_chains`` is < 1; a
        name in ``free`` is unknown or repeated; ``priors`` names a
        parameter that is not free or an inclination, gives a distribution
        that is not a scalar numpyro distribution, or one whose support
        excludes the start; a planet with a free inclination does not
        transit at the start; the light curve's flux has a median outside
        (0.5, 2) (not relative flux); ``alpha`` is not one finite angle; or
        the log-likelihood at the start is not finite.

    Warns
    -----
    UserWarning
        When the optimiser did not find the posterior mode
        (``start["converged"]`` False), or a user prior on a planet's a
        keeps plain coordinates for it.

    Examples
    --------
    A short chain for the radius of a simulated planet, with a prior of our
    own (far too short for science: check ``result.diagnostics``):

    >>> import numpy as np
    >>> import numpyro.distributions as dist
    >>> import jaxppo as jp
    >>> star = jp.Star.quadratic(0.4, 0.25)
    >>> system = jp.System(star, [jp.Planet(period=3.0, t0=0.0, a=10.0, inc=89.0, radius=0.1, name="b")])
    >>> lc = jp.simulate(system, np.linspace(-0.15, 0.15, 200), noise=1e-3, seed=1)
    >>> result = jp.sample(system, lc, free=("b.radius",), num_warmup=30, num_samples=20, num_chains=1,
    ...                    progress_bar=False, priors={"b.radius": dist.Uniform(0.05, 0.15)})
    >>> result.start["optimised"], result.start["converged"]
    (True, True)
    >>> print(f"radius {result.intervals['b.radius'][0]:.2f} R* ({len(result.samples['b.radius'])} draws)")
    radius 0.10 R* (20 draws)
    """
    for name, v in (("num_warmup", num_warmup), ("num_samples", num_samples), ("num_chains", num_chains)):
        if int(v) < 1:
            raise ValueError(f"{name} must be >= 1, got {v}")
    lightcurve = checked_lightcurve(lightcurve, "jaxppo.sample")
    # A posterior spreads further than a fit moves (grazing draws keep a
    # disk near the limb for long): compute the frames within 1 R* of the
    # star at the start, so that sampling again (below) is rarely needed.
    model = Model(system, lightcurve, free, alpha, case, active_margin=1.0)
    system = off_circular(system, model.slots)  # a free (secosw, sesinw) never starts at e = 0
    _check_priors(model, system, priors)
    fold_inc = fold_inc and system.orbits == "kepler"  # N-body orbits keep the sign of cos i
    u0, chol, start = _start_point(model, start_q(model, system), priors, fold_inc, optimise)
    # The frames computed (and those given the exact union integral) are
    # fixed for a run. Before sampling they grow to where the Laplace
    # approximation at the start reaches (256 draws at twice its widths);
    # after it, to every frame the draws need, and the chains run again
    # from the same start and metric, so no draw is scored on frames that
    # were not computed.
    z = 2.0 * np.random.default_rng(seed).standard_normal((256, u0.size))
    model = _wider(model, priors, fold_inc, u0 + z @ chol.T) or model
    for _ in range(4):
        used = model
        result, u = _run_nuts(model, u0, chol, num_warmup, num_samples, seed, num_chains, progress_bar, dense_mass,
                              priors, fold_inc, system)
        result.start, result.union_frames = dict(start, frames_complete=True), model.union_idx
        wider = _wider(model, priors, fold_inc, np.unique(u.reshape(-1, u0.size), axis=0))
        if wider is None:
            break
        model = wider
    else:
        result.start["frames_complete"] = False
        warnings.warn(f"sample: after 4 runs the draws still reach frames the model did not compute "
                      f"({used.active_idx.size} of {used.t_model.shape[0]} computed, {model.active_idx.size} needed): "
                      "those draws' likelihoods are short of the planets' transits there; check the posterior's "
                      "tails (grazing orbits) or narrow the priors", UserWarning, stacklevel=2)
    result.start["prior_bound"] = _against_windows(model, priors, result)
    if start.get("misfit"):
        warnings.warn(f"sample: at the posterior mode {start['misfit']}", UserWarning, stacklevel=2)
    if start["converged"] is False:
        warnings.warn(f"sample: the optimiser did not find the posterior mode from the given system ({start['message']});"
                      " the chains started there with the Laplace metric of that point: check R-hat, or start closer "
                      "(e.g. at jp.fit's solution)", UserWarning, stacklevel=2)
    return result


def _against_windows(model: Model, user, result: SampleResult) -> list:
    """The free parameters whose posterior lies against a bound of its
    default prior window (``window_priors``: the median within 3 standard
    deviations of the bound), each with a UserWarning: the window cut the
    posterior (a start far from the data's solution: the windows are
    centred on it), not the data."""
    out = []
    for name, (lo, hi) in window_priors(model, user).items():
        s = np.asarray(result.samples[name], float)
        med, sd = float(np.median(s)), float(np.std(s))
        bound = lo if med - lo < hi - med else hi
        if abs(med - bound) < 3.0 * sd or not np.isfinite(med):
            out.append(name)
            warnings.warn(f"sample: the posterior of {name} (median {med:.10g}, sd {sd:.3g}) lies against the bound "
                          f"{bound:.10g} of its default prior [{lo:.10g}, {hi:.10g}], a window centred on the start: "
                          "the window, not the data, sets that edge (a start far from the data's solution, or data "
                          "that do not measure it, e.g. a period from one transit); start nearer the solution (e.g. "
                          f"at jp.fit's) or give priors={{{name!r}: ...}}", UserWarning, stacklevel=3)
    return out


def _check_priors(model: Model, system: System, user) -> None:
    """User priors: known names, scalar distributions, a start inside each
    support; says when a planet leaves the T14 coordinates."""
    priors = default_priors(model, user)
    q0 = start_q(model, system)
    for name, pr, v in zip(model.free, priors, q0):
        if user and name in user and not bool(pr.support(jnp.asarray(v))):
            raise ValueError(f"priors[{name!r}]: the start {v:.10g} is outside the prior's support {pr.support}")
    coords = Coordinates(model, priors, user or ())
    for owner in coords.plain:
        label = model.system.planets[owner].name or str(owner)
        warnings.warn(f"sample: a user prior on {label}.a: planet {label} is sampled in plain coordinates (a, b) "
                      "instead of (T14, b), which mixes more slowly along the a-b ridge", UserWarning, stacklevel=3)


def _coords(model: Model, user, fold) -> Coordinates:
    """NUTS's coordinates of ``model`` (the priors' maps; ``._coords``)."""
    return Coordinates(model, default_priors(model, user), user or (), fold)


def _loglike(model: Model, coords: Coordinates):
    """(u -> ln L at the coordinates u, the Gaussian normalisation)."""
    log_norm = -float(np.sum(np.log(np.asarray(model.sigma)))) - 0.5 * model.y.size * np.log(2.0 * np.pi)

    def loglike_u(u):
        # with a free jitter the residuals carry ln(1 + s^2 / sigma^2) terms:
        # the sum of squares is -2 ln L - sum ln(2 pi sigma^2) (fit's objective)
        return -0.5 * jnp.sum(model.residuals(model.theta_from(coords.to_q(u))) ** 2) + log_norm

    return loglike_u, log_norm


def _start_point(model: Model, q0, user, fold, optimise):
    """(u at the start, the Cholesky factor of the Laplace covariance there,
    the start's record): the posterior mode found from q0 when
    ``optimise``, else q0 itself."""
    coords = _coords(model, user, fold)
    loglike_u, _ = _loglike(model, coords)
    u0 = coords.from_q(q0)

    @jax.jit
    def potential_u(u):
        v = -(loglike_u(u) + coords.log_prior(u))
        return jnp.where(jnp.isnan(v), jnp.inf, v)

    jacobian_u = jax.jit(jax.jacfwd(lambda u: model.residuals(model.theta_from(coords.to_q(u)))))
    ll0 = float(jax.jit(loglike_u)(jnp.asarray(u0)))
    if not np.isfinite(ll0):
        raise ValueError(f"sample: the log-likelihood at the start is {ll0} (flux_err as small as "
                         f"{float(np.min(np.asarray(model.sigma))):.3g} overflows float64, or the model is not finite)")
    prior_sd = coords.prior_widths(u0)
    if optimise:
        u0, chol, ok, why = find_mode(potential_u, jacobian_u, u0, prior_sd)
        # chi^2 at the mode: flux_err that under- or overstates the scatter scales every width
        r = np.asarray(model.residuals(model.theta_from(coords.to_q(jnp.asarray(u0)))))[:model.y.size]
        chi2 = float(np.sum(r**2))
        note = None if "lc.jitter" in model.free else misfit_note(chi2, model.y.size - len(model.free))
        return np.asarray(u0), chol, {"optimised": True, "converged": bool(ok), "message": why, "misfit": note}
    return np.asarray(u0), laplace_factor(jacobian_u, u0, prior_sd), {
        "optimised": False, "converged": None, "message": "started at the given system"}


def _wider(model: Model, user, fold, us) -> "Model | None":
    """The Model whose frames also cover the coordinates ``us`` [n, k]
    (``Model.widened_at``), or None when they do already."""
    coords = _coords(model, user, fold)
    thetas = jax.jit(jax.vmap(lambda u: model.theta_from(coords.to_q(u))))(jnp.asarray(us))
    return model.widened_at(np.asarray(thetas))


def _run_nuts(model, u0, chol, num_warmup, num_samples, seed, num_chains, progress_bar, dense_mass, user, fold,
              system):
    """(SampleResult, the draws' coordinates u [chain, draw, k]): NUTS in
    w, u = u0 + L w, from u0 with the metric L L^T."""
    from numpyro.infer import MCMC, NUTS

    coords = _coords(model, user, fold)
    loglike_u, log_norm = _loglike(model, coords)
    k = len(model.free)
    u0j, lj = jnp.asarray(u0), jnp.asarray(chol)

    @jax.jit  # numpyro evaluates it eagerly while it initialises: one program, not hundreds
    def potential(w):
        u = u0j + lj @ w
        v = -(loglike_u(u) + coords.log_prior(u))
        return jnp.where(jnp.isnan(v), jnp.inf, v)

    kernel = NUTS(potential_fn=potential, dense_mass=dense_mass)
    mcmc = MCMC(kernel, num_warmup=num_warmup, num_samples=num_samples, num_chains=num_chains,
                chain_method="vectorized", progress_bar=progress_bar)
    # chains start around the mode, 0.3 Laplace widths apart
    init = 0.3 * np.random.default_rng(seed).standard_normal((num_chains, k)) if num_chains > 1 else np.zeros((1, k))
    mcmc.run(jax.random.PRNGKey(seed), init_params=jnp.asarray(init if num_chains > 1 else init[0]),
             extra_fields=("diverging", "num_steps", "energy", "potential_energy", "accept_prob", "adapt_state.step_size"))
    w = np.asarray(mcmc.get_samples(group_by_chain=True)).reshape(num_chains, num_samples, k)
    u = u0[None, None] + np.einsum("ij,cdj->cdi", chol, w)
    return _result(model, system, coords, mcmc, u, loglike_u, log_norm), u


def _result(model: Model, system: System, coords: Coordinates, mcmc, u, loglike_u, log_norm: float) -> SampleResult:
    """The SampleResult of the draws ``u`` [chain, draw, k] (NUTS's
    coordinates): physical values, the best draw, intervals, diagnostics
    and the sample statistics."""
    num_chains, num_samples, k = u.shape

    @jax.jit
    def post(uu):
        def one(v):
            q = coords.to_q(v)
            th = model.theta_from(q)
            return q, jnp.concatenate([model.physical(th), model.derived(th)]), loglike_u(v)

        return jax.lax.map(one, uu, batch_size=256)

    q, phys, loglike = (np.asarray(v) for v in post(jnp.asarray(u.reshape(-1, k))))
    # free parameters, then the derived u1, u2 of Kipping's q1, q2
    all_names = tuple(model.free) + model.derived_names()
    samples = {n: phys[:, i] for i, n in enumerate(all_names)}
    chains = {n: phys[:, i].reshape(num_chains, num_samples) for i, n in enumerate(all_names)}
    best_i = int(np.argmax(loglike))
    best = model.result_system(model.theta_from(jnp.asarray(q[best_i])))
    on_circle = {n: _unwrapped(samples[n]) for n in all_names if n.endswith(".omega")}
    intervals = {n: _central_interval(samples[n], on_circle.get(n)) for n in all_names}
    diagnostics = {n: rank_diagnostics(chains[n] if n not in on_circle else on_circle[n].reshape(chains[n].shape))
                   for n in all_names}

    def pointwise(vals):
        """[draw, k] physical free parameters -> [draw, time] log-likelihood."""
        ref = model.to_theta(system)
        return np.asarray(jax.lax.map(lambda v: model.pointwise_loglike(model.theta_from(v, ref)),
                                      jnp.asarray(vals), batch_size=64))

    return SampleResult(samples, best, intervals, diagnostics, float(-2 * (loglike[best_i] - log_norm)), mcmc,
                        chains=chains, log_likelihood=loglike.reshape(num_chains, num_samples),
                        stats=_sample_stats(mcmc, num_chains, num_samples), time=np.asarray(model.lc.time),
                        flux=np.asarray(model.lc.flux), flux_err=np.asarray(model.lc.flux_err), pointwise=pointwise,
                        names=tuple(model.free))


def _unwrapped(deg) -> np.ndarray:
    """Draws of an angle [deg] on the branch centred on their circular mean
    (each within 180 deg of it): a posterior of omega around +-180 deg is
    one interval there, not the whole circle."""
    deg = np.asarray(deg, float)
    rad = np.deg2rad(deg)
    centre = np.rad2deg(np.arctan2(np.mean(np.sin(rad)), np.mean(np.cos(rad))))
    return centre + np.mod(deg - centre + 180.0, 360.0) - 180.0


def _central_interval(draws, unwrapped=None) -> tuple:
    """(median, lower, upper) of the central 68.3 % of ``draws``; an angle's
    from its ``unwrapped`` draws, the median then brought into (-180, 180]
    deg and the bounds moved with it (they may pass +-180)."""
    if unwrapped is None:
        return tuple(float(x) for x in np.percentile(draws, [50.0, 15.85, 84.15]))
    med, lo, hi = np.percentile(unwrapped, [50.0, 15.85, 84.15])
    shift = (180.0 - np.mod(180.0 - med, 360.0)) - med  # a multiple of 360
    return float(med + shift), float(lo + shift), float(hi + shift)


def _sample_stats(mcmc, num_chains: int, num_samples: int) -> dict:
    """numpyro's extra fields as the sample statistics of ``SampleResult``."""
    extra = mcmc.get_extra_fields(group_by_chain=True)

    def shaped(v):
        return np.asarray(v).reshape(num_chains, num_samples)

    n_steps = shaped(extra["num_steps"])
    return {"diverging": shaped(extra["diverging"]).astype(bool), "step_size": shaped(extra["adapt_state.step_size"]),
            "n_steps": n_steps, "tree_depth": np.floor(np.log2(np.maximum(n_steps, 1))).astype(int) + 1,
            "energy": shaped(extra["energy"]), "lp": -shaped(extra["potential_energy"]),
            "acceptance_rate": shaped(extra["accept_prob"])}
