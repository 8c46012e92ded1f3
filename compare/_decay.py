"""Free-decay analysis: modal frequency, damping and the shape of the envelope.

After the reels stop (t = 6.44 s in the built-in dig maneuver) the rig swings freely;
the way that swing decays tells which damping the model lacks (docs/diagnosis.md):
an exponential envelope is viscous damping, a linear one Coulomb friction,
a hyperbolic one ``A0 / (1 + c t)`` quadratic (aerodynamic) drag.

- :func:`matrix_pencil` fits a sum of damped exponentials (Hua & Sarkar
  1990) and :func:`dominant_mode` picks the strongest oscillation.
- :func:`envelope_shape` fits the three envelope laws to the half-cycle
  extremes and ranks them by AIC.
- :func:`free_decay` does both on the window after ``t_start``.

Signals are 1-D arrays sampled uniformly (``dt`` in s); functions never
modify their inputs. Frequencies are in Hz, damping ratios dimensionless,
amplitudes in the unit of the signal.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import least_squares
from scipy.ndimage import uniform_filter1d
from scipy.signal import find_peaks, savgol_coeffs, savgol_filter

__all__ = ["matrix_pencil", "dominant_mode", "envelope_shape", "free_decay"]

# Order selection: singular values above NOISE_FACTOR times the median are
# signal. The median of a Hankel matrix of white noise sits near the noise
# level and its largest singular values are a few times that (they follow
# the periodogram's spread), so a factor well above the iid Gavish-Donoho
# value (~2.2 for the aspect ratio used here) keeps noise out.
NOISE_FACTOR = 8.0
# Whatever the noise, singular values below this fraction of the largest are
# rounding error.
RELATIVE_FLOOR = 1e-9
MAX_ORDER = 40


def _signal_1d(signal):
    y = np.asarray(signal, dtype=float)
    if y.ndim != 1:
        raise ValueError(f"signal must be a 1-D array, got shape {y.shape}")
    if not np.all(np.isfinite(y)):
        raise ValueError("signal contains NaN or infinite samples")
    return y


def _block_average(y, q):
    """Average non-overlapping blocks of q samples.

    A moving average is a linear filter, so a damped exponential z^k stays a
    damped exponential with pole z^q after averaging and taking every q-th
    sample: the poles survive exactly while white noise drops by sqrt(q).
    """
    n = (y.size // q) * q
    return y[:n].reshape(-1, q).mean(axis=1)


def _poles(y, order, pencil_fraction):
    n = y.size
    pencil = max(2, int(round(pencil_fraction * n)))
    pencil = min(pencil, n - 2)
    rows = n - pencil
    idx = np.arange(rows)[:, None] + np.arange(pencil + 1)[None, :]
    _, sv, vt = np.linalg.svd(y[idx], full_matrices=False)
    if order is None:
        if sv[0] == 0.0:
            return np.empty(0, complex), sv
        threshold = max(NOISE_FACTOR * np.median(sv), RELATIVE_FLOOR * sv[0])
        order = int(np.count_nonzero(sv > threshold))
        order = max(1, min(order, MAX_ORDER, pencil))
    order = min(order, pencil, sv.size)
    v = vt[:order]
    # Shift invariance of the signal subspace: v[:, 1:] ~ Q v[:, :-1]; the
    # eigenvalues of Q are the poles z_i.
    q_mat = v[:, 1:] @ np.linalg.pinv(v[:, :-1])
    return np.linalg.eigvals(q_mat), sv


def matrix_pencil(
    signal, dt, n_modes=None, offset=True, pencil_fraction=1.0 / 3.0, max_samples=600
):
    """Damped exponential modes of a uniformly sampled signal (matrix pencil).

    The signal is modelled as ``y[k] = sum_i R_i z_i^k``; the poles ``z_i``
    come from the right singular vectors of the Hankel matrix of ``y``
    truncated to the model order (Hua & Sarkar 1990, SVD-filtered matrix
    pencil) and the residues ``R_i`` from linear least squares on all
    samples. Complex-conjugate poles are reported once, as one real mode
    ``A exp(-zeta w_n t) cos(w_d t + phase)``.

    Parameters
    ----------
    signal : array_like, shape (n,)
        Uniformly sampled signal, no NaN.
    dt : float
        Sample interval (s).
    n_modes : int, optional
        Number of oscillatory modes to fit. Default: chosen from the
        singular values (those above ``NOISE_FACTOR`` times their median,
        i.e. above the noise floor; capped at ``MAX_ORDER`` poles).
    offset : bool
        When ``n_modes`` is given, add one real pole for a settling value or
        slow drift (a real mode with frequency 0). Ignored when the order is
        chosen automatically (a constant then shows up by itself).
    pencil_fraction : float
        Pencil parameter L as a fraction of the number of samples used
        (Hua & Sarkar recommend N/3 to N/2 under noise).
    max_samples : int
        Longer signals are block-averaged by an integer factor first (poles
        are preserved exactly, see ``_block_average``) to bound the SVD
        cost; residues are still fitted on every original sample. Modes
        above the reduced Nyquist frequency are then out of reach.

    Returns
    -------
    list of dict
        One dict per mode, sorted by decreasing ``amplitude``, with
        ``frequency_hz`` (damped frequency, >= 0), ``natural_frequency_hz``,
        ``damping_ratio`` (``-Re(s)/|s|``; negative for a growing mode),
        ``decay_rate`` (1/s, ``-Re(s)``), ``amplitude`` (at the first
        sample) and ``phase`` (rad, cosine phase at the first sample).
    """
    y = _signal_1d(signal)
    dt = float(dt)
    if not dt > 0.0:
        raise ValueError(f"dt must be positive, got {dt}")
    if y.size < 8:
        raise ValueError(f"signal needs at least 8 samples, got {y.size}")
    if not 0.1 <= pencil_fraction <= 0.5:
        raise ValueError(f"pencil_fraction must lie in [0.1, 0.5], got {pencil_fraction}")
    order = None
    if n_modes is not None:
        if int(n_modes) < 1:
            raise ValueError(f"n_modes must be at least 1, got {n_modes}")
        order = 2 * int(n_modes) + (1 if offset else 0)

    q = max(1, int(math.ceil(y.size / int(max_samples))))
    y_red = _block_average(y, q) if q > 1 else y
    if y_red.size < 8:
        raise ValueError("signal too short after block averaging; raise max_samples")
    z_red, _ = _poles(y_red, order, pencil_fraction)
    if z_red.size == 0:
        return []
    z_red = z_red[np.abs(z_red) > 1e-12]
    s = np.log(z_red.astype(complex)) / (q * dt)

    # Residues on the full-rate signal. Poles are paired with their
    # conjugates so the fit is real; a lone complex pole (odd order) is
    # completed by its conjugate.
    s = _conjugate_closed(s)
    t = np.arange(y.size) * dt
    # Each column is scaled to peak magnitude 1 so that a (noise) mode that
    # grows cannot overflow or swamp the least squares.
    log_peak = np.maximum(0.0, s.real * t[-1])
    basis = np.exp(np.outer(t, s) - log_peak)
    scaled, *_ = np.linalg.lstsq(basis, y.astype(complex), rcond=None)
    residues = scaled * np.exp(-log_peak)

    modes = []
    for si, ri in zip(s, residues):
        if si.imag < 0.0:
            continue
        real = si.imag == 0.0
        amplitude = abs(ri) if real else 2.0 * abs(ri)
        phase = float(np.angle(ri.real if real else ri))
        wn = abs(si)
        modes.append(
            {
                "frequency_hz": float(si.imag / (2.0 * math.pi)),
                "natural_frequency_hz": float(wn / (2.0 * math.pi)),
                "damping_ratio": float(-si.real / wn) if wn > 0.0 else float("nan"),
                "decay_rate": float(-si.real),
                "amplitude": float(amplitude),
                "phase": phase,
            }
        )
    modes.sort(key=lambda mode: -mode["amplitude"])
    return modes


def _conjugate_closed(s):
    """Poles with real ones made exactly real and complex ones paired."""
    out = []
    tol = 1e-9 * max(1.0, float(np.max(np.abs(s)))) if s.size else 0.0
    for si in s:
        if abs(si.imag) <= tol:
            out.append(complex(si.real, 0.0))
        elif si.imag > 0.0:
            out.extend([si, si.conjugate()])
        elif not np.any(np.abs(s - si.conjugate()) <= 1e-6 * abs(si)):
            out.extend([si.conjugate(), si])
    return np.array(out, dtype=complex)


def dominant_mode(signal, dt, n_modes=None):
    """The strongest oscillatory mode of a signal.

    Parameters
    ----------
    signal : array_like, shape (n,)
        Uniformly sampled signal, no NaN.
    dt : float
        Sample interval (s).
    n_modes : int, optional
        Passed to :func:`matrix_pencil`.

    Returns
    -------
    frequency_hz : float
        Damped frequency (Hz).
    damping_ratio : float
    amplitude : float
        At the first sample, unit of the signal.

    Notes
    -----
    "Oscillatory" means at least one full cycle within the signal
    (``frequency_hz >= 1 / duration``); slower modes are drift. Returns
    three NaN when no mode qualifies.
    """
    y = _signal_1d(signal)
    modes = matrix_pencil(y, dt, n_modes=n_modes)
    duration = float(dt) * (y.size - 1)
    osc = [m for m in modes if m["frequency_hz"] >= 1.0 / duration]
    if not osc:
        nan = float("nan")
        return nan, nan, nan
    best = max(osc, key=lambda m: m["amplitude"])
    return best["frequency_hz"], best["damping_ratio"], best["amplitude"]


# --------------------------------------------------------------------------
# Envelope shape

ENVELOPE_MODELS = ("exponential", "linear", "hyperbolic")
MIN_EXTREMA = 6  # three parameters per model and a few degrees of freedom
SWING_NOISE_FACTOR = 10.0  # a half-cycle swing below this many sigma is noise


def _time_1d(time, n):
    t = np.asarray(time, dtype=float)
    if t.ndim != 1 or t.size != n:
        raise ValueError(f"time must be a 1-D array of {n} samples, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise ValueError("time contains NaN or infinite samples")
    steps = np.diff(t)
    if np.any(steps <= 0.0):
        raise ValueError("time must be strictly increasing")
    if np.max(np.abs(steps - steps.mean())) > 0.01 * steps.mean():
        raise ValueError("time must be uniformly spaced")
    return t, float(steps.mean())


def _coarse_frequency(y, dt):
    """Frequency (Hz) of the periodogram peak of the linearly detrended signal."""
    k = np.arange(y.size)
    resid = y - np.polyval(np.polyfit(k, y, 1), k)
    n_fft = 8 * int(2 ** math.ceil(math.log2(y.size)))
    power = np.abs(np.fft.rfft(resid * np.hanning(y.size), n_fft)) ** 2
    freq = np.fft.rfftfreq(n_fft, dt)
    duration = dt * (y.size - 1)
    power[freq < 1.0 / duration] = 0.0
    return float(freq[int(np.argmax(power))]) if power.max() > 0.0 else float("nan")


def _noise_sigma(y, dt, freq):
    """Robust white-noise level: residual of a local quintic smoother.

    The window spans a quarter period (at least 11 samples), where a
    quintic follows the oscillation to well under a percent of its
    amplitude, so the residual is noise; it is scaled for the part of the
    noise the smoother itself keeps.
    """
    window = max(11, int(0.25 / (freq * dt)) | 1)
    if window >= y.size:
        return 0.0
    resid = y - savgol_filter(y, window, 5, mode="interp")
    keep = 1.0 - savgol_coeffs(window, 5)[window // 2]
    mad = np.median(np.abs(resid - np.median(resid)))
    return float(1.4826 * mad / math.sqrt(keep))


def _half_cycle_extrema(y, t, dt, freq):
    """Alternating local extrema, refined by a parabola through the raw samples."""
    period = 1.0 / freq
    width = max(1, int(round(0.1 * period / dt)))
    smooth = uniform_filter1d(y, width, mode="nearest")
    distance = max(1, int(0.7 * period / dt))
    peaks = [(i, 1) for i in find_peaks(smooth, distance=distance)[0]]
    troughs = [(i, -1) for i in find_peaks(-smooth, distance=distance)[0]]
    merged = []
    for i, kind in sorted(peaks + troughs):
        if merged and merged[-1][1] == kind:
            if kind * smooth[i] > kind * smooth[merged[-1][0]]:
                merged[-1] = (i, kind)
            continue
        merged.append((i, kind))

    half = max(2, int(round(0.125 * period / dt)))
    times, values, kinds = [], [], []
    for i, kind in merged:
        lo, hi = max(0, i - half), min(y.size, i + half + 1)
        tv, yv = t[lo:hi] - t[i], y[lo:hi]
        value, when = y[i], t[i]
        if yv.size >= 5:
            a, b, c = np.polyfit(tv, yv, 2)
            if a * kind < 0.0 and abs(b / (2.0 * a)) <= 0.5 * (tv.max() - tv.min()):
                when = t[i] - b / (2.0 * a)
                value = c - b * b / (4.0 * a)
        times.append(when)
        values.append(value)
        kinds.append(kind)
    return np.array(times), np.array(values), np.array(kinds, dtype=float)


def _envelope(model, tau, amp0, rate):
    if model == "exponential":
        return amp0 * np.exp(-rate * tau)
    if model == "linear":
        return amp0 - rate * tau
    return amp0 / (1.0 + rate * tau)


def _fit_envelope(model, tau, values, kinds, start):
    def residual(p):
        return values - (p[0] + kinds * _envelope(model, tau, p[1], p[2]))

    lower = [-np.inf, 0.0, 0.0 if model == "hyperbolic" else -np.inf]
    x0 = np.array(start, dtype=float)
    x0[2] = max(x0[2], 0.0) if model == "hyperbolic" else x0[2]
    sol = least_squares(residual, x0, bounds=(lower, np.inf), x_scale="jac", method="trf")
    return sol.x, float(np.sum(sol.fun**2))


def _start_values(tau, values, kinds):
    mids = 0.5 * (values[1:] + values[:-1])
    settle = float(np.median(mids))
    amp = np.maximum(np.abs(values - settle), 1e-12 * np.max(np.abs(values - settle)))
    starts = {}
    slope, icpt = np.polyfit(tau, np.log(amp), 1)
    starts["exponential"] = (settle, math.exp(icpt), -slope)
    slope, icpt = np.polyfit(tau, amp, 1)
    starts["linear"] = (settle, icpt, -slope)
    slope, icpt = np.polyfit(tau, 1.0 / amp, 1)
    icpt = max(icpt, 1e-12)
    starts["hyperbolic"] = (settle, 1.0 / icpt, max(slope / icpt, 0.0))
    return starts


def envelope_shape(signal, time):
    """Classify the decay envelope of an oscillation about a settling value.

    The half-cycle extremes ``e_k`` (signed, alternating maxima and minima,
    each refined by a parabola through the raw samples within an eighth of
    a period) are fitted, by nonlinear least squares, with
    ``e_k = x_s + sign_k A(t_k)`` for three envelope laws, each with three
    parameters (settling value ``x_s``, initial amplitude ``A0`` and a rate):

    - ``exponential`` (viscous): ``A = A0 exp(-lambda tau)``;
    - ``linear`` (Coulomb friction): ``A = A0 - r tau``;
    - ``hyperbolic`` (quadratic drag): ``A = A0 / (1 + c tau)``, i.e.
      ``dA/dt = -kappa A^2`` with ``kappa = c / A0``;

    with ``tau`` the time since the first extreme. The settling value is
    fitted, not assumed, because a Coulomb oscillation's half-cycles are
    centred alternately either side of where it finally sticks.

    Models are ranked by AIC, ``n ln(RSS/n) + 2k`` (equal k, so the
    ranking is by residual), and the confidence is the winner's Akaike
    weight ``exp(-dAIC/2) / sum exp(-dAIC_j/2)``: near 1 when the others
    fit clearly worse, near 1/3 when the decay is too weak (or the window
    too short) to tell the laws apart. Extremes are kept from the start
    until the first half-cycle swing smaller than ten times the noise level
    (robust residual of a local smoother), so a stuck or fully decayed tail
    does not feed noise into the fit.

    Parameters
    ----------
    signal : array_like, shape (n,)
        Free oscillation, no NaN.
    time : array_like, shape (n,)
        Uniformly spaced sample times (s).

    Returns
    -------
    dict
        ``shape`` (one of ``exponential``, ``linear``, ``hyperbolic``, or
        ``undetermined`` when fewer than 6 usable extremes are found),
        ``confidence`` (Akaike weight of the winner, None if undetermined),
        ``frequency_hz`` (from the extreme spacing), ``settling_value`` (the
        winner's), ``n_extrema``, ``extrema_time`` and ``extrema_value``
        (lists), and ``models``: for each law ``amplitude`` (A0), ``rss``,
        ``aic``, ``weight``, ``settling_value`` and its rate -
        exponential: ``decay_rate`` (lambda, 1/s) and ``log_decrement``
        (lambda times the period); linear: ``rate`` (r, signal unit/s) and
        ``decrement_per_cycle`` (r times the period; 4 mu g / w^2 for
        Coulomb friction); hyperbolic: ``c`` (1/s) and
        ``quadratic_coefficient`` (kappa, 1/(signal unit s); for
        ``x'' + c_d |x'| x' + w^2 x = 0`` first-order averaging gives
        ``kappa = 4 c_d w / (3 pi)``). Undefined values are None.
    """
    y = _signal_1d(signal)
    t, dt = _time_1d(time, y.size)
    if y.size < 16:
        raise ValueError(f"signal needs at least 16 samples, got {y.size}")
    result = {
        "shape": "undetermined",
        "confidence": None,
        "frequency_hz": None,
        "settling_value": None,
        "n_extrema": 0,
        "extrema_time": [],
        "extrema_value": [],
        "models": {},
    }
    freq = _coarse_frequency(y, dt)
    if not np.isfinite(freq) or freq <= 0.0:
        return result
    times, values, kinds = _half_cycle_extrema(y, t, dt, freq)
    if values.size >= 2:
        swings = np.abs(np.diff(values))
        floor = max(SWING_NOISE_FACTOR * _noise_sigma(y, dt, freq), 1e-9 * swings.max())
        small = np.flatnonzero(swings < floor)
        keep = small[0] + 1 if small.size else values.size
        times, values, kinds = times[:keep], values[:keep], kinds[:keep]
    result["n_extrema"] = int(values.size)
    result["extrema_time"] = [float(v) for v in times]
    result["extrema_value"] = [float(v) for v in values]
    if values.size < MIN_EXTREMA:
        return result

    period = 2.0 * float(np.mean(np.diff(times)))
    tau = times - times[0]
    starts = _start_values(tau, values, kinds)
    n = values.size
    scale = float(np.max(np.abs(np.diff(values))))
    fits = {}
    for model in ENVELOPE_MODELS:
        params, rss = _fit_envelope(model, tau, values, kinds, starts[model])
        rss = max(rss, n * (1e-9 * scale) ** 2)  # exact fits: avoid log(0)
        fits[model] = (params, rss, n * math.log(rss / n) + 2 * 3)
    best_aic = min(f[2] for f in fits.values())
    raw = {k: math.exp(-0.5 * (f[2] - best_aic)) for k, f in fits.items()}
    total = sum(raw.values())
    models = {}
    for model, (params, rss, aic) in fits.items():
        entry = {
            "amplitude": float(params[1]),
            "settling_value": float(params[0]),
            "rss": rss,
            "aic": aic,
            "weight": raw[model] / total,
        }
        rate = float(params[2])
        if model == "exponential":
            entry.update(decay_rate=rate, log_decrement=rate * period)
        elif model == "linear":
            entry.update(rate=rate, decrement_per_cycle=rate * period)
        else:
            kappa = rate / params[1] if params[1] > 0.0 else float("nan")
            entry.update(c=rate, quadratic_coefficient=kappa)
        models[model] = {k: _json(v) for k, v in entry.items()}
    shape = max(models, key=lambda k: models[k]["weight"])
    result.update(
        shape=shape,
        confidence=models[shape]["weight"],
        frequency_hz=_json(1.0 / period),
        settling_value=models[shape]["settling_value"],
        models=models,
    )
    return result


def _finite_run_after(time, signal, t_start):
    """Longest run of consecutive finite samples with time >= t_start."""
    t = np.asarray(time, dtype=float)
    y = np.asarray(signal, dtype=float)
    if t.ndim != 1 or y.ndim != 1 or t.shape != y.shape:
        raise ValueError(
            f"time and signal must be 1-D arrays of equal length, got {t.shape} and {y.shape}"
        )
    ok = np.isfinite(t) & np.isfinite(y) & (t >= t_start)
    if not ok.any():
        raise ValueError(f"no finite samples at or after t_start = {t_start} s")
    edges = np.diff(np.concatenate([[0], ok.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    longest = int(np.argmax(stops - starts))
    return t[starts[longest] : stops[longest]], y[starts[longest] : stops[longest]]


def free_decay(time, signal, t_start):
    """Frequency, damping and envelope law of a free oscillation after t_start.

    Parameters
    ----------
    time : array_like, shape (n,)
        Uniformly spaced sample times (s).
    signal : array_like, shape (n,)
        Any channel (for example ``bucket.pitch`` in rad); NaN allowed - the
        longest run of consecutive finite samples after ``t_start`` is used
        (no gap is filled).
    t_start : float
        Start of the free decay (s), e.g. 6.5 when the reels stop.

    Returns
    -------
    dict
        ``t_start``, ``t_end`` (s, the window actually used), ``n_samples``;
        from :func:`dominant_mode`: ``frequency_hz`` (damped), ``damping_ratio``
        (viscous equivalent), ``amplitude``; from :func:`envelope_shape`:
        ``shape``, ``confidence``, ``settling_value``, ``decay_rate`` (1/s),
        ``decrement_per_cycle`` (signal unit), ``quadratic_coefficient``
        (1/(signal unit s)) and the full ``envelope`` dictionary. Undefined
        values are None (JSON-ready).
    """
    t, y = _finite_run_after(time, signal, float(t_start))
    if y.size < 16:
        raise ValueError(
            f"only {y.size} consecutive finite samples after t_start = {t_start} s; need 16"
        )
    t, dt = _time_1d(t, y.size)
    freq, zeta, amp = dominant_mode(y, dt)
    env = envelope_shape(y, t)
    models = env["models"]

    def rate(model, key):
        return models[model][key] if model in models else None

    return {
        "t_start": float(t[0]),
        "t_end": float(t[-1]),
        "n_samples": int(y.size),
        "frequency_hz": _json(freq),
        "damping_ratio": _json(zeta),
        "amplitude": _json(amp),
        "shape": env["shape"],
        "confidence": env["confidence"],
        "settling_value": env["settling_value"],
        "decay_rate": rate("exponential", "decay_rate"),
        "decrement_per_cycle": rate("linear", "decrement_per_cycle"),
        "quadratic_coefficient": rate("hyperbolic", "quadratic_coefficient"),
        "envelope": env,
    }


def _json(x):
    x = float(x)
    return x if math.isfinite(x) else None
