"""Where a measured trajectory differs from a simulated one, beyond noise.

Step 1 of the diagnosis (``_diagnose``): the residual ``measured -
simulated`` of the channels that carry the rig's dynamics is judged
against the measurement noise, estimated from the measured signals
themselves, per channel and per time window (the maneuver's phases and the
free decay after the reels stop), with the residual's dominant frequency.

Noise and structure
-------------------
Marker noise is white: a reconstructed position or angle is a fresh
triangulation in every frame (positions are not smoothed). Its level
``sigma`` is the robust spread of the second difference, ``1.4826 MAD /
sqrt(6)`` (the second difference of white noise has variance ``6
sigma^2``; that of a 0.6 Hz swing of 1 m at 200 Hz is 1e-4 m, far below).

A *structured* mismatch is what survives a low-pass: the moving average
over ``LOWPASS_S`` (passes the swing, 0.6-2.5 Hz, nearly unchanged; leaves
white noise at ``sigma / sqrt(n)``). A window's mismatch counts when the
RMS of its low-passed residual exceeds both ``STRUCTURE_SIGMAS`` times
what noise alone leaves there and a physical floor (``STRUCTURE_FLOOR``):
the reconstruction's own systematic errors (calibration scale, marker
offsets) reach a fraction of a millimetre and must not pass for physics.
These constants are the dragline's; another machine gets them at its own
scale (``_scale``: lengths by its pendulum length, the low-pass by its
slowest period).
"""

from __future__ import annotations

import math

import numpy as np

from ...simulate import ROPE_CHANNELS
from .._compare import channel_kind
from .._paper import FREE_DECAY_CHANNELS
from ._scale import REFERENCE

__all__ = [
    "DYNAMIC_CHANNELS",
    "STRUCTURE_FLOOR",
    "noise_level",
    "low_pass",
    "time_windows",
    "dominant_frequency",
    "structure_threshold",
    "locate_mismatch",
]

# The channels that carry the dynamics: positions and pitch angles of the
# four bodies (the paper's figures) and the rope lengths (rope held in a
# pulley by friction shows there first); velocities and rates are derived
# from them by differencing and smoothing and add nothing independent.
DYNAMIC_CHANNELS = tuple(FREE_DECAY_CHANNELS) + tuple(ROPE_CHANNELS)

LOWPASS_S = 0.1
STRUCTURE_SIGMAS = 4.0
STRUCTURE_FLOOR = {"position": 1.0e-3, "angle": math.radians(0.25), "rope_length": 2.0e-3}
# Lowest noise level believed (a table with less noise than this was
# smoothed or simulated; sigma must not go to zero).
NOISE_FLOOR = {"position": 5.0e-5, "angle": 2.0e-4, "rope_length": 5.0e-5}
# The noise's differences go no higher than this: a tenth difference shrinks a swing at a tenth of the rate by
# (2 sin(0.31))^10 = 0.005 and amplifies the noise by sqrt(184756) = 430, still far from rounding in float64.
MAX_DIFFERENCE_ORDER = 10
# A MAD-based deviation's relative standard error times sqrt(n) (the MAD's efficiency at the normal, 37 %).
MAD_RELATIVE_SE = 1.16
# Windows: maneuver phases shorter than this are merged with the next one;
# a maneuver with more phases than MAX_PHASES is cut into 1 s windows.
MIN_WINDOW_S = 0.5
MAX_PHASES = 8


def noise_level(values, kind="position", scale=REFERENCE):
    """White-noise level of a sampled signal from its differences, of the second order or higher.

    The k-th difference of white noise of deviation s has deviation
    s sqrt(C(2k, k)); a motion of angular frequency w sampled every dt is
    shrunk by (2 sin(w dt / 2))^k. At 200 Hz the second difference holds
    noise alone; at 10 Hz a 1 Hz swing (w dt = 0.63) leaves a second
    difference of 0.4 times its amplitude, and a box turning 0.3 rad read
    as 30 mrad of noise where the tracker's is a few. Every order up to
    ``MAX_DIFFERENCE_ORDER`` is estimated (the MAD of the difference).
    Where the third is not lower than the second by three standard errors
    (the MAD's, ``MAD_RELATIVE_SE`` / sqrt(n) relative) noise rules, and
    the second's is taken, as it always was; else the lowest order within
    three standard errors of the lowest estimate (the least estimate
    itself would be biased low).

    Parameters
    ----------
    values : array_like, shape (n,)
        Uniformly sampled signal; NaN allowed (differences across them are
        skipped).
    kind : str
        ``position``, ``angle`` or ``rope_length``: selects the floor ``NOISE_FLOOR``.
    scale : MachineScale
        The machine's, at which the floor is taken (default: the dragline's).

    Returns
    -------
    float
        Standard deviation (unit of the signal), at least the floor.
    """
    y = np.asarray(values, float)
    floor = scale.floor(NOISE_FLOOR, kind if kind in NOISE_FLOOR else "position")
    estimates, margin = [], []
    for order in range(2, MAX_DIFFERENCE_ORDER + 1):
        d = np.diff(y, order)
        d = d[np.isfinite(d)]
        if d.size < 10:
            break
        mad = float(np.median(np.abs(d - np.median(d))))
        estimates.append(1.4826 * mad / math.sqrt(math.comb(2 * order, order)))
        margin.append(1.0 + 3.0 * MAD_RELATIVE_SE / math.sqrt(d.size))
        if order == 3 and estimates[1] * margin[1] >= estimates[0]:
            break  # the third difference no lower: noise rules the second, no higher order is needed
    if not estimates:
        return floor
    if len(estimates) == 1 or estimates[1] * margin[1] >= estimates[0]:
        return max(estimates[0], floor)
    lowest = min(estimates)
    best = next(e for e, m in zip(estimates, margin) if e <= lowest * m)
    return max(best, floor)


def low_pass(values, width):
    """Centred moving average over ``width`` samples along axis 0, NaN-aware.

    Parameters
    ----------
    values : array_like, shape (n, ...)
    width : int

    Returns
    -------
    ndarray, same shape
        Mean of the finite samples in each window; NaN where the window
        holds none, or where the sample itself is NaN.
    """
    x = np.asarray(values, float)
    ok = np.isfinite(x)
    filled = np.where(ok, x, 0.0)
    kernel = np.ones(int(width))
    flat_x = filled.reshape(x.shape[0], -1)
    flat_ok = ok.reshape(x.shape[0], -1).astype(float)
    num = np.column_stack([np.convolve(flat_x[:, j], kernel, mode="same") for j in range(flat_x.shape[1])])
    den = np.column_stack([np.convolve(flat_ok[:, j], kernel, mode="same") for j in range(flat_x.shape[1])])
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(den > 0, num / den, np.nan)
    out = out.reshape(x.shape)
    out[~ok] = np.nan
    return out


def structure_threshold(channel, sigma, width, scale=REFERENCE):
    """Low-passed residual RMS above which a channel's mismatch is structured (floor at the machine's ``scale``)."""
    return max(scale.floor(STRUCTURE_FLOOR, channel_kind(channel)), STRUCTURE_SIGMAS * sigma / math.sqrt(width))


def time_windows(maneuver, t_stop, t_end):
    """The maneuver's phases and the free decay, as ``(label, t_start, t_end)``.

    Phases run between the maneuver's rows where a winch's speed or a moving
    point's velocity changes;
    phases shorter than ``MIN_WINDOW_S`` join the next; a table of more
    than ``MAX_PHASES`` phases (a smooth profile) is cut into 1 s windows.
    The free decay runs from ``t_stop`` to ``t_end``.
    """
    t = np.asarray(maneuver.time, float)
    t0 = float(t[0])
    stop = float(t_stop)
    if t.size > 2:
        moves = [np.diff(v) for v in maneuver.lengths.values()]
        moves += [np.diff(xyz[:, k]) for xyz in maneuver.points.values() for k in range(3)]
        rates = np.column_stack(moves or [np.zeros(t.size - 1)]) / np.diff(t)[:, None]
        change = np.flatnonzero(np.any(np.abs(np.diff(rates, axis=0)) > 1e-6, axis=1)) + 1
        cuts = [float(t[i]) for i in change if t0 < t[i] < stop]
    else:
        cuts = []
    edges = [t0]
    for c in cuts:
        if c - edges[-1] >= MIN_WINDOW_S:
            edges.append(c)
    if stop - edges[-1] < MIN_WINDOW_S and len(edges) > 1:
        edges.pop()
    edges.append(stop)
    if len(edges) - 1 > MAX_PHASES:
        n = max(1, int(round(stop - t0)))
        edges = list(np.linspace(t0, stop, n + 1))
    windows = [(f"phase {k + 1}", float(a), float(b)) for k, (a, b) in enumerate(zip(edges[:-1], edges[1:])) if b > a]
    if t_end > stop:
        windows.append(("free decay", stop, float(t_end)))
    return windows


def dominant_frequency(values, dt):
    """Frequency (Hz) of the periodogram peak of a signal, at least one cycle per window.

    NaN samples are set to the mean; None for fewer than 8 finite samples or
    a flat signal.
    """
    y = np.asarray(values, float)
    ok = np.isfinite(y)
    if np.count_nonzero(ok) < 8:
        return None
    y = np.where(ok, y - y[ok].mean(), 0.0)
    n_fft = 8 * int(2 ** math.ceil(math.log2(y.size)))
    power = np.abs(np.fft.rfft(y * np.hanning(y.size), n_fft)) ** 2
    freq = np.fft.rfftfreq(n_fft, dt)
    power[freq < 1.0 / (dt * y.size)] = 0.0
    if not power.max() > 0.0:
        return None
    return float(freq[int(np.argmax(power))])


def locate_mismatch(time, residual, channels, sigma, windows, scale=REFERENCE):
    """Per channel and window: how much structured mismatch, and at what frequency.

    Parameters
    ----------
    time : ndarray, shape (n,)
        Uniform time base (s).
    residual : ndarray, shape (n, channels)
        Measured minus simulated (SI units), NaN where not measured.
    channels : sequence of str
    sigma : sequence of float
        Noise level per channel (:func:`noise_level`).
    windows : sequence of (label, t_start, t_end)
    scale : MachineScale
        The machine's: its floors and low-pass (default: the dragline's).

    Returns
    -------
    list of dict
        One per channel and window, sorted by ``score`` (largest first):
        ``channel``, ``window``, ``t_start``, ``t_end`` (s), ``score``
        (low-passed residual RMS over :func:`structure_threshold`; above 1
        is a structured mismatch), ``rms`` (the low-passed residual RMS),
        ``raw_rms`` (unfiltered), ``mean`` (signal unit), ``noise``
        (sigma), ``frequency_hz`` (dominant frequency of the residual),
        ``significant`` (score > 1).
    """
    t = np.asarray(time, float)
    dt = float(t[1] - t[0])
    width = scale.lowpass_width(LOWPASS_S, dt)
    smooth = low_pass(residual, width)
    out = []
    for label, t0, t1 in windows:
        sel = (t >= t0 - 1e-9) & (t <= t1 + 1e-9)
        if np.count_nonzero(sel) < 8:
            continue
        for j, ch in enumerate(channels):
            r, s = residual[sel, j], smooth[sel, j]
            ok = np.isfinite(s)
            if np.count_nonzero(ok) < 8:
                continue
            rms = float(np.sqrt(np.mean(s[ok] ** 2)))
            score = rms / structure_threshold(ch, sigma[j], width, scale)
            out.append({
                "channel": ch,
                "window": label,
                "t_start": float(t0),
                "t_end": float(t1),
                "score": score,
                "rms": rms,
                "raw_rms": float(np.sqrt(np.nanmean(r**2))),
                "mean": float(np.nanmean(r)),
                "noise": float(sigma[j]),
                "frequency_hz": dominant_frequency(r, dt),
                "significant": bool(score > 1.0),
            })
    out.sort(key=lambda e: -e["score"])
    return out
