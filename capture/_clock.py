"""A table's clock recovered from the motion it records, for logs written without timestamps.

Some labs log a row whenever a callback fires (a camera frame, a
controller tick) and keep no time column. The rows then come at a known
mean rate but not evenly: each row waits a varying latency after its
frame, so one interval can be half the mean and the next one and a half.
Read on an even clock, that jitter is a velocity error of the same size,
which no model of the machine can fit.

Every tracked coordinate of a row was sampled at the same unknown
instant, so the motion itself says how long each interval was, without
any model of the machine: over a few rows the motion is nearly a
parabola in time, and a row's step along the local velocity is the
interval times the speed (``_motion_intervals``, a few passes, each on
the clock the last one found). Smoothness alone cannot tell a slow
stretch of the clock from slower motion, so the slow part comes from the
log: each row is a frame of a steady clock at the stated mean rate plus
a latency, and the times are the least-squares compromise between the
frames and the motion's intervals, each weighted by its precision (the
latencies' spread is measured from the intervals the motion is sure of;
the motion's precision from the rows' scatter about the local parabolas).

Not recovered: a dropped frame. Its interval is measured like any other,
but the frames it is anchored to assume none is missing, so a drop's
whole frame is spread over the neighbouring rows. A log that drops frames
keeps the mean rate's long-run error.
"""

from __future__ import annotations

import numpy as np

__all__ = ["recover_clock", "unusable_rows"]

# Rows each side of an interval for its velocity: 0.1-0.2 s at 30-60 Hz, far below a pendulum's period.
HALF_WINDOW = 3
ITERATIONS = 2
# Beyond twice the local step, a row's distance from its neighbours' parabola must exceed this (m) to be a
# glitch: ten times a motion-capture system's millimetre, where nothing moves.
GLITCH_FLOOR = 0.01


def recover_clock(samples, mean_step, *, noise=None):
    """Each row's time (s) from the motion of ``samples``, the rows' mean interval being ``mean_step``.

    Parameters
    ----------
    samples : ndarray (n, m)
        Every tracked coordinate in one frame and unit (m), time on the
        first axis, all sampled at the same instants; a row with a NaN
        gets no time (NaN), as a repeated or glitched row does.
    mean_step : float
        The mean interval between rows (s), from the log's stated rate.
    noise : float, optional
        The coordinates' noise (m); default the spread of the rows about
        the local parabolas, on the clock found so far.

    Returns
    -------
    ndarray (n,)
        Increasing times, whose mean step is about ``mean_step``; NaN for
        a row that cannot be timed (``unusable_rows``: a repeat of the row
        before, or a tracking glitch), which a reader then drops.
    """
    values = np.asarray(samples, float)
    n = values.shape[0]
    bad = unusable_rows(values)
    usable = np.flatnonzero(~bad)
    if usable.size < 2 * HALF_WINDOW + 2:
        return np.where(bad, np.nan, np.arange(n) * float(mean_step))
    x = values[usable]
    frames_between = np.diff(usable)
    measured, precision = _motion_intervals(x, frames_between * mean_step, noise)
    grid = mean_step * np.r_[0.0, np.cumsum(frames_between)]
    sure = precision * mean_step**2 > 16.0  # the motion times these intervals within a quarter frame
    jitter = _latency_spread(measured[sure] - mean_step * frames_between[sure], mean_step)
    times = _times_on_frames(grid, measured, precision, jitter)
    times = usable[0] * mean_step + np.r_[0.0, np.cumsum(np.maximum(np.diff(times), 0.1 * mean_step))]
    out = np.full(n, np.nan)
    out[usable] = times
    return out


def unusable_rows(samples):
    """Rows no instant can be given to (bool, (n,)): non-finite ones, exact repeats of the row before
    (a logger writing a stale sample again), and tracking glitches.

    A glitch (a rigid body swapped or lost for one frame: a jump of tens of
    centimetres to metres in real logs) is a row further from the parabola
    through its four neighbours than twice the typical step between rows
    there, plus ``GLITCH_FLOOR``: a row's latency is less than an interval,
    so its timing can move it along its path by less than one step; the
    floor stands for the tracker's noise where nothing moves. Only the worst
    row of a run is the glitch (it throws its neighbours' parabolas off too).
    """
    from numpy.lib.stride_tricks import sliding_window_view

    values = np.asarray(samples, float)
    n = values.shape[0]
    bad = ~np.all(np.isfinite(values), axis=1)
    bad[1:] |= np.all(values[1:] == values[:-1], axis=1) & ~bad[:-1]
    if n < 8:
        return bad
    x = np.where(bad[:, None], np.nan, values)
    # The parabola through rows k-2, k-1, k+1, k+2 at row k: (-x[k-2] + 4 x[k-1] + 4 x[k+1] - x[k+2]) / 6.
    miss = np.full(n, np.nan)
    miss[2:-2] = np.linalg.norm(x[2:-2] - (-x[:-4] + 4 * x[1:-3] + 4 * x[3:-1] - x[4:]) / 6.0, axis=1)
    steps = np.linalg.norm(np.diff(values, axis=0), axis=1)
    typical = np.nanmedian(sliding_window_view(np.pad(steps, (3, 3), mode="edge"), 6), axis=1)[:n]
    with np.errstate(invalid="ignore"):
        glitch = miss > 2.0 * typical + GLITCH_FLOOR
        worst = miss >= np.fmax(np.r_[miss[1:], -np.inf], np.r_[-np.inf, miss[:-1]])
    return bad | (glitch & worst)


def _motion_intervals(x, prior, noise):
    """Each interval's length (s) as the motion measures it, and its precision (1/s^2)."""
    steps = np.diff(x, axis=0)
    dt = prior.copy()
    for _ in range(ITERATIONS):
        t = np.r_[0.0, np.cumsum(dt)]
        velocity, slope_variance, residual = _local_fits(t, x)
        sigma = max(float(np.median(np.abs(residual))) * 1.4826, 1e-6) if noise is None else float(noise)
        speed2 = np.einsum("ij,ij->i", velocity, velocity)
        with np.errstate(invalid="ignore", divide="ignore"):
            measured = np.einsum("ij,ij->i", steps, velocity) / speed2
        # The step's projection carries noise sqrt(2) sigma: in time, sqrt(2) sigma / speed. The
        # speed is the part of the fitted one that its own noise does not explain.
        signal2 = np.maximum(speed2 - x.shape[1] * sigma**2 * slope_variance, 0.0)
        precision = signal2 / (2.0 * sigma**2)
        usable = np.isfinite(measured) & (speed2 > 0) & (measured > 0)
        measured = np.where(usable, measured, prior)
        precision = np.where(usable, precision, 0.0)
        dt = np.where(precision * prior**2 > 16.0, measured, prior)
    return measured, precision


def _latency_spread(deviations, period):
    """Each row's latency spread (s): an interval is the difference of two latencies (variance 2 s^2)."""
    if deviations.size < 10:
        return 0.25 * period
    spread = 1.4826 * float(np.median(np.abs(deviations - np.median(deviations))))
    return max(spread / np.sqrt(2.0), 1e-3 * period)


def _times_on_frames(grid, measured, precision, jitter):
    """Times closest to the frames plus latencies of spread ``jitter`` and to the motion's intervals.

    Minimizes sum precision (t[k+1] - t[k] - measured)^2 + sum (t - grid - c)^2 / jitter^2,
    a tridiagonal least-squares problem, with c (the mean latency) left free.
    """
    from scipy.linalg import solve_banded

    n = grid.size
    w = np.minimum(precision, 1e6 / jitter**2)
    prior = 1.0 / jitter**2
    diag = np.full(n, prior)
    diag[:-1] += w
    diag[1:] += w
    off = -w
    rhs = prior * grid
    rhs[:-1] -= w * measured
    rhs[1:] += w * measured
    banded = np.zeros((3, n))
    banded[0, 1:] = off
    banded[1] = diag
    banded[2, :-1] = off
    times = solve_banded((1, 1), banded, rhs)
    return times - np.mean(times - grid)


def _local_fits(t, x):
    """Each interval's velocity (m/s, (n-1, m)), the slope at its midpoint of a parabola through the
    rows around it; that slope's variance per unit noise variance (s^-2); and the rows' residuals from
    those parabolas (m, scaled to the noise's sigma)."""
    n = t.size
    centre = np.arange(n - 1)
    offsets = np.arange(-HALF_WINDOW + 1, HALF_WINDOW + 1)
    rows = np.clip(centre[:, None] + offsets[None, :], 0, n - 1)
    tau = t[rows] - 0.5 * (t[centre] + t[centre + 1])[:, None]
    basis = np.stack([np.ones_like(tau), tau, tau * tau], axis=-1)        # (n-1, W, 3)
    normal = np.einsum("kwi,kwj->kij", basis, basis)
    coef = np.linalg.solve(normal, np.einsum("kwi,kwm->kim", basis, x[rows]))  # (n-1, 3, m)
    residual = x[rows] - np.einsum("kwi,kim->kwm", basis, coef)
    width = offsets.size
    return coef[:, 1, :], np.linalg.inv(normal)[:, 1, 1], residual * np.sqrt(width / (width - 3))
