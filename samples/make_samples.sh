#!/usr/bin/env bash
# How the committed sample session was made (run from the repository root).
# A 10 s dig maneuver at 100 Hz, filmed by the six simulated cameras with the
# default noise, occlusion, dropouts and ghosts, and short calibration takes;
# its hidden lab truth is the built-in run's (ring-pulley friction), written
# to samples/dig_sample_truth/, apart from the session.
set -euo pipefail
# The committed folders carry no .dragline-output marker (they are inputs to
# users), so --force would refuse them: they are removed here on purpose.
rm -rf samples/dig_sample samples/dig_sample_truth
dragline synth --seed 7 --duration 10 --rate 100 --wand-frames 600 --lframe-frames 50 \
    --physics pulley_friction:mu=0.02 \
    --out samples/dig_sample --truth-out samples/dig_sample_truth --quiet
# Inputs again: without the marker no later --force can replace them.
rm -f samples/dig_sample/.dragline-output samples/dig_sample_truth/.dragline-output
