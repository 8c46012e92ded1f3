"""The integration step: the integrator's stability limit for the model (RK4's or Verlet's).

The ropes' axial modes are the fastest motion in the model (kHz for the
baseline's short elements) and set the explicit step; accuracy needs far
less (docs/model.md: the baseline's error at this step is micrometres). Two
estimates of the fastest mode:

- a Gershgorin bound on M^-1 K at the stiffest configuration the maneuver
  is assumed to reach (``stable_time_step``): cheap and needs no
  equilibrium, but it over-estimates the eigenvalue where particles meet
  rigid bodies and rings, and it assumes ring sides keep three quarters of
  their share, which the dig breaks (the dump rope's short side falls to a
  fifth), so it relies on a measured margin;
- the spectrum of the right-hand side's Jacobian at the starting state
  (every mode: axial, transverse under tension, body rotation, ring slide,
  Maxwell relaxation), against RK4's exact stability region (or Verlet's
  h |lambda| <= 2)
  (``start_time_step``): exact there, and carried through the run by
  ``_tracked.integrate_tracked``, which cuts the step as the Gershgorin
  bound of the current state grows (stiffness goes as 1 / element length,
  and the bound follows that exactly). ``simulate`` uses this one.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from scipy.sparse.linalg import ArpackError, eigs

from . import _kernel
from ._blas import one_blas_thread
from ._tracked import gershgorin_lambda, state_gershgorin_lambda
from ._verlet import VERLET_IMAGINARY_LIMIT

__all__ = ["stable_time_step", "start_time_step", "rk4_step_limit", "verlet_step_limit", "rhs_jacobian",
           "largest_eigenvalues"]

# RK4's stability interval on the imaginary axis: |R(iy)| <= 1 for |y| <= 2 sqrt(2).
RK4_IMAGINARY_LIMIT = 2.0 * np.sqrt(2.0)
# Safety factors, measured (see the functions' notes), not assumed.
GERSHGORIN_SAFETY = 0.75
SPECTRAL_SAFETY = 0.85
VERLET_SAFETY = 0.85
# Arnoldi basis size for the largest eigenvalues: 20 took 150 ms at ``high``
# (its two fastest modes are 0.01 % apart), 40 and 80 took 15-20 ms.
ARPACK_NCV = 40


def stable_time_step(model, safety=GERSHGORIN_SAFETY, state=None, t=None, integrator="rk4"):
    """A fixed step (s) for the whole maneuver, from the Gershgorin bound.

    The bound is taken at the stiffest the maneuver makes the rig before it
    runs: every segment at its shortest, ring sides at three quarters of
    their share (``state``, when given, sets the shares; an even split
    without). With ``t``, the segments are taken at their lengths of that
    time instead (the statics' relaxation, whose lengths are frozen there,
    steps with it: a reel table that runs a rope to nothing later in the
    maneuver once set a step of femtoseconds for the statics at its start).

    Notes
    -----
    The bound leaves out the transverse (tension) stiffness and ring sides
    shrinking below three quarters of their share, so the safety factor was
    measured: at the high level, 0.9 of the bound let an asymmetric mode
    grow slowly over the 10 s dig, 0.8 did not; 0.75 keeps a margin.
    ``simulate`` uses ``start_time_step`` and a tracked step instead.
    """
    Lmin = (model.segment_lengths(model.arrays["reel_t"]).min(axis=1) if t is None
            else model.segment_lengths(np.array([float(t)])).min(axis=1))
    worst = gershgorin_lambda(_shortest_rest_lengths(model, Lmin, state), Lmin, model.kernel_tuple())
    if worst == 0.0:  # nothing stiff: a step that still resolves 1 kHz
        return 1e-3
    limit = VERLET_IMAGINARY_LIMIT if integrator == "verlet" else RK4_IMAGINARY_LIMIT
    return safety * limit / np.sqrt(worst)


def start_time_step(model, state, t=None, safety=None, integrator="rk4"):
    """The integration step (s) at ``state`` from the spectrum, and the Gershgorin bound there.

    Parameters
    ----------
    model : Model
    state : ndarray
        Where the run starts (the statics' rest pose, or any state).
    t : float, optional
        Its time (s); the maneuver's start by default.
    safety : float, optional
        Fraction of the integrator's stability limit for the Jacobian's
        eigenvalues; ``SPECTRAL_SAFETY`` (RK4) or ``VERLET_SAFETY`` by default.
    integrator : {"rk4", "verlet"}

    Returns
    -------
    dt : float
        Step (s).
    lam : float
        Gershgorin bound (rad^2/s^2) at ``state``: ``integrate_tracked``
        cuts the step by sqrt(lam / bound now) once the rig is stiffer.

    Notes
    -----
    The default safety was measured with the 10 s dig and the tracked step
    (``integrate_tracked``) at fractions f of the limit: at every level
    (low to high) f = 1.0 ran with the accuracy of smaller steps, f = 1.1
    blew up (low) or let a mode grow (0.2-1.4 mm off), f = 1.25 blew up
    within a second; 0.85 keeps a 15 % margin
    (``tests/test_time_step.py`` holds the low level to this).
    """
    t = float(model.arrays["reel_t"][0]) if t is None else float(t)
    m = model.kernel_tuple()
    lam = state_gershgorin_lambda(t, np.asarray(state, float), m, _kernel.make_work(m))
    # One BLAS thread: many-threaded LAPACK on a busy 2-core machine (the
    # diagnosis simulates in parallel processes) took 20x longer here.
    with one_blas_thread():
        jacobian = rhs_jacobian(model, state, t)
        if integrator == "verlet":
            return (VERLET_SAFETY if safety is None else safety) * verlet_step_limit(largest_eigenvalues(jacobian)), lam
        eigenvalues = np.linalg.eigvals(jacobian)
    return (SPECTRAL_SAFETY if safety is None else safety) * rk4_step_limit(eigenvalues), lam


def largest_eigenvalues(matrix, ncv=ARPACK_NCV):
    """The eigenvalues of largest magnitude of a square matrix (at least the largest one).

    Verlet's limit needs only the largest |lambda|. ARPACK (implicitly
    restarted Arnoldi, converged to machine precision, from a fixed start
    vector so that a run repeats to the bit) finds it in 3-5 ms at the
    baseline and medium levels and 20 ms at ``high``, where the full
    spectrum takes 24 and 140 ms; they agree to 1e-14. A matrix too small
    for ARPACK, or one where it fails, gets the full spectrum.

    Returns
    -------
    ndarray of complex
    """
    a = np.asarray(matrix, float)
    n = a.shape[0]
    if n > 2 * ncv:
        try:
            return eigs(a, k=2, which="LM", return_eigenvectors=False, tol=0.0, ncv=ncv,
                        v0=np.linspace(1.0, 2.0, n))
        except ArpackError:  # no convergence, or ARPACK refused the matrix
            pass
    return np.linalg.eigvals(a)


def verlet_step_limit(eigenvalues):
    """Largest h with h |lambda| <= 2 for every eigenvalue: kick-drift-kick's limit on an oscillator.

    The Maxwell branches' relaxation, which the Jacobian holds as real
    eigenvalues, is integrated exactly (``_verlet``) and sets no limit; it is
    slow on this rig anyway (|lambda| below 200 /s against 16,000 rad/s for
    the chains' axial modes at baseline).
    """
    lam = np.asarray(eigenvalues, complex)
    big = np.abs(lam).max(initial=0.0)
    return np.inf if big == 0.0 else VERLET_IMAGINARY_LIMIT / big


def rk4_step_limit(eigenvalues):
    """Largest h with |R(h lambda)| <= 1 for every eigenvalue (R: RK4's stability polynomial).

    Eigenvalues far below the largest (slow modes, the rigid swing whose
    tiny positive real parts are rounding) are integrated accurately at any
    step the fast ones allow and are left out.
    """
    lam = np.asarray(eigenvalues, complex)
    big = np.abs(lam).max(initial=0.0)
    if big == 0.0:
        return np.inf
    lam = lam[np.abs(lam) > 1e-2 * big]

    def stable(h):
        z = h * lam
        return np.all(np.abs(1 + z * (1 + z / 2 * (1 + z / 3 * (1 + z / 4)))) <= 1 + 1e-9)

    lo, hi = 0.0, 3.0 / big  # RK4 is unstable beyond |z| = 2.97 on every ray (measured: 2.960)
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo


def rhs_jacobian(model, state, t):
    """d(dy/dt)/dy at ``state`` by central differences, (n_state, n_state)."""
    m = model.kernel_tuple()
    y = np.array(state, float)
    jac = np.empty((y.size, y.size))
    _central_differences(float(t), y, m, _kernel.make_work(m), jac)
    return jac


@njit(cache=True)
def _central_differences(t, y, m, work, jac):
    # Compiled: from Python the 2 n right-hand sides cost 7 ms at the baseline, paid by every simulation.
    n = y.shape[0]
    fp, fm = np.zeros(n), np.zeros(n)
    for j in range(n):
        h = 1e-7 * max(1.0, abs(y[j]))
        keep = y[j]
        y[j] = keep + h
        _kernel.rhs(t, y, fp, m, work)
        y[j] = keep - h
        _kernel.rhs(t, y, fm, m, work)
        y[j] = keep
        for i in range(n):
            jac[i, j] = (fp[i] - fm[i]) / (2.0 * h)


def _shortest_rest_lengths(model, Lmin, state):
    """Each element's rest length at the maneuver's shortest, ring spans at 3/4 of their share."""
    a = model.arrays
    rest = np.empty(model.n_elements)
    for e in range(model.n_elements):
        s = a["el_seg"][e]
        side = a["el_side"][e]
        even = Lmin[s] / a["seg_nel"][s]
        if side == 0:
            rest[e] = even
            continue
        if state is None:
            rest[e] = 0.75 * even
            continue
        rings = model.seg_rings[model.seg_names[s]]
        bounds = [0.0] + [state[model.o_ring + 2 * r] for r in rings] + [Lmin[s]]
        share = (bounds[side] - bounds[side - 1]) / np.count_nonzero(a["el_side"][model.seg_elements[model.seg_names[s]]] == side)
        rest[e] = 0.75 * min(share, even)
    return rest
