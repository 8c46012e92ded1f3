"""The JSON ``calibration`` block: what the updating moved, how sure it is, and what it could not explain."""

from __future__ import annotations

import math

import numpy as np

from .._compare import channel_kind
from ._differences import FD_FRACTION, WIDE_STEP, _smooth
from ._objective import BOUND_TOLERANCES, OFFSET_PRIOR
from ._scale import REFERENCE

__all__ = ["OFFSET_FINDING", "DEGENERATE", "IDENTIFIABLE_RATIO"]

# Offsets left after updating beyond these are a finding: no parameter
# within tolerance explains them (the old 10 mm / 2 deg gate, now applied
# after updating).
OFFSET_FINDING = {"position": 0.010, "angle": math.radians(2.0), "rope_length": 0.010}
# Two parameters whose posterior correlation exceeds this are reported as a
# pair the recording can move only together.
DEGENERATE = 0.9
# Identifiable: the recording shrinks the prior standard deviation at least this much.
IDENTIFIABLE_RATIO = 0.5


def _value_or_none(parameter, coordinate):
    """The parameter's value at a coordinate, None where it overflows."""
    try:
        value = parameter.value(float(coordinate))
    except OverflowError:
        return None
    return value if math.isfinite(value) else None


def _spread_block(params, coords, active, spread):
    """The JSON of ``_heterogeneity.between_trials``: per active parameter, each trial's own estimate and
    standard deviation (the parameter's units), the between-trial standard deviation and Cochran's Q."""
    out = {"trials": spread["trials"], "parameters": {}}
    for j, i in enumerate(active):
        p = params[i]
        if p.of_a_trial:
            continue
        values = [_value_or_none(p, x) for x in spread["estimates"][:, j]]
        scale = (lambda v, sd: v * sd) if p.scale == "log" else (lambda v, sd: sd)
        out["parameters"][p.name] = {
            # None: a trial alone that sets the parameter beyond what a float holds (ln p past 700)
            "trial_estimates": values,
            "trial_at_bound": [bool(b) for b in spread["at_bound"][:, j]],
            "trial_uncertainties": [None if v is None else scale(v, float(sd))
                                    for v, sd in zip(values, spread["sd"][:, j])],
            "between_trials_sd": scale(p.value(float(coords[i])), float(spread["tau"][j])),
            "cochran_q": float(spread["q"][j]),
            "degrees_of_freedom": len(spread["trials"]) - 1,
        }
    return out


def _calibration_block(params, coords, cov, information, strength, offsets, ctx, history, failed, rough=None,
                       fd_widening=None):
    rough = rough or {}
    entries = []
    for i, p in enumerate(params):
        sd = float(math.sqrt(max(cov[i, i], 0.0)))
        x = float(coords[i])
        estimate = p.value(x)
        if p.scale == "log":
            unc = estimate * sd
        else:
            unc = sd
        entries.append({
            "parameter": p.name,
            "kind": p.kind,
            "unit": p.unit,
            "nominal": p.nominal,
            "estimate": estimate,
            "uncertainty": unc,
            "tolerance": p.tolerance if p.scale == "linear" else p.nominal * (math.exp(p.tolerance) - 1.0),
            "coordinate": x,
            "coordinate_sd": sd,
            "coordinate_scale": "ln p" if p.scale == "log" else p.unit,
            "shift_in_tolerances": x / p.tolerance,
            "posterior_over_prior": float(information[i]),
            "sensitivity": float(strength[i]),
            # a rough parameter is never active: its posterior is its prior
            "identifiable": bool(information[i] < IDENTIFIABLE_RATIO and p.name not in failed),
            # null where unchecked, or where the two ways cancel exactly (inf: not smooth)
            "one_sided_disagreement": rough[i] if math.isfinite(rough.get(i, math.inf)) else None,
            "difference_step": FD_FRACTION * (1.0 if fd_widening is None else float(fd_widening[i])),
            "smooth": _smooth(rough, i),
            "at_bound": bool(abs(x) >= BOUND_TOLERANCES * p.tolerance * (1 - 1e-6)),
            "description": p.describe(x),
        })
    sd = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
    corr = cov / np.outer(sd, sd)
    pairs = [{"parameters": [params[i].name, params[j].name], "correlation": float(corr[i, j])}
             for i in range(len(params)) for j in range(i + 1, len(params))
             if abs(corr[i, j]) > DEGENERATE and information[i] < 1.0 and information[j] < 1.0]
    left = {}
    findings = []
    scale = ctx.get("scale", REFERENCE)
    for j, ch in enumerate(ctx["channels"]):
        kind = channel_kind(ch)
        left[ch] = float(offsets[j])
        lim = scale.floor(OFFSET_FINDING, kind)
        if lim is not None and abs(offsets[j]) > lim:
            findings.append(ch)
    return {
        "parameters": entries,
        "degenerate_pairs": pairs,
        "offsets_left": left,
        "unexplained_offsets": findings,
        "iterations": history,
        # Only the gain rule says the next step has nothing to gain: stopped by the cap or by trf's own tolerances
        # with more to gain, the estimates are where the fit stopped, not a minimum (docs/diagnosis.md, section 3).
        "converged": history[-1].get("stopped_by") in ("gain", "nothing to fit") if history else None,
        "failed_sensitivities": failed,
        "method": ("bounded trust-region least squares (scipy trf) over the rig file's tolerances, with them as "
                   f"priors: sensitivities by finite differences over {FD_FRACTION:g} tolerance ({WIDE_STEP:g} times "
                   "that where the differences either way disagree, the parameter held where they disagree at both); "
                   "per-channel offsets (prior "
                   f"{scale.floor(OFFSET_PRIOR, 'position') * 1000:.3g} mm, "
                   f"{math.degrees(OFFSET_PRIOR['angle']):g} deg) and the "
                   "clock shift fitted jointly; identifiable when the data at least halve the prior spread"),
    }
