"""The diagnosis as a sequence of steps over one ``DiagnosisState`` (``_state``).

``STEPS`` runs in order (docs/diagnosis.md states the method):

1. ``align_recording``: the nominal run, the recording's clock tied to the
   maneuver by the rope lengths, the channels and their noise;
2. ``locate_nominal``: where the nominal model as given misses;
3. ``update_rig``: the model's own numerical error, then the rig's
   uncertain parameters updated within their tolerances;
4. ``locate_updated``: what the updated model still misses;
5. ``fit_mechanisms``: each candidate fitted on top of the updated model;
6. ``refit_jointly``: the leading candidates refitted with the parameters;
7. ``test_against_noise``: the threshold noise and the model's error set;
   ``refit_rivals``: the lead's close rivals refitted jointly too;
   ``split_joined_sites``: a lead acting at several sites, and the laws
   alike to it, fitted at each site alone (``_sites``);
8. ``score_hypotheses``: each candidate's held-out evidence;
9. ``locate_after``: what the best significant candidate leaves;
10. ``judge_offsets``: constant offsets no parameter explains;
11. ``decide_verdict``: the rules of ``_decide``;
12. ``test_second_mechanism``: the others on top of a named one;
13. ``predict_held_out``: trials the fit never saw, predicted (``_predict``).

Each step returns a new state (``dataclasses.replace``) and leaves its
input as it was.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ...simulate import make_mechanism
from .._compare import channel_kind
from ._align_recording import align_recording
from ._band import band_improvement, significance
from ._calibration_block import OFFSET_FINDING
from ._confounding import marginal_uncertainty, nuisance_correlation, parameter_span_share
from ._decide import DIFFERENT_RIG, alike_laws, decide, leftover_share, model_error_share, offsets_too_far
from ._hypotheses import (
    REFINE_XATOL,
    affordable_range,
    autocorrelation_time,
    candidate_list,
    fit_candidates,
    score_candidate,
    signature_match,
    simulate_channels,
    unavailable_reason,
)
from ._lead import lead_tests
from ._locate import locate_mismatch
from ._model_error import finer_discretization, mark_model_error, model_error
from ._null import null_threshold
from ._predict import held_out_entry
from ._second_round import second_round
from ._sites import drop_law_twins, join_alike_sites, screen_sites, sets_to_split
from ._state import NullTest, _note
from ._summary import significant_updates, stated_uncertainty, structure_energy
from ._trials import first_maneuver
from ._updating import joint_refit, resume_update, rig_alone_channels, update_model

__all__ = ["STEPS", "OFFSET_LIMIT", "DIFFERENT_RIG", "SECOND_EXCESS_SHARE", "SPAN_REFIT"]

# Constant offsets beyond these mean the geometry or calibration differs (the dragline's; a machine's own at
# its scale, ``_scale``).
OFFSET_LIMIT = {"position": 0.010, "angle": math.radians(2.0)}
# A second mechanism must explain at least this share of the chi2 the named
# model leaves above noise (see ``test_second_mechanism``). Calibrated from
# below on the trusted-verdict records (``bench decisions``): none of their
# 120 cases, one mechanism or none hidden in each, shows a second from 0.385
# up; from above on the two-mechanism records (``bench discovery --realism
# --pairs``, seed 103): every hidden second is named below 0.455.
SECOND_EXCESS_SHARE = 0.4
# A candidate (not the lead) whose signature a parameter change reproduces
# to this share is refitted jointly with the parameters too (``refit_jointly``).
SPAN_REFIT = 0.7


def locate_nominal(state):
    """Where the nominal model, as the user gave it, misses."""
    rec = state.recording
    evaluation = state.plain_problem.evaluate(state.nominal_sim)
    residual = state.plain_problem.residual(state.nominal_sim, evaluation["nuisance"])
    located = locate_mismatch(rec.time, residual, rec.channels, rec.noise, rec.windows, rec.scale)
    return replace(state, r_nominal=residual, nominal_nuisance=evaluation["nuisance"], located_nominal=located)


def update_rig(state):
    """The model's own numerical error, then the rig's parameters updated within their tolerances."""
    problem, ctx, workers = state.plain_problem, state.nominal_ctx, state.workers
    note = state.note
    _note(state, "estimating the model's own numerical error (finer discretization, half time step)")
    directions, block = model_error(problem, ctx, state.nominal_sim, workers=workers)
    if not ctx["parameters"]:
        return replace(state, problem=problem.with_regressors(directions, bounds=directions.amplitude_bounds()),
                       base_sim=state.nominal_sim,
                       error_directions=directions, model_error_block=block, model_error_sims=2)
    _note(state, f"updating {len(ctx['parameters'])} rig parameters within their tolerances")
    update = update_model(problem, ctx, state.nominal_sim, directions, workers=workers, progress=note)
    # The finer model's difference depends on the parameters (a few percent
    # on a frequency moves its phase drift): estimated again at the updated
    # rig, and updating resumed with it (on a recording simulated at the
    # next finer level, chi2 fell from 1.5 to 1.04 times the noise).
    _note(state, "estimating the model's own numerical error again at the updated rig")
    directions, block = model_error(
        problem, dict(ctx, rig=update["rig"], maneuver=update["maneuver"], initial_state=update["initial_state"]),
        update["sim"], workers=workers)
    block["rig"] = "updated"
    update = update_model(problem, ctx, state.nominal_sim, directions, workers=workers, progress=note, start=update)
    return _with_update(state, update, directions, block, model_error_sims=4)


def _with_update(state, update, directions, block, model_error_sims):
    """The state with ``update`` as the model the mechanisms are fitted on: its linearised parameter freedom
    (prior centred on the nominal rig) and the model's own error as regressors."""
    problem, ctx = state.plain_problem, state.nominal_ctx
    tol = np.array([p.tolerance for p in ctx["parameters"]])
    updated_problem = problem.with_regressors(
        [*update["sensitivities"], *directions],
        prior_precision=np.r_[1.0 / tol**2, np.zeros(len(directions))],
        prior_mean=np.r_[-update["coords"], np.zeros(len(directions))], shift_center=update["shift"],
        bounds=np.vstack([np.tile([-np.inf, np.inf], (len(update["sensitivities"]), 1)),
                          directions.amplitude_bounds()]))
    return replace(state, problem=updated_problem,
                   ctx=dict(ctx, rig=update["rig"], maneuver=update["maneuver"],
                            initial_state=update["initial_state"]),
                   base_sim=update["sim"], update=update, error_directions=directions, model_error_block=block,
                   model_error_sims=model_error_sims)


def locate_updated(state):
    """What the updated model still misses beyond its own numerical error."""
    rec = state.recording
    evaluation = state.problem.evaluate(state.base_sim)
    residual = state.problem.residual(state.base_sim, evaluation["nuisance"])
    # A mismatch the finer model also shows is the model's own error, not missing physics.
    located = mark_model_error(locate_mismatch(rec.time, residual, rec.channels, rec.noise, rec.windows, rec.scale),
                               rec.time, state.error_directions, rec.channels, scale=rec.scale)
    structured = [e for e in located if e["significant"] and not e["within_model_error"]]
    return replace(state, base_eval=evaluation, r_base=residual, located=located, structured_before=structured,
                   structured_after=structured, located_after=located)


def fit_mechanisms(state):
    """Each runnable candidate fitted through the simulator on top of the updated model."""
    cands = candidate_list(state.candidate_names, state.rig)
    # A law at each of its sites: the sites the recording cannot tell apart become one candidate (``_sites``).
    cands, site_groups, signatures = join_alike_sites(state.problem, state.ctx, cands, state.base_sim,
                                                      workers=state.workers)
    cands, twins = drop_law_twins(cands, state.ctx)
    if twins:
        _note(state, f"{', '.join(twins)}: the law everywhere, tried under its own name")
    sensitivities = state.update["sensitivities"] if state.update is not None else []
    cands, screen, screened_out = screen_sites(state.problem, cands, signatures, state.r_base, sensitivities)
    if screen:
        _note(state, "sites screened (linearized improvement): " + ", ".join(
            f"{e['name']} {e['improvement']:.3g}{'' if e['fitted'] else ' (not fitted)'}" for e in screen))
    runnable, skipped = _runnable(state, cands)
    _note(state, f"fitting {len(runnable)} candidate mechanisms ({', '.join(c['name'] for c in runnable)})")
    points = fit_candidates(state.problem, state.ctx, runnable, state.base_sim, workers=state.workers,
                            progress=state.note)
    scored = {c["name"]: score_candidate(state.problem, c, points[c["name"]]) for c in runnable}
    return replace(state, candidates=cands, runnable=runnable, skipped=skipped, points=points, scored=scored,
                   site_groups=site_groups, site_screen=screen, screened_out=screened_out, site_split=[])


def _runnable(state, candidates):
    """``candidates`` that can run on this rig and maneuver, each with its affordable range (``searched``), and
    the others with why not."""
    runnable, skipped = [], []
    maneuver = first_maneuver(state.nominal_ctx)
    for c in candidates:
        why = unavailable_reason(c, state.rig, maneuver, state.discretization)
        if why:
            skipped.append({"name": c["name"], "reason": why})
            continue
        c["searched"] = affordable_range(c, state.rig, maneuver, state.discretization)
        runnable.append(c)
    return runnable, skipped


def refit_jointly(state):
    """The lead candidate (and the one a parameter change imitates best) refitted with the rig parameters.

    Updating ran before any mechanism, so the parameters took up what they
    could of a real one (a sheave's inertia read as cluster mass): on top of
    the updated rig its score is too low. The lead among the candidates that
    could be named (off the bounds of their range) is refitted jointly with
    the parameters: one at a bound would spend the budget on a dead end.
    Rivals the lead may not be told apart from are refitted after the null
    test (``refit_rivals``). Laws at sites are refitted whatever their
    score, and with them the same laws everywhere (``joint_refit_list``).
    """
    update, problem = state.update, state.problem
    if update is None or not state.scored:
        return state
    eligible = _eligible(state)
    # The candidate a parameter change imitates best lost most to updating:
    # refitted jointly as well, when it is not the lead.
    span = {c["name"]: parameter_span_share(problem, state.scored[c["name"]]["sim"] - state.base_sim, update)
            for c in eligible}
    if span:
        _note(state, "share of each candidate's signature a parameter change reproduces: "
              + ", ".join(f"{n} {v:.2f}" for n, v in span.items()))
    return _refit(replace(state, joints={}), joint_refit_list(state.runnable, state.scored, eligible, span))


def joint_refit_list(runnable, scored, eligible, span):
    """The candidates ``refit_jointly`` refits: the lead among ``eligible`` (best first), the one a parameter
    change imitates most (``span`` at least ``SPAN_REFIT``), every law at a site, and each law everywhere whose
    sites are among them; none at a bound of its range or fitted at zero."""
    refit = eligible[:1]
    imitated = [c for c in eligible[1:] if span[c["name"]] >= SPAN_REFIT]
    if imitated:
        refit.append(max(imitated, key=lambda c: span[c["name"]]))
    # A law at one site (LAW@SITE, asked for by name) is refitted jointly whatever its first score: the
    # updating, run without it, may have taken up its effect at the rig's bounds. Friction at the boom's
    # sheave alone (mu 0.05): seven parameters within 0.15 tolerance of their bounds, the candidate on top of
    # them 4.0e6 worse on held-out data than without it; refitted jointly from the nominal rig, mu 0.0501.
    # And so is the same law everywhere, when it is a candidate: a site and everywhere are then compared on equal
    # terms. Realistic seed 42, friction 0.05 at both of the dragline's rings, asked where: friction at the hoist
    # cluster's ring alone, refitted jointly, led (8.7e7) the law everywhere fitted on the rig updated without it
    # (5.4e7), 3.4e7 ahead - beyond the threshold, so no rival refit - and its 65 mm offsets read "unexplained";
    # refitted jointly, as the default list's lead on the same recording, the law everywhere reached 1.45e8.
    placeable = [c for c in runnable if scored[c["name"]]["value"] > 0 and not scored[c["name"]]["at_bound"]
                 and c not in refit]
    refit += [c for c in placeable if "@" in c["name"]]
    laws = {c["name"].partition("@")[0] for c in refit if "@" in c["name"]}
    return refit + [c for c in placeable if c["name"] in laws]


def _eligible(state):
    """Candidates a joint refit could help: fitted off the bounds of their range, improving the fit."""
    scored = state.scored
    return sorted((c for c in state.runnable if scored[c["name"]]["value"] > 0
                   and scored[c["name"]]["improvement"] > 0 and not scored[c["name"]]["at_bound"]),
                  key=lambda c: -scored[c["name"]]["improvement"])


def _refit(state, candidates):
    """Each candidate refitted jointly with the rig parameters (``joint_refit``), its score on the joint point."""
    problem, update = state.problem, state.update
    scored, points, joints = dict(state.scored), dict(state.points), dict(state.joints)
    for candidate in candidates:
        name = candidate["name"]
        s = scored[name]
        _note(state, f"refitting {name} and the rig parameters together")
        joint = joint_refit(state.plain_problem, state.nominal_ctx, update,
                            make_mechanism(name, **{candidate["main"]: s["value"]}), state.error_directions,
                            workers=state.workers, progress=state.note, value_range=candidate["searched"])
        if joint is None:
            continue
        joints[name] = joint
        value = float(joint["mechanism"].parameters[candidate["main"]])
        points[name] = [*points[name], (value, joint["sim"], problem.evaluate(joint["sim"]))]
        # The profile's curvature comes from the search on one rig; the
        # joint point sits on another and would bend the parabola.
        rescored = score_candidate(problem, candidate, points[name])
        rescored["profile"] = s["profile"]
        rescored["n_simulations"] += joint["n_simulations"] - 1
        scored[name] = rescored
    return replace(state, points=points, scored=scored, joints=joints)


def refit_rivals(state):
    """The candidates the lead may not be told apart from, refitted jointly too; the null test taken again.

    Whether a lead is real (``_decide`` rule 4) is judged between fits on
    equal terms: a rival fitted only on the rig updated without it was
    compared with a lead whose parameters moved with it. Rivals within the
    threshold of the lead get their own joint refit, when the lead is
    beyond the threshold itself. On a gantry crane with
    air drag (cd 0.9) the lead, hook-sheave friction, fitted 0.6 % better
    than drag with its parameters freed and drag's not; drag's own joint
    refit reached the objective of the truth and led by 5,200.
    """
    eligible = _eligible(state)
    if state.update is None or not eligible or eligible[0]["name"] not in state.joints:
        return state
    lead = state.scored[eligible[0]["name"]]["improvement"]
    if lead <= state.null.threshold:
        return state  # a lead that could not be named has no rival to be told apart from
    rivals = [c for c in eligible[1:] if c["name"] not in state.joints
              and lead - state.scored[c["name"]]["improvement"] < state.null.threshold]
    if not rivals:
        return state
    return test_against_noise(_refit(state, rivals))


def split_joined_sites(state):
    """A lead acting at several sites, and the laws alike to it, fitted at each of those sites alone.

    A joined set or the law everywhere is fitted with one coefficient at all
    its sites, so one site's effect is stood in for by the law spread over
    them all, and of two laws the one that spreads it better leads: on the
    crane (site seed 304) friction at the head sheave, 5x its threshold,
    was named bearing friction at all three sheaves, 890 ahead of the
    capstan at every ring, and the capstan at the head sheave was never
    fitted (``_sites.sets_to_split``). Each member is fitted as any
    candidate is, the best member of each set refitted jointly with the
    parameters, as its set was, and the null test taken again with the new
    signatures (its multiple-testing cost). Only a lead beyond the threshold
    is split: below it nothing would be named.
    """
    eligible = _eligible(state)
    if state.null is None or not eligible or state.scored[eligible[0]["name"]]["improvement"] <= state.null.threshold:
        return state
    leading = [c["name"] for c in eligible]
    signatures = {n: state.scored[n]["sim"] - state.base_sim for n in leading}
    sets = sets_to_split(state.problem, state.rig, leading, signatures, {g["law"] for g in state.site_groups})
    fitted = {c["name"] for c in state.runnable}
    members = [m for ms in sets.values() for m in ms if m not in fitted]
    if not members:
        return state
    new, skipped = _runnable(state, candidate_list(list(dict.fromkeys(members)), state.rig))
    skipped = state.skipped + skipped
    _note(state, f"fitting {', '.join(sets)} at each site alone ({', '.join(c['name'] for c in new)})")
    points = fit_candidates(state.problem, state.ctx, new, state.base_sim, workers=state.workers,
                            progress=state.note)
    scored = dict(state.scored, **{c["name"]: score_candidate(state.problem, c, points[c["name"]]) for c in new})
    split = [{"set": name, "members": ms} for name, ms in sets.items()]
    state = replace(state, candidates=state.candidates + new, runnable=state.runnable + new, skipped=skipped,
                    points=dict(state.points, **points), scored=scored, site_split=split)
    best = []
    for ms in sets.values():
        named = [c for c in _eligible(state) if c["name"] in ms and c["name"] not in state.joints]
        if named and named[0] not in best:
            best.append(named[0])
    return test_against_noise(_refit(state, best))


def test_against_noise(state):
    """The improvement noise alone gives (surrogates of the best model's residual), and the model-error budget.

    What the updated model leaves above noise (chi2 beyond its expectation)
    holds what updating could not reach - degenerate parameter pairs,
    nonlinearity, the finer model's error beyond its fitted direction. A
    mechanism must explain a real share of it, not a sliver that any smooth
    signature would absorb. A small excess is mostly the measurement's own
    (``_decide.MODEL_ERROR_FULL``).

    Nor may a mechanism be named for less than the model's own numerical
    error weighs (``own_error_weight``): an improvement no larger could be
    the candidate taking up that error, whatever its share of the excess.
    """
    problem, scored = state.problem, state.scored
    best_name = min(scored, key=lambda n: scored[n]["evaluation"]["full"]) if scored else None
    best_res = state.r_base if best_name is None or scored[best_name]["value"] == 0 else problem.residual(
        scored[best_name]["sim"], scored[best_name]["evaluation"]["nuisance"])
    signatures = [s["signature_sim"] - state.base_sim for s in scored.values() if s["signature_sim"] is not None]
    signatures += state.screened_out  # sites tried but not fitted raise the threshold as fitted ones do
    threshold, q = null_threshold(problem, best_res, signatures, seed=state.seed)
    z = np.where(problem.valid, best_res, 0.0) / state.recording.noise
    tau = autocorrelation_time(z)
    chi_min = min([s["evaluation"]["full"] for s in scored.values()] + [state.base_eval["full"]])
    kappa = max(1.0, chi_min / problem.n_weighted) * float(np.average(tau, weights=(z**2).sum(0) + 1e-12))
    excess = max(0.0, state.base_eval["full"] - problem.n_weighted)
    share = model_error_share(excess, problem.n_weighted) if state.update is not None else 0.0
    allowance = share * excess
    own = own_error_weight(state.model_error_block)
    null = NullTest(threshold=max(threshold, allowance, own), noise_threshold=threshold, surrogate_quantile=q,
                    kappa=kappa, allowance=allowance, excess=excess, share=share, own_error=own,
                    n_weighted=float(problem.n_weighted))
    return replace(state, null=null)


def own_error_weight(block):
    """The chi2 weight of the model's own numerical error: what the finer discretization and the half step change
    in the simulated channels (``_model_error.model_error``), summed.

    The held-out improvement sums over every sample, as this does. On the
    pendulum with nothing hidden (seed 71) bending damping improved the
    held-out data by 222 where the finer model differed by 347, and was
    named on 7 of 14 such recordings: what it took up was the model's
    error in the ball's rocking, which the truth, simulated finer, did not
    have.
    """
    return float(sum(entry.get("chi2", 0.0) for entry in (block or {}).values()
                     if isinstance(entry, dict) and entry.get("status") == "ok"))


def _signature_slope(points, value, refitted):
    """d channels / d ln p near ``value``: the secant between the searched points nearest it on either side.

    ``points``: the candidate's (value, sim, evaluation) on the updated rig,
    the joint refit's point last when ``refitted`` (another rig: left out).
    The two points must lie at least twice the search's resolution apart in
    ln p (``REFINE_XATOL``), so that the secant is a slope, not the
    simulations' rounding; None without such a pair.
    """
    pts = [(math.log(v), sim) for v, sim, _ in (points[:-1] if refitted else points) if v > 0 and sim is not None]
    if value <= 0 or len(pts) < 2:
        return None
    x0 = math.log(value)
    pts.sort(key=lambda p: p[0])
    pairs = [(a, b) for i, a in enumerate(pts) for b in pts[i + 1:]]
    # those on either side of the optimum first, then any; nearest first
    pairs.sort(key=lambda ab: (not ab[0][0] <= x0 < ab[1][0], abs(ab[0][0] - x0) + abs(ab[1][0] - x0)))
    for a, b in pairs:
        if b[0] - a[0] >= 2.0 * REFINE_XATOL:
            return (b[1] - a[1]) / (b[0] - a[0])
    return None


def _marginal(state, candidate, scored, residual):
    """``marginal_uncertainty`` of a fitted candidate, with its value's discretization shift, and the candidate
    simulated at the next finer discretization; (None, None) without an update or a slope."""
    name = candidate["name"]
    if state.update is None or scored["value"] <= 0 or scored["at_bound"]:
        return None, None
    slope = _signature_slope(state.points[name], scored["value"], name in state.joints)
    if slope is None:
        return None, None
    ctx = state.ctx
    if name in state.joints:  # the candidate's best point sits on its jointly refitted rig
        joint = state.joints[name]
        ctx = dict(ctx, rig=joint["rig"], maneuver=joint["maneuver"], initial_state=joint["initial_state"])
    finer = simulate_channels(name, candidate["main"], scored["value"], ctx,
                              finer_discretization(ctx["rig"], ctx["discretization"]))
    return marginal_uncertainty(state.plain_problem, state.nominal_ctx, state.update, slope, scored["sim"], residual,
                                state.error_directions, finer=finer), finer


def score_hypotheses(state):
    """Each candidate's held-out evidence, confounders and what it explains, best first."""
    rec, problem, update = state.recording, state.problem, state.update
    channels, sigma, width = rec.channels, rec.noise, rec.lowpass_width
    threshold, r0 = state.null.threshold, state.r_base
    e_before = structure_energy(r0, channels, sigma, width, rec.scale)
    hypotheses, fitted_series, residuals, finer_chi2 = [], {}, {}, {}
    for c in state.runnable:
        s = state.scored[c["name"]]
        main, value = c["main"], s["value"]
        params = dict(make_mechanism(c["name"]).parameters)
        params[main] = value
        if value > 0:
            res = problem.residual(s["sim"], s["evaluation"]["nuisance"])
            frac = 1.0 - structure_energy(res, channels, sigma, width, rec.scale) / e_before if e_before > 0 else 0.0
            sig_match = signature_match(problem, r0, s["sim"] - state.base_sim)
            band = band_improvement(problem, r0, res)
            residuals[c["name"]] = res
            fitted_series[c["name"]] = rec.values - res
        else:
            frac, sig_match, band = 0.0, 0.0, {"resolved": 0.0, "resolved_share": 0.0}
        confounders = (nuisance_correlation(problem, s["sim"] - state.base_sim, update,
                                            tolerances=[p.tolerance for p in state.ctx["parameters"]])
                       if update is not None and value > 0 else [])
        rms_ch = {}
        for j, ch in enumerate(channels):
            after = residuals[c["name"]][:, j] if c["name"] in residuals else r0[:, j]
            rms_ch[ch] = {"before": float(np.sqrt(np.nanmean(r0[:, j] ** 2))),
                          "after": float(np.sqrt(np.nanmean(after**2)))}
        n_w = problem.n_weighted
        marginal, finer = _marginal(state, c, s, residuals.get(c["name"]))
        if finer is not None:
            finer_chi2[c["name"]] = (s["evaluation"]["full"], problem.evaluate(finer)["full"])
        # Evidence only where the model does not resolve the motion is not
        # evidence (``_band``).
        significant, unresolved = significance(s["improvement"], band["resolved"], value, threshold)
        hypotheses.append({
            "name": c["name"],
            "main_parameter": main,
            "parameters": params,
            "uncertainty": stated_uncertainty(s, main, state.null.kappa, marginal, own_error=state.null.own_error),
            "range": list(c["range"]),
            "searched_range": list(c["searched"]),
            "rms_before": math.sqrt(s["heldout_before"] / n_w),
            "rms_after": math.sqrt(s["heldout_after"] / n_w),
            "improvement": s["improvement"],
            "threshold": threshold,
            "score": s["improvement"] / threshold,
            "significant": significant,
            "unresolved": unresolved,
            "resolved_share": band["resolved_share"],
            "resolved_improvement": band["resolved"],
            "signature_match": sig_match,
            "nuisance_correlation": confounders,
            "parameter_span_share": (parameter_span_share(problem, s["sim"] - state.base_sim, update)
                                     if update is not None and value > 0 else 0.0),
            "explained_fraction": frac,
            "at_bound": s["at_bound"],
            "time_shift_s": float(s["evaluation"]["nuisance"][1]),
            "n_simulations": s["n_simulations"],
            "n_failed": s["n_failed"],
            "rms_channels": rms_ch,
            "profile": [{"value": v, "chi2": ch} for v, ch in s["profile"]],
            "chi2_nominal": state.base_eval["full"],
        })
    for h in hypotheses:
        h["leftover_share"] = leftover_share(h)
    hypotheses.sort(key=lambda h: -h["improvement"])
    # Each candidate's lead over every one behind it, against what noise and model error could give (``_lead``).
    held = {h["name"]: problem.held_out_residual(*state.scored[h["name"]]["fold_sims"]) for h in hypotheses}
    leads = lead_tests(problem, held, [h["name"] for h in hypotheses], seed=state.seed,
                       base=problem.held_out_residual(state.base_sim, state.base_sim), finer_chi2=finer_chi2)
    for h in hypotheses:
        h["leads"] = leads[h["name"]]
    for k, h in enumerate(sorted(hypotheses, key=lambda h: -h["signature_match"])):
        h["signature_rank"] = k + 1
    return replace(state, hypotheses=hypotheses, fitted_series=fitted_series, residuals=residuals)


def _about_joint_rig(state, joint):
    """The scoring problem with its linearised parameter freedom centred on a joint refit's rig."""
    problem = state.problem
    return problem.with_regressors(problem.regressors, prior_precision=problem.prior_precision,
                                   prior_mean=np.r_[-joint["coords"], np.zeros(len(state.error_directions))],
                                   bounds=problem.regressor_bounds)


def credit_at_joint_rig(state):
    """What the best candidate adds at its own joint rig: the held-out chi2 there without it minus with it.

    A joint refit moves the parameters on from where updating stopped. When
    updating stopped short of the rig's best fit, the refit's gain is the
    parameters', not the mechanism's: on a recording with nothing added
    (case 91555 of the trusted-verdict set) updating left chi2 5.7e6, the
    joint refit with a sheave inertia of 1.8e-4 kg m^2 (0.7 of its
    detection threshold) reached 1.4e5, and the inertia led every rival.
    Scored on equal terms - the same rig, the same linearised parameter
    freedom about it - the candidate must still beat the threshold
    (``_decide``, rule 3b). One simulation.
    """
    best = next((h for h in state.hypotheses if h["significant"] and not h["at_bound"]), None)
    if best is None or best["name"] not in state.joints:
        return state
    joint = state.joints[best["name"]]
    _note(state, f"{best['name']}'s joint rig without it")
    alone = rig_alone_channels(state.nominal_ctx, joint)
    problem = _about_joint_rig(state, joint)
    with_it = problem.evaluate(joint["sim"])
    credit = {"with": with_it["AB"] + with_it["BA"], "n_simulations": 1}
    if alone is None:
        credit.update(without=None, credit=math.inf)
    else:
        without = problem.evaluate(alone)
        credit.update(without=without["AB"] + without["BA"])
        credit["credit"] = credit["without"] - credit["with"]
    hypotheses = [dict(h, credit_at_joint_rig=credit) if h is best else h for h in state.hypotheses]
    return replace(state, hypotheses=hypotheses)


def hypotheses_simulations(hypotheses):
    """The simulations the candidates' fits and their credits at a joint rig ran."""
    return sum(h["n_simulations"] + h.get("credit_at_joint_rig", {}).get("n_simulations", 0) for h in hypotheses)


def _stopped_short_lead(state):
    """The candidate whose joint rig can show that updating stopped short: the one credited there, else the
    best-ranked one refitted jointly."""
    credited = next((h for h in state.hypotheses if "credit_at_joint_rig" in h), None)
    return credited or next((h for h in state.hypotheses if h["name"] in state.joints), None)


def update_again(state):
    """Updating taken up again from the lead's joint rig when the verdict is "unexplained" and that rig fits
    better without the mechanism than the updated rig did; the candidates' steps run anew on the rig it
    reaches (once).

    A joint refit moves the parameters on with the lead's help. When its
    rig, the mechanism taken out, fits the recording better than the
    updated rig, updating had stopped short (its Jacobian cap, or its
    predicted-gain stop along a valley where masses and stiffness trade):
    every candidate was fitted, tested and judged against a rig short of
    the recording's best, and what held the verdict back - a credit at the
    joint rig below the threshold (``_decide`` rule 3b), a lead whose gain
    lies above the resolved band, a share left over - can be what the
    parameters could still take up. On the trusted-verdict set's seed 92
    the rig alone at the joint point fitted 5.6 to 18 times better
    (held-out chi2) than the updated rig in the four cases rule 3b read
    "unexplained" (three with nothing added, one with bending damping at
    twice its threshold); on seed 94 a recording with nothing added read
    "unexplained" on chain-link friction's gain above the resolved band,
    its joint refit at chi2 1.7e6 where updating had stopped at 8.5e6.
    Only an "unexplained" verdict is examined: a named mechanism or "none"
    already says what the recording holds. Updating resumes from there
    (``resume_update``); the first round is kept in ``superseded`` (with
    ``taken_up`` False, and nothing run again, where the joint rig alone
    fits no better: one simulation).
    """
    lead = _stopped_short_lead(state)
    if state.superseded is not None or state.verdict != "unexplained" or lead is None:
        return state
    credit = lead.get("credit_at_joint_rig", {}).get("credit")
    resumed = resume_update(state.plain_problem, state.nominal_ctx, state.nominal_sim, state.update,
                            state.joints[lead["name"]], state.error_directions, workers=state.workers,
                            progress=state.note)
    update = resumed["update"]
    first = {"lead": lead["name"], "improvement": lead["improvement"], "credit_at_joint_rig": credit,
             "threshold": state.null.threshold, "verdict": state.verdict, "reason": state.reason,
             "objective_updated": resumed["objective_updated"],
             "objective_joint_rig": resumed["objective_joint_rig"], "taken_up": update is not None,
             "chi2_updated": state.update["block"]["iterations"][-1]["chi2"]}
    if update is None:
        # The joint rig alone fits no better: nothing to resume from; its one simulation is counted here.
        return replace(state, superseded=dict(first, n_simulations=1))
    first.update(chi2_updated_again=update["block"]["iterations"][-1]["chi2"],
                 n_simulations=hypotheses_simulations(state.hypotheses))
    again = _with_update(replace(state, superseded=first, after_name=None, located_after=[], structured_after=[]),
                         update, resumed["error_directions"], resumed["model_error"],
                         model_error_sims=state.model_error_sims + 2)
    for step in (locate_updated, fit_mechanisms, refit_jointly, test_against_noise, refit_rivals, split_joined_sites,
                 score_hypotheses, credit_at_joint_rig, locate_after, judge_offsets, decide_verdict):
        again = step(again)
    return again


def locate_after(state):
    """What the best significant candidate leaves (the updated model's own when none is)."""
    significant = [h for h in state.hypotheses if h["significant"]]
    if not significant:
        return state
    rec = state.recording
    name = significant[0]["name"]
    located = mark_model_error(locate_mismatch(rec.time, state.residuals[name], rec.channels, rec.noise,
                                               rec.windows, rec.scale),
                               rec.time, state.error_directions, rec.channels, scale=rec.scale)
    return replace(state, after_name=name, located_after=located,
                   structured_after=[e for e in located if e["significant"] and not e["within_model_error"]])


def judge_offsets(state):
    """Constant offsets left by the best model, against calibration's accuracy and the rig's tolerances.

    A mechanism can shift the mean pose (rope held in a pulley); beyond
    calibration accuracy the geometry differs. Rope-length offsets were
    judged against the reel table (``check_maneuver``). With tolerances,
    the offsets the updated parameters leave are judged: beyond
    OFFSET_FINDING a finding, beyond OFFSET_LIMIT times DIFFERENT_RIG
    another rig.
    """
    channels, update, after = state.recording.channels, state.update, state.after_name
    scale = state.recording.scale
    b_ref = state.scored[after]["evaluation"]["nuisance"][0] if after else state.base_eval["nuisance"][0]
    offsets = {c: float(b) for c, b in zip(channels, b_ref)}
    left = None
    if update is not None:
        left = update["block"]["offsets_left"]
        if after in state.joints:
            # A mechanism can shift the mean pose (rope held in a ring): the
            # offsets left are those of the joint refit with it.
            left = state.joints[after]["offsets"]
    kept = left if update is not None else offsets
    judged = {c: (float(kept[c]), scale.floor(OFFSET_LIMIT, channel_kind(c)))
              for c in channels if channel_kind(c) in OFFSET_LIMIT}
    too_far = offsets_too_far(judged, update is not None)
    offsets_note = None
    if too_far:
        offsets_note = ("constant offsets beyond what calibration " + ("and the rig's tolerances " if update else "")
                        + "explain on " + ", ".join(f"{c} ({judged[c][0]:+.3g})" for c in too_far)
                        + ": the rig geometry or the calibration differs from the model, so no dynamic mechanism "
                        "can be trusted")
    return replace(state, offsets=offsets, offsets_left=left, too_far=too_far, offsets_note=offsets_note,
                   offsets_judged={"after_updating": update is not None, "channels": judged})


def decide_verdict(state):
    """The verdict and its reason (``_decide``), with the offsets no parameter explains as a finding."""
    verdict, reason = decide(state.hypotheses, state.null.threshold, state.structured_before, state.structured_after,
                             offsets_ok=not state.too_far, offsets_note=state.offsets_note,
                             updates=significant_updates(state.update), noise_threshold=state.null.noise_threshold)
    left = state.offsets_left
    findings = [] if state.update is None else [
        c for c in state.recording.channels
        if c in left and abs(left[c]) > state.recording.scale.floor(OFFSET_FINDING, channel_kind(c), math.inf)]
    if findings and not state.too_far:
        reason += ("; finding: constant offsets no parameter within tolerance explains on "
                   + ", ".join(f"{c} ({left[c]:+.3g})" for c in findings))
    unjudged = [h for h in state.hypotheses if h.get("n_simulations") and 2 * h.get("n_failed", 0) > h["n_simulations"]]
    if unjudged:
        reason += ("; not judged: " + ", ".join(f"{h['name']} ({h['n_failed']} of {h['n_simulations']} simulations "
                                                 "failed)" for h in unjudged)
                   + ": the simulation blew up or found no equilibrium at the rig the candidates were fitted on")
    first = state.superseded
    if first is not None and first["taken_up"]:
        reason += (f"; updating had stopped short: {first['lead']}'s joint rig fitted better without it, so "
                   f"updating was taken up again from there (chi2 {first['chi2_updated']:.4g} -> "
                   f"{first['chi2_updated_again']:.4g}) and every candidate fitted anew on that rig")
    significant = [h for h in state.hypotheses if h.get("significant")]
    named = bool(significant) and verdict == significant[0]["name"]
    alike = alike_laws(state.hypotheses, state.null.threshold, state.null.noise_threshold) if named else []
    return replace(state, verdict=verdict, reason=reason, alike_laws=tuple(alike))


def test_second_mechanism(state):
    """Every other candidate fitted on top of a named one (``_second_round``)."""
    verdict = state.verdict
    if verdict not in state.scored:
        return state
    _note(state, f"fitting the other candidates on top of {verdict}")
    named = next(h for h in state.hypotheses if h["name"] == verdict)
    ctx, problem, base_sim = state.ctx, state.problem, state.scored[verdict]["sim"]
    if verdict in state.joints:
        # The named fit sits on the jointly refitted rig: the others are
        # fitted on that rig too. Against the joint fit from the updated
        # rig, each had to beat the parameters' shifts as well as the
        # mechanism (at the low level a sheave's inertia under aero drag
        # scored 0, though strong on its own). The linearised parameter
        # freedom stays, its prior centred as the joint rig's shifts say.
        joint = state.joints[verdict]
        ctx = dict(ctx, rig=joint["rig"], maneuver=joint["maneuver"], initial_state=joint["initial_state"])
        problem = _about_joint_rig(state, joint)
        main = named["main_parameter"]
        base_sim = joint["sim"]
        named = dict(named, parameters=dict(named["parameters"], **{main: float(joint["mechanism"].parameters[main])}))
    # What the named model leaves above noise holds its own error (the
    # updated rig's nonlinearity, the discretization): a second mechanism
    # must explain a good part of it, not a slice any smooth signature
    # would take (on `dragline run`'s recording, friction alone in its
    # truth, a sheave inertia took 24 % of it and beat the noise threshold
    # 4.6 times; the inertia hidden under aero drag in tests/test_diagnose.py
    # takes 64 %). (Its own name: the JSON's model_error_allowance is the
    # first round's.)
    allowance, named_excess = 0.0, None
    if state.update is not None:
        named_excess = problem.evaluate(base_sim)["full"] - problem.n_weighted
        allowance = SECOND_EXCESS_SHARE * max(0.0, named_excess)
    second = second_round(problem, ctx, state.runnable, named, base_sim, workers=state.workers, seed=state.seed,
                          progress=state.note, allowance=allowance)
    second["named_excess"] = named_excess
    reason = state.reason
    also = [h for h in second["candidates"] if h["significant"]]
    if also:
        h = also[0]
        (k, v), = h["parameters"].items()
        reason += (f"; on top of it, {h['name']} ({k}={v:.3g}) also improves held-out data, {h['score']:.1f} "
                   "times what noise alone gives: a second mechanism may be at work")
    return replace(state, second=second, reason=reason)


def predict_held_out(state):
    """The trials the fit never saw, predicted by the nominal, the updated and the named model (``_predict``)."""
    entries, series = [], []
    for (name, _, _), aligned in zip(state.held_out, state.held_aligned):
        _note(state, f"predicting the held-out trial {name}")
        # the aligned trial's maneuver: with its start where a start is read from the recording
        entry, drawn = held_out_entry(state, name, aligned, aligned["ctx"]["maneuver"])
        entries.append(entry)
        series.append(drawn)
    return replace(state, predictions=entries, predicted_series=series)


STEPS = (align_recording, locate_nominal, update_rig, locate_updated, fit_mechanisms, refit_jointly,
         test_against_noise, refit_rivals, split_joined_sites, score_hypotheses, credit_at_joint_rig, locate_after,
         judge_offsets, decide_verdict, update_again, test_second_mechanism, predict_held_out)
