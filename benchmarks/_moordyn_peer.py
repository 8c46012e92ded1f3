"""Peer benchmark: our rope solver against MoorDyn v2 on one equivalent line.

Issue 2's speed comparison. One line hangs between a fixed anchor and a
fairlead that moves by a prescribed table; both codes integrate the same
lumped-mass ODE and we compare wall time at equal accuracy.

The equivalent MoorDyn line (python ``moordyn`` 2.x):
  n particles here = N - 1 interior nodes there, N = n + 1 segments;
  EA = K = Ks + Kv (``dissipation=False`` makes each element a pure spring
  of K per unit strain, tension only); BA = 0, EI = 0, Cd = Ca = 0, water
  density 0 (no buoyancy, drag or added mass);
  mass per length w = rho (n + 1) / n, so that MoorDyn's interior node mass
  w L / N equals ours rho L / n (and so does its weight).
MoorDyn's z is up; the line is placed ``_DEPTH`` m under its water surface
with the seabed 1000 m down, out of reach. Our K points down:
(x, y, z)_moordyn = (x, y, -z - _DEPTH).

The fairlead table is linear between samples in both codes: MoorDyn takes a
coupled point's position at the start of each coupling step plus a constant
velocity, so coupling steps that divide the table interval reproduce our
interpolation exactly.

Both start from static equilibrium: ours from ``solve_statics``, MoorDyn's
from its own stationary initial-condition solver, run once and loaded into
every later MoorDyn instance with ``LoadState``.

MoorDyn 2.7.2 caveat (found here, measured): after ``Close()`` of one
instance, a later instance in the same process that is given a state with
``LoadState`` integrates wrongly (a spurious uniform vertical acceleration
of about 7.5 m/s^2 on every node, different from run to run). Every
instance is therefore kept open until the whole benchmark is done.
"""

from __future__ import annotations

import os
import tempfile
import time
from contextlib import contextmanager

import numpy as np

from dragline.simulate import Maneuver, assemble, rig_from_dict, simulate, solve_statics, stable_time_step

__all__ = ["bench_moordyn", "line_rig", "line_maneuver", "MoorDynLine"]

LINE = {
    "length": 3.5,
    "weight_per_length": 0.06751,
    "static_stiffness": 1859.0,
    "viscous_stiffness": 7439.0,
    "viscous_damping": 74.0,
}
ANCHOR = (0.0, 0.0, -1.0)
FAIRLEAD = (3.0, 0.0, -1.0)
AMPLITUDE = 0.2  # fairlead surge (m)
FREQUENCY = 0.5  # Hz
TABLE_DT = 0.1  # fairlead table interval (s)
RECORD_DT = 0.01  # output interval of both codes (s)
G = 9.81
_DEPTH = 50.0
_SEABED = 1000.0


def line_rig(particles=12):
    """The benchmark line as a rig: anchor and fairlead fixed points, one rope."""
    doc = {
        "fixed_points": {"anchor": list(ANCHOR), "fairlead": list(FAIRLEAD)},
        "ropes": {"line": {"start": "fixed.anchor", "end": "fixed.fairlead", "particles": int(particles), **LINE}},
    }
    return rig_from_dict(doc, source="benchmark line")


def line_maneuver(duration=10.0, table_dt=TABLE_DT, ramp=0.0):
    """Fairlead surge 0.2 m at 0.5 Hz, tabulated every ``table_dt`` s (reels unused).

    Parameters
    ----------
    duration : float
        s.
    table_dt : float
        Table interval (s); both codes interpolate linearly in between.
    ramp : float
        Seconds over which the amplitude grows from zero (quintic smoothstep,
        so the motion starts from rest with zero acceleration); 0 starts the
        sine at full speed, 0.63 m/s, at t = 0.
    """
    t = np.arange(int(round(duration / table_dt)) + 1) * table_dt
    envelope = np.ones_like(t)
    if ramp > 0:
        s = np.clip(t / ramp, 0.0, 1.0)
        envelope = s**3 * (10 - 15 * s + 6 * s**2)
    x = FAIRLEAD[0] + AMPLITUDE * envelope * np.sin(2 * np.pi * FREQUENCY * t)
    fairlead = np.column_stack([x, np.full_like(t, FAIRLEAD[1]), np.full_like(t, FAIRLEAD[2])])
    return Maneuver(t, points={"fairlead": fairlead})


def to_moordyn(p):
    """Our frame (K down) to MoorDyn's (z up, ``_DEPTH`` below the surface); also back."""
    p = np.array(p, float)
    p[..., 2] = -p[..., 2] - _DEPTH
    return p


def moordyn_input(particles, dt, scheme="RK4", ic_time=600.0):
    """Text of the MoorDyn input file for the benchmark line.

    Parameters
    ----------
    particles : int
        Our particle count n (MoorDyn gets n + 1 segments).
    dt : float or None
        MoorDyn's internal step dtM (s); None leaves it to MoorDyn's CFL rule.
    scheme : str
        MoorDyn time scheme (RK4, RK2, ...).
    ic_time : float
        Simulated time (s) its initial-condition solver may use.
    """
    n = int(particles)
    rho = LINE["weight_per_length"] / G
    w = rho * (n + 1) / n
    K = LINE["static_stiffness"] + LINE["viscous_stiffness"]
    a = [float(v) for v in to_moordyn(ANCHOR)]
    f = [float(v) for v in to_moordyn(FAIRLEAD)]
    dt_line = "" if dt is None else f"{dt!r} dtM\n"
    return (
        "--------------------- MoorDyn Input File ------------------------------------\n"
        "dragline benchmark line\n"
        "----------------------- LINE TYPES ------------------------------------------\n"
        "TypeName Diam Mass/m EA BA/-zeta EI Cd Ca CdAx CaAx\n"
        "(name) (m) (kg/m) (N) (N-s/-) (N-m^2) (-) (-) (-) (-)\n"
        f"rope 0.01 {w!r} {K!r} 0.0 0.0 0.0 0.0 0.0 0.0\n"
        "---------------------- POINT PROPERTIES --------------------------------\n"
        "ID Type X Y Z Mass Volume CdA Ca\n"
        "(#) (-) (m) (m) (m) (kg) (m^3) (m^2) (-)\n"
        f"1 Fixed {a[0]!r} {a[1]!r} {a[2]!r} 0 0 0 0\n"
        f"2 Coupled {f[0]!r} {f[1]!r} {f[2]!r} 0 0 0 0\n"
        "---------------------- LINES ----------------------------------------\n"
        "ID LineType AttachA AttachB UnstrLen NumSegs LineOutputs\n"
        "(#) (name) (ID) (ID) (m) (-) (-)\n"
        f"1 rope 1 2 {LINE['length']!r} {n + 1} -\n"
        "---------------------- OPTIONS -----------------------------------------\n"
        f"{dt_line}"
        f"{scheme} tScheme\n"
        f"{G!r} g\n"
        "0.0 WtrDnsty\n"
        f"{_SEABED!r} WtrDpth\n"
        "1e-9 threshIC\n"
        f"{ic_time!r} TmaxIC\n"
        "0 writeLog\n"
        "1 disableOutput\n"
        "1 disableOutTime\n"
        "------------------------- need this line -------------------------------------\n"
    )


@contextmanager
def _quiet():
    """Silence MoorDyn's console output (it writes to the C streams, not Python's)."""
    saved = os.dup(1), os.dup(2)
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 1)
        os.dup2(null, 2)
        yield
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, null):
            os.close(fd)


class MoorDynLine:
    """MoorDyn instances of the benchmark line, all closed together at the end.

    Use as a context manager. ``equilibrium()`` runs MoorDyn's initial
    condition solver once; ``run()`` starts a fresh instance from it.
    """

    def __init__(self, particles=12, ic_time=600.0, ic_dt=3e-4):
        import moordyn

        self.md = moordyn
        self.particles = int(particles)
        self.ic_time = float(ic_time)
        self.ic_dt = float(ic_dt)
        self._dir = tempfile.TemporaryDirectory(prefix="dragline-moordyn-")
        self._systems = []
        self._state = None
        self.ic_seconds = float("nan")
        self.ic_nodes = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        with _quiet():
            for s in self._systems:
                self.md.Close(s)
        self._systems.clear()
        self._dir.cleanup()

    def _create(self, dt, scheme, ic_time=0.0):
        path = os.path.join(self._dir.name, f"line{len(self._systems)}.txt")
        with open(path, "w") as fh:
            fh.write(moordyn_input(self.particles, dt, scheme, ic_time))
        with _quiet():
            s = self.md.Create(path)
        self.md.SetVerbosity(s, self.md.LEVEL_ERR)
        self._systems.append(s)  # never closed before the end: see the module note
        return s

    def _nodes(self, line):
        return np.array([self.md.GetLineNodePos(line, i) for i in range(self.particles + 2)])

    def equilibrium(self):
        """Node positions (our frame, m) of MoorDyn's static solution, (n + 2, 3)."""
        if self._state is None:
            s = self._create(self.ic_dt, "RK4", self.ic_time)
            t0 = time.perf_counter()
            with _quiet():
                err = self.md.Init(s, list(to_moordyn(FAIRLEAD)), [0.0, 0.0, 0.0])
            self.ic_seconds = time.perf_counter() - t0
            if err:
                raise RuntimeError(f"MoorDyn initial conditions failed (error {err})")
            self._state = os.path.join(self._dir.name, "equilibrium.state")
            self.md.SaveState(s, self._state)
            self.ic_nodes = to_moordyn(self._nodes(self.md.GetLine(s, 1)))
        return self.ic_nodes

    def start(self, dt, scheme="RK4"):
        """A new instance at MoorDyn's equilibrium: (system, line) handles.

        ``dt`` is MoorDyn's internal step (s), used as given (None: its CFL rule).
        """
        self.equilibrium()
        s = self._create(dt, scheme)
        with _quiet():
            self.md.Init_NoIC(s, list(to_moordyn(FAIRLEAD)), [0.0, 0.0, 0.0])
        self.md.LoadState(s, self._state)
        return s, self.md.GetLine(s, 1)

    def run(self, dt, maneuver, scheme="RK4", duration=10.0):
        """Integrate from MoorDyn's equilibrium with the maneuver's fairlead table.

        Parameters
        ----------
        dt : float or None
            Internal step (s); it is nudged to divide the coupling step (the
            table interval or ``RECORD_DT``, whichever is shorter) so that no
            sliver step is left at the end of a coupling step. None: MoorDyn's
            own default (its CFL rule).
        maneuver : Maneuver
            Fairlead table at a constant interval that divides ``RECORD_DT``
            or is a multiple of it.
        scheme : str
        duration : float
            s, a multiple of ``RECORD_DT``.

        Returns
        -------
        nodes : ndarray (records, n + 2, 3)
            Node positions in our frame (m) every ``RECORD_DT``; NaN after a blow-up.
        wall : float
            Seconds spent stepping (and reading the nodes back).
        setup : float
            Seconds to create the instance and load the equilibrium.
        """
        self.equilibrium()
        table_dt = float(maneuver.time[1] - maneuver.time[0])
        couple = min(table_dt, RECORD_DT)
        per_table = int(round(table_dt / couple))
        per_record = int(round(RECORD_DT / couple))
        if dt is not None:
            per_couple = max(1, int(np.ceil(couple / dt - 1e-9)))
            dt = couple / per_couple * (1.0 + 1e-9)
        t0 = time.perf_counter()
        s, line = self.start(dt, scheme)
        setup = time.perf_counter() - t0

        n_couple = int(round(duration / couple))
        pos = to_moordyn(maneuver.points["fairlead"])
        vel = np.diff(pos, axis=0) / table_dt
        x = [list(pos[k // per_table] + vel[k // per_table] * (k % per_table) * couple) for k in range(n_couple)]
        v = [list(vel[k // per_table]) for k in range(n_couple)]
        out = np.full((n_couple // per_record + 1, self.particles + 2, 3), np.nan)
        out[0] = to_moordyn(self.ic_nodes)  # positions read before a step are MoorDyn's stale first guess
        step, nodes = self.md.Step, self._nodes
        with _quiet():  # a blow-up is reported on the C streams; it shows as NaN here
            t0 = time.perf_counter()
            try:
                for k in range(n_couple):
                    step(s, x[k], v[k], k * couple, couple)
                    if (k + 1) % per_record == 0:
                        out[(k + 1) // per_record] = nodes(line)
            except (RuntimeError, ValueError):
                pass
            wall = time.perf_counter() - t0
        return to_moordyn(out), wall, setup


def _max_error_mm(nodes, reference):
    """Largest node position error (mm) over the whole run; inf after a blow-up."""
    err = np.abs(np.asarray(nodes) - reference)
    return float("inf") if not np.isfinite(err).all() else 1e3 * float(err.max())


def time_to_error(walls, errors, level):
    """Wall time needed for a given error, from one solver's error-vs-time points.

    Log-log interpolation between the last point above ``level`` and the
    first at or below it, in order of wall time.

    Parameters
    ----------
    walls, errors : array_like
        Wall time (s) and error (any unit) of each run.
    level : float
        Target error, same unit.

    Returns
    -------
    seconds : float
        NaN when no run reaches ``level``.
    bound : bool
        True when the cheapest run already meets ``level``: its step is set by
        stability, not accuracy, so ``seconds`` is an upper bound.
    """
    order = np.argsort(walls)
    w = np.asarray(walls, float)[order]
    e = np.asarray(errors, float)[order]
    ok = np.nonzero(e <= level)[0]
    if ok.size == 0:
        return float("nan"), False
    j = ok[0]
    if j == 0:
        return float(w[0]), True
    if not np.isfinite(e[j - 1]):
        return float(w[j]), False
    f = (np.log(level) - np.log(e[j - 1])) / (np.log(e[j]) - np.log(e[j - 1]))
    return float(np.exp(np.log(w[j - 1]) + f * (np.log(w[j]) - np.log(w[j - 1])))), False


def _ours(rig, maneuver, y0, dt, duration, integrator="rk4"):
    t0 = time.perf_counter()
    r = simulate(rig, maneuver, duration=duration, rate_hz=1.0 / RECORD_DT, dt=dt, dissipation=False, initial_state=y0,
                 integrator=integrator)
    wall = time.perf_counter() - t0
    return r.rope_nodes("line"), wall, r.dt


def _as_briefed(rig, maneuver, y0, step, duration, md_run, repeats):
    """Equal-step speed on the briefed drive, and how far apart its runs drift (mm)."""
    walls_ours, walls_md = [], []
    for _ in range(repeats):  # interleaved, like the main curves
        a1, w, _ = _ours(rig, maneuver, y0, step, duration)
        walls_ours.append(w)
        m1, w = md_run(step, "RK4", maneuver)
        walls_md.append(w)
    a4, _, _ = _ours(rig, maneuver, y0, step / 4, duration)
    m4, _ = md_run(step / 4, "RK4", maneuver)
    nudged = np.array(y0, float)
    nudged[2] += 1e-6  # the first particle 1 um lower
    a1n, _, _ = _ours(rig, maneuver, nudged, step, duration)
    first = int(round(1.0 / RECORD_DT)) + 1
    rest = LINE["length"] / (a4.shape[1] - 1)
    return {
        "step_s": step,
        "ours_wall_s": float(np.median(walls_ours)),
        "moordyn_rk4_wall_s": float(np.median(walls_md)),
        "ratio_moordyn_over_ours": float(np.median(walls_md) / np.median(walls_ours)),
        "ours_step_vs_quarter_step_mm": _max_error_mm(a1, a4),
        "ours_step_vs_quarter_step_first_second_mm": _max_error_mm(a1[:first], a4[:first]),
        "moordyn_step_vs_quarter_step_mm": _max_error_mm(m1, m4),
        "moordyn_vs_ours_quarter_step_mm": _max_error_mm(m4, a4),
        "ours_start_nudged_1um_mm": _max_error_mm(a1, a1n),
        "slack_element_fraction": float(np.mean(np.linalg.norm(np.diff(a4, axis=1), axis=2) <= rest)),
    }


def _python_overhead(md, step, duration, couple):
    """Seconds MoorDyn's wall times spend in Python: coupling calls and node read-back."""
    s, line = md.start(step)
    x = list(to_moordyn(FAIRLEAD))
    per_record = int(round(RECORD_DT / couple))
    t0 = time.perf_counter()
    for k in range(int(round(duration / couple))):
        md.md.Step(s, x, [0.0, 0.0, 0.0], k * couple, 0.0)  # dt = 0: the call without the stepping
        if (k + 1) % per_record == 0:
            md._nodes(line)
    return time.perf_counter() - t0


def bench_moordyn(particles=12, repeats=3, duration=10.0, levels_mm=(1.0, 0.1), ic_time=600.0):
    """Wall time of our solver and MoorDyn on one equivalent line, at equal accuracy.

    Two fairlead drives of the same line (0.2 m surge at 0.5 Hz):

    * ``smooth`` (the measured comparison): amplitude ramped in over 2 s,
      table every 1 ms. The line stays taut, the ODE is well conditioned (a
      1 um nudge of the start moves no node by more than about 1 um) and both
      codes converge to one solution. Reference: our solver at 1/16 of the
      base step; MoorDyn RK4 at 1/8 of it is checked against it.
    * ``as_briefed``: the sine at full speed from t = 0, table every 0.1 s.
      The velocity jumps (at t = 0 and at every table knot) ring the stiff,
      undamped axial modes; the line goes slack and snaps many times a
      second and the motion is chaotic: a 1 um nudge, a smaller step or the
      other code each move nodes by tens of mm within 10 s. No reference
      exists, so only the plain speed ratio at equal step is reported, with
      those drifts.

    The base step is the largest step within our RK4 stability bound
    (``stable_time_step``) that divides the 1 ms coupling interval; both
    codes use it (same ODE, same classical RK4, same stability limit).
    MoorDyn's own default (RK2 with its CFL rule) is run too.

    Parameters
    ----------
    particles : int
        Particles n of our line (MoorDyn: n + 1 segments).
    repeats : int
        Runs per timing, the two codes interleaved; the median (and the
        minimum, the run least disturbed by other load) is reported.
    duration : float
        Simulated seconds, a multiple of 0.01.
    levels_mm : sequence of float
        Error levels (max node position error over the run, mm) at which
        the wall times are compared.
    ic_time : float
        Pseudo-time (s) given to MoorDyn's stationary initial-condition solver.

    Returns
    -------
    dict
        Plain numbers (s, mm). ``curves``: one row per solver, scheme and
        step (wall time, error against the reference); ``equal_accuracy``:
        per level, each code's wall time to reach it and the ratio MoorDyn /
        ours; ``default_step``: each code at its own default step;
        ``reference``, ``equilibrium_difference_mm``, ``as_briefed``,
        ``setup_s``, ``moordyn_python_overhead_s`` (MoorDyn's coupling
        calls and node read-back, included in its wall times),
        ``repeat_runs_identical``. Wall times exclude compilation, statics
        and instance creation, which are under ``setup_s``.

    Raises
    ------
    ValueError
        On a non-positive particle count, repeat count or duration.
    ModuleNotFoundError
        When the ``moordyn`` package is not installed.
    """
    if int(particles) < 1 or int(repeats) < 1 or not duration > 0:
        raise ValueError(f"particles, repeats and duration must be positive, got {particles}, {repeats}, {duration}")
    if abs(duration / RECORD_DT - round(duration / RECORD_DT)) > 1e-9:
        raise ValueError(f"duration must be a multiple of {RECORD_DT} s, got {duration}")
    repeats = int(repeats)
    rig = line_rig(particles)
    smooth = line_maneuver(duration, table_dt=0.001, ramp=2.0)
    briefed = line_maneuver(duration)
    model = assemble(rig, smooth, "baseline", dissipation=False)
    out = {"particles": int(particles), "duration_s": float(duration), "repeats": repeats, "levels_mm": list(levels_mm)}

    t0 = time.perf_counter()
    eq = solve_statics(model, 0.0)
    setup = {"ours_statics": time.perf_counter() - t0}
    couple = 0.001
    base = couple / int(np.ceil(couple / stable_time_step(model) - 1e-9))
    t0 = time.perf_counter()
    _ours(rig, smooth, eq.state, base, RECORD_DT)  # numba load or compile
    setup["ours_first_call"] = time.perf_counter() - t0
    out["base_step_s"] = base
    ours0 = model.node_positions(eq.state[None], "line", [0.0])[0]

    ref, ref_wall, _ = _ours(rig, smooth, eq.state, base / 16, duration)
    out["reference"] = {"solver": "ours RK4", "step_s": base / 16, "wall_s": ref_wall}
    curves = []
    same = True
    ours_default, default_wall, default_step = _ours(rig, smooth, eq.state, None, duration, "verlet")
    nudged = eq.state.copy()
    nudged[2] += 1e-6  # the first particle 1 um lower: how sensitive is this drive?
    out["start_nudged_1um_mm"] = _max_error_mm(_ours(rig, smooth, nudged, base, duration)[0], ours_default)

    with MoorDynLine(particles, ic_time=ic_time) as md:
        md_eq = md.equilibrium()
        setup["moordyn_equilibrium"] = md.ic_seconds
        out["equilibrium_difference_mm"] = 1e3 * float(np.abs(md_eq - ours0).max())
        instance = []

        def md_run(dt, scheme, man=smooth):
            nodes, wall, s = md.run(dt, man, scheme, duration)
            instance.append(s)
            return nodes, wall

        finest, _ = md_run(base / 8, "RK4")
        out["reference"]["moordyn_rk4_step_s"] = base / 8
        out["reference"]["moordyn_rk4_error_mm"] = _max_error_mm(finest, ref)
        runs = [("ours", "RK4", f, lambda dt: _ours(rig, smooth, eq.state, dt, duration)) for f in (1, 2, 4)]
        # Verlet is stable to 2 / omega against RK4's 2.83 / omega: from half the base step
        runs += [("ours", "Verlet", f, lambda dt: _ours(rig, smooth, eq.state, dt, duration, "verlet")) for f in (2, 4, 8)]
        runs += [("moordyn", "RK4", f, lambda dt: md_run(dt, "RK4")) for f in (1, 2, 4)]
        runs += [("moordyn", "RK2", f, lambda dt: md_run(dt, "RK2")) for f in (4, 8, 16)]
        results = {i: [] for i in range(len(runs))}
        for rep in range(repeats):  # interleaved, so that both codes see the same machine load
            for i, (solver, scheme, f, run) in enumerate(runs):
                if rep == 0 or not np.isinf(_max_error_mm(results[i][0][0], ref)):
                    results[i].append(run(base / f)[:2])
        for i, (solver, scheme, f, _) in enumerate(runs):
            nodes = results[i][0][0]
            walls = [w for _, w in results[i]]
            same &= all(np.array_equal(nodes, n, equal_nan=True) for n, _ in results[i])
            curves.append(
                {
                    "solver": solver,
                    "scheme": scheme,
                    "step_s": base / f,
                    "wall_s": float(np.median(walls)),
                    "wall_min_s": float(np.min(walls)),
                    "walls_s": walls,
                    "error_mm": _max_error_mm(nodes, ref),
                }
            )
        nodes, wall = md_run(None, "RK2")
        blown = ~np.isfinite(nodes).all(axis=(1, 2))
        same_step = [c["wall_s"] for c in curves if c["solver"] == "ours" and c["scheme"] == "Verlet"
                     and abs(c["step_s"] - default_step) < 1e-15]
        out["default_step"] = {
            "ours": {
                "scheme": "Verlet, the step from the spectrum",
                "step_s": default_step,
                "wall_s": same_step[0] if same_step else default_wall,
                "error_mm": _max_error_mm(ours_default, ref),
            },
            "moordyn_own_default": {
                "scheme": "RK2, dtM from its CFL rule",
                "blew_up_at_s": float(np.argmax(blown) * RECORD_DT) if blown.any() else None,
            },
        }

        out["as_briefed"] = _as_briefed(rig, briefed, eq.state, base, duration, md_run, repeats)
        setup["moordyn_instance_median"] = float(np.median(instance))
        out["moordyn_python_overhead_s"] = _python_overhead(md, base, duration, couple)

    out["curves"] = curves
    out["repeat_runs_identical"] = same
    out["setup_s"] = setup
    equal = {}
    for level in levels_mm:
        row = {}
        for key in ("wall_s", "wall_min_s"):  # the fastest repeat is the one least disturbed by other load
            tag = "" if key == "wall_s" else "_from_min"
            ours = {}
            for scheme in ("Verlet", "RK4"):
                rows = [c for c in curves if c["solver"] == "ours" and c["scheme"] == scheme]
                t, bound = time_to_error([c[key] for c in rows], [c["error_mm"] for c in rows], level)
                name = "ours" if scheme == "Verlet" else "ours_rk4"  # ours: the default integrator
                row[f"{name}_s{tag}"], row[f"{name}_at_stability_limit"] = t, bound
                ours[scheme] = t
            for scheme in ("RK4", "RK2"):
                rows = [c for c in curves if c["solver"] == "moordyn" and c["scheme"] == scheme]
                t_md, b_md = time_to_error([c[key] for c in rows], [c["error_mm"] for c in rows], level)
                row[f"moordyn_{scheme.lower()}_s{tag}"] = t_md
                row[f"moordyn_{scheme.lower()}_at_stability_limit"] = b_md
                row[f"ratio_{scheme.lower()}{tag}"] = t_md / ours["Verlet"]
                row[f"ratio_{scheme.lower()}_ours_rk4{tag}"] = t_md / ours["RK4"]
        equal[str(level)] = row
    out["equal_accuracy"] = equal
    md_base = next(c for c in curves if c["solver"] == "moordyn" and c["scheme"] == "RK4" and c["step_s"] == base)
    out["default_step"]["ratio_moordyn_rk4_base_step_over_ours_default"] = md_base["wall_s"] / out["default_step"]["ours"]["wall_s"]
    return out
