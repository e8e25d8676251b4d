"""Adaptive tempered sequential Monte Carlo over (transit parameters, tilt
alpha): the joint posterior of one hemisphere case and its evidence.

The particles start from a reference q(w, alpha) = N(w; 0, s^2 I) x
U(alpha; 0, 360), w the transit parameters whitened at the no-PPO mode
(u = u_mode + L w), and move through the geometric bridge
pi_beta = q^(1 - beta) gamma^beta to the target gamma(u, alpha) (the
unnormalised posterior density). Each next beta is found by bisection so
that the conditional ESS of the incremental weights is ``cess`` x N (Zhou,
Johansen & Aston 2016); the particles are resampled (systematic) when their
ESS falls below N / 2 and then moved by Metropolis-Hastings kernels that
leave pi_beta invariant, built from the particles before the move:

* a **joint random walk in (w, alpha)** whose covariance is the particles'
  pooled covariance within their alpha clusters (runs of alpha without a
  gap over ``GAP`` deg): the PPO ties alpha to the planets' t0 (a PPO a
  minute later is the same PPO at a slightly different tilt), and only a
  move along that ridge is accepted at high signal-to-noise;
* an **independence proposal from a Gaussian mixture** fitted to the
  clusters (weight, mean and covariance of each, widened) and the
  reference's modes, which moves particles between the narrow modes a PPO
  makes without walking over the plateaus between them;
* **alpha drawn afresh from U(0, 360)**, w kept, which spreads the particles
  over the plateaus (where the likelihood does not depend on alpha).

The log evidence log Z = log int gamma du dalpha / 360 (alpha uniform a
priori) is the sum of the logs of the mean incremental weights, plus log |L|
and minus log 360. Unlike the importance average over no-PPO draws, it does
not rest on the few draws that happen to fall where the PPO signal is: the
particles move there.
"""

from __future__ import annotations

import time

import jax.numpy as jnp
import numpy as np

from ._mapped import mapped_over_devices

__all__ = ["tempered_smc", "alpha_clusters"]

GAP = 5.0
"""[deg] Particles whose sorted alphas are further apart than this are in
different clusters (the moves' covariances are taken within clusters)."""


REF_SCALE = 1.5  # the plateau's width in w (whitened units) in the reference


def _systematic(weights: np.ndarray, rng) -> np.ndarray:
    n = weights.size
    cdf = np.cumsum(weights)
    cdf[-1] = 1.0
    return np.minimum(np.searchsorted(cdf, (rng.random() + np.arange(n)) / n), n - 1)


def _next_beta(beta: float, delta: np.ndarray, logw: np.ndarray, cess: float) -> float:
    """The largest beta' <= 1 whose incremental weights exp((beta' - beta)
    delta) keep the conditional ESS >= cess (bisection)."""
    w = np.exp(logw - np.max(logw))
    w /= w.sum()
    finite = np.isfinite(delta)

    def ratio(b):
        inc = np.where(finite, (b - beta) * np.where(finite, delta, 0.0), -np.inf)
        e = np.exp(inc - np.max(inc))
        return float(np.sum(w * e) ** 2 / np.sum(w * e**2))

    if ratio(1.0) >= cess:
        return 1.0
    lo, hi = beta, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if ratio(mid) >= cess:
            lo = mid
        else:
            hi = mid
    return max(lo, beta + 1e-12)


def alpha_clusters(alpha: np.ndarray, gap: float = GAP) -> np.ndarray:
    """Cluster labels 0..k-1 of the tilts ``alpha`` [deg] on the circle:
    runs of sorted alphas without a gap over ``gap`` deg. One cluster when no
    gap is that wide."""
    a = np.mod(np.asarray(alpha, float), 360.0)
    order = np.argsort(a)
    s = a[order]
    gaps = np.diff(np.concatenate([s, [s[0] + 360.0]]))  # gaps[j]: s[j] -> s[j + 1], the last one wraps
    lab = np.concatenate([[0], np.cumsum(gaps[:-1] > gap)])
    if gaps[-1] <= gap:  # the run that wraps past 360 is one cluster with the first
        lab[lab == lab[-1]] = 0
    labels = np.empty(a.size, int)
    labels[order] = np.unique(lab, return_inverse=True)[1]
    return labels


def _local(alpha: np.ndarray, labels: np.ndarray, wt: np.ndarray):
    """Each cluster's weighted circular mean alpha [deg] (per particle) and
    the particles' alpha relative to it, in (-180, 180]."""
    centre = np.zeros(alpha.size)
    for c in np.unique(labels):
        m = labels == c
        ang = np.deg2rad(alpha[m])
        ww = wt[m] + 1e-300
        centre[m] = np.rad2deg(np.arctan2(np.sum(ww * np.sin(ang)), np.sum(ww * np.cos(ang))))
    rel = (alpha - centre + 180.0) % 360.0 - 180.0
    return centre, rel


def _mixture(w, alpha, wt, labels, dim, widen):
    """Gaussian mixture over (w, alpha) fitted to the weighted particles,
    one component per alpha cluster: [(weight, mean [dim + 1], chol)]; alpha
    of a component is wrapped (its density sums the images k x 360)."""
    centre, rel = _local(alpha, labels, wt)
    z = np.column_stack([w, rel])
    pooled = _pooled_cov(z, wt, labels)
    comps = []
    for c in np.unique(labels):
        m = labels == c
        wc = wt[m]
        mass = float(wc.sum())
        if mass <= 0:
            continue
        wn = wc / mass
        mean = wn @ z[m]
        ess = 1.0 / np.sum(wn**2)
        if ess >= 2 * (dim + 1):
            d = z[m] - mean
            cov = d.T @ (d * wn[:, None])
            cov = 0.5 * (cov + cov.T)
        else:
            cov = pooled
        cov = widen**2 * cov + 1e-10 * np.eye(dim + 1)
        mean = mean.copy()
        mean[-1] += centre[m][0]
        try:
            chol = np.linalg.cholesky(cov)
        except np.linalg.LinAlgError:
            chol = np.linalg.cholesky(widen**2 * pooled + 1e-8 * np.eye(dim + 1))
        comps.append((mass, mean, chol))
    tot = sum(c[0] for c in comps)
    return [(m / tot, mu, ch) for m, mu, ch in comps]


def _mixture_logpdf(comps, w, alpha):
    """log density of the wrapped mixture at (w, alpha) [N]."""
    out = []
    for mass, mean, chol in comps:
        lp_img = []
        for k in (-2, -1, 0, 1, 2):
            z = np.column_stack([w, alpha + 360.0 * k]) - mean
            y = np.linalg.solve(chol, z.T).T
            lp_img.append(-0.5 * np.sum(y**2, axis=1))
        lp = np.logaddexp.reduce(np.stack(lp_img), axis=0)
        lp += np.log(mass) - np.sum(np.log(np.diag(chol))) - 0.5 * chol.shape[0] * np.log(2 * np.pi)
        out.append(lp)
    return np.logaddexp.reduce(np.stack(out), axis=0)


def _mixture_draw(comps, n, rng):
    masses = np.array([c[0] for c in comps])
    which = rng.choice(len(comps), size=n, p=masses / masses.sum())
    z = np.empty((n, comps[0][1].size))
    for j, (_, mean, chol) in enumerate(comps):
        m = which == j
        z[m] = mean + rng.standard_normal((int(m.sum()), mean.size)) @ chol.T
    return z[:, :-1], np.mod(z[:, -1], 360.0)


def _pooled_cov(z, wt, labels):
    """The weighted covariance of z within the clusters ``labels``."""
    d = np.empty_like(z)
    for c in np.unique(labels):
        m = labels == c
        wc = wt[m]
        mean = (wc @ z[m]) / max(float(wc.sum()), 1e-300)
        d[m] = z[m] - mean
    cov = d.T @ (d * wt[:, None]) / max(float(wt.sum()), 1e-300)
    return 0.5 * (cov + cov.T)


def tempered_smc(log_gamma, dim: int, *, n_particles: int = 256, ref_scale: float = REF_SCALE, cess: float = 0.5,
                 n_moves: int = 6, seed: int = 0, max_steps: int = 500, log_det_l: float = 0.0,
                 modes=(), plateau: float = 1.0, final_rounds: int = 4, progress=None) -> dict:
    """Adaptive tempered SMC (module docstring) for a target on (w, alpha),
    w in R^dim, alpha in [0, 360) deg.

    ``log_gamma(w, alpha)``: the log unnormalised target of ONE particle (a
    jax function; vmapped and jitted here; -inf or NaN outside the support);
    ``ref_scale``: s of the reference N(0, s^2 I) in w; ``cess``: the
    conditional-ESS fraction kept per tempering step; ``n_moves``: rounds
    of the three kernels per step; ``final_rounds``: steps of moves after
    beta reaches 1; ``log_det_l``: log |L| of the whitening, added to log Z;
    ``modes``: [(weight, mean [dim + 1], chol [dim + 1, dim + 1])], Gaussian
    components in (w, alpha) (e.g. the joint posterior's modes with their
    Laplace covariances, ``jaxppo.inference._posterior.joint_modes``), mixed
    into the reference with the weights given and the N(0, s^2 I) x U(alpha)
    component with weight ``plateau`` (weights normalised; the reference is
    then close to the target and its modes are populated from the start);
    ``progress``: None or a callable of one line of text.

    Returns {"w" [N, dim], "alpha" [N], "weights" [N] (normalised, at
    beta = 1), "log_gamma" [N] (the target at the particles), "log_z",
    "ess" (of the final weights), "steps", "betas", "acceptance" (per step:
    random walk, mixture, uniform alpha), "calls" (target evaluations),
    "seconds"}."""
    if int(n_particles) != n_particles or n_particles < 16:
        raise ValueError(f"n_particles must be an integer >= 16, got {n_particles!r}")
    if not 0.0 < cess < 1.0:
        raise ValueError(f"cess must be in (0, 1), got {cess!r}")
    if int(n_moves) != n_moves or n_moves < 1:
        raise ValueError(f"n_moves must be an integer >= 1, got {n_moves!r}")
    t_start = time.perf_counter()
    rng = np.random.default_rng(seed)
    n = int(n_particles)
    ref = _Reference(dim, ref_scale, modes, plateau)
    # one particle after another (``_mapped``): faster than vmap on CPU, and
    # the model skips the union integral where no disks meet; the particles
    # split over every device of every JAX process (each process then holds
    # all the values, and runs the same steps)
    batch = mapped_over_devices(log_gamma)
    calls = [0]

    def evaluate(w, a):
        calls[0] += w.shape[0]
        v = np.asarray(batch(w, a), float)
        return np.where(np.isnan(v), -np.inf, v)

    w, a = ref.draw(n, rng)
    lg, lq = evaluate(w, a), ref.log_q(w, a)
    logw = np.zeros(n)  # log weights at beta
    beta, log_z, betas, acc_hist = 0.0, 0.0, [0.0], []
    scale = 2.38 / np.sqrt(dim + 1)
    extra = 0
    for step in range(max_steps):
        if beta >= 1.0:
            # after beta = 1: more rounds of moves, so the particles spread
            # over the target beyond the reference's Gaussian modes
            if extra >= final_rounds:
                break
            extra += 1
        else:
            delta = lg - lq
            new = _next_beta(beta, delta, logw, cess)
            inc = np.where(np.isfinite(delta), (new - beta) * np.where(np.isfinite(delta), delta, 0.0), -np.inf)
            lw_norm = logw - np.logaddexp.reduce(logw)
            log_z += float(np.logaddexp.reduce(lw_norm + inc))
            logw = lw_norm + inc
            beta = new
            betas.append(beta)
        wt = np.exp(logw - np.logaddexp.reduce(logw))
        if 1.0 / np.sum(wt**2) < 0.5 * n:
            idx = _systematic(wt, rng)
            w, a, lg, lq = w[idx], a[idx], lg[idx], lq[idx]
            logw = np.zeros(n)
            wt = np.full(n, 1.0 / n)
        (w, a, lg, lq), acc = _moves((w, a, lg, lq), wt, beta, ref, evaluate, n_moves, scale, rng)
        # keep the random walk's acceptance near 0.25
        scale *= 1.25 if acc[0] > 0.35 else 0.8 if acc[0] < 0.15 else 1.0
        acc_hist.append(acc.tolist())
        if progress is not None:
            progress(f"step {step + 1}: beta {beta:.4g}, log Z {log_z:.3f}, clusters {alpha_clusters(a).max() + 1}, "
                     f"acceptance walk {acc[0]:.2f} mixture {acc[1]:.2f} uniform alpha {acc[2]:.2f}")
    else:
        raise RuntimeError(f"tempered SMC did not reach beta = 1 in {max_steps} steps (beta = {beta:.3g})")
    wt = np.exp(logw - np.logaddexp.reduce(logw))
    # q is a density in (w, alpha) with alpha uniform over 360 deg; Z is per
    # unit alpha prior (alpha ~ U(0, 360)) and per unit u = u_mode + L w
    return {"w": w, "alpha": a, "weights": wt, "log_gamma": lg,
            "log_z": log_z + float(log_det_l) - np.log(360.0), "ess": float(1.0 / np.sum(wt**2)),
            "steps": len(betas) - 1, "betas": betas, "acceptance": acc_hist, "calls": int(calls[0]),
            "seconds": time.perf_counter() - t_start}


class _Reference:
    """The reference density of the bridge: a weighted mixture of Gaussian
    modes in (w, alpha) (alpha wrapped) and the plateau N(0, s^2 I) x
    U(0, 360) (``tempered_smc``'s ``modes`` and ``plateau``)."""

    def __init__(self, dim, ref_scale, modes, plateau):
        comps = [(float(m), np.asarray(mu, float), np.asarray(ch, float)) for m, mu, ch in modes]
        if any(not (m > 0) or mu.shape != (dim + 1,) or ch.shape != (dim + 1, dim + 1) for m, mu, ch in comps):
            raise ValueError(f"modes must be (weight > 0, mean [{dim + 1}], chol [{dim + 1}, {dim + 1}]) triples")
        if not plateau >= 0 or (plateau == 0 and not comps):
            raise ValueError(f"plateau must be >= 0 (> 0 without modes), got {plateau!r}")
        total = plateau + sum(m for m, _, _ in comps)
        self.comps = [(m / total, mu, ch) for m, mu, ch in comps]
        self.p_plateau = plateau / total
        self.dim, self.s2 = dim, float(ref_scale) ** 2

    def log_q(self, w, a):
        """log density of the reference (normalised over w and alpha in [0, 360))."""
        lp = np.full(w.shape[0], -np.inf)
        if self.p_plateau > 0:
            lp = (np.log(self.p_plateau) - 0.5 * np.sum(w**2, axis=1) / self.s2
                  - 0.5 * self.dim * np.log(2.0 * np.pi * self.s2) - np.log(360.0))
        if self.comps:
            lp = np.logaddexp(lp, _mixture_logpdf(self.comps, w, a))
        return lp

    def draw(self, m, rng):
        """m draws (w [m, dim], alpha [m])."""
        k = rng.binomial(m, self.p_plateau) if self.comps else m
        w0 = rng.standard_normal((k, self.dim)) * np.sqrt(self.s2)
        a0 = rng.uniform(0.0, 360.0, k)
        if k < m:
            w1, a1 = _mixture_draw(self.comps, m - k, rng)
            w0, a0 = np.concatenate([w0, w1]), np.concatenate([a0, a1])
        return w0, a0


def _moves(state, wt, beta, ref, evaluate, n_moves, scale, rng):
    """``n_moves`` rounds of the three Metropolis-Hastings kernels (module
    docstring) at the bridge beta, each built from the particles before the
    moves; returns the new (w, alpha, log gamma, log q) and the acceptance
    rates."""
    w, a, lg, lq = state
    n, dim = w.shape

    def target(lg_, lq_):
        return np.where(np.isfinite(lg_), beta * lg_ + (1.0 - beta) * lq_, -np.inf)

    def accept(ok, w_new, a_new, lg_new, lq_new):
        return (np.where(ok[:, None], w_new, w), np.where(ok, a_new, a), np.where(ok, lg_new, lg),
                np.where(ok, lq_new, lq))

    labels = alpha_clusters(a)
    _, rel = _local(a, labels, wt)
    chol = np.linalg.cholesky(_pooled_cov(np.column_stack([w, rel]), wt, labels) + 1e-12 * np.eye(dim + 1))
    # the particles' clusters, and the reference's modes (fixed components:
    # an independence proposal may use any density)
    comps = _mixture(w, a, wt, labels, dim, 1.3)
    if ref.comps:
        comps = [(0.5 * m, mu, ch) for m, mu, ch in comps] + [(0.5 * m, mu, ch) for m, mu, ch in ref.comps]
    acc = np.zeros(3)
    for _ in range(n_moves):
        # joint random walk in (w, alpha)
        step_z = scale * rng.standard_normal((n, dim + 1)) @ chol.T
        w_new, a_new = w + step_z[:, :-1], np.mod(a + step_z[:, -1], 360.0)
        lg_new, lq_new = evaluate(w_new, a_new), ref.log_q(w_new, a_new)
        ok = np.log(rng.random(n)) < target(lg_new, lq_new) - target(lg, lq)
        w, a, lg, lq = accept(ok, w_new, a_new, lg_new, lq_new)
        acc[0] += ok.mean() / n_moves
        # independence proposal from the clusters' and modes' mixture
        w_new, a_new = _mixture_draw(comps, n, rng)
        lg_new, lq_new = evaluate(w_new, a_new), ref.log_q(w_new, a_new)
        ok = np.log(rng.random(n)) < (target(lg_new, lq_new) - target(lg, lq) + _mixture_logpdf(comps, w, a)
                                      - _mixture_logpdf(comps, w_new, a_new))
        w, a, lg, lq = accept(ok, w_new, a_new, lg_new, lq_new)
        acc[1] += ok.mean() / n_moves
        # alpha drawn afresh from U(0, 360), w kept (a symmetric independence
        # proposal): spreads the particles over the plateaus, where the
        # likelihood does not depend on alpha
        a_new = rng.uniform(0.0, 360.0, n)
        lg_new, lq_new = evaluate(w, a_new), ref.log_q(w, a_new)
        ok = np.log(rng.random(n)) < target(lg_new, lq_new) - target(lg, lq)
        w, a, lg, lq = accept(ok, w, a_new, lg_new, lq_new)
        acc[2] += ok.mean() / n_moves
    return (w, a, lg, lq), acc


def reference_weights(plateau: float, modes, floor: float = 0.2):
    """The reference's weights from log masses: the plateau's
    (``plateau``) and each mode's ((log mass, mean, chol) of ``modes``, as
    :func:`jaxppo.inference._posterior.joint_modes` gives them), normalised,
    each at least ``floor`` / (number of components). Returns (plateau
    weight, [(weight, mean, chol)])."""
    logm = np.array([plateau] + [m[0] for m in modes])
    wts = np.exp(logm - logm.max())
    wts = np.maximum(wts / wts.sum(), floor / logm.size)
    return float(wts[0]), [(float(wt), m[1], m[2]) for wt, m in zip(wts[1:], modes)]


def joint_case_smc(system, data, free, density, case: str, alpha_ref: float, *, n_particles: int = 256,
                   seed: int = 0, cess: float = 0.5, n_moves: int = 6, floor: float = 0.2, progress=None,
                   found=None) -> dict:
    """The joint posterior of (transit parameters, alpha) of one hemisphere
    case by :func:`tempered_smc`: the transit parameters in the coordinates
    of :class:`jaxppo.inference._posterior.TransitPosterior` (priors there),
    whitened at the no-PPO mode (found at the quiet tilt ``alpha_ref``),
    alpha uniform on [0, 360); the likelihood is the exact model at the
    sampled alpha (every frame where two disks could meet at some tilt by
    the union integral). The reference mixes the modes that
    :func:`jaxppo.inference._posterior.joint_modes` finds (Laplace) with the
    no-PPO plateau, weighted by their Laplace masses, each at least
    ``floor`` / (number of components). ``found``: that function's result, to reuse over seeds.
    Returns :func:`tempered_smc`'s dict with "u" [N, dim] (the transit
    coordinates), "modes" (the search's info), "found" and "chi2_best"
    (``_least_chi2``) added."""
    from ._posterior import TransitPosterior, joint_modes, mode_and_cov

    if found is None:
        post = TransitPosterior(system, data, free, density, alpha_ref, case)
        u_mode, chol, _ = mode_and_cov(post)
        post.exact_overlaps_anywhere()
        modes, plateau, info = joint_modes(post, u_mode, chol)
        # the frames where disks can meet at the modes' parameters, and at
        # 4096 draws of the reference, which the particles start from and
        # rarely leave (on real data, widened only to the particles of each
        # run, the frames grew at every run: 660, 788, 836, ...)
        plateau_wt, comps = reference_weights(plateau, modes, floor)
        w, _ = _Reference(chol.shape[0], REF_SCALE, comps, plateau_wt).draw(4096, np.random.default_rng(seed))
        post.exact_overlaps_anywhere(us=np.vstack([[u_mode + m[1][:-1] @ chol.T for m in modes] or
                                                   np.empty((0, u_mode.size)), u_mode + w @ chol.T]))
        found = (post, u_mode, chol, modes, plateau, info)
    post, u_mode, chol, modes, plateau, info = found
    uj, lj = jnp.asarray(u_mode), jnp.asarray(chol)

    def log_gamma(w, alpha):
        return post.log_density(uj + lj @ w, alpha)

    plateau_wt, comps = reference_weights(plateau, modes, floor)
    for _ in range(3):
        out = tempered_smc(log_gamma, chol.shape[0], n_particles=n_particles, seed=seed, cess=cess,
                           n_moves=n_moves, log_det_l=float(np.sum(np.log(np.diag(chol)))), progress=progress,
                           plateau=plateau_wt, modes=comps)
        # the exact overlap integral is fixed to the frames where disks can
        # meet at the start and the modes; particles that moved further
        # (e.g. a t0 many minutes off) widen them, and the case runs again
        distinct = np.unique(out["w"], axis=0)
        if distinct.shape[0] > 256:
            distinct = distinct[np.random.default_rng(seed).choice(distinct.shape[0], 256, replace=False)]
        # (contact at margin 0: the start's and modes' frames already carry
        # a 0.05 R* margin, and a wider net here would rerun for nothing)
        if not post.exact_overlaps_anywhere(margin=0.0, us=u_mode + distinct @ chol.T):
            break
        if progress is not None:
            progress(f"the particles reach frames beyond those computed exactly: {post.model.union_idx.size} "
                     "frames now; sampling again")
    else:
        raise RuntimeError("joint sampler: the particles kept reaching frames beyond those computed exactly")
    out["u"] = u_mode + out["w"] @ chol.T
    out["modes"] = info
    out["found"] = found
    out["chi2_best"] = _least_chi2(post, u_mode, chol, modes, out)
    return out


def _least_chi2(post, u_mode, chol, modes, out) -> float:
    """The least chi^2 of the data the case reached: at the no-PPO mode
    (its quiet tilt), at the search's modes and at the particle of the
    highest posterior density (``jaxppo.joint_scan``'s goodness-of-fit
    check); NaN where none is finite."""
    top = int(np.argmax(out["log_gamma"]))
    points = [(u_mode, None), (out["u"][top], float(out["alpha"][top]))]
    points += [(u_mode + m[1][:-1] @ chol.T, float(m[1][-1])) for m in modes]
    chi2 = np.array([float(jnp.sum(post.data_residuals(jnp.asarray(u), a) ** 2)) for u, a in points])
    return float(np.min(chi2[np.isfinite(chi2)])) if np.any(np.isfinite(chi2)) else float("nan")
