"""One step of ALI3-P (index-3 augmented Lagrangian with projections) on the trapezoidal rule, in
viz3d's velocity variables ``v = [W_v, B_omega]`` (seed 004, eqs. 3.17-3.28; docs/notation.md).

The seed writes the method for coordinates whose derivative is the velocity (natural
coordinates). Here positions live on ``R^3 x SO(3)`` per body, so the unknown of a step is the
velocity-space increment ``dx`` (n_v,) that moves the positions, ``q1 = retract(q0, dx)``
(``W_r + dW_r``, ``R_WB exp(skew(B_dphi))``), and the trapezoidal rule reads

    dx = h (v0 + v1) / 2,   v1 = v0 + h (a0 + a1) / 2,

so that ``v1 = 2 dx / h - v0`` and ``a1 = 4 dx / h^2 - 4 v0 / h - a0`` (eqs. 3.19, 3.20). The
equations of motion at ``t1``, scaled by ``h^2 / 4`` (eq. 3.23), are solved for ``dx`` by
Newton-Raphson with the approximate tangent (eq. 3.26)

    T = M + h/2 D + h^2/4 (alpha C_v^T C_v + K),   K = -dQ/dx,  D = -dQ/dv,

(the seed prints ``K = dQ/dq``, ``C = dQ/dq_dot``: the minus signs are needed for ``T`` to be the
derivative of its residual), and ``lam* += alpha C`` after each iteration (eq. 3.18). ``K`` and
``D`` come from finite differences of the applied and gyroscopic forces; they are kept between
steps and rebuilt when the iteration stalls; an iteration that still contracts slowly switches
to Newton on the exact tangent of its residual by finite differences (the seed's tangent omits the
geometric stiffness of the constraint forces ``d(C_v^T lam)/dx`` and, on rotations, the
kinematics of the increment: it matters when joint arms turn fast). Then velocities and accelerations are projected
with the same matrix (eqs. 3.27, 3.28), ``gamma = -C_v_dot v`` standing for ``-Phi_q_dot q_dot``.

Above ``DENSE_MAX`` unknowns the matrices are sparse (``M`` block diagonal, ``C_v`` 12 entries per
row, the force tangents with the zeros their finite differences leave) and ``T`` is factored by
SuperLU with a fill-reducing column order: on a chain its factors stay banded, so a step costs
O(N) in the number of links, not the O(N^3) of a dense LU; below, dense matrices and LAPACK cost
less. The finite-difference tangents difference the columns of bodies that share no neighbour
together (``viz3d.sparsity``): 2 x 18 + 1 force evaluations on a chain of any length.

Forces with branches (``ForceElement.branches``: shape contacts that touch or not, on one face or
another, stops engaged or not) would make the residual a non-smooth function of the iterate: a
contact set that changes between iterates stalls the iteration. A step therefore holds them as they
are at its predictor (``ForceElement.frozen``: contacts as material points against tangent planes,
an active set, anchors fixed), iterates on that smooth problem, may take the exact tangent there,
and checks the branches found at its converged point; where they move the solution by more than
the tolerance, it iterates again from there with those (``_solve``, ``MAX_SET_UPDATES``). Where that
cycles (each of two sets' solutions finds the other: the forces jump between them within the step,
a stop's damper as the stop is reached, a face pressed on a face found at two or at four points),
the solution is on the boundary between the two sets, with forces between theirs (Filippov's): a
bisection on the blend of the two sets' forces finds it (``_filippov``).

The method is written here, on NumPy: the reference. When the compiled kernel covers the system,
``viz3d.simulate.Simulation`` gives the memory a ``viz3d.kernel.ali3p.KernelALI3P``: the attempts of
a step (``_one_step``) are one compiled call of the same iteration (the same stopping tests,
``small_update``, ``too_slow`` and ``refresh_tangent`` compiled from this module, the same tangents
and counts of evaluations, the same held branches, check and re-solve: ``hold_piece``) on band
matrices in an order of the bodies that narrows the band and LAPACK's banded LU, and a run's steps
from one output frame to the next are one call too (``KernelALI3P.frames``); a step that fails
comes back here for its halvings and diagnosis.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from viz3d._typing import FloatArray
from viz3d.compiled import entry
from viz3d.constraints import constraint_rows, dense_jacobian, residual_and_jacobian, sparse_jacobian
from viz3d.dynamics import accelerations, aux_rates, body_state, drive_power, flat_velocity, generalized_forces, retract
from viz3d.integrators.base import Status
from viz3d.integrators.implicit import FD_REL
from viz3d.mass import dense_mass_matrix, sparse_mass_matrix
from viz3d.sparsity import grouped_fd_jacobian, sparse_fd_plan
from viz3d.system import State, System

#: Iterations of the augmented-Lagrangian Newton loop per attempt.
MAX_ITER = 40
#: A step that needed more iterations than this rebuilds the force tangent for the next step.
REFRESH_ITER = 12
#: An iteration contracting slower than this (after 3 updates) switches to Newton on the exact
#: tangent of its residual, by finite differences, rebuilt while the contraction stays slow.
SLOW_RATE = 0.5
#: An iteration whose updates stop shrinking (rate above STALL_RATE) while below
#: ROUND_OFF_FACTOR times the tolerance has reached round-off: accepted if |C| <= tol.
STALL_RATE, ROUND_OFF_FACTOR = 0.9, 100.0
#: A step that fails is retried as two halves, down to ``h / 2**MAX_HALVINGS``.
MAX_HALVINGS = 3
#: Why an attempt failed, besides ``no_convergence`` (the reason in the step's diagnosis).
NONFINITE_STATE, SINGULAR_MATRIX = "non-finite state", "singular iteration matrix"
#: A step's iteration holds the branches of the forces that have them (``ForceElement.branches``:
#: which shape contacts push, on which faces, with which anchors; which stops are engaged) as they
#: are at its predictor; where those found at the converged configuration move the solution by more
#: than the tolerance, it is solved again with them, from there: at most this many times (``_solve``).
MAX_SET_UPDATES = 3
#: A held set that cycles (``_solve``: the solution of an update back within ``ROUND_OFF_FACTOR`` times
#: the tolerance of the one two updates before) straddles a jump of the forces between two branch sets; the step's
#: solution is then sought between them (``_filippov``) by at most this many bisections.
MAX_BISECTIONS = 30
#: Halvings of an update in a row that an iteration on the exact tangent may take where it overshoots
#: (systems whose forces have branches: ``_iterate``'s line search).
MAX_CUTS = 4
#: Systems up to this many velocity unknowns factor T densely (21 rigid bodies; above, multithreaded
#: LAPACK on this 2-core machine took 28 ms for the 150 x 150 T of 25 links where SuperLU takes 3.6 ms).
DENSE_MAX = 128


@dataclass(frozen=True)
class ALI3PMemory:
    """What ALI3-P carries from one step to the next (held by ``viz3d.simulate.Simulation``).

    Attributes
    ----------
    v_dot : ndarray, shape (n_v,)
        Accelerations at the current state [m/s^2, rad/s^2] (eq. 3.20 needs them).
    lam : ndarray, shape (n_c,)
        Augmented-Lagrangian multipliers ``lam*`` [N].
    K, D : sparse matrix, shape (n_v, n_v), or None
        Force tangents ``-dQ/dx`` [N/m, N] and ``-dQ/dv`` [N s/m, N s], possibly from an
        earlier step; ``None``: rebuild before the next step.
    n_evals : int
        Evaluations of forces and constraint rows so far (the cost, like vector-field evaluations).
    plan : tuple
        ``viz3d.sparsity.sparse_fd_plan`` of the system: which columns one evaluation differences
        together for the tangents.
    w_dot : ndarray, shape (n_aux,)
        Rates of the energy ledger's work integrals at the current state [W] (``aux_rates``): the
        step integrates them by the trapezoidal rule, like the motion.
    kernel : viz3d.kernel.ali3p.KernelALI3P or None
        Takes the steps in the compiled kernel (then ``K``, ``D`` are its band matrices); None: here,
        on NumPy (module docstring).
    """

    v_dot: FloatArray
    lam: FloatArray
    K: FloatArray | None
    D: FloatArray | None
    n_evals: int = 0
    plan: tuple = ()
    w_dot: FloatArray = field(default_factory=lambda: np.zeros(0))
    kernel: object = None


@dataclass(frozen=True)
class _Point:
    """Everything the iteration needs at one trial increment ``dx``."""

    q: FloatArray
    v: FloatArray
    a: FloatArray
    C: FloatArray
    Cv: object  # sparse (n_c, n_v)
    Q: FloatArray
    M: object  # sparse (n_v, n_v)


@dataclass(frozen=True)
class _Converged:
    """A converged iteration: its last trial point and increment ``dx`` (n_v,), multipliers ``lam``
    (n_c,), the factors ``lu`` of its last iteration matrix and ``W`` (eq. 3.26 without the
    constraints)."""

    p: _Point
    dx: FloatArray
    lam: FloatArray
    lu: object
    W: object


@dataclass(frozen=True)
class _Mix:
    """Two held memories of the force elements (``_held``) whose forces are blended:
    ``Q = (1 - theta) Q(a) + theta Q(b)`` (``_filippov``)."""

    theta: float
    a: tuple
    b: tuple


def init_memory(system: System, formulation, state: State, kernel=None) -> ALI3PMemory:
    """Initial accelerations and multipliers from ``formulation.start`` (the penalty method);
    ``kernel``: a ``viz3d.kernel.ali3p.KernelALI3P`` that takes the steps (None: NumPy)."""
    acc = accelerations(system, formulation.start, state.t, state.q, state.v, state.chart,
                        elements=state.element_memory)
    w_dot = np.zeros(0)
    if system.n_aux:
        start = state.replace(memory=())
        w_dot = (work_rates(system, formulation, start) if kernel is None
                 else kernel.work_rates(system, formulation, start))
    return ALI3PMemory(acc.v_dot, acc.lam, None, None, 1, sparse_fd_plan(system), w_dot, kernel)


def _work_rates(system: System, state: State, acc) -> FloatArray:
    """The ledger's work rates at ``state`` (n_aux,) [W] from its accelerations and index-1 multipliers
    ``acc`` (``viz3d.dynamics.Accelerations``)."""
    return aux_rates(system, acc.cfg, state.memory, state.element_memory, drive_power(acc.lam, acc.rows.C_t))


def ali3p_step(system: System, formulation, state: State, h: float, memory: ALI3PMemory, halvings: int = 0,
               failed: tuple[ALI3PMemory, Status] | None = None) -> tuple[State, ALI3PMemory, Status]:
    """Advance ``state`` by ``h`` [s]; return the new state, memory and a status.

    Tries with the kept force tangent first, then once with a fresh one, then as two steps of
    ``h / 2`` (down to ``h / 2^MAX_HALVINGS``: a contact that starts within the step, a snatch of a
    chain); a failed step returns the old state and memory with the reason. ``failed``: the memory and
    status those first attempts already gave (a batched kernel call stopped there), not redone.
    """
    if failed is None:
        state1, memory1, status = _one_step(system, formulation, state, h, memory)
    else:
        state1, (memory1, status) = state, failed
    if status.ok or halvings >= MAX_HALVINGS:
        return state1, memory1, status
    mid, memory_mid, status = ali3p_step(system, formulation, state, h / 2, memory1, halvings + 1)
    if not status.ok:
        return state, memory_mid, status
    end, memory_end, status = ali3p_step(system, formulation, mid, h / 2, memory_mid, halvings + 1)
    return (end, memory_end, status) if status.ok else (state, memory_end, status)


def _one_step(system: System, formulation, state: State, h: float, memory: ALI3PMemory
              ) -> tuple[State, ALI3PMemory, Status]:
    """The attempts of a step: with the kept force tangent, then with a fresh one (or only with a
    fresh one); in the compiled kernel when the memory has one."""
    if memory.kernel is not None:
        return memory.kernel.step(system, formulation, state, h, memory)
    with np.errstate(all="ignore"):
        held = _held(system, state, _predictor(state, memory, h), h)
        for fresh in ((False, True) if memory.K is not None else (True,)):
            if fresh:
                K, D = _force_tangent(system, state, memory, h, held)
                memory = replace(memory, K=K, D=D, n_evals=memory.n_evals + 2 * len(memory.plan[0]) + 1)
            result, evals = _solve(system, formulation, state, h, memory, held, exact_ok=fresh)
            if isinstance(result, _Converged):
                try:
                    return _finish(system, formulation, state, result, h, memory, evals) + (Status.OK,)
                except RuntimeError:
                    result = SINGULAR_MATRIX
            memory = replace(memory, n_evals=memory.n_evals + evals)
    return state, memory, failure(state, h, result)


def _force_tangent(system: System, state: State, memory: ALI3PMemory, h: float, held: tuple):
    """``force_tangent`` at ``state``, or, when the iteration holds some forces' choices (``_held``),
    with them at the predictor, where they were taken: a contact that begins within the step has no
    stiffness yet at ``state``."""
    if held is state.element_memory:
        return force_tangent(system, state.t, state.q, state.v, state.chart, memory.plan, held)
    dx = _predictor(state, memory, h)
    return force_tangent(system, state.t + h, retract(system, state.q, dx, state.chart), 2.0 / h * dx - state.v,
                         state.chart, memory.plan, held)


def _predictor(state: State, memory: ALI3PMemory, h: float) -> FloatArray:
    """The increment (n_v,) of the trapezoidal rule with ``a1 = a0``: the iteration's first iterate."""
    return h * state.v + 0.5 * h * h * memory.v_dot


def _held(system: System, state: State, dx: FloatArray, h: float) -> tuple:
    """``state.element_memory`` with the ``branches`` of the force elements held as they are at the
    trial point of the increment ``dx`` (``ForceElement.frozen``): the forces the iteration
    evaluates, smooth in the iterate; ``state.element_memory`` itself when no element has branches."""
    if not any(e.branches for e in system.forces):
        return state.element_memory
    q1, t1 = retract(system, state.q, dx, state.chart), state.t + h
    cfg = body_state(system, q1, 2.0 / h * dx - state.v, state.chart, t1)
    old = state.element_memory or (None,) * len(system.forces)
    return tuple(e.frozen(cfg, m) if e.branches else m for e, m in zip(system.forces, old))


def _solve(system, formulation, state, h, memory, held: tuple, exact_ok: bool):
    """The iteration (``_iterate``) with the forces' branches ``held`` (``_held``), then, at its
    converged point, the check against the forces found there: the difference of the two Newton
    updates there (the solution's shift, to first order, overestimated where the iteration matrix
    lacks a contact's stiffness) within the tolerance, or the iteration goes on from that point with
    the branches found there held, until it moves the solution by less than the tolerance
    (``MAX_SET_UPDATES`` times at most; then the reason names what changed, and where). Branches found
    unchanged, with held contacts as deep as those found to ``ROUND_OFF_FACTOR * tol``, settle it too.
    A solution back within ``ROUND_OFF_FACTOR * tol`` of the one two updates before is a cycle (its
    branches, held where they were found, are the same as then to the resolution ``_change`` grants
    the narrow phase; m9 of the hoist's heel-5 ensemble: 3.7e-8 to 3.2e-7 m apart):
    ``_filippov`` solves the step between its two sets. ``(result, evaluations)``, the result a ``_Converged`` or a
    reason string. An active-set strategy, as implicit contact methods take it."""
    dx, lam, evals = _predictor(state, memory, h), memory.lam, 0
    search = held is not state.element_memory
    solutions = []  # of the updates before
    for update in range(MAX_SET_UPDATES + 1):
        result, n = _iterate(system, formulation, state, h, memory, exact_ok, dx, lam, held, search)
        evals += n
        if not isinstance(result, _Converged) or not search:
            return result, evals
        if update and np.max(np.abs(result.dx - dx)) <= formulation.tol:
            return result, evals  # the branches found at the last solution moved it by less than tol
        found = _point(system, state, memory.v_dot, result.dx, h, state.t + h, result.p.M, state.element_memory)
        evals += 1
        shift = result.lu.solve(0.25 * h * h * (result.p.Q - found.Q))
        if np.max(np.abs(shift), initial=0.0) <= formulation.tol:
            return result, evals
        change = _change(system, state, result.dx, h, held, ROUND_OFF_FACTOR * formulation.tol)
        if not change:  # the same branches, the held contacts' depths those found to the narrow phase's
            return result, evals  # resolution (a face on a face: which witness points is arbitrary)
        here = _held(system, state, result.dx, h)
        if len(solutions) >= 2 and np.max(np.abs(result.dx - solutions[-2].dx)) <= ROUND_OFF_FACTOR * formulation.tol:
            # a cycle: the branches found here were held for the last solution, which found these (held
            # where they were found: the same to the narrow phase's resolution, ``_change``)
            out, n = _filippov(system, formulation, state, h, memory, exact_ok, held, here, result, solutions[-1])
            return out, evals + n
        solutions.append(result)
        dx, lam, held = result.dx, result.lam, here
    return _unsettled(state.t + h, change, np.max(np.abs(shift))), evals


def _filippov(system, formulation, state, h, memory, exact_ok: bool, held_a: tuple, held_b: tuple, lo: _Converged,
              hi: _Converged):
    """The step's solution where the held branches cycle (``_solve``): held as ``held_a`` the iteration
    converges to ``lo``, where the branches ``held_b`` are found; held as those, to ``hi``, where
    ``held_a``'s are found. The forces jump between the two sets and neither set's equations have a
    solution that keeps it: the solution is on the boundary between them, where the forces take a
    value between both (Filippov's convex combination, as a stop reached or a contact touched within
    the step). The forces ``(1 - theta) Q(held_a) + theta Q(held_b)`` (``_Mix``) move the solution from
    ``lo`` (theta = 0, ``held_b`` found) to ``hi`` (theta = 1, ``held_a`` found); bisection on theta
    (``MAX_BISECTIONS``) keeps a solution on each side until the two are within ``ROUND_OFF_FACTOR *
    tol`` (the resolution ``_change`` grants the narrow phase's contact depths, and ``small_update`` a
    stalled iteration: the solutions along theta are not known closer). The accepted point (the
    ``held_b`` side's) solves the equations of motion with forces in the convex hull of the two sets'
    to the tolerance (constraints within ``tol``), within ``ROUND_OFF_FACTOR * tol`` of the boundary. Branches of a third
    set found between them, or a bisection that does not close, fail the attempt with the reason.
    ``(result, evaluations)`` as ``_solve``'s."""
    tol, evals = formulation.tol, 0
    t_lo, t_hi = 0.0, 1.0
    for _ in range(MAX_BISECTIONS):
        if np.max(np.abs(hi.dx - lo.dx)) <= ROUND_OFF_FACTOR * tol:
            return lo, evals
        theta = 0.5 * (t_lo + t_hi)
        mid, n = _iterate(system, formulation, state, h, memory, exact_ok, 0.5 * (lo.dx + hi.dx),
                          0.5 * (lo.lam + hi.lam), _Mix(theta, held_a, held_b), True)
        evals += n
        if not isinstance(mid, _Converged):
            return mid, evals
        if not _change(system, state, mid.dx, h, held_b, np.inf):
            lo, t_lo = mid, theta
        elif not _change(system, state, mid.dx, h, held_a, np.inf):
            hi, t_hi = mid, theta
        else:
            return cycled(state.t + h), evals
    return cycled(state.t + h), evals


def cycled(t1: float) -> str:
    """The reason of an attempt whose held branches cycled and whose bisection (``_filippov``) found
    another set between the two, or did not close, by ``t1`` [s]."""
    return (f"the contact set cycled at t = {t1:.6g} s and no boundary between its two sets was found in "
            f"{MAX_BISECTIONS} bisections")


def _unsettled(t1: float, change: str, shift: float) -> str:
    """The reason of an attempt whose held branches did not settle (``_solve``) by ``t1`` [s]: what
    changed (``_change``) and by how much it moved the solution [m, rad]."""
    return (f"the contact set did not settle in {MAX_SET_UPDATES} updates at t = {t1:.6g} s: {change}, "
            f"moving the solution by {shift:.2e}")


def not_settled(system: System, formulation, state: State, h: float, dx_held: FloatArray, dx: FloatArray,
                shift: float) -> str:
    """``_unsettled`` of an attempt (the compiled kernel's) whose last iteration held the branches found
    at the trial point of the increment ``dx_held`` (n_v,) and converged to ``dx`` (n_v,), where those
    found moved the solution by ``shift`` [m, rad]."""
    held = _held(system, state, dx_held, h)
    return _unsettled(state.t + h, _change(system, state, dx, h, held, ROUND_OFF_FACTOR * formulation.tol), shift)


def _change(system: System, state: State, dx: FloatArray, h: float, held: tuple, tol: float) -> str:
    """What the elements with branches find at the trial point of ``dx`` that differs from what they
    ``held``, beyond positions within ``tol`` [m] (``ForceElement.frozen_change``); '' if nothing."""
    cfg = body_state(system, retract(system, state.q, dx, state.chart), 2.0 / h * dx - state.v, state.chart,
                     state.t + h)
    said = [e.frozen_change(cfg, m, tol) for e, m in zip(system.forces, held) if e.branches]
    return "; ".join(s for s in said if s)


def failure(state: State, h: float, reason: str) -> Status:
    """The failed status of a step of ``h`` [s] from ``state`` whose last attempt failed for ``reason``."""
    return Status.failed(f"t = {state.t:.6g} s: ALI3-P iteration did not converge in {MAX_ITER} iterations with "
                         f"h = {h:.3g} s ({reason}); try a smaller sim.dt or another sim.ali3p_alpha")


def no_convergence(step: float, C_max: float) -> str:
    """The reason of an attempt that used up its iterations: its last update [m, rad] and max |C| [m]."""
    return f"last update {step:.2e}, max |C| = {C_max:.2e} m"


@entry
def refresh_tangent(evals: int) -> bool:
    """Does a step that took ``evals`` evaluations rebuild the force tangent for the next? (Compiled,
    like ``small_update``.)"""
    return evals > REFRESH_ITER


def _iterate(system, formulation, state, h, memory, exact_ok: bool, dx: FloatArray, lam: FloatArray,
             elements: tuple, search: bool = False):
    """Newton-Raphson + multiplier updates from the increment ``dx`` (n_v,) and multipliers ``lam``
    (n_c,), the force elements evaluated with the memory ``elements``: ``(result, evaluations)``, the
    result a ``_Converged`` or a reason string if it fails. With ``exact_ok``, an iteration that would
    not converge within ``MAX_ITER`` at its present rate switches to the exact tangent; with
    ``search`` (held branches, ``_solve``), an update on it after which the residual (max norm) is larger
    than where the update was taken is halved back (``MAX_CUTS`` times in a row at most). (The test was the
    size of the next update, more than ``SLOW_RATE`` times the last: where the exact tangent is poor, a
    kink of forces not held, it backed off updates that had shrunk the residual, and the iteration
    stalled: the hoist's jammed anchor, 40 iterations at an update of 1e-7 to 1e-6 m.)"""
    alpha, tol, t1 = formulation.alpha, formulation.tol, state.t + h
    M = mass_matrix(system, state)
    W = M + 0.5 * h * memory.D + 0.25 * h * h * memory.K
    lam = lam.copy()
    lu, step, prev, exact, evals, last, cuts, base = None, np.inf, np.inf, False, 0, None, 0, np.inf
    for it in range(MAX_ITER):
        try:
            p = _point(system, state, memory.v_dot, dx, h, t1, M, elements)
        except OverflowError:  # a diverging iterate (force laws on math's exp)
            return NONFINITE_STATE, evals + 1
        evals += 1
        if not (np.all(np.isfinite(p.C)) and np.all(np.isfinite(p.Q))):
            return NONFINITE_STATE, evals
        rate = np.inf
        if it > 0:
            lam += alpha * p.C
            rate = step / prev if np.isfinite(prev) else np.inf
            if small_update(step, rate, tol) and np.max(np.abs(p.C), initial=0.0) <= tol:
                return _Converged(p, dx, lam, lu, W), evals
        prev = step
        residual = _residual(p, alpha, lam, h)
        if lu is None:
            try:
                lu = _factor(W + 0.25 * h * h * alpha * (p.Cv.T @ p.Cv))
            except RuntimeError:
                return SINGULAR_MATRIX, evals
        elif exact_ok and (exact or it >= 3) and rate > SLOW_RATE and (exact or too_slow(step, rate, tol, MAX_ITER - it)):
            # slow: Newton on the exact tangent (turning joint arms, rotation kinematics,
            # gyroscopic terms), rebuilt at every iterate while the contraction stays slow
            tangent = _residual_tangent(system, state, memory.v_dot, dx, h, t1, M, alpha, lam, residual, memory.plan,
                                        elements)
            evals += len(memory.plan[0])
            try:
                lu, exact = _factor(_matrix(tangent)), True
            except RuntimeError:  # a singular difference tangent: go on with the approximate one
                exact_ok = False
        ddx = lu.solve(-residual)
        size = np.max(np.abs(residual))
        if search and exact and size > base and cuts < MAX_CUTS:
            # the update that led here overshot: the residual grew (a friction law steep near sticking,
            # a kink): back half-way along it (a backtracking line search on max |residual|)
            ddx, last, cuts = -0.5 * last, 0.5 * last, cuts + 1
        else:
            last, cuts, base = ddx, 0, size
        step = np.max(np.abs(ddx))
        dx = dx + ddx
    return no_convergence(step, np.max(np.abs(p.C), initial=0.0)), evals


@entry
def small_update(step: float, rate: float, tol: float) -> bool:
    """Has an iteration whose last update was ``step`` [m, rad], contracting at ``rate``, converged
    (with max |C| <= tol)? The update, or the error still ahead of a contracting iteration, is below
    ``tol``, or it stopped contracting at the round-off floor of the penalty forces (about
    alpha h^2 / (4 m) eps |q|, comparable to tol for stiff alpha). Compiled: the kernel's iteration
    takes this same test."""
    return (step <= tol or (rate < 1.0 and rate / (1.0 - rate) * step <= tol)
            or (rate >= STALL_RATE and step <= ROUND_OFF_FACTOR * tol))


def _finish(system, formulation, state, done: _Converged, h, memory, evals: int) -> tuple[State, ALI3PMemory]:
    """Project velocities (eq. 3.27, with the drives' explicit rate ``C_t``: ``C_v v = -C_t``) and
    accelerations (eq. 3.28) with the matrix ``W + h^2/4 alpha C_v^T C_v`` at the converged
    positions. A step that needed more than ``REFRESH_ITER`` evaluations rebuilds the force tangent
    for the next."""
    alpha, p, W, lam, t1 = formulation.alpha, done.p, done.W, done.lam, state.t + h
    T = _factor(W + 0.25 * h * h * alpha * (p.Cv.T @ p.Cv))
    C_t = _rows(system, p.q, p.v, state.chart, t1)[0]
    v = T.solve(W @ p.v if C_t is None else W @ p.v - 0.25 * h * h * alpha * (p.Cv.T @ C_t))
    gamma = _rows(system, p.q, v, state.chart, t1)[1]
    a = T.solve(W @ p.a + 0.25 * h * h * alpha * (p.Cv.T @ gamma))
    keep = not refresh_tangent(evals)
    new = State(t1, p.q, v, state.chart, element_memory=state.element_memory)  # (renewed by the simulation)
    w_dot = np.zeros(0)
    if system.n_aux:  # the ledger's work integrals by the trapezoidal rule; the drives' power from the
        # index-1 multipliers at the new state (those the frames report), not lam*
        new = new.replace(memory=state.memory)
        w_dot = work_rates(system, formulation, new)
        new = new.replace(w=state.w + 0.5 * h * (memory.w_dot + w_dot))
    return new, replace(memory, v_dot=a, lam=lam, K=memory.K if keep else None, D=memory.D if keep else None,
                        n_evals=memory.n_evals + evals + 1 + (1 if w_dot.size else 0), w_dot=w_dot)


class _DenseLU:
    """LAPACK's LU of a dense matrix with SuperLU's ``solve`` interface; ``RuntimeError`` if the
    matrix is singular (as SuperLU raises)."""

    def __init__(self, A):
        from scipy.linalg import lu_factor
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # scipy warns of an exactly singular matrix: raised below
            self.lu = lu_factor(A, check_finite=False)
        if not np.all(np.diag(self.lu[0])):
            raise RuntimeError("singular matrix")

    def solve(self, b):
        from scipy.linalg import lu_solve
        return lu_solve(self.lu, b)


def _factor(A):
    """Factors of the square matrix ``A`` with ``.solve(b)``: SuperLU (COLAMD column order) for a
    sparse one, LAPACK's LU for a dense one (``_dense``)."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu
    return splu(sp.csc_matrix(A)) if sp.issparse(A) else _DenseLU(A)


@entry
def too_slow(step: float, rate: float, tol: float, left: int) -> bool:
    """Would an iteration contracting at ``rate`` miss ``tol`` within ``left`` more updates? (Compiled,
    like ``small_update``.)"""
    return rate >= 1.0 or step * rate**left > tol


def _residual(p: _Point, alpha, lam, h) -> FloatArray:
    """Equations of motion at ``t1`` scaled by ``h^2 / 4`` (eq. 3.23), shape (n_v,) [N s^2]."""
    return 0.25 * h * h * (p.M @ p.a + p.Cv.T @ (alpha * p.C + lam) - p.Q)


def _residual_tangent(system, state, a0, dx, h, t1, M, alpha, lam, r0, plan, elements: tuple):
    """``d residual / d dx`` at fixed multipliers by forward differences, sparse (n_v, n_v), columns
    grouped by ``plan`` (``viz3d.sparsity``): everything the seed's tangent (eq. 3.26) leaves out
    (the geometric stiffness of the constraint forces, the rotation kinematics, gyroscopic terms at
    the iterate) is in it."""
    return grouped_fd_jacobian(lambda x: _residual(_point(system, state, a0, x, h, t1, M, elements), alpha, lam, h),
                               dx, r0, *plan, FD_REL * np.maximum(np.abs(dx), 1.0))


def mass_matrix(system: System, state: State):
    """``M`` (n_v, n_v) at ``state`` [kg, kg m^2, ...], dense or sparse (``_dense``): ``diag(m I3, I)``
    per rigid body, the flexible bodies' blocks at their configuration."""
    cfg = body_state(system, state.q, state.v, state.chart, state.t)
    return dense_mass_matrix(system, cfg) if _dense(system) else sparse_mass_matrix(system, cfg)


def _dense(system: System) -> bool:
    """Dense matrices up to ``DENSE_MAX`` velocity unknowns (their lower overhead wins), sparse above."""
    return system.n_v <= DENSE_MAX


def force_tangent(system: System, t: float, q: FloatArray, v: FloatArray, chart: FloatArray, plan: tuple = (),
                  elements: tuple = ()):
    """``K = -dQ/dx`` and ``D = -dQ/dv``, (n_v, n_v), dense or sparse (``_dense``), by forward
    differences of the applied and gyroscopic forces
    (``dx``: velocity-space displacement of the positions), columns grouped by ``plan``
    (``viz3d.sparsity.sparse_fd_plan``; default: built here); ``elements``: the force elements'
    memory (``State.element_memory``), fixed during a step."""
    def forces(q_, v_):
        return flat_velocity(system, *generalized_forces(system, body_state(system, q_, v_, chart, t),
                                                         elements=elements))

    plan = plan or sparse_fd_plan(system)
    Q0 = forces(q, v)
    zero = np.zeros(system.n_v)
    K = -grouped_fd_jacobian(lambda w: forces(retract(system, q, w, chart), v), zero, Q0, *plan,
                             FD_REL * np.ones(system.n_v))
    D = -grouped_fd_jacobian(lambda v_: forces(q, v_), v, Q0, *plan, FD_REL * np.maximum(np.abs(v), 1.0))
    return _matrix(K), _matrix(D)


def _point(system: System, state: State, a0, dx, h: float, t1: float, M, elements: tuple) -> _Point:
    """The trial point of the increment ``dx`` (n_v,) from ``state`` with accelerations ``a0``; ``M``:
    the constant mass matrix of a rigid system (flexible ones carry their own); ``elements``: the
    force elements' memory (``state.element_memory``, or held by ``_held``)."""
    q1 = retract(system, state.q, dx, state.chart)
    v1 = 2.0 / h * dx - state.v
    a1 = 4.0 / (h * h) * (dx - h * state.v) - a0
    cfg = body_state(system, q1, v1, state.chart, t1)
    C, J, Je = residual_and_jacobian(system.joints, cfg)
    C_v = (_dense(system) and dense_jacobian or sparse_jacobian)(system, J, Je)
    Q = _forces(system, cfg, elements)
    if system.n_elastic:
        M = (_dense(system) and dense_mass_matrix or sparse_mass_matrix)(system, cfg)
    return _Point(q1, v1, a1, C, C_v, Q, M)


def _forces(system: System, cfg, elements) -> FloatArray:
    """The applied and gyroscopic forces (n_v,) at ``cfg`` with the force elements' memory ``elements``,
    or the blend of two (``_Mix``)."""
    if isinstance(elements, _Mix):
        return (1.0 - elements.theta) * _forces(system, cfg, elements.a) + elements.theta * _forces(system, cfg,
                                                                                                  elements.b)
    return flat_velocity(system, *generalized_forces(system, cfg, elements=elements))


def _rows(system: System, q, v, chart, t: float):
    """``(C_t, gamma)`` at ``(t, q, v)`` (``C_t`` None without drives)."""
    rows = constraint_rows(system.joints, body_state(system, q, v, chart, t))
    return rows.C_t, rows.gamma


def _matrix(S):
    """A finite-difference tangent (sparse CSC) dense or sparse (``_dense``)."""
    return S.toarray() if S.shape[0] <= DENSE_MAX else S.tocsr()


def work_rates(system: System, formulation, state: State) -> FloatArray:
    """The ledger's work rates at ``state`` (n_aux,) [W] (index-1 multipliers for the drives' power)."""
    return _work_rates(system, state, accelerations(system, formulation, state.t, state.q, state.v, state.chart,
                                                    state.memory, elements=state.element_memory))
