"""Derivatives and smoothing of sampled signals (paper section 3.3).

Time is axis 0 everywhere; trailing axes are independent channels.

The paper differentiates positions and angles with second-order finite
differences and smooths with a 12-sample running average. How that average
is centred decides its lag, so both forms are offered:

* ``centred=True``: for a window ``w`` the output at sample ``i`` averages
  samples ``i - (w - 1) // 2 ... i + w // 2``. For the paper's ``w = 12``
  that is ``i - 5 ... i + 6``: the average is centred on ``i + 0.5``, so it
  is offset half a sample ahead of the input (a lag of -0.5 sample; zero
  for odd windows).
* ``centred=False``: the trailing (causal) average of ``i - w + 1 ... i``,
  which lags ``(w - 1) / 2`` samples: 5.5 samples (27.5 ms at 200 Hz) for 12.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

__all__ = [
    "finite_difference",
    "running_average",
    "body_rates",
    "Smoother",
    "RunningAverage",
    "SavitzkyGolay",
    "make_smoother",
]


def finite_difference(x, dt):
    """Second-order finite-difference derivative along axis 0.

    Central differences ``(x[i+1] - x[i-1]) / (2 dt)`` inside; the
    second-order one-sided forms ``(-3 x0 + 4 x1 - x2) / (2 dt)`` and its
    mirror at the ends. Exact for quadratics. A NaN sample makes the
    derivatives that use it NaN.

    Parameters
    ----------
    x : array_like, shape (frames, ...)
        Samples at a uniform step.
    dt : float
        Sample interval (s).

    Returns
    -------
    ndarray, same shape as ``x``
        Derivative (units of x per second).
    """
    x = np.asarray(x, dtype=float)
    if x.ndim == 0 or x.shape[0] < 3:
        raise ValueError("finite_difference needs at least 3 samples along axis 0")
    if not dt > 0:
        raise ValueError(f"dt must be positive, got {dt}")
    d = np.empty_like(x)
    d[1:-1] = (x[2:] - x[:-2]) / (2.0 * dt)
    d[0] = (-3.0 * x[0] + 4.0 * x[1] - x[2]) / (2.0 * dt)
    d[-1] = (3.0 * x[-1] - 4.0 * x[-2] + x[-3]) / (2.0 * dt)
    return d


def running_average(x, window=12, centred=True):
    """The paper's running average, with its alignment stated.

    Parameters
    ----------
    x : array_like, shape (frames, ...)
    window : int, optional
        Samples per average (the paper's 12).
    centred : bool, optional
        Centred window ``i - (window-1)//2 ... i + window//2`` (default) or
        trailing window ``i - window + 1 ... i``; see the module docstring for
        the lags.

    Returns
    -------
    ndarray, same shape as ``x``

    Notes
    -----
    Edges: near the ends the window is truncated to the samples that exist
    and the output is the mean of those (so the first outputs of the trailing
    average are means of samples ``0 ... i``). The lag there differs from
    the interior value.

    NaN: any NaN inside a sample's window makes that output NaN, so a gap
    grows by the window's reach rather than being papered over.
    """
    x = np.asarray(x, dtype=float)
    window = int(window)
    if window < 1:
        raise ValueError(f"window must be a positive integer, got {window}")
    if x.ndim == 0 or x.shape[0] == 0:
        raise ValueError("running_average needs at least one sample along axis 0")
    if centred:
        before, after = (window - 1) // 2, window // 2
    else:
        before, after = window - 1, 0
    pad = [(before, after)] + [(0, 0)] * (x.ndim - 1)
    padded = np.pad(x, pad, constant_values=0.0)
    present = np.pad(np.ones(x.shape[0]), (before, after), constant_values=0.0)
    # Sums of `window` neighbours directly (no running cumsum, so no drift).
    total = sliding_window_view(padded, window, axis=0).sum(axis=-1)
    count = sliding_window_view(present, window).sum(axis=-1)
    return total / count.reshape((-1,) + (1,) * (x.ndim - 1))


def body_rates(T, dt):
    """Body-frame angular velocity from a sequence of orientation matrices.

    ``T^T dT/dt = [omega_body]x`` for ``T = T_B->I``; ``dT/dt`` is taken by
    ``finite_difference`` (second order) and the skew part of the product
    gives ``p, q, r``.

    Parameters
    ----------
    T : array_like, shape (frames, 3, 3)
        Body-to-inertial matrices (columns are the body axes).
    dt : float
        Sample interval (s).

    Returns
    -------
    ndarray, shape (frames, 3)
        ``p, q, r`` (rad/s), body-frame components; NaN where a matrix used
        is NaN.
    """
    T = np.asarray(T, dtype=float)
    if T.ndim != 3 or T.shape[1:] != (3, 3):
        raise ValueError(f"T must have shape (frames, 3, 3), got {T.shape}")
    W = np.swapaxes(T, 1, 2) @ finite_difference(T, dt)
    return 0.5 * np.stack(
        [W[:, 2, 1] - W[:, 1, 2], W[:, 0, 2] - W[:, 2, 0], W[:, 1, 0] - W[:, 0, 1]], axis=-1
    )


class Smoother:
    """Interchangeable smoothing step: ``smoother(x, dt) -> smoothed x``.

    ``x`` has time on axis 0; ``dt`` is the sample interval (s), which a
    smoother may ignore.
    """

    name = "none"

    def __call__(self, x, dt):
        return np.asarray(x, dtype=float).copy()


class RunningAverage(Smoother):
    """The paper's running average (``running_average``)."""

    name = "running_average"

    def __init__(self, window=12, centred=True):
        self.window = int(window)
        self.centred = bool(centred)

    def __call__(self, x, dt):
        return running_average(x, self.window, self.centred)


class SavitzkyGolay(Smoother):
    """Savitzky-Golay smoothing (``scipy.signal.savgol_filter``, mode 'interp').

    Zero lag and exact for polynomials up to ``polyorder``; a NaN in the
    input makes the whole channel NaN, so fill gaps first.
    """

    name = "savgol"

    def __init__(self, window=13, polyorder=3):
        if int(window) <= int(polyorder):
            raise ValueError(f"savgol window ({window}) must exceed polyorder ({polyorder})")
        self.window = int(window)
        self.polyorder = int(polyorder)

    def __call__(self, x, dt):
        from scipy.signal import savgol_filter  # noqa: PLC0415

        x = np.asarray(x, dtype=float)
        if x.shape[0] < self.window:
            raise ValueError(f"savgol needs at least {self.window} samples, got {x.shape[0]}")
        return savgol_filter(x, self.window, self.polyorder, axis=0, mode="interp")


_SMOOTHERS = {"none": Smoother, "running_average": RunningAverage, "savgol": SavitzkyGolay}


def make_smoother(name, **options):
    """A smoother by name: ``'none'``, ``'running_average'`` or ``'savgol'``."""
    try:
        cls = _SMOOTHERS[name]
    except KeyError:
        raise ValueError(f"unknown smoother {name!r}; choose from {sorted(_SMOOTHERS)}") from None
    return cls(**options)
