"""The seed paper's study of the dragline: its reported dig-maneuver numbers, figure captions, the channels
its figures single out and the notes its report prints (the dragline's report preset).

Source: "Comparison of measured and simulated motion of a scaled dragline
excavation system", section 4 ("Dig maneuver results") and the captions of
Figs. 8-21; the peak numbers are also transcribed independently, by hand,
in tests/data/paper/paper_parameters.toml (table ``[dig_maneuver]``), and a
test checks the two agree.

The paper reports values, not their sign convention: its peaks are copied
here exactly as printed (m/s, rad/s, s). Our tables follow docs/conventions.md (K points
down, so ``vz > 0`` is downward motion), and the report shows the paper's
numbers beside ours without re-signing them.
"""

from __future__ import annotations

import numpy as np

from ..simulate import euler_rates_from_body_rates

__all__ = [
    "PAPER_SOURCE",
    "DIG_PEAKS",
    "DIG_REELS_STOP",
    "SPREADER_BAR_X_OFFSET",
    "FIGURES",
    "FIG21_CAPTION",
    "DECAY_PANELS",
    "STUDY_CHANNEL",
    "FREE_DECAY_CHANNELS",
    "BODY_SIZES",
    "spreader_offset",
    "pitch_rate_note",
]

PAPER_SOURCE = (
    "seed paper section 4 (Dig maneuver results)"
)

# Peak table of section 4: (value, time) for the paper's measurement and its
# simulation. "Pitch rate" is compared with our body rate q (bucket.q); see
# ``pitch_rate_note`` below for how far it is from the Euler pitch rate.
DIG_PEAKS = {
    "bucket.vx": {
        "quantity": "longitudinal velocity",
        "unit": "m/s",
        "measured": (0.99, 6.2),
        "predicted": (1.01, 5.95),
    },
    "bucket.vz": {
        "quantity": "vertical velocity",
        "unit": "m/s",
        "measured": (0.73, 6.05),
        "predicted": (0.91, 6.27),
    },
    "bucket.q": {
        "quantity": "pitch rate",
        "unit": "rad/s",
        "measured": (-2.4, 6.77),
        "predicted": (-3.2, 6.77),
    },
}

# Both reels stop after 2.5 + 1 + 2 + 1 s of the dig maneuver as its text reads (section 4); the
# built-in reading, identified against the peak table, stops at 6.44 s (docs/model.md).
DIG_REELS_STOP = 6.5

# "a consistent offset of approximately 51 mm" in spreader-bar x (section 4).
SPREADER_BAR_X_OFFSET = 0.051

# Figs. 8-20: (figure label, channel, the paper's caption, y-axis label).
# Angles and angular rates are plotted in degrees (docs/conventions.md), everything else
# in SI units.
FIGURES = (
    ("8", "hoist_rope.length", "Measured and predicted hoist rope length vs. time.",
     "Hoist rope length (m)"),
    ("9", "drag_rope.length", "Measured and predicted drag rope length vs. time.",
     "Drag rope length (m)"),
    ("10", "bucket.x",
     "Measured and predicted X inertial position of bucket mass center vs. time.",
     "X inertial position (m)"),
    ("11", "bucket.z",
     "Measured and predicted Z inertial position of bucket mass center vs. time.",
     "Z inertial position (m)"),
    ("12", "bucket.pitch", "Measured and predicted bucket pitch angle vs. time.",
     "Pitch angle (deg)"),
    ("13", "bucket.vx",
     "Measured and predicted X inertial velocity of bucket mass center vs. time.",
     "X inertial velocity (m/s)"),
    ("14", "bucket.vz",
     "Measured and predicted Z inertial velocity of bucket mass center vs. time.",
     "Z inertial velocity (m/s)"),
    ("15", "bucket.q", "Measured and predicted bucket pitch rate vs. time.",
     "Pitch rate (deg/s)"),
    ("16a", "spreader_bar.x",
     "Measured and predicted X inertial position of spreader bar mass center vs. time.",
     "X inertial position (m)"),
    ("16b", "spreader_bar.z",
     "Measured and predicted Z inertial position of spreader bar mass center vs. time.",
     "Z inertial position (m)"),
    ("17", "spreader_bar.pitch", "Measured and predicted spreader bar pitch angle vs. time.",
     "Pitch angle (deg)"),
    ("18a", "hoist_cluster.x",
     "Measured and predicted X inertial position of hoist cluster mass center vs. time.",
     "X inertial position (m)"),
    ("18b", "hoist_cluster.z",
     "Measured and predicted Z inertial position of hoist cluster mass center vs. time.",
     "Z inertial position (m)"),
    ("19", "hoist_cluster.pitch", "Measured and predicted hoist cluster pitch angle vs. time.",
     "Pitch angle (deg)"),
    ("20a", "drag_cluster.x",
     "Measured and predicted X inertial position of drag cluster mass center vs. time.",
     "X inertial position (m)"),
    ("20b", "drag_cluster.z",
     "Measured and predicted Z inertial position of drag cluster mass center vs. time.",
     "Z inertial position (m)"),
)

# The free-decay page's four panels and Fig. 21's channel.
DECAY_PANELS = ("bucket.pitch", "bucket.z", "spreader_bar.pitch", "hoist_cluster.pitch")
STUDY_CHANNEL = "bucket.pitch"

FIG21_CAPTION = (
    "Measured and predicted bucket pitch angle vs. time for varying bead discretization."
)

# Channels whose free swing after the reels stop is analysed (the paper's
# figures of positions and pitch angles).
FREE_DECAY_CHANNELS = (
    "bucket.x", "bucket.z", "bucket.pitch",
    "spreader_bar.x", "spreader_bar.z", "spreader_bar.pitch",
    "hoist_cluster.x", "hoist_cluster.z", "hoist_cluster.pitch",
    "drag_cluster.x", "drag_cluster.z",
)

# Bucket: 0.381 x 0.203 x 0.152 m (paper section 3.1); the results file draws the other bodies small.
BODY_SIZES = {"bucket": (0.381, 0.203, 0.152)}


def spreader_offset(meas, sim):
    """Mean predicted-minus-measured spreader-bar x, beside the paper's ~51 mm."""
    ch = "spreader_bar.x"
    out = {"channel": ch, "paper": SPREADER_BAR_X_OFFSET, "mean_difference": None}
    if ch in meas.columns and ch in sim.columns:
        d = np.asarray(sim[ch], float) - np.asarray(meas[ch], float)
        if np.isfinite(d).any():
            out["mean_difference"] = float(np.mean(d[np.isfinite(d)]))
    return out


def pitch_rate_note(meas, sim, body="bucket"):
    """How far the Euler pitch rate is from the body rate q the paper's "pitch rate" is compared with (rad/s)."""
    cols = [f"{body}.{q}" for q in ("roll", "yaw", "p", "q", "r")]
    diff = {}
    for side, table in (("measured", meas), ("simulated", sim)):
        if not all(c in table.columns for c in cols):
            diff[side] = None
            continue
        roll, yaw, p, q, r = (np.asarray(table[c], float) for c in cols)
        _, pitch_rate, _ = euler_rates_from_body_rates(roll, yaw, p, q, r)
        d = np.abs(pitch_rate - q)
        diff[side] = float(np.max(d[np.isfinite(d)])) if np.isfinite(d).any() else None
    return {
        "definition": f"body rate q ({body}.q), rad/s",
        "euler_pitch_rate": "(p sin(yaw) + q cos(yaw)) / cos(roll)",
        "max_difference": diff,
    }
