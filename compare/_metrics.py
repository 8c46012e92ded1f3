"""Measured-versus-simulated metrics for one channel on a common time base.

Every function takes the measured signal (the reference, "test") and the
simulated signal (the "model"/CAE curve) as 1-D arrays of equal length,
sampled at the same instants ``time`` (s) where time matters. Samples where
either signal (or the time) is NaN are dropped pairwise; the number of
samples actually used is reported by :func:`channel_metrics` as
``n_samples``. Functions never modify their inputs.

Definitions
-----------
- RMS error ``sqrt(mean((s - m)^2))`` and peak error ``max |s - m|``
  (units of the signal).
- :func:`peak` is the signed extreme (the sample of largest magnitude) and
  its time, the quantity in the seed paper's peak table (section 4).
- Sprague-Geers (Sprague & Geers 2004; Schwer 2007), with
  ``psi_mm = int m^2 dt``, ``psi_ss = int s^2 dt``, ``psi_ms = int m s dt``
  by the trapezoid rule over ``time``::

      M = sqrt(psi_ss / psi_mm) - 1
      P = arccos(psi_ms / sqrt(psi_mm psi_ss)) / pi
      C = sqrt(M^2 + P^2)

- Theil's inequality coefficient
  ``U = sqrt(mean((m - s)^2)) / (sqrt(mean(m^2)) + sqrt(mean(s^2)))``,
  0 for a perfect match, 1 for ``s = -m`` or ``s = 0``.
- An ISO/TS 18571-style rating, see :func:`iso18571`.

Undefined results (for example Sprague-Geers against an all-zero measured
signal) are NaN from the single-metric functions and ``None`` in the
:func:`channel_metrics` dictionary, so that it serialises to strict JSON.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = [
    "rms_error",
    "peak_error",
    "peak",
    "sprague_geers",
    "theil_u",
    "iso18571",
    "channel_metrics",
]

# ISO/TS 18571:2014 default parameters (Table 1 of the standard).
ISO_A0 = 0.05  # inner corridor half-width, fraction of max |reference|
ISO_B0 = 0.5  # outer corridor half-width, fraction of max |reference|
ISO_KZ = 2.0  # corridor score progression exponent
ISO_KP = 1.0  # phase score exponent
ISO_KM = 1.0  # magnitude score exponent
ISO_KS = 1.0  # slope score exponent
ISO_EPS_P = 0.2  # largest allowed time shift, fraction of the duration
ISO_EPS_M = 0.5  # magnitude error at which the magnitude score reaches 0
ISO_EPS_S = 2.0  # slope error at which the slope score reaches 0
ISO_WEIGHTS = {"corridor": 0.4, "phase": 0.2, "magnitude": 0.2, "slope": 0.2}
# The standard smooths the derivative curves with a short moving average
# before the slope error; we use a centred 9-sample window.
ISO_SLOPE_SMOOTHING = 9


def _as_1d(name, values):
    arr = np.asarray(values, dtype=float)
    if arr.ndim != 1:
        raise ValueError(f"{name} must be a 1-D array, got shape {arr.shape}")
    return arr


def _paired(measured, simulated, time=None, minimum=2):
    """Drop samples where any input is NaN; return copies (m, s[, t])."""
    m = _as_1d("measured", measured)
    s = _as_1d("simulated", simulated)
    if m.shape != s.shape:
        raise ValueError(
            f"measured and simulated differ in length ({m.size} vs {s.size})"
        )
    ok = np.isfinite(m) & np.isfinite(s)
    if time is not None:
        t = _as_1d("time", time)
        if t.shape != m.shape:
            raise ValueError(
                f"time and measured differ in length ({t.size} vs {m.size})"
            )
        ok &= np.isfinite(t)
    if np.count_nonzero(ok) < minimum:
        raise ValueError(
            f"fewer than {minimum} samples where measured and simulated are both finite"
        )
    if time is None:
        return m[ok], s[ok]
    t = t[ok]
    if np.any(np.diff(t) <= 0):
        raise ValueError("time must be strictly increasing")
    return m[ok], s[ok], t


def rms_error(measured, simulated):
    """Root-mean-square of ``simulated - measured`` over paired finite samples.

    Parameters
    ----------
    measured, simulated : array_like, shape (n,)
        Signals on a common time base (any unit).

    Returns
    -------
    float
        RMS difference, same unit as the signals.
    """
    m, s = _paired(measured, simulated, minimum=1)
    return float(np.sqrt(np.mean((s - m) ** 2)))


def peak_error(measured, simulated):
    """Largest absolute difference ``max |simulated - measured|``.

    Parameters
    ----------
    measured, simulated : array_like, shape (n,)

    Returns
    -------
    float
        Same unit as the signals.
    """
    m, s = _paired(measured, simulated, minimum=1)
    return float(np.max(np.abs(s - m)))


def peak(values, time):
    """Signed extreme of a signal and when it occurs.

    Parameters
    ----------
    values : array_like, shape (n,)
        Signal; NaN samples are ignored.
    time : array_like, shape (n,)
        Sample times (s).

    Returns
    -------
    value : float
        The sample of largest magnitude, with its sign (first one on ties).
    time : float
        Its time (s).
    """
    v = _as_1d("values", values)
    t = _as_1d("time", time)
    if v.shape != t.shape:
        raise ValueError(f"values and time differ in length ({v.size} vs {t.size})")
    ok = np.isfinite(v) & np.isfinite(t)
    if not ok.any():
        raise ValueError("values has no finite sample")
    v, t = v[ok], t[ok]
    i = int(np.argmax(np.abs(v)))
    return float(v[i]), float(t[i])


def sprague_geers(time, measured, simulated):
    """Sprague-Geers magnitude, phase and combined errors.

    Parameters
    ----------
    time : array_like, shape (n,)
        Sample times (s), strictly increasing where finite.
    measured, simulated : array_like, shape (n,)

    Returns
    -------
    M, P, C : float
        Magnitude error (``simulated = a * measured`` gives ``|a| - 1``),
        phase error in [0, 1] (a shift of phase angle ``phi`` of a sinusoid
        over whole periods gives ``phi / pi``) and ``sqrt(M^2 + P^2)``.
        NaN where an integral that divides is zero.
    """
    m, s, t = _paired(measured, simulated, time)
    psi_mm = np.trapezoid(m * m, t)
    psi_ss = np.trapezoid(s * s, t)
    psi_ms = np.trapezoid(m * s, t)
    if psi_mm <= 0.0 or psi_ss <= 0.0:
        nan = float("nan")
        mag = math.sqrt(psi_ss / psi_mm) - 1.0 if psi_mm > 0.0 else nan
        return mag, nan, nan
    mag = math.sqrt(psi_ss / psi_mm) - 1.0
    cosine = float(np.clip(psi_ms / math.sqrt(psi_mm * psi_ss), -1.0, 1.0))
    phase = math.acos(cosine) / math.pi
    return mag, phase, math.hypot(mag, phase)


def theil_u(measured, simulated):
    """Theil's inequality coefficient U in [0, 1].

    Parameters
    ----------
    measured, simulated : array_like, shape (n,)

    Returns
    -------
    float
        ``sqrt(mean((m-s)^2)) / (sqrt(mean(m^2)) + sqrt(mean(s^2)))``;
        NaN when both signals are identically zero.
    """
    m, s = _paired(measured, simulated, minimum=1)
    den = math.sqrt(np.mean(m * m)) + math.sqrt(np.mean(s * s))
    if den == 0.0:
        return float("nan")
    return float(math.sqrt(np.mean((m - s) ** 2)) / den)


# --------------------------------------------------------------------------
# ISO/TS 18571


def _linear_score(error, eps_star, k):
    """``((eps* - e) / eps*)^k`` on [0, eps*], 1 below 0, 0 beyond eps*."""
    if not np.isfinite(error) or error >= eps_star:
        return 0.0
    return float(max(0.0, 1.0 - error / eps_star) ** k)


def _corridor_score(m, s, a0, b0, kz):
    norm = float(np.max(np.abs(m)))
    diff = np.abs(s - m)
    inner, outer = a0 * norm, b0 * norm
    if outer <= inner:
        return float(np.mean(diff <= inner))
    z = ((outer - diff) / (outer - inner)) ** kz
    z = np.where(diff <= inner, 1.0, np.where(diff > outer, 0.0, z))
    return float(np.mean(z))


def _best_shift(m, s, max_shift):
    """Integer lag d (|d| <= max_shift) maximising the Pearson correlation.

    Positive d means the simulated curve lags: s[i + d] ~ m[i]. Ties go to
    the smallest |d|, then to the positive lag.
    """
    n = m.size
    best_d, best_r = 0, -np.inf
    for d in sorted(range(-max_shift, max_shift + 1), key=lambda k: (abs(k), -k)):
        x, y = (m[: n - d], s[d:]) if d >= 0 else (m[-d:], s[: n + d])
        if x.size < 2:
            continue
        x = x - x.mean()
        y = y - y.mean()
        den = math.sqrt(float(np.dot(x, x)) * float(np.dot(y, y)))
        r = float(np.dot(x, y)) / den if den > 0.0 else -np.inf
        if r > best_r + 1e-12:
            best_d, best_r = d, r
    return best_d


@njit(cache=True)
def _dtw_path(a, b):  # pragma: no cover - compiled
    n, k = a.size, b.size
    # Only the previous row of accumulated cost is needed; the moves are kept
    # for the backtrack (n * k bytes).
    prev = np.empty(k)
    cur = np.empty(k)
    step = np.zeros((n, k), dtype=np.int8)  # 0 diagonal, 1 up (i-1), 2 left (j-1)
    for i in range(n):
        for j in range(k):
            d = abs(a[i] - b[j])
            if i == 0 and j == 0:
                cur[j] = d
                continue
            best = np.inf
            move = 0
            if i > 0 and j > 0:
                best = prev[j - 1]
            if i > 0 and prev[j] < best:
                best = prev[j]
                move = 1
            if j > 0 and cur[j - 1] < best:
                best = cur[j - 1]
                move = 2
            cur[j] = d + best
            step[i, j] = move
        prev, cur = cur, prev
    ia = np.empty(n + k, dtype=np.int64)
    ib = np.empty(n + k, dtype=np.int64)
    i, j, length = n - 1, k - 1, 0
    while True:
        ia[length] = i
        ib[length] = j
        length += 1
        if i == 0 and j == 0:
            break
        move = step[i, j]
        if i == 0:
            j -= 1
        elif j == 0:
            i -= 1
        elif move == 0:
            i -= 1
            j -= 1
        elif move == 1:
            i -= 1
        else:
            j -= 1
    return ia[:length][::-1].copy(), ib[:length][::-1].copy()


def _relative_l1(reference, other):
    num = float(np.sum(np.abs(other - reference)))
    if num == 0.0:
        return 0.0
    den = float(np.sum(np.abs(reference)))
    return num / den if den > 0.0 else float("inf")


def _moving_average(x, width):
    if x.size < width or width < 2:
        return x
    return np.convolve(x, np.ones(width) / width, mode="valid")


def iso18571(time, measured, simulated):
    """ISO/TS 18571-style objective rating of a simulated against a measured curve.

    Implements the four sub-scores and the weighted rating of ISO/TS
    18571:2014 with the standard's default parameters (corridor a0 = 0.05,
    b0 = 0.5, kz = 2; phase eps_P* = 0.2 of the duration, kP = 1; magnitude
    eps_M* = 0.5, kM = 1; slope eps_S* = 2.0, kS = 1; weights 0.4, 0.2,
    0.2, 0.2). The measured curve is the reference C, the simulated one T.

    - Corridor: inner/outer half-widths ``a0 * norm`` and ``b0 * norm`` with
      ``norm = max |C|``; per sample 1 inside the inner corridor, 0 outside
      the outer one, ``((outer - |C-T|)/(outer - inner))^kz`` between;
      averaged over the samples.
    - Phase: T is shifted against C sample by sample up to eps_P* of the
      duration; the lag maximising the correlation of the overlapping parts
      is kept; score ``(1 - |lag| / (eps_P* duration))^kP``.
    - Magnitude: the two overlapping (shift-corrected, truncated) curves are
      aligned by dynamic time warping; EEARTH magnitude error
      ``sum |T_w - C_w| / sum |C_w|``; score ``(1 - err/eps_M*)^kM``.
    - Slope: derivatives of the shift-corrected curves (forward differences,
      smoothed by a centred 9-sample moving average); EEARTH slope error
      ``sum |T' - C'| / sum |C'|``; score ``(1 - err/eps_S*)^kS``.

    Simplifications (stated honestly): the standard's pre-processing
    (resampling to 10 kHz, automatic evaluation interval from threshold
    crossings) is not done - the whole given interval is rated at its own
    sampling rate; the correlation used for the phase step is the Pearson
    (mean-removed) coefficient of the overlapping parts; the DTW is a plain,
    unconstrained DTW with the symmetric (1,0)/(0,1)/(1,1) step pattern and
    absolute-difference cost (it stores n^2 bytes of moves); the lower error
    thresholds (eps_P, eps_M, eps_S) are zero. Samples dropped as NaN are
    treated as if the remaining ones were consecutive.

    Parameters
    ----------
    time : array_like, shape (n,)
        Uniformly spaced sample times (s).
    measured, simulated : array_like, shape (n,)

    Returns
    -------
    dict
        ``corridor``, ``phase``, ``magnitude``, ``slope``, ``rating`` (all in
        [0, 1], 1 = identical), ``shift`` (s, positive when the simulation
        lags), ``magnitude_error``, ``slope_error`` (dimensionless).
    """
    m, s, t = _paired(measured, simulated, time, minimum=3)
    steps = np.diff(t)
    dt = float(np.min(steps))
    # Steps that are whole multiples of dt are NaN gaps; anything else is not
    # a uniform sampling.
    ratio = steps / dt
    if np.any(np.abs(ratio - np.round(ratio)) > 0.01):
        raise ValueError("iso18571 needs a uniform time base; resample first")
    duration = dt * (m.size - 1)
    corridor = _corridor_score(m, s, ISO_A0, ISO_B0, ISO_KZ)

    max_shift = int(math.floor(ISO_EPS_P * (m.size - 1) + 1e-9))
    lag = _best_shift(m, s, max_shift)
    phase = _linear_score(abs(lag) * dt, ISO_EPS_P * duration, ISO_KP)
    n = m.size
    if lag >= 0:
        c_s, t_s = m[: n - lag], s[lag:]
    else:
        c_s, t_s = m[-lag:], s[: n + lag]

    ia, ib = _dtw_path(np.ascontiguousarray(c_s), np.ascontiguousarray(t_s))
    mag_err = _relative_l1(c_s[ia], t_s[ib])
    magnitude = _linear_score(mag_err, ISO_EPS_M, ISO_KM)

    dc = _moving_average(np.diff(c_s) / dt, ISO_SLOPE_SMOOTHING)
    dtt = _moving_average(np.diff(t_s) / dt, ISO_SLOPE_SMOOTHING)
    slope_err = _relative_l1(dc, dtt)
    slope = _linear_score(slope_err, ISO_EPS_S, ISO_KS)

    w = ISO_WEIGHTS
    rating = (
        w["corridor"] * corridor
        + w["phase"] * phase
        + w["magnitude"] * magnitude
        + w["slope"] * slope
    )
    return {
        "corridor": corridor,
        "phase": phase,
        "magnitude": magnitude,
        "slope": slope,
        "rating": float(rating),
        "shift": float(lag * dt),
        "magnitude_error": float(mag_err),
        "slope_error": float(slope_err),
    }


def _json_float(x):
    x = float(x)
    return x if math.isfinite(x) else None


def channel_metrics(time, measured, simulated):
    """All comparison metrics for one channel, as a JSON-ready dictionary.

    Parameters
    ----------
    time : array_like, shape (n,)
        Common, uniformly spaced time base (s).
    measured, simulated : array_like, shape (n,)
        Signals (any unit, the same for both); NaN samples are dropped
        pairwise.

    Returns
    -------
    dict
        ``n_samples`` (int, samples used), ``rms_error``, ``peak_error``,
        ``measured_peak``, ``measured_peak_time``, ``simulated_peak``,
        ``simulated_peak_time``, ``peak_time_error`` (s, simulated minus
        measured), ``sg_magnitude``, ``sg_phase``, ``sg_combined``,
        ``iso_corridor``, ``iso_phase``, ``iso_magnitude``, ``iso_slope``,
        ``iso_rating``, ``iso_shift`` (s), ``theil_u``. Floats are plain
        Python floats; undefined values are ``None``.

    Raises
    ------
    ValueError
        Inputs of different lengths, or fewer than 3 paired finite samples.
    """
    m, s, t = _paired(measured, simulated, time, minimum=3)
    m_peak, m_time = peak(m, t)
    s_peak, s_time = peak(s, t)
    sg_m, sg_p, sg_c = sprague_geers(t, m, s)
    iso = iso18571(t, m, s)
    out = {
        "n_samples": int(m.size),
        "rms_error": rms_error(m, s),
        "peak_error": peak_error(m, s),
        "measured_peak": m_peak,
        "measured_peak_time": m_time,
        "simulated_peak": s_peak,
        "simulated_peak_time": s_time,
        "peak_time_error": s_time - m_time,
        "sg_magnitude": sg_m,
        "sg_phase": sg_p,
        "sg_combined": sg_c,
        "iso_corridor": iso["corridor"],
        "iso_phase": iso["phase"],
        "iso_magnitude": iso["magnitude"],
        "iso_slope": iso["slope"],
        "iso_rating": iso["rating"],
        "iso_shift": iso["shift"],
        "theil_u": theil_u(m, s),
    }
    return {k: (v if isinstance(v, int) else _json_float(v)) for k, v in out.items()}
