"""The obliquity scan marginalised over the transit-parameter posterior.

Mueller et al. (2021) hold every transit parameter fixed while they scan the
tilt alpha and name the improvement "beyond the scope of this paper" (end of
Sect. 4.2): repeat the scan for models drawn from the transit-parameter
posterior and average the chi^2 curves by their likelihoods. This module does
that (docs/marginal.md):

    p(alpha | D) = integral p(alpha, theta | D) dtheta
                 ~ integral L(D | alpha, theta) pi(theta) dtheta
                 ~ E_{theta ~ p0(theta | D)} [ L(D | alpha, theta) / L0(D | theta) ]
                 = E_{theta ~ p0} [ exp(-(chi^2(alpha, theta) - chi^2_0(theta)) / 2) ]

with p0 the posterior of the transit parameters under the no-PPO model (each
planet's own transit only: the model of every alpha without a PPO) and
chi^2_0(theta) its chi^2, so the weight of a draw at alpha is exp(-Delta
chi^2 / 2) with that draw's own no-PPO model as reference. The NUTS draws are
taken at an alpha where no planet-planet occultation occurs in any frame
(``alpha_ref``), so the sampled posterior is p0 exactly (checked per draw).

The draws x alphas x cases x frames work is one batched computation per chunk
of draws: the one-disk terms of every draw's frames (which hold for every
alpha and case) in one call, and the frames in which the tilted planet's disk
overlaps another disk (found from the geometry) of all draws, alphas and
cases in one call of the same overlap kernel the plain scan uses
(``jaxppo.model._sweep.overlap_flux``). chi^2 is then updated sparsely: only
the points containing an overlapping sub-exposure change.

Results are written as they go (one checksummed JSON line per draw and case,
the progress format of ``jaxppo.obliquity._progress``, fsynced per chunk of
draws); an interrupted run resumes without recomputing finished draws.
"""

from __future__ import annotations

import hashlib
import json
import numbers
import os
import tempfile
import time
import warnings
from pathlib import Path
from types import SimpleNamespace

import jax
import numpy as np

from ._config import ScanConfig, check_alpha_grid, config_from_arguments, require_scan_system
from ._keywords import Default, refuse_with_config, resolved
from ._marginal_result import MarginalResult, analyse_draws, marginal_csv, plot_marginal
from ._progress import atomic_write, progress_header, read_progress, record_line
from ._scan import run_scan
from ._windows import windows_and_events, windows_data
from ..inference._importance import MIN_IMPORTANCE_ESS
from ..inference._coords import check_density, default_density
from ..inference._posterior import PLANET_PARAMS, nuts_draws, posterior_slot
from ..model._lightcurve import LightCurve
from ..model._overlap import case_xy, contact_frames, on_star, ppo_table, quiet_model, untilted_geometry
from ..model._plan import one_disk_sum, overlap_flux
from ..model._processes import is_writer, on_writer, process_info, read_once, share
from ..model._cases import case_signs
from ..model._system import System

__all__ = ["marginal_scan", "MarginalResult", "marginal_chi2", "default_free", "quiet_alpha", "density_prior",
           "centre_epochs", "config_of"]

PROGRESS = "marginal_progress.jsonl"
DRAWS = "marginal_draws.json"
_ORDER, _KCHUNK = 24, 65536


def default_free(system: System) -> tuple[str, ...]:
    """t0, period, a, inc and radius of every planet (the issue's default);
    not the t0 of a planet with transit times (they fix its mid-times, t0
    cancels)."""
    return tuple(f"{pl.name or i}.{p}" for i, pl in enumerate(system.planets) for p in PLANET_PARAMS
                 if not (p == "t0" and pl.transit_times is not None))




def _systems_from(system: System, samples: dict, names) -> list[System]:
    """One System per draw: the given system with the sampled parameters."""
    n = len(np.asarray(samples[names[0]]))
    slots = [posterior_slot(system, name, "samples") for name in names]
    values = [np.asarray(samples[name], float) for name in names]
    out = []
    for i in range(n):
        planets = list(system.planets)
        for (idx, par), v in zip(slots, values):
            if isinstance(par, tuple):  # a listed transit time: "b.tc[12]"
                times = list(planets[idx].transit_times)
                times[par[1]] = float(v[i])
                planets[idx] = planets[idx].replace(transit_times=times)
            else:
                planets[idx] = planets[idx].replace(**{par: float(v[i])})
        out.append(system.replace(planets=planets))
    return out


def sampled_system(system: System, sampler: dict) -> System:
    """The system the draws were sampled about: NUTS samples at each
    planet's t0 moved to the middle of the data (``centre_epochs``; the
    sampler records them as ``t0_epochs``), so a draw with a free period
    but a fixed t0 is that period about the moved t0 (about the config's t0
    it would put each transit n dP off); draws given by the caller are
    about ``system`` itself."""
    moved = sampler.get("t0_epochs")
    if not moved:
        return system
    planets = [pl.replace(t0=float(moved.get(pl.name or str(i), pl.t0))) if pl.transit_times is None else pl
               for i, pl in enumerate(system.planets)]
    return system.replace(planets=planets)


def _check_samples(system: System, samples: dict) -> tuple[list[str], int]:
    if not isinstance(samples, dict) or not samples:
        raise ValueError(f"samples must be a non-empty dict name -> array of draws, got {type(samples).__name__}")
    names = list(samples)
    lengths = {n: np.asarray(samples[n]).shape for n in names}
    n = lengths[names[0]]
    if any(s != n for s in lengths.values()) or len(n) != 1 or n[0] < 1:
        raise ValueError(f"samples: every entry must be a 1D array of the same length >= 1, got shapes {lengths}")
    seen = {}
    for name in names:
        owner, _, par = name.partition(".")
        tc_listed = [pl.transit_times is not None for i, pl in enumerate(system.planets) if (pl.name or str(i)) == owner]
        if par == "tc" and any(tc_listed):
            raise ValueError(f"samples: {name!r}: draws name one listed transit time each, like '{owner}.tc[12]'")
        key = posterior_slot(system, name, "samples")
        if key in seen:
            raise ValueError(f"samples: {seen[key]!r} and {name!r} name the same parameter")
        seen[key] = name
        if not np.all(np.isfinite(np.asarray(samples[name], float))):
            raise ValueError(f"samples: {name!r} holds non-finite values")
    return names, int(n[0])




def _overlap_jobs(systems, geo, tm, alpha, cases):
    """The frames in which some disk overlaps another, over every (draw,
    case, alpha): the one contact test. Returns (draw, case, alpha, frame,
    x, y of the tilted planet) arrays, or None when there are none, and ppo
    [draw, case, alpha] (the tilted planet overlaps another in some frame)."""
    jobs = [[] for _ in range(6)]
    ppo = np.zeros((len(systems), len(cases), alpha.size), bool)
    for di, (s, g) in enumerate(zip(systems, geo)):
        xt, yt = g[3], g[4]  # [alpha, time]
        ppo[di] = contact_frames(s, tm, alpha, cases, tilted_only=True, geometry=g).any(-1)
        hits = contact_frames(s, tm, alpha, cases, geometry=g)
        for ci in range(len(cases)):
            ai, ti = np.nonzero(hits[ci])
            if ai.size:
                for lst, v in zip(jobs, (np.full(ai.size, di), np.full(ai.size, ci), ai, ti, xt[ai, ti], yt[ai, ti])):
                    lst.append(v)
    if not jobs[0]:
        return None, ppo
    return tuple(np.concatenate(v) for v in jobs), ppo


def marginal_chi2(systems, tm, nsub, y, sig, alpha, cases):
    """chi^2 of every (draw, case, alpha) and each draw's no-PPO chi^2.

    Args:
        systems: one ``System`` per draw (same star, planets, tilted).
        tm: model times [d] (``LightCurve.supersampled_times``), nsub per point.
        y, sig: the data and their errors per point.
        alpha [deg], cases: the grid.

    Returns:
        chi2 [draw, case, alpha], chi2_null [draw] (the no-PPO model: the sum
        of each disk's own transit), ppo [draw, case, alpha] (True where the
        tilted planet overlaps another planet on the star in some frame:
        ``jaxppo.model._overlap.ppo_table`` over all events at once).

    One batched computation: the one-disk terms of all draws in one call, the
    overlapping frames of all draws, cases and alphas in one call of the
    overlap kernel the plain scan uses (bounded by its own chunking).
    """
    alpha = np.asarray(alpha, float)
    tm = np.asarray(tm, float)
    n_d, n_c, n_a, n_t = len(systems), len(cases), alpha.size, tm.size
    n_pts = n_t // nsub
    star = systems[0].star
    k, tilted = len(systems[0].planets), systems[0].tilted
    signs_of = [case_signs(k, tilted, c) for c in cases]
    # untilted geometry of every draw ("same" case, r = 0 behind the star)
    # and its tilted planet at every alpha
    geo = [untilted_geometry(s, tm, alpha) for s in systems]
    x0 = np.stack([g[0] for g in geo])  # [draw, time, disk]
    y0 = np.stack([g[1] for g in geo])
    r0 = np.stack([g[2] for g in geo])
    d0 = np.hypot(x0, y0)
    on = on_star(x0, y0, r0)
    # one-disk terms: alpha- and case-independent, one call for all draws
    base = np.ones((n_d, n_t))
    fr = on.any(-1)
    if fr.any():
        base[fr] = one_disk_sum(star, d0[fr], r0[fr], _ORDER, _KCHUNK)
    m_base = base.reshape(n_d, n_pts, nsub).mean(-1)
    res0 = (y[None, :] - m_base) / sig[None, :]
    chi2_null = np.sum(res0**2, axis=1)

    # overlapping frames of every (draw, case, alpha): the one contact test
    jobs, ppo = _overlap_jobs(systems, geo, tm, alpha, cases)
    chi2 = np.broadcast_to(chi2_null[:, None, None], (n_d, n_c, n_a)).copy()
    if jobs is None:
        return chi2, chi2_null, ppo
    jd, jc, ja, jt, xt_j, yt_j = jobs
    # untilted planets mirrored per case as System.positions mirrors them
    # (before their node: case_xy); multiplying y by the sign misplaced a
    # planet with a nonzero lnode
    X, Y = (np.array(v) for v in case_xy(systems[0], x0[jd, jt], y0[jd, jt], np.stack(signs_of)[jc]))
    X[:, tilted] = xt_j
    Y[:, tilted] = yt_j
    vals = np.asarray(overlap_flux(star, X, Y, r0[jd, jt], _ORDER, _KCHUNK))
    # sparse chi^2 update: each overlapping sub-exposure moves its point's
    # exposure-averaged model by (val - base) / nsub
    shift = (vals - base[jd, jt]) / nsub
    pt = jt // nsub
    key = ((jd * n_c + jc) * n_a + ja) * n_pts + pt
    uk, inv = np.unique(key, return_inverse=True)
    dm = np.bincount(inv, weights=shift, minlength=uk.size)
    p_idx = uk % n_pts
    rest = uk // n_pts
    a_idx = rest % n_a
    rest //= n_a
    c_idx = rest % n_c
    d_idx = rest // n_c
    r_old = res0[d_idx, p_idx]
    r_new = r_old - dm / sig[p_idx]
    np.add.at(chi2, (d_idx, c_idx, a_idx), r_new**2 - r_old**2)
    return chi2, chi2_null, ppo


def _chi2_0(chi2, ppo, systems, tm, nsub, y, sig, cases):
    """Ground level per draw and case as the scan defines it: the median of
    chi^2 over the alphas with no PPO in any frame; with none, the chi^2 of
    the model of such an alpha (``quiet_model``: the untilted planets'
    overlaps kept; the sum of one-disk terms left them out)."""
    n_d, n_c, _ = chi2.shape
    out = np.empty((n_d, n_c))
    for d in range(n_d):
        for c in range(n_c):
            quiet = ~ppo[d, c]
            if quiet.any():
                out[d, c] = np.median(chi2[d, c, quiet])
            else:
                model = quiet_model(systems[d], tm, cases[c]).reshape(-1, nsub).mean(-1)
                out[d, c] = float(np.sum(((y - model) / sig) ** 2))
    return out


def quiet_alpha(system: System, tm: np.ndarray, case) -> float:
    """A tilt [deg] without a PPO in any frame, as far as possible (in
    alpha) from every tilt with one, so the transit posterior sampled there
    is the no-PPO posterior for all plausible draws."""
    grid = np.arange(0.0, 360.0, 0.5)
    quiet = ~ppo_table(system, [tm], grid, case)[:, 0]
    if not quiet.any():
        raise ValueError("alpha: every tilt produces a planet-planet occultation in these windows; "
                         "the no-PPO transit posterior cannot be sampled at a quiet tilt (pass samples=)")
    if quiet.all():
        return 0.0
    # distance (circular, in grid steps) to the nearest PPO tilt
    loud = np.nonzero(~quiet)[0]
    idx = np.arange(grid.size)
    dist = np.min(np.abs((idx[:, None] - loud[None, :] + grid.size // 2) % grid.size - grid.size // 2), axis=1)
    return float(grid[int(np.argmax(np.where(quiet, dist, -1)))])


def centre_epochs(system: System, t_mid: float) -> System:
    """The same orbits with each planet's t0 moved by whole periods to the
    transit nearest t_mid [d]. A planet with listed transit times keeps its
    t0 and epochs: its t0 cancels (the orbit is shifted by tc_n - t0 - n P)
    and is never sampled, and its epochs keep the user's numbering, so that
    a free "b.tc[12]" names the same transit."""
    planets = []
    for pl in system.planets:
        if pl.transit_times is not None:
            planets.append(pl)
            continue
        n = int(np.round((t_mid - float(pl.t0)) / float(pl.period)))
        planets.append(pl.replace(t0=float(pl.t0) + n * float(pl.period)))
    return system.replace(planets=planets)


def _digest(cfg: ScanConfig, settings: dict) -> str:
    payload = json.dumps({"scan": cfg.digest, "marginal": settings}, sort_keys=True, default=str).encode()
    return hashlib.sha256(payload).hexdigest()[:16]


def config_of(system, lightcurve, kw, who: str = "jaxppo.marginal_scan",
              what: str = "the marginalised obliquity scan") -> ScanConfig:
    """The ScanConfig of a workflow called with a config (``kw``, its scan
    settings, refused as ``who`` does) or with a System and a light curve
    (``kw`` builds the config); ``what`` names the workflow when the
    system cannot be scanned."""
    if isinstance(system, ScanConfig):
        if lightcurve is not None:
            raise ValueError("lightcurve must not be given with a ScanConfig (the config names its data)")
        refuse_with_config(kw, system, who)
        require_scan_system(system.system, what)
        return system
    cfg = config_from_arguments(system, lightcurve, **resolved(kw), block=60)
    check_alpha_grid(cfg.alpha)
    return cfg


def _check_options(draws, samples, min_ess, chunk, thin, num_warmup, chains):
    """The sampler and batching options checked; returns ``draws`` as int
    (unchanged when ``samples`` give the draws)."""
    if samples is None:
        if isinstance(draws, bool) or int(draws) != draws or int(draws) < 1:
            raise ValueError(f"draws must be an integer >= 1, got {draws!r}")
        draws = int(draws)
    if not (isinstance(min_ess, numbers.Real) and not isinstance(min_ess, (bool, np.bool_))
            and np.isfinite(min_ess) and min_ess >= 1):
        raise ValueError(f"min_ess must be a finite number >= 1 (effective draws), got {min_ess!r}")
    if samples is None and draws < min_ess and is_writer():  # (process 0 of several says it)
        warnings.warn(f"draws = {draws} is below min_ess = {min_ess:g}: the importance weights of fewer draws than "
                      "that can never carry a probability, peak or rating, so none will be given; draw more",
                      stacklevel=3)
    for name, v, lo in (("chunk", chunk, 1), ("thin", thin, 1), ("num_warmup", num_warmup, 1), ("chains", chains, 1)):
        if isinstance(v, bool) or int(v) != v or int(v) < lo:
            raise ValueError(f"{name} must be an integer >= {lo}, got {v!r}")
    return draws


def density_prior(system, sysm: System, free, given, stellar_density):
    """(density prior [mean, sd] [g/cm^3] or None, its source) of the
    sampler: only when NUTS samples a free a/R*."""
    density, density_source = None, None
    if given is None and any(n.endswith(".a") for n in free):
        if stellar_density is None and isinstance(system, ScanConfig):
            stellar_density = (system.raw.get("fit") or {}).get("stellar_density")
            density_source = (system.raw.get("fit") or {}).get("stellar_density_source", "[fit] stellar_density")
        if stellar_density is None:
            labels = [pl.name or str(i) for i, pl in enumerate(sysm.planets)]
            tied = [labels.index(n.split(".")[0]) for n in free if n.endswith(".a") and n.split(".")[0] in labels]
            *density, density_source = default_density(sysm, tied)
        else:
            density = check_density(stellar_density)
            density_source = density_source or "stellar_density argument"
        density = [float(v) for v in density]
    return density, density_source


def marginal_scan(system, lightcurve=None, *, draws: int = 64, out=None, free=None, samples=None,
                  num_warmup: int = 300, thin: int = 1, seed: int = 0, chains: int = 4, stellar_density=None,
                  chunk: int = 16, fixed=None,
                  restart: bool = False, progress: bool = True, figures: bool = True, alpha=Default(None),
                  cases=Default(("same", "opposite")), margin: float = Default(0.05), detrend=Default(2),
                  baseline: float = Default(0.3), clip=Default(5.0), multi_transits=Default(None),
                  min_ess: float = MIN_IMPORTANCE_ESS) -> MarginalResult:
    """Run the obliquity scan marginalised over the transit parameters.

    The paper's proposal at the end of Sect. 4.2 (issue 11; docs/marginal.md):
    the scan repeated for N draws of the transit parameters from their
    posterior under the no-PPO model, averaged by importance weights,

        p(alpha | D) ~ E_theta [ exp(-(chi^2(alpha, theta) - chi^2_ref(theta)) / 2) ],

    with chi^2_ref the draw's chi^2 at the tilt alpha_ref the NUTS draws were
    taken at (a tilt without planet-planet occultations), or its chi^2_0 for
    draws given by the caller. The draws are NUTS draws of the no-PPO
    transit posterior, taken at alpha_ref, unless ``samples`` gives them.

    ``jp.marginal_scan(jp.load_config(path), draws=64, out="dir")`` or
    ``jp.marginal_scan(system, lightcurve, alpha=np.arange(0, 360, 1.0), ...)``.
    The results are written as they go; a run in the same ``out`` resumes
    without recomputing finished draws. Needs float64.

    Parameters
    ----------
    system : ScanConfig or System
        A ``ScanConfig`` (with its own scan settings), or a
        ``System`` with ``lightcurve``.
    lightcurve : LightCurve, optional
        The data, with a System; not with a config.
    draws : int, optional
        N, the number of posterior draws (>= 1; default 64).
    out : str or pathlib.Path or None, optional
        Folder for marginal.csv, marginal.json, marginal.png, the draws
        (marginal_draws.json) and the progress file (resumes); None: a
        temporary folder, removed afterwards (and no figure).
    free : sequence of str or None, optional
        The sampled transit parameters, such as ``"b.t0"`` (default: t0,
        period, a, inc and radius of every planet; not the t0 of a planet
        with transit times); the a/R* named here are tied to one stellar
        density (Kepler's third law).
    samples : dict of str to array_like, optional
        Name (``"b.inc"``) -> array [N] of draws to use instead of NUTS
        (e.g. your own posterior); ``draws`` is then their number.
    num_warmup : int, optional
        NUTS warm-up steps per chain (default 300).
    thin : int, optional
        Keep every thin-th NUTS sample (N x thin samples are drawn).
    seed : int, optional
        NUTS random seed.
    chains : int, optional
        NUTS chains, run vectorised (default 4).
    stellar_density : sequence of 2 float or None, optional
        (mean, sd) [g/cm^3], the Gaussian prior on rho* when an a/R* is
        free; default: a config's ``[fit] stellar_density``, else the density
        the system's a/R* imply, 10 % wide.
    chunk : int, optional
        Draws per batched computation and per progress flush (memory grows
        by about 21 bytes per chunk x alphas x cases x frames element,
        docs/scale.md; default 16).
    fixed : ScanResult or None, optional
        The fixed-parameter scan of the same config, if already computed
        (else it is computed, without figures).
    restart : bool, optional
        Discard this folder's marginal progress and draws first.
    progress : bool, optional
        Show progress bars.
    figures : bool, optional
        With ``out``, draw marginal.png (default True).
    alpha : array_like, optional
        Tilt grid [deg], [n_alpha], as in ``jaxppo.scan`` (default 0, 1,
        ..., 359). Only with a System: with a ScanConfig this and the six
        below are refused (the config's own settings are used; set them
        there).
    cases : str or sequence of str, optional
        Hemisphere cases as in ``jaxppo.scan`` (default ``("same",
        "opposite")``).
    margin : float or Quantity, optional
        Out-of-transit data [d] (a time Quantity is converted) in the chi^2 on each side of an event
        (default 0.05).
    detrend : int or "none", optional
        Order 0..5 of each event's out-of-transit polynomial (default 2);
        "none" uses the flux as loaded.
    baseline : float or Quantity, optional
        Baseline [d] (a time Quantity is converted) fitted on each side of an event, > ``margin``
        (default 0.3).
    clip : float or "none", optional
        Outlier threshold [robust sigmas] >= 2 for the baseline points
        (default 5).
    multi_transits : float or sequence of float or None, optional
        Mid-times [d] of the multi-transits to use (each matched within
        0.1 d); None (default): all of them.
    min_ess : float, optional
        The guard (default 25): a case's geometry probabilities, posterior
        peak and rating are given only when the importance weights of each
        geometry's mass and of the total have a Kish ESS >= ``min_ess`` and
        a Pareto k-hat <= min(0.7, 1 - 1/log10 N) (from 100 draws on);
        otherwise they are None and the case says why.

    Returns
    -------
    MarginalResult
        ``summary`` (marginal.json), ``table`` (marginal.csv),
        ``delta_chi2`` [n_draws, n_cases, n_alpha] and ``fixed``.

    Raises
    ------
    ValueError
        When ``lightcurve`` or a scan setting is given with a
        ``ScanConfig``; when ``draws``, ``min_ess``, ``chunk``,
        ``thin``, ``num_warmup``, ``chains``, ``samples`` (unknown parameter,
        unequal lengths, non-finite values), ``stellar_density`` or a scan
        setting is invalid; when ``fixed`` is a scan of another
        configuration; when ``out`` holds draws of a different marginal scan
        (use ``restart=True``); when every tilt produces a PPO, so the no-PPO
        posterior cannot be sampled (pass ``samples``); when float64 is not
        enabled.

    Warns
    -----
    UserWarning
        When ``draws`` < ``min_ess`` (no probability can then be given).

    Examples
    --------
    Three given draws of planet b's inclination [deg] and radius [R*]
    (``min_ess=1`` only because three draws can never pass the default
    guard; real use keeps it, with >= 64 draws):

    >>> from importlib.resources import files
    >>> import numpy as np
    >>> import jaxppo as jp
    >>> cfg = jp.load_config(files("jaxppo") / "data" / "kepler20_synthetic.toml", alpha=[0, 360, 1])
    >>> draws = {"b.inc": np.array([87.65, 87.687, 87.72]), "b.radius": np.array([0.0179, 0.01805, 0.0182])}
    >>> res = jp.marginal_scan(cfg, samples=draws, min_ess=1, out="marginal_out", figures=False, progress=False)
    >>> import os; sorted(os.listdir("marginal_out"))
    ['marginal.csv', 'marginal.json', 'marginal_draws.json', 'marginal_progress.jsonl']
    >>> geo = res.probabilities["same"]
    >>> print(geo["favoured"], f"{geo['retrograde, different hemispheres']['probability']:.3f}")
    retrograde, different hemispheres 0.541
    >>> again = jp.marginal_scan(cfg, samples=draws, min_ess=1, out="marginal_out", figures=False, progress=False)
    >>> again.summary["seconds"]["draws_computed"]  # resumed: nothing recomputed
    0
    >>> [run["draws_computed"] for run in again.summary["seconds"]["earlier_runs"]]  # the first run's timings kept
    [3]
    """
    t_begin = time.perf_counter()
    cfg = config_of(system, lightcurve, dict(alpha=alpha, cases=cases, margin=margin, detrend=detrend,
                                           baseline=baseline, clip=clip, multi_transits=multi_transits))
    draws = _check_options(draws, samples, min_ess, chunk, thin, num_warmup, chains)
    sysm = cfg.system
    free = default_free(sysm) if free is None else tuple(free)
    if samples is not None:
        snames, draws = _check_samples(sysm, samples)
        free = tuple(snames)
        given = {n: np.asarray(samples[n], float).tolist() for n in snames}
    else:
        given = None
    density, density_source = density_prior(system, sysm, free, given, stellar_density)
    settings = {"draws": draws, "free": list(free), "num_warmup": int(num_warmup), "thin": int(thin),
                "seed": int(seed), "chains": int(chains), "density": density, "samples_sha256": None if given is None else
                hashlib.sha256(json.dumps(given, sort_keys=True).encode()).hexdigest()[:20]}
    opts = SimpleNamespace(digest=_digest(cfg, settings), settings={**settings, "scan_config_digest": cfg.digest},
                           given=given, free=free, draws=draws,
                           num_warmup=num_warmup,
                           thin=thin, seed=seed, chunk=chunk, chains=chains, density=density,
                           density_source=density_source, min_ess=min_ess, restart=restart, progress=progress,
                           t_begin=t_begin)
    if out is None:
        with tempfile.TemporaryDirectory(prefix="jaxppo_marginal_") as tmp:
            return _run(cfg, Path(tmp), fixed, False, opts)
    return _run(cfg, Path(out), fixed, figures, opts)


def _stored_draws(draws_path: Path, digest: str):
    """The draws record an earlier run with this digest stored in
    ``draws_path`` ({"sampler", "samples"}), or None; draws of another scan
    there are refused."""
    if not draws_path.exists():
        return None
    try:
        rec = json.loads(draws_path.read_text())
    except (json.JSONDecodeError, OSError):
        rec = None
    if not isinstance(rec, dict) or rec.get("digest") != digest:
        raise ValueError(f"{draws_path.parent} holds draws of a different marginal scan ({draws_path.name}); "
                         "use another out folder or restart=True (CLI: --restart)")
    return {"sampler": rec["sampler"], "samples": rec["samples"]}


def _draws(cfg: ScanConfig, data: LightCurve, tm, draws_path: Path, stored, o, timing: dict):
    """(samples, sampler) of the marginal scan: the ``stored`` draws of an
    earlier run with this digest, else those given by the caller, else NUTS
    draws of the no-PPO transit posterior (written to ``draws_path``: a
    resumed run uses the same). Under several JAX processes every process
    runs the same sampler and process 0's draws are used by all."""
    if stored is not None:
        return {k: np.asarray(v, float) for k, v in stored["samples"].items()}, stored["sampler"]
    if o.given is not None:
        samples = {k: np.asarray(v, float) for k, v in o.given.items()}
        sampler = {"method": "given by the caller"}
    else:
        sysm = cfg.system
        a_ref = quiet_alpha(sysm, tm, cfg.cases[0])
        # Sample t0 at the transit nearest the middle of the windows: the
        # same orbit, but t0 and the period are then nearly uncorrelated
        # (a config's t0 lies hundreds of periods before most events, where
        # the two are correlated to |r| ~ 1 and NUTS needs deep trees).
        centred = centre_epochs(sysm, 0.5 * (float(tm.min()) + float(tm.max())))
        t0 = time.perf_counter()
        samples, sampler = nuts_draws(centred, data, o.free, o.density, a_ref, cfg.cases[0], o.draws, o.num_warmup,
                                      o.thin, o.seed, o.chains, o.progress and is_writer())
        timing["sampler_s"] = time.perf_counter() - t0
        sampler.update({"alpha_ref": a_ref, "case_ref": cfg.cases[0], "density_prior": o.density,
                        "density_prior_source": o.density_source,
                        "t0_epochs": {pl.name or str(i): float(pl.t0) for i, pl in enumerate(centred.planets)}})
        if "star.density" in samples:
            sampler["star.density"] = samples.pop("star.density").tolist()
    rec = json.loads(json.dumps({"sampler": sampler, "samples": {k: v.tolist() for k, v in samples.items()}},
                                allow_nan=False, default=float))
    rec = share(rec)  # process 0's draws in every process (a no-op with one)
    on_writer(f"writing {draws_path}", lambda: atomic_write(draws_path, json.dumps({"digest": o.digest, **rec},
                                                                                 allow_nan=False)))
    return {k: np.asarray(v, float) for k, v in rec["samples"].items()}, rec["sampler"]


def _key(d, case) -> str:
    return f"{case}#{d}"


def _chi2_curves(cfg, systems, tm, nsub, y, sig, sampler, done, prog_path, o, timing):
    """Per-draw chi^2 curves, batched per chunk of draws, written as they go
    (one record per draw and case, fsynced per chunk); returns (Delta chi^2
    [draw, case, alpha], chi^2 [draw, case, alpha], chi^2_0 [draw, case],
    no-PPO chi^2 [draw], reference chi^2 [draw] or None)."""
    from tqdm import tqdm

    n_d, digest = len(systems), o.digest
    # The draws were sampled from the transit posterior at tilt alpha_ref:
    # the exact importance weight of alpha is L(alpha) / L(alpha_ref), so
    # each draw's chi^2 at alpha_ref is its reference (the no-PPO chi^2
    # wherever alpha_ref is free of PPOs for that draw). Draws given by the
    # caller are taken as no-PPO posterior draws: reference chi^2_0.
    a_ref = sampler.get("alpha_ref")

    def finished(d):
        return (_key(d, "null"), 0.0) in done and (a_ref is None or (_key(d, "ref"), 0.0) in done) and all(
            (_key(d, c), round(float(a), 9)) in done for c in cfg.cases for a in cfg.alpha)

    todo = [d for d in range(n_d) if not finished(d)]
    bar = tqdm(total=n_d, initial=n_d - len(todo), desc="marginal scan", unit="draw",
               disable=not (o.progress and is_writer()),
               leave=False)
    t0 = time.perf_counter()
    # one chunk of draws after another, each appended to the progress file by process 0
    for i in range(0, len(todo), o.chunk):
        idx = todo[i:i + o.chunk]
        chi2, chi2_null, ppo = marginal_chi2([systems[d] for d in idx], tm, nsub, y, sig, cfg.alpha, cfg.cases)
        c0 = _chi2_0(chi2, ppo, [systems[d] for d in idx], tm, nsub, y, sig, cfg.cases)
        if a_ref is not None:
            c_ref = marginal_chi2([systems[d] for d in idx], tm, nsub, y, sig, np.array([float(a_ref)]),
                                  (sampler["case_ref"],))[0][:, 0, 0]
        lines = []
        for j, d in enumerate(idx):
            recs = [{"config_digest": digest, "case": _key(d, "null"), "alpha": [0.0],
                     "chi2": [float(chi2_null[j])]}]
            if a_ref is not None:
                recs.append({"config_digest": digest, "case": _key(d, "ref"), "alpha": [0.0],
                             "chi2": [float(c_ref[j])]})
            for ci, c in enumerate(cfg.cases):
                recs.append({"config_digest": digest, "case": _key(d, c), "alpha": cfg.alpha.tolist(),
                             "chi2": chi2[j, ci].tolist()})
                recs.append({"config_digest": digest, "case": _key(d, "c0:" + c), "alpha": [0.0],
                             "chi2": [float(c0[j, ci])]})
            for rec in recs:
                lines.append(record_line(rec))
                for a, v in zip(rec["alpha"], rec["chi2"]):
                    done[(rec["case"], round(float(a), 9))] = float(v)
        on_writer(f"writing {prog_path}", lambda: _append(prog_path, lines))
        bar.update(len(idx))
    bar.close()
    timing["chi2_s"] = time.perf_counter() - t0
    timing["draws_computed"] = len(todo)

    chi2 = np.array([[[done[(_key(d, c), round(float(a), 9))] for a in cfg.alpha] for c in cfg.cases]
                     for d in range(n_d)])
    c0 = np.array([[done[(_key(d, "c0:" + c), 0.0)] for c in cfg.cases] for d in range(n_d)])
    chi2_null = np.array([done[(_key(d, "null"), 0.0)] for d in range(n_d)])
    chi2_ref = None if a_ref is None else np.array([done[(_key(d, "ref"), 0.0)] for d in range(n_d)])
    return chi2 - c0[:, :, None], chi2, c0, chi2_null, chi2_ref


def _run(cfg: ScanConfig, out: Path, fixed, figures: bool, o) -> MarginalResult:
    """The marginal scan in ``out`` (resumes; see ``marginal_scan``)."""
    if fixed is not None and fixed.config_digest != cfg.digest:
        raise ValueError(f"fixed: a scan of another configuration (digest {fixed.config_digest}, "
                         f"this one {cfg.digest})")
    prog_path, draws_path = out / PROGRESS, out / DRAWS
    done, notes, stored = _read_state(out, cfg, o)
    for note in notes if is_writer() else ():  # (process 0 of several says it)
        warnings.warn(note, stacklevel=3)

    windows, _ = windows_and_events(cfg)
    data = windows_data(windows, cfg.lightcurve.exposure)
    tm, nsub = data.supersampled_times()
    y, sig = np.asarray(data.flux), np.asarray(data.flux_err)
    timing = {}
    samples, sampler = _draws(cfg, data, tm, draws_path, stored, o, timing)
    systems = _systems_from(sampled_system(cfg.system, sampler), samples, list(samples))
    dchi2, chi2, c0, chi2_null, chi2_ref = _chi2_curves(cfg, systems, tm, nsub, y, sig, sampler, done, prog_path,
                                                        o, timing)

    # ---- the fixed-parameter scan, for comparison ----
    if fixed is None:
        with tempfile.TemporaryDirectory(prefix="jaxppo_fixed_") as tmp:
            fixed = run_scan(cfg, tmp, progress=False)
    # a draw is sampled under the no-PPO model iff alpha_ref is quiet for it
    a_ref, ref_quiet = sampler.get("alpha_ref"), None
    if a_ref is not None:
        ref_quiet = float(np.mean([~ppo_table(s, [tm], np.array([float(a_ref)]), sampler["case_ref"])[0, 0]
                                   for s in systems]))
    result = analyse_draws(cfg, dchi2, chi2, c0, chi2_null, chi2_ref, fixed, samples, sampler, o.digest, ref_quiet,
                           o.min_ess)
    summary = result.summary
    if "star.density" in sampler:
        rho = np.asarray(sampler["star.density"], float)
        summary["parameters"]["star.density"] = {"median": float(np.median(rho)),
                                                 "p16": float(np.percentile(rho, 15.865)),
                                                 "p84": float(np.percentile(rho, 84.135))}
    summary["seconds"] = {"total": time.perf_counter() - o.t_begin, **timing,
                          "per_draw_chi2": timing["chi2_s"] / max(1, timing["draws_computed"]),
                          "earlier_runs": _earlier_seconds(out / "marginal.json", o.digest)}
    summary["cpu"] = {"devices": [str(d) for d in jax.devices()], "load_average": list(os.getloadavg())}
    summary.update(process_info())
    summary["progress_notes"] = notes
    if figures:
        summary["figures"] = [str(out / "marginal.png")]

    def write():
        atomic_write(out / "marginal.csv", marginal_csv(result.table))
        if figures:
            plot_marginal(out, result, cfg)
        atomic_write(out / "marginal.json", json.dumps(summary, indent=2, allow_nan=False))

    # every process returns once process 0 has written the folder (or each raises its error)
    on_writer(f"writing marginal.csv, marginal.json and marginal.png in {out}", write)
    return result


def _earlier_seconds(path: Path, digest: str) -> list:
    """The timings of the earlier runs of this marginal scan (``digest``)
    recorded in its marginal.json (each run's ``seconds`` without its own
    list of earlier runs), oldest first: a rerun that computes nothing
    keeps what the sampler and the chi^2 of the draws cost."""
    try:
        rec = json.loads(path.read_text())
    except (OSError, ValueError):
        return []
    if not isinstance(rec, dict) or rec.get("marginal_digest") != digest or not isinstance(rec.get("seconds"), dict):
        return []
    last = dict(rec["seconds"])
    earlier = last.pop("earlier_runs", [])
    return (earlier if isinstance(earlier, list) else []) + [last]


def _append(path: Path, lines: list[str]) -> None:
    """Append ``lines`` to the progress file ``path``, fsynced."""
    with open(path, "a") as fh:
        fh.write("".join(lines))
        fh.flush()
        os.fsync(fh.fileno())


def _read_state(out: Path, cfg: ScanConfig, o):
    """(done, notes, stored draws or None) of the folder ``out`` (emptied
    first for ``o.restart``): read by process 0 alone and shared with the
    other JAX processes, so that all of them compute the same draws."""

    def read():
        out.mkdir(parents=True, exist_ok=True)
        if o.restart:
            for name in ("marginal.json", "marginal.csv", "marginal.png", DRAWS, PROGRESS):
                if (out / name).is_file():
                    (out / name).unlink()
        done, notes = read_progress(out / PROGRESS, o.digest, out, cfg.source, o.settings)
        stored = _stored_draws(out / DRAWS, o.digest)
        if not (out / PROGRESS).exists():  # (written here: a folder that cannot be written stops every process now)
            atomic_write(out / PROGRESS, progress_header(o.digest, cfg.source, o.settings))
        return done, notes, stored

    def encode(state):
        done, notes, stored = state
        return {"done": [[c, a, v] for (c, a), v in done.items()], "notes": notes, "stored": stored}

    def decode(state):
        return {(c, a): v for c, a, v in state["done"]}, state["notes"], state["stored"]

    return read_once(read, out, encode, decode)
