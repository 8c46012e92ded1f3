"""``dragline simulate``: run the dynamic model, write a trajectory table."""

from __future__ import annotations

import sys
import time

from dragline.simulate import SimulationError, StaticsError, simulate, write_trajectory_csv

from ._guard import guard_outputs
from ._options import (
    add_model_options,
    check_output_path,
    discretization_from_args,
    maneuver_from_args,
    number,
    physics_from_args,
    rig_from_args,
)


def add_parser(sub):
    p = sub.add_parser("simulate", help="simulate a maneuver from static equilibrium",
                       description="Simulate a maneuver from static equilibrium and write the trajectory table (CSV).")
    add_model_options(p)
    p.add_argument("--duration", type=number(), default=10.0, metavar="S", help="simulated time (s, default 10)")
    # a table sampled faster than every 1e-5 s is refused by every reader (capture.MIN_TIME_STEP_S)
    p.add_argument("--rate", type=number(maximum=1e5), default=200.0, metavar="HZ",
                   help="output rate (Hz, default 200, at most 100000)")
    p.add_argument("--dt", type=number(), default=None, metavar="S", help="fixed integration step (s; default: the integrator's stability limit, cut as the rig stiffens)")
    p.add_argument("--integrator", choices=("verlet", "rk4"), default="verlet",
                   help="velocity Verlet (default: one right-hand side a step) or classical RK4 (the reference)")
    p.add_argument("--out", required=True, metavar="TRAJ.csv", help="trajectory table to write")
    p.add_argument("--quiet", action="store_true", help="print nothing on success")


def run(args):
    check_output_path(args.out)
    guard_outputs([args.rig, args.maneuver], files=[args.out])
    rig = rig_from_args(args)
    maneuver = maneuver_from_args(args, rig)
    discretization = discretization_from_args(args, rig)
    physics = physics_from_args(args)
    t0 = time.perf_counter()
    try:
        result = simulate(rig, maneuver, discretization, physics, duration=args.duration, rate_hz=args.rate,
                          dt=args.dt, integrator=args.integrator)
    except SimulationError as exc:
        if args.dt is None:
            raise  # the tool's own step blew up: a fault of the tool (exit 1)
        # The user's fixed step: an explicit step above the stability limit
        # grows without bound (a fuzzed --dt 1e300 became 0.02 s and blew up).
        raise ValueError(f"--dt {args.dt:g}: {exc}; a fixed step must stay below the integrator's stability limit "
                         "(leave --dt out and the step follows it)") from None
    except ValueError as exc:
        text = str(exc)
        if text.startswith("the maneuver"):
            raise ValueError(f"{args.maneuver or rig.source + ' (its own maneuver)'}: {exc}") from None
        if args.dt is not None and "step needs" in text:
            raise ValueError(f"--dt {args.dt:g}: {exc}") from None
        if "records of" in text:
            raise ValueError(f"--duration {args.duration:g} at --rate {args.rate:g}: {exc}") from None
        if isinstance(exc, StaticsError) and args.rig:
            raise ValueError(f"{args.rig} (with maneuver {args.maneuver}): {exc}") from None
        raise
    write_trajectory_csv(args.out, result.table)
    if not args.quiet:
        print(
            f"simulated {args.duration:g} s ({result.model.n_state} states, smallest step {result.dt * 1e6:.1f} us) "
            f"in {time.perf_counter() - t0:.1f} s; wrote {args.out}",
            file=sys.stderr,
        )
    return 0
