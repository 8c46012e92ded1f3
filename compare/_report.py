"""The comparison report: a deterministic multi-page PDF.

Page order: summary (verdicts against the stated tolerances and the paper's
peak table beside ours), every channel's metrics, the paper's Figs. 8-20 as
measured versus predicted with residuals, the free-decay analysis, and
Fig. 21 (the discretization study) when one was run. The figure pages are
drawn by ``_report_figures``; this module writes the text pages and the file.

Determinism: one fixed font family (DejaVu Sans, shipped with matplotlib),
TrueType embedding, no creation or modification date, no pyplot state, so
identical inputs give a byte-identical file.
"""

from __future__ import annotations

import math
from contextlib import contextmanager

import matplotlib
from matplotlib.backends.backend_pdf import PdfPages
from matplotlib.figure import Figure
from matplotlib.ticker import NullFormatter

from ..capture import atomic_file
from ._align import align_tables
from ._compare import channel_kind
from ._machine_figure import draw_machine
from ._report_figures import ERROR_UNITS, discretization_page, figure_pages, free_decay_page

__all__ = ["write_report", "report_pdf", "REPORT_STYLE"]

PAGE_SIZE = (8.27, 11.69)  # A4 portrait, inches
REPORT_STYLE = {
    "font.family": "DejaVu Sans",
    "font.monospace": ["DejaVu Sans Mono"],
    "font.size": 8,
    "pdf.fonttype": 42,
    "pdf.compression": 6,
    "axes.unicode_minus": False,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "lines.linewidth": 1.0,
    "legend.fontsize": 7,
}
# Text pages: DejaVu Sans Mono is 0.6 em wide; the text block is 7.3 in wide.
TEXT_WIDTH_IN = 7.3
TEXT_TOP, TEXT_BOTTOM = 0.91, 0.04


@contextmanager
def report_pdf(path, title):
    """A deterministic PDF (no dates, ``REPORT_STYLE``) written under a temporary name, renamed when complete."""
    with atomic_file(path) as tmp, matplotlib.rc_context(REPORT_STYLE):
        with PdfPages(tmp, metadata={"CreationDate": None, "ModDate": None, "Title": title}) as pdf:
            yield pdf


def fmt(value, spec=".3g", none="-"):
    """Format a number for a table; ``none`` for None or NaN."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return none
    return format(value, spec)


def error_text(channel, value, spec=".3g"):
    """An error of a channel in its table unit, e.g. ``'12.3 mm'``."""
    scale, unit = ERROR_UNITS[channel_kind(channel)]
    return "-" if value is None else f"{format(value * scale, spec)} {unit}"


def _wrap(line, width):
    """Split a long line at spaces; continuation lines are indented."""
    out = []
    while len(line) > width:
        cut = line.rfind(" ", 0, width)
        cut = width if cut <= 4 else cut
        out.append(line[:cut])
        line = "    " + line[cut:].lstrip()
    out.append(line)
    return out


def text_pages(pdf, title, lines, size=7.5):
    """Monospace pages of text lines (wrapped), continued over as many pages as needed."""
    width = int(TEXT_WIDTH_IN * 72.0 / (0.6 * size))
    step = 1.4 * size / 72.0 / PAGE_SIZE[1]
    lines = [piece for line in lines for piece in _wrap(line, width)]
    per_page = int((TEXT_TOP - TEXT_BOTTOM) / step)
    for k in range(0, max(1, len(lines)), per_page):
        fig = Figure(figsize=PAGE_SIZE)
        fig.text(0.06, 0.95, title if k == 0 else f"{title} (continued)", fontsize=12,
                 fontweight="bold", va="top")
        y = TEXT_TOP
        for line in lines[k : k + per_page]:
            fig.text(0.06, y, line, family="monospace", fontsize=size, va="top")
            y -= step
        pdf.savefig(fig)


def _seconds(offset):
    """A signed offset to 0.1 ms; one that rounds to zero prints +0.0000, not -0.0000."""
    return f"{round(offset, 4) + 0.0:+.4f}"


def _offset_lines(metrics):
    off = metrics["time_offset"]
    base = metrics["time_base"]
    lines = [
        f"Common time base: {base['start']:.3f} to {base['end']:.3f} s on the simulation clock, "
        f"{base['n_samples']} samples at {1000 * base['step']:.2f} ms.",
    ]
    if off["estimated"]:
        ropes = ", ".join(
            f"{ch.split('_')[0]} {1000 * r['residual_rms']:.1f} mm rms / bias {1000 * r['bias']:+.1f} mm"
            for ch, r in off["ropes"].items()
        )
        lines.append(
            f"Time offset (measured clock - simulation clock): estimated {_seconds(off['offset'])} s "
            f"from {' and '.join(off['channels'])} (search {off['search_range'][0]:+.2f} to "
            f"{off['search_range'][1]:+.2f} s)."
        )
        lines.append(
            f"  Rope-length mismatch after the shift {fmt(off['cost'])}, without it {fmt(off['cost_at_zero'])} "
            f"(normalised); residual {ropes}."
        )
        if off["at_search_edge"]:
            lines.append("  WARNING: the best offset lies at the edge of the search range; it may be wrong.")
    else:
        lines.append(f"Time offset: not estimated ({off['reason']}).")
    lines.append(f"Offset applied: {_seconds(off['applied'])} s ({off['source']}).")
    reels = metrics["reels_stop"]
    if reels["time"] is None:
        lines.append(f"Reels stop: unknown ({reels['method']}); free decay not analysed.")
    else:
        lines.append(f"Reels stop: {reels['time']:.2f} s ({reels['method']}); free decay analysed after it.")
        if reels.get("reason"):
            lines.append(f"  {reels['reason']}.")
    return lines


def _peak_lines(metrics):
    lines = [
        "Peak table (paper section 4, dig maneuver): peak = signed extreme, value @ time",
        f"{'Quantity':<32}{'This measurement':<22}{'This prediction':<22}{'Paper measured':<20}{'Paper predicted':<20}",
    ]
    for row in metrics["peaks"]:
        unit = row["unit"]
        label = f"{row['quantity']} {row['channel'].split('.')[1]} ({unit})"

        def cell(entry, width):
            if entry is None:
                return f"{'missing':<{width}}"
            return f"{entry['value']:+.3f} @ {entry['time']:.2f} s".ljust(width)

        lines.append(
            f"{label:<32}{cell(row['measured'], 22)}{cell(row['simulated'], 22)}"
            f"{cell(row['paper_measured'], 20)}{cell(row['paper_predicted'], 20)}"
        )
    note = metrics["pitch_rate"]
    diff = note["max_difference"]
    if diff.get("measured") is None and diff.get("simulated") is None:
        compare_text = "could not be computed (roll, yaw, p, q or r missing)"
    else:
        compare_text = (f"differs from it by at most {fmt(diff.get('measured'))} rad/s in the measurement and "
                        f"{fmt(diff.get('simulated'))} rad/s in the prediction")
    lines.append(f"Pitch rate is the {note['definition']}; the Euler pitch rate {note['euler_pitch_rate']} {compare_text}.")
    sb = metrics["spreader_bar_x_offset"]
    lines.append(
        f"Spreader bar x, mean predicted - measured: {fmt(None if sb['mean_difference'] is None else 1000 * sb['mean_difference'], '+.1f')} mm "
        f"(the paper: a consistent offset of about {1000 * sb['paper']:.0f} mm)."
    )
    lines.append(
        "Signs follow docs/conventions.md (K points down: vz > 0 is downward). The paper does not state its plots' "
        "sign convention; its numbers are as printed."
    )
    return lines


def _verdict_row(label, channel, entry):
    if entry is None or entry["status"] != "ok":
        reason = "not compared" if entry is None else entry["reason"]
        return f"{label:<5}{channel:<21}MISSING: {reason}"
    iso = f"{fmt(entry['iso_rating'], '.2f')} ({entry['iso_grade']})"
    if not entry["iso_applies"]:
        iso += "*"
    return (
        f"{label:<5}{channel:<21}{error_text(channel, entry['rms_error']):<13}"
        f"{error_text(channel, entry['rms_tolerance'], '.3g'):<12}{iso:<19}"
        f"{fmt(entry['sg_combined'], '.3f'):<8}{fmt(entry['theil_u'], '.3f'):<8}{entry['verdict'].upper()}"
    )


def _summary_lines(metrics, sources):
    s = metrics["summary"]
    lines = []
    if sources:
        lines.append("   ".join(f"{k.capitalize()}: {v}" for k, v in sources.items()))
    lines += _offset_lines(metrics)
    lines += [
        "",
        f"Verdict: {s['n_pass']} of {s['n_channels']} channels within tolerance, "
        f"{s['n_fail']} outside, {s['n_missing']} missing.",
        "",
    ]
    if "peaks" in metrics:
        lines += _peak_lines(metrics)
    paper = metrics["preset"]["name"] == "paper"
    lines += ["", f"Per-channel verdict for the {'paper' + chr(39) + 's' if paper else 'report' + chr(39) + 's'} "
              "figures (all channels on the next page)",
              f"{'Fig':<5}{'Channel':<21}{'RMS error':<13}{'Tolerance':<12}{'ISO rating':<19}"
              f"{'S&G C':<8}{'Theil U':<8}Verdict"]
    for label, channel, _, _ in metrics["preset"]["figures"]:
        lines.append(_verdict_row(label, channel, metrics["channels"].get(channel)))
    lines += [
        "* ISO rating shown but not counted: the measured channel moves less than "
        f"{metrics['iso_grades']['applies_when_range_exceeds_tolerances']:g} tolerances.",
        "",
        "Tolerances (a channel passes when RMS error <= tolerance and, where it counts, ISO rating >= "
        f"{metrics['iso_grades']['verdict_needs']:.2f})",
    ]
    for kind, tol in metrics["tolerances"].items():
        scale, unit = ERROR_UNITS[kind]
        lines.append(f"  {kind:<12} RMS <= {tol['rms'] * scale:.3g} {unit}: {tol['reason']}")
    lines.append(
        "  ISO/TS 18571 grades: excellent > 0.94, good > 0.80, fair > 0.58, poor otherwise."
    )
    return lines


def _channel_lines(metrics):
    head = (
        f"{'Channel':<21}{'RMS error':<15}{'Peak error':<15}{'Meas. peak @ t':<18}{'Pred. peak @ t':<18}"
        f"{'S&G M':<7}{'S&G P':<6}{'S&G C':<6}{'ISO':<5}{'Theil':<6}Verdict"
    )
    lines = ["Errors in mm, deg, m/s or deg/s; peaks in SI units (m, rad, m/s, rad/s) @ time (s); "
             "S&G = Sprague-Geers magnitude, phase, combined; ISO = ISO/TS 18571 rating; Theil = Theil's U.", "", head]
    for channel, e in metrics["channels"].items():
        if e["status"] != "ok":
            lines.append(f"{channel:<21}MISSING: {e['reason']}")
            continue
        mp = f"{e['measured_peak']:+.3g} @ {e['measured_peak_time']:.2f}"
        sp = f"{e['simulated_peak']:+.3g} @ {e['simulated_peak_time']:.2f}"
        lines.append(
            f"{channel:<21}{error_text(channel, e['rms_error']):<15}{error_text(channel, e['peak_error']):<15}"
            f"{mp:<18}{sp:<18}{fmt(e['sg_magnitude'], '+.3f'):<7}{fmt(e['sg_phase'], '.3f'):<6}"
            f"{fmt(e['sg_combined'], '.3f'):<6}{fmt(e['iso_rating'], '.2f'):<5}{fmt(e['theil_u'], '.3f'):<6}"
            f"{e['verdict'].upper()}"
        )
    return lines


def _side_cells(channel, res):
    if res is None or res.get("status") != "ok":
        return f"MISSING: {'no data' if res is None else res['reason']}"
    kind = channel_kind(channel)
    escale, eunit = ERROR_UNITS[kind]
    shape = res["shape"]
    if res["confidence"] is not None:
        shape = f"{shape} ({res['confidence']:.2f})"
    else:
        shape = f"{shape} ({res['envelope']['n_extrema']} extrema)"
    f = "-" if res["frequency_hz"] is None else f"{res['frequency_hz']:.3f}"
    z = "-" if res["damping_ratio"] is None else f"{res['damping_ratio']:.3f}"
    a = "-" if res["amplitude"] is None else f"{res['amplitude'] * escale:.3g} {eunit}"
    return f"{f:<9}{z:<8}{a:<13}{shape}"


def _difference_text(diff):
    if diff is None:
        return "no comparison"
    if diff["simulated_frequency_hz"] is None:
        return f"model has no mode within 25 % of {diff['reference_frequency_hz']:.3f} Hz"
    ratio = diff["damping_ratio_ratio"]
    text = (f"model's mode at {diff['simulated_frequency_hz']:.3f} Hz ({100 * diff['frequency_shift']:+.1f} %), "
            f"zeta {diff['simulated_damping_ratio']:.3f}")
    if ratio is not None:
        text += f"; measured damps {ratio:.2f}x as fast"
    if not diff["same_dominant_mode"]:
        text += "; the model's dominant mode is another one"
    return text


def _decay_lines(metrics):
    reels = metrics["reels_stop"]
    decay = metrics["free_decay"]
    if not decay:
        return [f"Free decay not analysed: {reels.get('reason', reels['method'])}."]
    lines = [
        f"Free decay after the reels stop at {reels['time']:.2f} s ({reels['method']}).",
        "Dominant mode by matrix pencil (damped frequency f, viscous-equivalent damping ratio zeta, amplitude at the",
        "window's start); envelope law of the half-cycle extremes by AIC with its Akaike weight: exponential = viscous,",
        "linear = Coulomb friction, hyperbolic = quadratic drag (docs/diagnosis.md). 'undetermined' = fewer than 6 extremes.",
        "",
        f"{'Channel':<21}{'Side':<11}{'f (Hz)':<9}{'zeta':<8}{'Amplitude':<13}Envelope (confidence)",
    ]
    for channel in metrics["preset"]["decay_channels"]:
        entry = decay.get(channel)
        if entry is None:
            continue
        lines.append(f"{channel:<21}{'measured':<11}{_side_cells(channel, entry['measured'])}")
        lines.append(f"{'':<21}{'predicted':<11}{_side_cells(channel, entry['simulated'])}")
        lines.append(f"{'':<21}{'':<11}{_difference_text(entry['difference'])}")
    lines += ["", "In numbers:"] + [f"  {line}" for line in _decay_summary_lines(metrics["free_decay_summary"])]
    return lines


def _decay_summary_lines(summary):
    n, same = summary["n_compared"], summary["n_same_mode"]
    if n == 0:
        return ["no channel had a free decay on both sides to compare."]
    lines = [f"{n} channels with a free decay on both sides; in {same} the model's dominant mode is the measured one."]
    ratio, shift = summary["damping_ratio_ratio"], summary["frequency_shift"]
    if ratio is not None:
        lines.append(
            f"Measured damping ratio / predicted, same mode: median {ratio['median']:.2f} "
            f"(range {ratio['min']:.2f} to {ratio['max']:.2f}); above 1 = the measurement settles faster."
        )
    if shift is not None:
        lines.append(
            f"Predicted frequency shift against the measured, same mode: median {100 * shift['median']:+.1f} % "
            f"(range {100 * shift['min']:+.1f} to {100 * shift['max']:+.1f} %)."
        )
    for side in ("measured", "simulated"):
        counts = ", ".join(f"{k} {v}" for k, v in summary[f"{side}_shapes"].items())
        lines.append(f"Envelope laws, {'predicted' if side == 'simulated' else side}: {counts}.")
    lines.append(
        "Reading (docs/diagnosis.md): more measured damping at the same frequency is damping the model lacks, and the "
        "measured envelope law names its kind; a frequency shift without extra decay points at added inertia."
    )
    return lines


def _glance_page(pdf, title, measured, simulated, metrics, machine):
    """The first page: the verdict, the machine, every channel's error against its tolerance, the worst plotted."""
    s = metrics["summary"]
    fig = Figure(figsize=PAGE_SIZE)
    fig.suptitle(title, fontsize=12)
    grid = fig.add_gridspec(3, 2, height_ratios=[0.35, 1.6, 1.0], hspace=0.45, wspace=0.45, left=0.1, right=0.96,
                            top=0.93, bottom=0.06)
    words = fig.add_subplot(grid[0, :])
    words.axis("off")
    words.text(0, 1, f"{s['n_pass']} of {s['n_channels']} channels within tolerance, {s['n_fail']} outside, "
                     f"{s['n_missing']} missing.", va="top", fontsize=11, weight="bold")
    ok = {c: e for c, e in metrics["channels"].items() if e["status"] == "ok" and e["rms_tolerance"]}
    ratio = {c: e["rms_error"] / e["rms_tolerance"] for c, e in ok.items()}
    worst = max(ratio, key=ratio.get) if ratio else None
    if worst is not None:
        words.text(0, 0.35, f"Worst: {worst}, RMS error {error_text(worst, ok[worst]['rms_error'])} against a "
                            f"tolerance of {error_text(worst, ok[worst]['rms_tolerance'])}.", va="top", fontsize=9)
    if machine is not None:
        draw_machine(fig.add_subplot(grid[1, 0]), machine)
    ax = fig.add_subplot(grid[1, 1])
    order = sorted(ratio, key=ratio.get)
    ax.barh(range(len(order)), [max(ratio[c], 1e-3) for c in order],
            color=["tab:green" if ok[c]["verdict"] == "pass" else "tab:red" for c in order])
    ax.axvline(1.0, color="k", lw=0.8, ls="--")
    ax.set_xscale("log")
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_yticks(range(len(order)))
    ax.set_yticklabels(order, fontsize=max(3.5, min(7.0, 300.0 / max(len(order), 1))))
    ax.set_xlabel("RMS error / tolerance (green: pass, red: fail)")
    ax.set_title("Every channel against its tolerance", fontsize=9)
    if worst is not None:
        ax = fig.add_subplot(grid[2, :])
        time, meas, sim = align_tables(measured, simulated, metrics["time_offset"]["applied"], channels=[worst])
        scale, unit = ERROR_UNITS[channel_kind(worst)]
        ax.plot(time, scale * meas[worst].to_numpy(), color="black", lw=1.0, label="measured")
        ax.plot(time, scale * sim[worst].to_numpy(), color="tab:red", lw=1.0, ls="--", label="predicted")
        ax.set_xlabel("time (s, simulation clock)")
        ax.set_ylabel(f"{worst} ({unit})")
        ax.set_title(f"The worst channel, {worst}", fontsize=9)
        ax.legend(loc="upper right", fontsize=7)
    pdf.savefig(fig)


def write_report(path, measured, simulated, metrics, study=None, sources=None, machine=None):
    """Write the comparison report as a multi-page PDF, atomically.

    Parameters
    ----------
    path : str or path-like
        Output PDF. Written to a temporary name, then renamed.
    measured, simulated : pandas.DataFrame
        The tables given to :func:`compare_tables`.
    metrics : dict
        Its result (the time offset and channel verdicts are taken from it).
    study : dict, optional
        :func:`discretization_study` output: adds Fig. 21.
    sources : dict, optional
        Labels printed on the summary page, e.g. ``{"measured": "a.csv"}``.
    machine : MachinePicture, optional
        The machine, drawn on the first page (``machine_picture``).
    """
    figure_channels = [ch for _, ch, _, _ in metrics["preset"]["figures"]]
    figure_channels += [row["channel"] for row in metrics.get("peaks", ())]
    channels = list(dict.fromkeys(
        c for c in figure_channels + list(metrics["free_decay"])
        if c in measured.columns or c in simulated.columns
    ))
    time, meas, sim = align_tables(measured, simulated, metrics["time_offset"]["applied"], channels=channels)
    title = ("Dragline validation" if metrics["preset"]["name"] == "paper"
             else f"Validation of {metrics['preset']['machine']}")
    with report_pdf(path, "dragline comparison report") as pdf:
        _glance_page(pdf, f"{title} at a glance", measured, simulated, metrics, machine)
        text_pages(pdf, f"{title}: measured vs predicted motion", _summary_lines(metrics, sources))
        text_pages(pdf, "All channels", _channel_lines(metrics), size=6.5)
        figure_pages(pdf, time, meas, sim, metrics, PAGE_SIZE)
        text_pages(pdf, "Free decay after the reels stop", _decay_lines(metrics), size=6.5)
        free_decay_page(pdf, time, meas, sim, metrics, PAGE_SIZE)
        if study is not None:
            discretization_page(pdf, time, meas, study, metrics, PAGE_SIZE)
