#!/usr/bin/env bash
# How the committed sample session was made (run from the repository root).
# A 10 s dig maneuver at 100 Hz, filmed by the six simulated cameras with the
# default noise, occlusion, dropouts and ghosts, and short calibration takes;
# its hidden lab truth is the built-in run's (ring-pulley friction), written
# to samples/dig_sample_truth/, apart from the session.
set -euo pipefail
dragline synth --seed 7 --duration 10 --rate 100 --wand-frames 600 --lframe-frames 50 \
    --physics pulley_friction:mu=0.02 \
    --out samples/dig_sample --truth-out samples/dig_sample_truth --force --quiet
