"""The diagnosis PDF: verdict, hypotheses, before/after overlays, fit profiles, mismatch map.

Deterministic like the comparison report (``_report``): one font family,
no dates, no pyplot state, so the same diagnosis gives the same bytes.
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import NullFormatter
from scipy.stats import chi2

import textwrap

from ...simulate import MECHANISMS
from .._compare import channel_kind
from .._machine_figure import draw_machine
from ._locate import low_pass
from .._report import PAGE_SIZE, report_pdf, text_pages

__all__ = ["write_report_pdf"]

DEG = 180.0 / math.pi
PLOT = {"position": (1.0, "m"), "angle": (DEG, "deg"), "rope_length": (1.0, "m")}
RESID = {"position": (1000.0, "mm"), "angle": (DEG, "deg"), "rope_length": (1000.0, "mm")}
TEXT_SIZE = 7.0


def _f(x, spec=".3g"):
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def _summary_lines(doc):
    lines = [f"Verdict: {doc['verdict']}", ""]
    lines += ["Reason: " + doc["reason"], ""]
    src = doc.get("source", {})
    if src:
        lines.append(f"Input: {src.get('input', '-')} ({src.get('kind', '-')}); maneuver: {src.get('maneuver', '-')}")
        if src.get("calibration"):
            lines.append(f"Calibration: {src['calibration']}")
    al = doc["alignment"]
    lines.append(f"Clock offset {al['time_offset']:+.4f} s (rope lengths), reels stop at {al['reels_stop']:.2f} s "
                 f"({al['reels_stop_method']})")
    for rope, r in al["ropes"].items():
        lines.append(f"  {rope}: {1000 * r['residual_rms']:.1f} mm RMS about a {1000 * r['bias']:+.1f} mm bias "
                     "(recording vs nominal simulation)")
    if doc.get("trials"):
        lines.append(f"{len(doc['trials'])} trials fitted together (shared rig and mechanism, each its own offsets): "
                     + ", ".join(f"{t['name']} ({t['rows']} samples)" for t in doc["trials"]))
    if doc.get("held_out"):
        lines += ["", "Held-out trials, never fitted: RMS residual in their own noise units (offsets removed):"]
        for e in doc["held_out"]:
            cells = "  ".join(f"{k} {v:.3f}" if v is not None else f"{k} failed" for k, v in e["rms_noise"].items())
            lines.append(f"  {e['trial']:<20}{cells}")
    loo = doc.get("leave_one_out")
    if loo:
        lines += ["", f"Leave one trial out ({len(loo['splits'])} splits): verdicts "
                      + ", ".join(f"{k} {v}" for k, v in loo["verdicts"].items())]
        for key, what in (("updated_better_share", "updated better than nominal on the trial left out"),
                          ("named_better_share", "named better than updated")):
            if loo[key] is not None:
                lines.append(f"  {what}: {100 * loo[key]:.0f} % of splits")
        for name, p in loo["parameters"].items():
            lines.append(f"  {name}: {p['min']:.4g} .. {p['max']:.4g} (sd {p['sd']:.2g}; stated "
                         f"+-{p['median_uncertainty']:.2g})")
    nt = doc["null_test"]
    lines += ["", f"Null test: held-out improvement threshold {nt['threshold']:.1f} (chi2 units): "
                  f"{100 * nt['quantile']:.0f}th percentile of {nt['n_surrogates']} noise surrogates "
                  f"({_f(nt['surrogate_quantile'])}), at least {nt['min_improvement']:g}", ""]
    lines.append("Hypotheses, best first (held-out RMS in units of the measurement noise; 1 = noise):")
    lines.append(f"{'mechanism':<22}{'parameter':>22}{'+-68%':>20}{'rms before':>11}{'after':>8}"
                 f"{'improve':>11}{'score':>9}  sig  bound")
    for h in doc["hypotheses"]:
        p = h["main_parameter"]
        u = h["uncertainty"]
        band = "-" if not u.get("interval_68") else f"{_f(u['interval_68'][0])}..{_f(u['interval_68'][1])}"
        lines.append(f"{h['name']:<22}{p + ' = ' + _f(h['parameters'][p], '.4g'):>22}{band:>20}"
                     f"{h['rms_before']:>11.3f}{h['rms_after']:>8.3f}{h['improvement']:>11.1f}{h['score']:>9.2f}"
                     f"  {'yes' if h['significant'] else 'no ':<4} {h['at_bound'] or '-'}")
    for s in doc.get("skipped", []):
        lines.append(f"{s['name']:<22} skipped: {s['reason']}")
    lines += ["", "Where the nominal model misses (structured RMS over its threshold; >1 is beyond noise):"]
    if not doc["mismatch"]:
        lines.append("  nowhere: the residual is measurement noise")
    for e in doc["mismatch"][:20]:
        scale, unit = RESID[channel_kind(e["channel"])]
        lines.append(f"  {e['channel']:<22}{e['window']:<12}{e['t_start']:6.2f}-{e['t_end']:5.2f} s  score "
                     f"{e['score']:6.2f}  rms {scale * e['rms']:7.3f} {unit:<3} at {_f(e['frequency_hz'])} Hz")
    after = doc["mismatch_after"]
    lines += ["", f"Left after {after['model']}: {len(after['entries'])} channel windows beyond noise"]
    for e in after["entries"][:10]:
        lines.append(f"  {e['channel']:<22}{e['window']:<12} score {e['score']:6.2f}")
    fd = doc["free_decay"]
    lines += ["", f"Free decay {fd['t_start']:.2f}-{fd['t_end']:.2f} s: frequency (Hz) / damping ratio / envelope"]
    lines.append(f"{'channel':<22}{'measured':>26}{'nominal':>26}{'fitted (' + str(fd['fitted_model']) + ')':>34}")
    for ch, e in fd["channels"].items():
        cells = []
        for side in ("measured", "nominal", "fitted"):
            r = e.get(side)
            cells.append("-" if r is None or r.get("status") != "ok" else
                         f"{_f(r['frequency_hz'])} / {_f(r['damping_ratio'])} / {r['shape'][:5]}")
        lines.append(f"{ch:<22}{cells[0]:>26}{cells[1]:>26}{cells[2]:>34}")
    met = doc.get("metrics", {})
    if met.get("channels"):
        lines += ["", f"Free-decay metrics, nominal -> {met['model'] or 'no fitted model'} "
                      "(RMS, peak error; Sprague-Geers C; ISO/TS 18571 rating):"]
        for ch, e in met["channels"].items():
            scale, unit = RESID[channel_kind(ch)] if channel_kind(ch) in RESID else (1000.0, "mm")
            b, a = e.get("before", {}), e.get("after", {})

            def cell(x, key, k=scale):
                v = x.get(key)
                return "-" if v is None else f"{k * v:.3g}"

            lines.append(f"  {ch:<20} rms {cell(b, 'rms_error'):>7} -> {cell(a, 'rms_error'):<7} {unit:<3} "
                         f"peak {cell(b, 'peak_error'):>7} -> {cell(a, 'peak_error'):<7} "
                         f"SG-C {cell(b, 'sg_combined', 1):>6} -> {cell(a, 'sg_combined', 1):<6} "
                         f"ISO {cell(b, 'iso_rating', 1):>5} -> {cell(a, 'iso_rating', 1)}")
    lines += _calibration_lines(doc)
    lines += ["", f"{doc['timing']['simulations']} simulations (discretization "
                  f"{doc['settings']['discretization']})"]
    return lines


def verdict_words(doc):
    """The verdict as a sentence a person reads first."""
    verdict = doc["verdict"]
    if verdict == "none":
        return "The model fits the recording within its noise: no missing physics is needed."
    if verdict == "unexplained":
        return "The model misses the recording, and no candidate mechanism explains it."
    best = next((h for h in doc["hypotheses"] if h["name"] == verdict), None)
    law, _, sites = verdict.partition("@")
    what = law + (f" at {' or '.join(sites.split('+'))}" if sites else "")
    lead = (f"The rig file's value is wrong: {what}" if MECHANISMS.get(law) is not None and MECHANISMS[law].rig_array
            else f"The model leaves out {what}")
    if best is None:
        return f"{lead}."
    p = best["main_parameter"]
    u = best["uncertainty"].get("interval_68")
    band = f" (68 %: {_f(u[0])} to {_f(u[1])})" if u else ""
    return (f"{lead}: {p} = {_f(best['parameters'][p], '.3g')}{band}; held-out RMS "
            f"{best['rms_before']:.2f} -> {best['rms_after']:.2f} times the noise.")


def _glance_page(pdf, diag):
    """The first page: the verdict in words, the machine, the worst channel before and after, the candidates."""
    doc = diag.doc
    fig = Figure(figsize=PAGE_SIZE)
    name = diag.machine.name if diag.machine is not None else "the rig"
    fig.suptitle(f"Diagnosis of {name}", fontsize=12)
    grid = fig.add_gridspec(3, 2, height_ratios=[0.5, 1.3, 1.2], hspace=0.45, wspace=0.3, left=0.09, right=0.96,
                            top=0.93, bottom=0.06)
    words = fig.add_subplot(grid[0, :])
    words.axis("off")
    words.text(0, 1, "\n".join(textwrap.wrap(verdict_words(doc), 85)), va="top", fontsize=10, weight="bold")
    words.text(0, 0.35, "\n".join(textwrap.wrap("Why: " + doc["reason"], 120)[:5]), va="top", fontsize=7)
    if diag.machine is not None:
        sites = doc["verdict"].partition("@")[2]
        draw_machine(fig.add_subplot(grid[1, 0]), diag.machine, sites=sites.split("+") if sites else ())
    _candidate_bars(fig.add_subplot(grid[1, 1]), doc)
    _worst_channel(fig.add_subplot(grid[2, :]), diag)
    pdf.savefig(fig)


def _candidate_bars(ax, doc):
    hyps = doc["hypotheses"]
    threshold = doc["null_test"]["threshold"]
    if not hyps:
        ax.text(0.5, 0.5, "no candidate was fitted", ha="center", va="center")
        ax.axis("off")
        return
    gains = [max(h["improvement"], 1e-3) for h in hyps]
    colours = ["tab:green" if h["significant"] else "0.6" for h in hyps]
    ax.barh(range(len(hyps)), gains, color=colours)
    ax.set_xscale("log")
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.axvline(max(threshold, 1e-3), color="tab:red", lw=1.0, ls="--", label=f"threshold {threshold:.3g}")
    ax.set_yticks(range(len(hyps)))
    ax.set_yticklabels([h["name"] for h in hyps], fontsize=7)
    ax.invert_yaxis()
    ax.set_xlabel("held-out improvement (chi2; green: significant)")
    ax.set_title("Candidates against the noise threshold", fontsize=9)
    ax.legend(loc="lower right", fontsize=7)


def _worst_channel(ax, diag):
    doc = diag.doc
    worst = next((e["channel"] for e in doc["mismatch"] if e["channel"] in diag.channels), diag.channels[0])
    j = diag.channels.index(worst)
    ps, pu = PLOT[channel_kind(worst)]
    best = doc["free_decay"]["fitted_model"]
    fitted = diag.fitted.get(best)
    t = diag.time
    ax.plot(t, ps * diag.measured[:, j], color="0.55", lw=0.6, label="measured")
    ax.plot(t, ps * diag.nominal[:, j], color="tab:red", ls="--", lw=1.0, label="nominal model")
    if fitted is not None:
        ax.plot(t, ps * fitted[:, j], color="tab:blue", lw=1.0, label=f"with {best}")
    def rms(model):
        return float(np.sqrt(np.nanmean((diag.measured[:, j] - model[:, j]) ** 2)))

    rs, ru = RESID[channel_kind(worst)]
    after = f" -> {rs * rms(fitted):.3g} {ru} with {best}" if fitted is not None else ""
    ax.set_title(f"Worst channel, {worst}: RMS error {rs * rms(diag.nominal):.3g} {ru} (nominal){after}", fontsize=9)
    ax.axvline(doc["alignment"]["reels_stop"], color="k", lw=0.6, ls=":")
    ax.set_xlabel("time (s, simulation clock); dotted: the maneuver stops")
    ax.set_ylabel(f"{worst} ({pu})")
    ax.legend(loc="upper right", ncol=3, fontsize=7)


def _disagreement_lines(cal):
    """Why a shared parameter the trials each see is still not identifiable: they disagree on it.

    The trials' own estimates differing beyond their spreads (Cochran's Q
    above its 95 % point: chance alone would exceed it one time in twenty)
    widen the shared estimate's spread by theirs; where the parameter is
    then not identifiable, the lab is told the trials' values, since what
    differs between them (the rig, or physics the model lacks) is the
    finding, not the noise.
    """
    spread = (cal.get("between_trials") or {}).get("parameters", {})
    lines = []
    for e in cal.get("parameters", []):
        s = spread.get(e["parameter"])
        if e["identifiable"] or not s or s["cochran_q"] <= chi2.ppf(0.95, s["degrees_of_freedom"]):
            continue
        held = s.get("trial_at_bound") or [False] * len(s["trial_estimates"])
        each = ", ".join(_f(v, ".4g") + (" (at its bound)" if b else "") for v, b in zip(s["trial_estimates"], held))
        lines.append(f"  the trials disagree on {e['parameter']}: each alone {each} {e['unit']} (Cochran's Q "
                     f"{s['cochran_q']:.3g} on {s['degrees_of_freedom']} degrees of freedom): its spread is "
                     "widened by theirs - the rig or the physics differs between the trials, not the noise")
    return lines


def _calibration_lines(doc):
    cal = doc.get("calibration") or {}
    lines = ["", "Model updating within the rig's tolerances (shift in tolerances; identifiable = the recording "
                 "at least halves the prior spread):"]
    if not cal.get("parameters"):
        lines.append(f"  none: {cal.get('method', 'no tolerances')}")
    for e in cal.get("parameters", []):
        lines.append(f"  {e['parameter']:<36} nominal {_f(e['nominal'], '.4g'):>9} -> {_f(e['estimate'], '.4g'):>9} "
                     f"+- {_f(e['uncertainty'], '.2g'):>7} {e['unit']:<4} ({e['shift_in_tolerances']:+.2f} tol) "
                     f"{'identifiable' if e['identifiable'] else 'not identifiable'}"
                     + (" (its response is not smooth: differences either way disagree by "
                        f"{_f(e['one_sided_disagreement'], '.2g')})" if e.get("smooth") is False else ""))
    for pair in cal.get("degenerate_pairs", []):
        lines.append(f"  moved only together: {pair['parameters'][0]} and {pair['parameters'][1]} "
                     f"(correlation {pair['correlation']:+.2f})")
    lines += _disagreement_lines(cal)
    for combo in cal.get("unresolved_combinations", []):
        seen = ", ".join(f"{name} ({w:+.2f})" for name, w in combo["parameters"].items())
        lines.append(f"  seen only in a combination: {seen} - the recording does not fix them along it "
                     f"(its information there {combo['information']:.2g} in tolerance units); measuring one decides "
                     "the others")
    if cal.get("unexplained_offsets"):
        lines.append("  offsets no parameter explains: " + ", ".join(cal["unexplained_offsets"]))
    if cal.get("converged") is False:
        last = cal["iterations"][-1]
        own = "evaluation count" if last.get("stopped_by") == "evaluations" else "tolerances"
        how = (f"at its cap of {last['jacobians']} Jacobians" if last.get("stopped_by") == "cap"
               else f"on the trust region's own {own}")
        gain = last.get("predicted_gain")
        ahead = (f" with a next step predicted to gain {gain:.3g} chi2 (its stop asks less than "
                 f"{last['least_gain']:.3g})" if gain is not None else "")
        lines.append(f"  not converged: the fit stopped {how}{ahead}: the estimates are where it stopped, "
                     "not a minimum")
    me = doc.get("model_error") or {}
    for name in ("discretization", "time_step"):
        e = me.get(name)
        if not e or e.get("status") != "ok":
            continue
        worst = max(e["channels"].items(), key=lambda kv: kv[1]["rms_noise"])
        lines.append(f"Model error, {name} ({' vs '.join(e['compared'])}): chi2 weight {e['chi2']:.3g}; largest on "
                     f"{worst[0]}, {worst[1]['rms_noise']:.2f} x noise RMS")
    return lines


def _overlay_pages(pdf, diag):
    doc = diag.doc
    best = doc["free_decay"]["fitted_model"]
    fitted = diag.fitted.get(best)
    chans = [c for c in diag.overlay_channels if c in diag.channels] or list(diag.channels)
    t = diag.time
    dt = float(t[1] - t[0])
    lowpass_s = doc["settings"]["lowpass_s"]
    width = max(3, int(round(lowpass_s / dt)) | 1)
    t_stop = doc["alignment"]["reels_stop"]
    for k in range(0, len(chans), 3):
        fig = Figure(figsize=PAGE_SIZE)
        fig.suptitle(f"Before/after: nominal model, updated model and {best or 'no fitted mechanism'}", fontsize=11)
        grid = fig.add_gridspec(6, 1, height_ratios=[2, 1] * 3, hspace=0.45, left=0.1, right=0.96, top=0.94,
                                bottom=0.05)
        for i, ch in enumerate(chans[k : k + 3]):
            j = diag.channels.index(ch)
            kind = channel_kind(ch)
            ps, pu = PLOT[kind]
            rs, ru = RESID[kind]
            ax = fig.add_subplot(grid[2 * i])
            ax.plot(t, ps * diag.measured[:, j], color="0.55", lw=0.6, label="measured")
            ax.plot(t, ps * diag.nominal[:, j], color="tab:red", ls="--", lw=1.0, label="nominal")
            if diag.updated is not None:
                ax.plot(t, ps * diag.updated[:, j], color="tab:green", ls="-.", lw=1.0, label="updated")
            if fitted is not None:
                ax.plot(t, ps * fitted[:, j], color="tab:blue", lw=1.0, label=best)
            ax.axvline(t_stop, color="k", lw=0.6, ls=":")
            ax.set_ylabel(f"{ch} ({pu})")
            ax.legend(loc="upper right", ncol=4)
            ax2 = fig.add_subplot(grid[2 * i + 1], sharex=ax)
            before = low_pass(diag.measured[:, j] - diag.nominal[:, j], width)
            ax2.plot(t, rs * before, color="tab:red", lw=0.9, label="measured - nominal")
            if diag.updated is not None:
                mid = low_pass(diag.measured[:, j] - diag.updated[:, j], width)
                ax2.plot(t, rs * mid, color="tab:green", lw=0.9, label="measured - updated")
            if fitted is not None:
                after = low_pass(diag.measured[:, j] - fitted[:, j], width)
                ax2.plot(t, rs * after, color="tab:blue", lw=0.9, label=f"measured - {best}")
            thr = doc["channels"][ch]["structure_threshold"]
            for sgn in (-1, 1):
                ax2.axhline(sgn * rs * thr, color="0.4", lw=0.5, ls=":")
            ax2.axvline(t_stop, color="k", lw=0.6, ls=":")
            ax2.set_ylabel(f"residual ({ru})")
            ax2.legend(loc="upper left", fontsize=6)
        ax2.set_xlabel("time (s, simulation clock); dotted: reels stop; residuals low-passed over "
                       f"{lowpass_s:.3g} s, dotted band: structure threshold")
        pdf.savefig(fig)


HELD_OUT_STYLE = {"nominal": ("tab:red", "--"), "updated": ("tab:green", "-."), "named": ("tab:blue", "-")}


def draw_held_out(fig, held, entry, most=3):
    """A held-out trial measured against each model's prediction, each channel's mean removed (as the RMS is)."""
    rms = entry["rms_noise"]
    fig.suptitle(f"Held-out trial {held.name}, never fitted: predicted by each model (each channel's mean removed)",
                 fontsize=10)
    chans = held.channels[:most]
    axes = fig.subplots(len(chans), 1, sharex=True, squeeze=False)[:, 0]
    for ax, ch in zip(axes, chans):
        j = held.channels.index(ch)
        scale, unit = PLOT[channel_kind(ch)]
        measured = held.measured[:, j]
        ok = np.isfinite(measured)
        ax.plot(held.time, scale * (measured - np.nanmean(measured)), color="0.55", lw=0.6, label="measured")
        for label, sim in held.predicted.items():
            color, ls = HELD_OUT_STYLE[label]
            name = held.named if label == "named" else label
            ax.plot(held.time, scale * (sim[:, j] - np.mean(sim[ok, j])), color=color, ls=ls, lw=1.0,
                    label=f"{name} ({rms[label]:.3g} x noise)" if rms.get(label) is not None else name)
        ax.set_ylabel(f"{ch} ({unit})")
        ax.legend(loc="upper right", fontsize=6, ncol=2)
    axes[-1].set_xlabel("time (s, simulation clock); legend: RMS residual over the trial in its noise units")


def _held_out_pages(pdf, diag):
    for held, entry in zip(diag.held_out, diag.doc.get("held_out", [])):
        fig = Figure(figsize=PAGE_SIZE)
        draw_held_out(fig, held, entry)
        pdf.savefig(fig)


def _profile_page(pdf, doc):
    hyps = [h for h in doc["hypotheses"] if h["profile"]]
    if not hyps:
        return
    fig = Figure(figsize=PAGE_SIZE)
    fig.suptitle("Fit profiles: chi2(p) - chi2(nominal) over each candidate's searched range", fontsize=11)
    n = len(hyps)
    for i, h in enumerate(hyps):
        ax = fig.add_subplot(n, 1, i + 1)
        nominal = h["rms_before"]  # held-out, only for the title
        v = np.array([p["value"] for p in h["profile"]])
        c = np.array([p["chi2"] for p in h["profile"]])
        base = h.get("chi2_nominal")
        y = c - (base if base is not None else c.max())
        ax.semilogx(v, y, "o-", ms=3, color="tab:blue")
        # symlog: the optimum's dip and the steep rise beyond it on one axis
        ax.set_yscale("symlog", linthresh=max(h["threshold"], 1.0))
        ax.axhline(-h["threshold"], color="0.4", lw=0.6, ls=":")
        p = h["parameters"][h["main_parameter"]]
        if p:
            ax.axvline(p, color="tab:red", lw=0.8)
        u = h["uncertainty"].get("interval_68")
        if u:
            ax.axvspan(u[0], u[1], color="tab:red", alpha=0.15)
        ax.set_title(f"{h['name']}: {h['main_parameter']} = {_f(p, '.4g')}; held-out RMS {nominal:.3f} -> "
                     f"{h['rms_after']:.3f} noise units; score {h['score']:.2f}", fontsize=8)
        ax.set_ylabel("delta chi2 (dotted: -threshold)")
    ax.set_xlabel("main parameter (docs/interfaces.md units)")
    fig.subplots_adjust(hspace=0.6, top=0.93, bottom=0.06)
    pdf.savefig(fig)


def _map_page(pdf, diag):
    doc = diag.doc
    windows = [w["window"] for w in doc["windows"]]
    fig = Figure(figsize=PAGE_SIZE)
    fig.suptitle("Mismatch map: structured residual RMS over threshold (>1: beyond noise)", fontsize=11)
    for i, (key, title) in enumerate((("before", "nominal model"), ("after", doc["mismatch_after"]["model"]))):
        entries = diag.located.get(key, [])
        grid = np.full((len(diag.channels), len(windows)), np.nan)
        for e in entries:
            if e["window"] in windows:
                grid[diag.channels.index(e["channel"]), windows.index(e["window"])] = e["score"]
        ax = fig.add_subplot(2, 1, i + 1)
        im = ax.imshow(np.log10(np.maximum(grid, 1e-2)), aspect="auto", cmap="viridis", vmin=-1, vmax=1.5)
        for (r, c), val in np.ndenumerate(grid):
            if np.isfinite(val):
                ax.text(c, r, f"{val:.2g}", ha="center", va="center", fontsize=6,
                        color="white" if val < 3 else "black")
        ax.set_xticks(range(len(windows)))
        ax.set_xticklabels(windows, fontsize=7)
        ax.set_yticks(range(len(diag.channels)))
        ax.set_yticklabels(diag.channels, fontsize=7)
        ax.set_title(title, fontsize=9)
        ax.grid(False)
        fig.colorbar(im, ax=ax, label="log10 score")
    pdf.savefig(fig)


def write_report_pdf(path, diag):
    """Write the diagnosis report of a ``Diagnosis`` atomically.

    Pages: the verdict at a glance (in words, the machine, the worst
    channel before and after, the candidates against their threshold),
    summary (verdict, hypotheses with uncertainty, mismatch, free
    decay), before/after overlays of the key channels with low-passed
    residuals, each held-out trial against each model's prediction, each
    candidate's fit profile, the mismatch map before and after.
    """
    with report_pdf(path, "dragline diagnosis") as pdf:
        _glance_page(pdf, diag)
        text_pages(pdf, "Diagnosis: what physics does the model leave out?", _summary_lines(diag.doc),
                    size=TEXT_SIZE)
        _overlay_pages(pdf, diag)
        _held_out_pages(pdf, diag)
        _profile_page(pdf, diag.doc)
        _map_page(pdf, diag)
