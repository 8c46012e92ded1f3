"""Figure pages of the comparison report (Figs. 8-21, residuals, free decay).

Every page is a ``matplotlib.figure.Figure`` saved into an open
``PdfPages``; nothing touches pyplot's global state. A channel that one side
lacks is drawn for the other side with a visible "MISSING" note, never as a
silent empty plot.
"""

from __future__ import annotations

import math
import textwrap

import numpy as np
from matplotlib.figure import Figure

from ._compare import channel_kind
from ._paper import FIG21_CAPTION

__all__ = ["figure_pages", "free_decay_page", "discretization_page", "PLOT_UNITS", "ERROR_UNITS"]

DEG = 180.0 / math.pi
# Plotted values: (scale from SI, unit). Angles and rates in degrees (docs/conventions.md).
PLOT_UNITS = {
    "position": (1.0, "m"),
    "angle": (DEG, "deg"),
    "velocity": (1.0, "m/s"),
    "rate": (DEG, "deg/s"),
    "rope_length": (1.0, "m"),
}
# Errors and residuals: (scale from SI, unit).
ERROR_UNITS = {
    "position": (1000.0, "mm"),
    "angle": (DEG, "deg"),
    "velocity": (1.0, "m/s"),
    "rate": (DEG, "deg/s"),
    "rope_length": (1000.0, "mm"),
}
MEASURED_STYLE = {"color": "black", "linewidth": 1.1, "label": "Measured"}
PREDICTED_STYLE = {"color": "tab:red", "linewidth": 1.0, "linestyle": "--", "label": "Predicted"}
LEVEL_COLORS = {"low": "tab:blue", "baseline": "tab:red", "medium": "tab:green", "high": "tab:purple"}


def _series(table, channel):
    if channel not in table.columns:
        return None
    y = np.asarray(table[channel], float)
    return y if np.isfinite(y).any() else None


def _missing_reason(metrics, channel, side):
    entry = metrics["channels"].get(channel)
    if entry and entry["status"] == "missing":
        return entry["reason"]
    return f"no finite samples in the {side} table"


def _reels_line(ax, metrics):
    t = metrics["reels_stop"]["time"]
    if t is not None:
        ax.axvline(t, color="0.5", linestyle=":", linewidth=0.9)


def _metric_line(channel, entry):
    if entry is None or entry["status"] != "ok":
        return "not compared: " + ("no data" if entry is None else entry["reason"])
    scale, unit = ERROR_UNITS[channel_kind(channel)]
    rating = "-" if entry["iso_rating"] is None else f"{entry['iso_rating']:.2f}"
    iso = f"ISO {rating} ({entry['iso_grade']}{'' if entry['iso_applies'] else ', not counted'})"
    sg = "S&G M/P/C " + "/".join("-" if v is None else f"{v:.2f}" for v in
                                 (entry["sg_magnitude"], entry["sg_phase"], entry["sg_combined"]))
    theil = "-" if entry["theil_u"] is None else f"{entry['theil_u']:.3f}"
    return (
        f"RMS {entry['rms_error'] * scale:.3g} {unit} (tolerance {entry['rms_tolerance'] * scale:.3g} {unit}), "
        f"peak error {entry['peak_error'] * scale:.3g} {unit}; {iso}; {sg}; Theil U {theil}: "
        f"{entry['verdict'].upper()}"
    )


def _one_figure(fig, spec_main, spec_resid, time, meas, sim, metrics, label, channel, caption, ylabel):
    kind = channel_kind(channel)
    scale, _ = PLOT_UNITS[kind]
    escale, eunit = ERROR_UNITS[kind]
    ax = fig.add_subplot(spec_main)
    axr = fig.add_subplot(spec_resid, sharex=ax)
    m, s = _series(meas, channel), _series(sim, channel)
    notes = []
    if m is not None:
        ax.plot(time, m * scale, **MEASURED_STYLE)
    else:
        notes.append(f"Measured: MISSING ({_missing_reason(metrics, channel, 'measured')})")
    if s is not None:
        ax.plot(time, s * scale, **PREDICTED_STYLE)
    else:
        notes.append(f"Predicted: MISSING ({_missing_reason(metrics, channel, 'simulated')})")
    _reels_line(ax, metrics)
    if notes:
        ax.text(0.5, 0.5, "\n".join(notes), transform=ax.transAxes, ha="center", va="center",
                color="tab:red", fontsize=9, fontweight="bold")
    if m is not None or s is not None:
        ax.legend(loc="best")
    ax.set_xlim(time[0], time[-1])
    ax.set_ylabel(ylabel)
    ax.set_title("\n".join(textwrap.wrap(f"Fig. {label}. {caption}", 95)), fontsize=8.5, loc="left")
    ax.tick_params(labelbottom=False)

    entry = metrics["channels"].get(channel)
    if m is not None and s is not None:
        axr.plot(time, (s - m) * escale, color="tab:blue", linewidth=0.9)
        if entry and entry["status"] == "ok":
            tol = entry["rms_tolerance"] * escale
            axr.axhspan(-tol, tol, color="tab:green", alpha=0.12, linewidth=0)
        axr.axhline(0.0, color="0.3", linewidth=0.6)
    else:
        axr.text(0.5, 0.5, "no residual: one side is missing", transform=axr.transAxes,
                 ha="center", va="center", color="tab:red")
    _reels_line(axr, metrics)
    axr.set_ylabel(f"Predicted - measured ({eunit})", fontsize=6.5)
    axr.set_xlabel("Time (s)")
    axr.text(0.0, -0.62, _metric_line(channel, entry), transform=axr.transAxes, fontsize=6.5, va="top")


def figure_pages(pdf, time, meas, sim, metrics, page_size):
    """Figs. 8-20, two per page, each with its residual strip and metrics."""
    figures = metrics["preset"]["figures"]
    for k in range(0, len(figures), 2):
        fig = Figure(figsize=page_size)
        grid = fig.add_gridspec(5, 1, height_ratios=[3.0, 1.1, 0.9, 3.0, 1.1], hspace=0.12,
                                left=0.11, right=0.95, top=0.93, bottom=0.09)
        for j, spec in enumerate(figures[k : k + 2]):
            label, channel, caption, ylabel = spec
            _one_figure(fig, grid[3 * j], grid[3 * j + 1], time, meas, sim, metrics,
                        label, channel, caption, ylabel)
        fig.text(0.5, 0.965, "Measured vs predicted (dashed); green band = RMS tolerance; "
                 "dotted line = reels stop", ha="center", fontsize=7)
        pdf.savefig(fig)


# -- free decay ------------------------------------------------------------


def _envelope_curve(res, t):
    env = res.get("envelope") or {}
    shape = env.get("shape")
    if shape not in ("exponential", "linear", "hyperbolic") or not env.get("extrema_time"):
        return None
    model = env["models"][shape]
    tau = t - env["extrema_time"][0]
    a0 = model["amplitude"]
    if shape == "exponential":
        amp = a0 * np.exp(-model["decay_rate"] * tau)
    elif shape == "linear":
        amp = np.maximum(a0 - model["rate"] * tau, 0.0)
    else:
        amp = a0 / (1.0 + model["c"] * tau)
    return model["settling_value"], amp, tau >= 0.0


def _decay_panel(ax, time, meas, sim, metrics, channel):
    kind = channel_kind(channel)
    scale, unit = PLOT_UNITS[kind]
    t0 = metrics["reels_stop"]["time"]
    sel = time >= t0
    entry = metrics["free_decay"].get(channel, {})
    drawn = False
    for side, table, style in (("measured", meas, MEASURED_STYLE), ("simulated", sim, PREDICTED_STYLE)):
        y = _series(table, channel)
        res = entry.get(side) or {}
        if y is None or res.get("status") != "ok":
            continue
        drawn = True
        ax.plot(time[sel], y[sel] * scale, **style)
        env = res["envelope"]
        if env["extrema_time"]:
            ax.plot(env["extrema_time"], np.asarray(env["extrema_value"]) * scale, "o",
                    color=style["color"], markersize=2.5)
        curve = _envelope_curve(res, time[sel])
        if curve is not None:
            settle, amp, ok = curve
            for sign in (1.0, -1.0):
                ax.plot(time[sel][ok], (settle + sign * amp[ok]) * scale, color=style["color"],
                        linewidth=0.6, alpha=0.6)
    if not drawn:
        ax.text(0.5, 0.5, f"{channel}: MISSING on both sides", transform=ax.transAxes,
                ha="center", va="center", color="tab:red")
    else:
        ax.legend(loc="upper right")
    ax.set_title(f"Free decay of {channel} after the reels stop (dots: half-cycle extremes; thin: envelope)",
                 fontsize=8, loc="left")
    ax.set_ylabel(f"{channel.split('.')[1]} ({unit})")
    ax.set_xlabel("Time (s)")


def free_decay_page(pdf, time, meas, sim, metrics, page_size):
    """The swing after the reels stop of four channels, both sides, with envelopes."""
    if not metrics["free_decay"]:
        return
    fig = Figure(figsize=page_size)
    panels = metrics["preset"]["decay_panels"]
    grid = fig.add_gridspec(len(panels), 1, hspace=0.45, left=0.11, right=0.95, top=0.94, bottom=0.06)
    for i, channel in enumerate(panels):
        _decay_panel(fig.add_subplot(grid[i]), time, meas, sim, metrics, channel)
    pdf.savefig(fig)


# -- Fig. 21 ---------------------------------------------------------------


def _study_panel(ax, time, m, study, summary, metrics, channel, t_from=None):
    scale, unit = PLOT_UNITS[channel_kind(channel)]
    escale, eunit = ERROR_UNITS[channel_kind(channel)]
    if m is not None:
        ax.plot(time, m * scale, **MEASURED_STYLE)
    for level, run in study.items():
        if run.get("error"):
            continue
        rms = summary.get(level, {}).get("rms_error")
        rms_text = "" if rms is None else f" (RMS {rms * escale:.2f} {eunit})"
        ax.plot(np.asarray(run["table"]["time"], float), np.asarray(run["table"][channel], float) * scale,
                color=LEVEL_COLORS.get(level), linewidth=0.9, linestyle="--", label=f"Predicted, {level}{rms_text}")
    _reels_line(ax, metrics)
    ax.set_xlim(time[0] if t_from is None else t_from, time[-1])
    ax.set_xlabel("Time (s)")
    ax.set_ylabel(f"{channel} ({unit})")


def discretization_page(pdf, time, meas, study, metrics, page_size):
    """Fig. 21: the study's channel (the dragline's bucket pitch) at each discretization level against the
    measurement.

    The upper panel is the whole record like the paper's figure; the lower
    one zooms into the free swing after the reels stop, where the levels
    differ. A level whose integration failed is listed with its error.
    """
    channel = metrics["preset"]["study_channel"]
    scale, _ = PLOT_UNITS[channel_kind(channel)]
    escale, eunit = ERROR_UNITS[channel_kind(channel)]
    fig = Figure(figsize=page_size)
    grid = fig.add_gridspec(3, 1, height_ratios=[3.0, 2.2, 1.0], hspace=0.3,
                            left=0.11, right=0.95, top=0.93, bottom=0.05)
    summary = (metrics.get("discretization_study") or {}).get("levels", {})
    m = _series(meas, channel)
    ax = fig.add_subplot(grid[0])
    _study_panel(ax, time, m, study, summary, metrics, channel)
    ax.legend(loc="best")
    caption = FIG21_CAPTION if metrics["preset"]["name"] == "paper" else (
        f"Measured and predicted {channel} vs. time at each discretization level.")
    ax.set_title(f"Fig. {'21' if metrics['preset']['name'] == 'paper' else 'D'}. {caption}", fontsize=8.5, loc="left")
    if m is None:
        ax.text(0.5, 0.5, f"Measured {channel}: MISSING", transform=ax.transAxes, ha="center",
                color="tab:red", fontsize=9, fontweight="bold")
    t_stop = metrics["reels_stop"]["time"]
    if t_stop is not None and t_stop < time[-1]:
        axz = fig.add_subplot(grid[1])
        _study_panel(axz, time, m, study, summary, metrics, channel, t_from=max(time[0], t_stop - 0.5))
        sel = time >= t_stop - 0.5
        values = [m[sel] * scale] if m is not None else []
        values += [np.interp(time[sel], np.asarray(r["table"]["time"], float),
                             np.asarray(r["table"][channel], float)) * scale
                   for r in study.values() if not r.get("error")]
        finite = np.concatenate(values)[np.isfinite(np.concatenate(values))] if values else np.array([])
        if finite.size:
            pad = 0.05 * (np.ptp(finite) or 1.0)
            axz.set_ylim(finite.min() - pad, finite.max() + pad)
        axz.set_title("Detail: the free swing after the reels stop", fontsize=8, loc="left")
    lines = [f"{'Level':<10}{'States':<9}{channel + ' RMS error':<25}Status"]
    for level, run in study.items():
        info = summary.get(level, {})
        if run.get("error"):
            lines.append(f"{level:<10}{'-':<9}{'-':<25}FAILED: {run['error']}")
            continue
        rms = info.get("rms_error")
        lines.append(f"{level:<10}{str(run.get('n_state', '-')):<9}"
                     f"{'-' if rms is None else f'{rms * escale:.2f} {eunit}':<25}ok")
    y = 0.15
    fig.text(0.06, y + 0.015, "RMS error against the measurement over the common time base; "
             "states = the model's state count.", fontsize=7.5)
    for line in lines:
        for piece in textwrap.wrap(line, 120, subsequent_indent=" " * 44) or [""]:
            fig.text(0.06, y, piece, va="top", family="monospace", fontsize=7)
            y -= 0.012
    pdf.savefig(fig)
