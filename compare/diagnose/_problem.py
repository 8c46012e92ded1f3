"""The fitting problem: a recording, its noise and weights, and what one simulation scores on it.

Objective
---------
``chi2 = sum_t sum_c w_t ((m_tc - s_c(t + delta) - b_c) / sigma_c)^2``
over the dynamic channels ``c``: measured ``m`` minus simulated ``s``, each
channel scaled by its own noise level ``sigma_c`` (``_locate.noise_level``),
free-decay samples weighted ``DECAY_WEIGHT`` (the swing after the reels
stop is where the mechanisms act alone, without the reel table's own
errors). Nuisance parameters, fitted for every simulation: a constant
offset ``b_c`` per channel (calibration origin, marker placement) and one
clock shift ``delta``, bounded by ``MAX_SHIFT`` about the updated model's
own shift.

The clock shift is exact: the simulation is read ``delta`` later
(``on_clock``: a cubic spline through its samples), found by Gauss-Newton
steps on the linear term ``delta ds/dt``. The rope-length alignment
(``_align_recording``) reads the clock against the nominal model, whose
stretch differs from the rig's: on realistic drawn rigs it was 12-18 ms
off, and the linear term cannot follow that far where the recording
holds fast motion (a spreader bar rattling at 40 Hz after the reels stop
turns a quarter period in 6 ms). Read exactly, the hidden truth with its
law left 3.1-8.6 times the noise per sample on four such recordings,
against 5.2-25.9 on the linear term.

Held-out scoring (2-fold cross-validation)
------------------------------------------
Samples fall in alternating ``BLOCK_S`` blocks, fold A and fold B. For each
fold, the evaluated point (and nuisance) that fits it best is chosen, and
scored on the other fold; the held-out improvement ``D`` is the drop in
held-out chi2 against the nominal model scored the same way. Measurement
noise is independent between the folds, so noise that a fit absorbs on one
fold is not rewarded on the other.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline

__all__ = ["DECAY_WEIGHT", "MAX_SHIFT", "BLOCK_S", "Problem", "bounded_solve", "on_clock"]

DECAY_WEIGHT = 2.0
MAX_SHIFT = 0.01  # s
BLOCK_S = 0.5
# Gauss-Newton steps on the clock shift, and the step (s) below which it has converged: a shift is read to a
# tenth of a microsecond in two or three steps from where the linear term puts it.
CLOCK_STEPS = 4
CLOCK_CONVERGED = 1e-7


def on_clock(values, dt, shift):
    """``values`` (n, ...) sampled every ``dt`` (s) read ``shift`` (s) later, at ``t + shift``.

    A cubic spline through the samples along axis 0; held at the first or
    last sample past the ends (a rig at rest before its maneuver starts).
    The inputs are not modified; a zero shift returns ``values`` itself.
    """
    values = np.asarray(values, float)
    if shift == 0.0:
        return values
    n = values.shape[0]
    where = np.clip(np.arange(n) + shift / dt, 0.0, n - 1.0)
    return CubicSpline(np.arange(n, dtype=float), values, axis=0)(where)


def bounded_solve(A, g, bounds):
    """``A x = g`` (normal equations, ``A`` symmetric positive semi-definite) with ``x`` within ``bounds`` (k, 2).

    The unconstrained solution; then, while any coefficient lies outside its
    bounds, the one furthest outside is held at its bound and the others
    solved again (an active set without release: exact for one bounded
    coefficient, which is how the clock shift was always clipped, and for
    the few here - the shift and the model error's amplitudes - it ends in
    at most that many rounds).
    """
    k = len(g)
    x = np.linalg.lstsq(A, g, rcond=None)[0]
    held = np.zeros(k, bool)
    for _ in range(k):
        low, high = bounds[:, 0], bounds[:, 1]
        excess = np.where(held, 0.0, np.maximum(low - x, x - high))
        worst = int(np.argmax(excess))
        if excess[worst] <= 0.0:
            break
        held[worst] = True
        x[worst] = np.clip(x[worst], low[worst], high[worst])
        free = ~held
        if free.any():
            x[free] = np.linalg.lstsq(A[np.ix_(free, free)], g[free] - A[np.ix_(free, held)] @ x[held],
                                      rcond=None)[0]
    return x


class Problem:
    """Measured data, noise levels, weights and folds: evaluates one simulation.

    Parameters
    ----------
    time : ndarray (n,)
        Uniform time base (s, simulation clock).
    measured : ndarray (n, c)
        Measured channels (SI), NaN where not measured.
    sigma : ndarray (c,)
        Noise level per channel.
    t_stop : float or ndarray (c,)
        When the reels stop (s); per channel for stacked trials (``_trials``).
    regressors : sequence of ndarray (n, c), optional
        Further nuisance directions fitted linearly with every simulation
        (``_updating``: the rig parameters' sensitivities and the model's
        own numerical error), so that a mechanism is credited only with
        what they cannot explain.
    prior_precision, prior_mean : ndarray (k,), optional
        A Gaussian prior on each regressor's coefficient (precision 0: free).
    shift_center : float, optional
        The clock shift (s) the bound ``MAX_SHIFT`` is taken about: the
        updated model's own (``_updating``), so that the clock the rig's
        update settled on is not clipped back (a sheave inertia of 4e-4
        kg m^2 moved the rope-length alignment by 15 ms; clipped at 10 ms,
        the updated model scored 1.9 times the chi2 its update reached).
    offset_free : ndarray (c,) of bool, optional
        Which channels carry a free constant offset (all by default). A
        channel measured in the frame the model is driven in (a tracker's
        body beside the points it moves, ``shared_frame``) has none: its
        mean is the model's to explain.
    """

    def __init__(self, time, measured, sigma, t_stop, regressors=(), prior_precision=None, prior_mean=None,
                 shift_center=0.0, regressor_bounds=None, offset_free=None):
        self.time = np.asarray(time, float)
        self.dt = float(self.time[1] - self.time[0])
        self.measured = np.asarray(measured, float)
        self.sigma = np.asarray(sigma, float)
        self.valid = np.isfinite(self.measured)
        c = self.measured.shape[1]
        self.offset_free = np.ones(c, bool) if offset_free is None else np.asarray(offset_free, bool).reshape(c)
        # Each channel's own stop (stacked trials, ``_trials``), or one for all.
        w = np.where(self.time[:, None] >= np.asarray(t_stop, float), DECAY_WEIGHT, 1.0)
        # Weight of each squared residual: sample weight / sigma^2, 0 if unmeasured.
        self.W = w * self.valid / self.sigma[None, :] ** 2
        fold = (np.floor((self.time - self.time[0]) / BLOCK_S).astype(int) % 2).astype(bool)
        self.folds = {"A": ~fold, "B": fold, "all": np.ones_like(fold)}
        self.n_weighted = float((w * self.valid).sum())
        self.m0 = np.where(self.valid, self.measured, 0.0)
        self.t_stop = t_stop
        self.shift_center = float(shift_center)
        self.regressors = np.array([np.where(self.valid, x, 0.0) for x in regressors], float).reshape(
            len(regressors), *self.measured.shape)
        k = len(self.regressors)
        self.prior_precision = np.zeros(k) if prior_precision is None else np.asarray(prior_precision, float)
        self.prior_mean = np.zeros(k) if prior_mean is None else np.asarray(prior_mean, float)
        # Each regressor's coefficient within (low, high): the model error's amplitude is bounded.
        self.regressor_bounds = (np.tile([-np.inf, np.inf], (k, 1)) if regressor_bounds is None
                                 else np.asarray(regressor_bounds, float).reshape(k, 2))
        # The regressors do not change between simulations: centre them and
        # form their Gram matrix once per fold.
        self._fold_regressors = {}
        for name, mask in self.folds.items():
            if not k:
                break
            W = self.W * mask[:, None]
            sw = np.maximum(W.sum(0), 1e-300)
            xc = self.regressors - self.offset_free * (W * self.regressors).sum(1)[:, None, :] / sw
            gram = np.einsum("inc,jnc->ij", xc * W, xc)
            self._fold_regressors[name] = (xc, gram)

    def with_regressors(self, regressors, prior_precision=None, prior_mean=None, shift_center=None, bounds=None):
        """The same problem with these nuisance regressors (a new object); the shift's centre kept unless given;
        ``bounds`` (k, 2) on their coefficients (none by default)."""
        centre = self.shift_center if shift_center is None else shift_center
        return Problem(self.time, self.measured, self.sigma, self.t_stop, regressors, prior_precision, prior_mean,
                       centre, bounds, self.offset_free)

    def nuisance(self, sim, fold):
        """Least-squares offsets b (c,), clock shift delta (s) and regressor coefficients a (k,) on one fold;
        a channel without a free offset keeps b = 0.

        The shift is exact (``on_clock``): Gauss-Newton steps from the
        centre, each the linear term's least squares on the simulation read
        at the shift so far, the whole shift within ``MAX_SHIFT`` of the
        centre; the offsets and coefficients are then those of the
        simulation read at it.
        """
        sim = np.asarray(sim, float)
        low, high = self.shift_center - MAX_SHIFT, self.shift_center + MAX_SHIFT
        shift = self.shift_center
        for _ in range(CLOCK_STEPS):
            read = on_clock(sim, self.dt, shift)
            step = self._linear_nuisance(read, np.gradient(read, self.dt, axis=0), fold, low - shift, high - shift)[1]
            shift += step
            if abs(step) < CLOCK_CONVERGED:
                break
        read = on_clock(sim, self.dt, shift)
        b, _, a = self._linear_nuisance(read, np.zeros_like(read), fold, 0.0, 0.0)
        return b, shift, a

    def _linear_nuisance(self, sim, rate, fold, low, high):
        """Offsets, the linear clock term's coefficient (within ``low``-``high``, s) and the regressors'
        coefficients on one fold."""
        W = self.W * self.folds[fold][:, None]
        r = self.m0 - sim
        # Dividing by infinity where the offset is not free: the channel's "mean" is 0 and nothing is centred.
        sw = np.where(self.offset_free, np.maximum(W.sum(0), 1e-300), np.inf)
        rc = r - (W * r).sum(0) / sw
        dc = rate - (W * rate).sum(0) / sw
        if len(self.regressors):
            return self._joint_nuisance(W, sw, r, rc, rate, dc, fold, low, high)
        den = float((W * dc * dc).sum())
        delta = float((W * rc * dc).sum()) / den if den > 0 else 0.0
        delta = float(np.clip(delta, low, high))
        b = ((W * r).sum(0) - delta * (W * rate).sum(0)) / sw
        return b, delta, np.zeros(0)

    def _joint_nuisance(self, W, sw, r, rc, rate, dc, fold, low, high):
        """Shift and regressors together (normal equations with the priors); offsets eliminated."""
        xc, gram = self._fold_regressors[fold]
        k = len(self.regressors)
        A = np.empty((k + 1, k + 1))
        A[0, 0] = float((W * dc * dc).sum())
        A[0, 1:] = A[1:, 0] = np.einsum("inc,nc->i", xc, W * dc)
        A[1:, 1:] = gram + np.diag(self.prior_precision)
        g = np.empty(k + 1)
        g[0] = float((W * rc * dc).sum())
        g[1:] = np.einsum("inc,nc->i", xc, W * rc) + self.prior_precision * self.prior_mean
        A[0, 0] = max(A[0, 0], 1e-300)
        bounds = np.vstack([[low, high], self.regressor_bounds])
        coef = bounded_solve(A, g, bounds)
        delta, a = float(coef[0]), coef[1:]
        fitted = delta * rate + np.einsum("i,inc->nc", a, self.regressors)
        b = (W * (r - fitted)).sum(0) / sw
        return b, delta, a

    def _fitted(self, sim, nuisance):
        """The simulation on its clock shift, its offsets and regressors added (SI)."""
        b, delta, a = nuisance
        part = on_clock(sim, self.dt, delta) + b[None, :]
        if len(a):
            part = part + np.einsum("i,inc->nc", a, self.regressors)
        return part

    def residual(self, sim, nuisance=None):
        """Measured minus simulated minus nuisance (SI), NaN where unmeasured."""
        sim = np.asarray(sim, float)
        nuisance = self.nuisance(sim, "all") if nuisance is None else nuisance
        return self.measured - self._fitted(sim, nuisance)

    def evaluate(self, sim):
        """chi2 of one simulation (n, c): on all data and fold by fold.

        Returns
        -------
        dict
            ``full`` (nuisance fitted on all), ``nuisance`` ((b, delta, a)
            on all), and ``AA``, ``AB``, ``BB``, ``BA``: chi2 on the second
            fold with the nuisance fitted on the first.
        """
        sim = np.asarray(sim, float)
        out = {}
        for fit in ("all", "A", "B"):
            nuisance = self.nuisance(sim, fit)
            r = self.m0 - self._fitted(sim, nuisance)
            sq = self.W * r * r
            if fit == "all":
                out["full"] = float(sq.sum())
                out["nuisance"] = nuisance
                continue
            for ev in ("A", "B"):
                out[fit + ev] = float(sq[self.folds[ev]].sum())
        return out

    def held_out_residual(self, sim_a, sim_b):
        """Each sample's held-out residual (n, c, SI; 0 where unmeasured): fold B's with the fit on A (``sim_a``),
        fold A's with the fit on B. ``sum W r^2`` of it is ``evaluate``'s ``AB`` of ``sim_a`` plus ``BA`` of
        ``sim_b``: a candidate's held-out score."""
        out = np.zeros(self.measured.shape)
        for sim, fit, held in ((sim_a, "A", "B"), (sim_b, "B", "A")):
            sim = np.asarray(sim, float)
            r = self.m0 - self._fitted(sim, self.nuisance(sim, fit))
            mask = self.folds[held]
            out[mask] = np.where(self.valid, r, 0.0)[mask]
        return out
