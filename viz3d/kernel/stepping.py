"""Explicit Runge-Kutta steps in the kernel, with what ``viz3d.simulate`` does between steps, in its
order: the ``projection`` formulation's projections (``viz3d.kernel.projection``), the health checks
(as ``viz3d.diagnosis.check_state`` makes them), then per frame the normalisation of Euler parameters
(``Quaternion.normalize``) or the chart switch of Euler angles (``EulerSwitching.rechart``), then the
force elements' memory (``after_step_piece``: shape contacts' stick anchors)."""

from __future__ import annotations

import math

import numpy as np

from viz3d.compiled import after_step_piece, entry, inline, jit
from viz3d.coordinates import SINGULAR_SIN, SWITCH_SIN
from viz3d.diagnosis import MAX_COORDINATE_TURN as MAX_TURN
from viz3d.kernel.field import (NONFINITE, OK, ROTATION, SINGULAR, SPEED, coordinate_rates, frames, rotation,
                                rotation_increment, stages, turn_quaternion)
from viz3d.kernel.projection import project
from viz3d.kernel.sampling import sample_state
from viz3d.points import kinematics

try:
    from numba import literal_unroll
except ImportError:  # pragma: no cover
    def literal_unroll(x):
        return x


@inline
def steps(n_steps, t0, h, y, chart, switches, ta, tb, tc, group, max_speed, m, v, w, forces, rows, memories, k, yi):
    """Take up to ``n_steps`` steps of the tableau ``(ta, tb, tc)`` in place, with the stage scratch
    ``k`` (stages, n) and ``yi`` (n,); returns (steps done, status). With ``group`` 1 (a tableau
    without an error estimate) Euler parameters advance on the group (``stages``, the
    Munthe-Kaas step of ``viz3d.integrators.explicit_rk.ExplicitRK``). Between steps, Euler parameters
    are normalised (``m.n_rot`` 4), frames near gimbal lock are re-charted (``m.switching``) and
    counted in ``switches`` (per body); the run
    stops at the first failed evaluation, non-finite state, frame speed above ``max_speed``, or
    orientation coordinates turning more than ``MAX_TURN`` rad in a step. With ``m.projects``, each
    step's end state is projected onto the constraints first (``viz3d.kernel.projection``: the
    ``projection`` formulation's ``post_step``, in the order of ``viz3d.simulate``); a projection
    that does not converge stops the run with ``PROJECTION``. On a failure ``y`` holds the failed
    step's result; steps done counts it, except when the status is ``SINGULAR`` (an evaluation
    or the projection's solve failed). With ``m.remembers``, the force elements ``memories`` renew
    their memory at each step's end (``renew``) after all that."""
    n = y.shape[0]
    s = tb.shape[0]
    turns = group == 1 and m.n_rot == 4
    n_turned = 7 * m.frame_body.shape[0] if turns else 0  # (q's frame coordinates: 3 + 4 per frame)
    for n_done in range(n_steps):
        status = stages(t0 + n_done * h, h, y, chart, ta, tc, 0, turns, m, v, w, forces, rows, k, yi)
        if status != OK:
            return n_done, status
        for f in range(n_turned // 7):
            u1, u2, u3 = rotation_increment(tb, s, h, k, 7 * f + 3)
            turn_quaternion(y, 7 * f + 3, u1, u2, u3)
        for j in range(n):
            if j < n_turned and j % 7 >= 3:
                continue
            acc = y[j]
            for i in range(s):
                if tb[i] != 0.0:
                    acc += h * tb[i] * k[i, j]
            y[j] = acc
        if not _finite(y):
            return n_done + 1, NONFINITE
        if m.projects == 1 and m.row_body.shape[0] > 0:  # (a call passing the model costs, even with no rows)
            status = project(t0 + (n_done + 1) * h, y, chart, m, v, w, rows)
            if status == SINGULAR:
                return n_done, status
            if status != OK:
                return n_done + 1, status
            if not _finite(y):
                return n_done + 1, NONFINITE
        status = _check_frames(m.n_q, m.n_rot, m.switching, m.frame_body, m.centre, m.centre_R, w.m3[3], y, chart,
                               switches, h, max_speed)
        if status != OK:
            return n_done + 1, status
        if m.remembers == 1:
            renew(t0 + (n_done + 1) * h, m, v, w, y, chart, memories)
    return n_steps, OK


@jit
def renew(t, m, v, w, y, chart, memories):
    """The force elements' memory after an accepted step ending at ``(t, y)`` (``after_step_piece``;
    ``viz3d.dynamics.element_memory``); nothing for ``memories`` None (a branch numba prunes)."""
    if memories is not None:
        frames(m, v, w, y, chart)
        kinematics(m, v, w)
        for d in literal_unroll(memories):
            if d.i.shape[0] > 0:
                after_step_piece(d, t, v)


@entry
def advance_frames(n_frames, every, n0, t0, h, y, chart, switches, ta, tb, tc, group, max_speed, m, v, w, forces, rows,
                   memories, k, yi, Y, charts, ts, sampled, geometry, energies, ydot, r, R, vW, wW, wB, eta, eta_dot, lam, C, J, gap,
                   T, V):
    """A run's output frames in one call, free of the per-frame Python overhead: its one compiled
    entry for fixed steps and sampling (each entry loaded from numba's cache costs a run's start tens
    of milliseconds, and each compiled on a cold cache a minute or more of CPU); plain steps are one
    frame of ``every`` steps, sampled or not (``KernelStepper.step``).

    ``every`` > 0: up to ``n_frames`` runs of ``steps`` (``group`` as there) of ``every`` steps each, the first from
    step ``n0`` of a run that started at ``t0`` (call ``f`` starts at ``t0 + (n0 + f every) h``, the
    time the run's own state would carry), the state after call ``f`` copied into ``Y[f]`` (n,) and
    ``charts[f]``, its time into ``ts[f]`` and, while ``sampled[0]`` (given as 1) is not cleared,
    its output sample into row ``f`` of ``r`` ... ``V`` (``viz3d.kernel.sampling.sample_state``): a
    state whose evaluation fails there clears ``sampled[0]`` (the caller then samples none of the
    call's frames here). On a failure ``y`` holds the failed step's result.

    ``every`` = 0: the output samples of the given states ``(ts[f], Y[f], charts[f])``, nothing
    stepped.

    ``every`` < 0: ``y`` projected in place onto the constraints at ``t0``
    (``viz3d.kernel.projection.project``: the initial projection, and the steps the kernel does not
    take itself).

    Returns (frames done, steps done in the next frame, status); sampling only, ``SINGULAR`` at
    the first state whose evaluation fails; projecting, (0, 0, the projection's status)."""
    if every < 0:
        return 0, 0, project(t0, y, chart, m, v, w, rows)
    for f in range(n_frames):
        if every > 0:
            done, status = steps(every, t0 + (n0 + f * every) * h, h, y, chart, switches, ta, tb, tc, group, max_speed,
                                 m, v, w, forces, rows, memories, k, yi)
            if status != OK:
                return f, done, status
            for j in range(y.shape[0]):
                Y[f, j] = y[j]
            for b in range(chart.shape[0]):
                for i in range(3):
                    for c in range(3):
                        charts[f, b, i, c] = chart[b, i, c]
            ts[f] = t0 + (n0 + (f + 1) * every) * h
        if (every == 0 or sampled[0] == 1) and not sample_state(f, ts[f], Y[f], charts[f], m, v, w, forces, rows,
                                                                geometry, energies, ydot, r, R, vW, wW, wB, eta,
                                                                eta_dot, lam, C, J, gap, T, V):
            if every == 0:
                return f, 0, SINGULAR
            sampled[0] = 0
    return n_frames, every, OK


@inline
def _finite(y):
    """True when every entry of ``y`` is finite."""
    for j in range(y.shape[0]):
        if not math.isfinite(y[j]):
            return False
    return True


@inline
def _frame_health(nq, n_rot, switching, y, f, h, max_speed):
    """``(status, |sin theta|)`` of floating frame ``f`` of ``y`` after a step ``h``, as
    ``viz3d.diagnosis.check_state`` judges it: ``SPEED`` above ``max_speed``, ``ROTATION`` when its
    orientation coordinates turn more than ``MAX_TURN`` (their rates ``coordinate_rates``: the signed
    Euler-angle rate map, or ``1/2 p (x) (0, B_omega)`` of the stored Euler parameters) or a plain
    Euler chart sits at its gimbal lock, else ``OK`` (``|sin theta|`` 1 for Euler parameters)."""
    v = nq + 6 * f
    if math.sqrt(y[v] ** 2 + y[v + 1] ** 2 + y[v + 2] ** 2) > max_speed:
        return SPEED, 0.0
    i0 = (3 + n_rot) * f + 3
    st = 1.0
    if n_rot == 3:
        st = abs(math.sin(y[i0 + 1]))
        if not st > 0.0:
            return ROTATION, st
    d = coordinate_rates(n_rot, y, i0, y[v + 3], y[v + 4], y[v + 5])
    turn = max(abs(d[0]), abs(d[1]), abs(d[2]), abs(d[3])) * h
    if not turn <= MAX_TURN or (n_rot == 3 and switching == 0 and st < SINGULAR_SIN):
        return ROTATION, st
    return OK, st


@inline
def unit_parameters(y, i0):
    """``p / |p|`` in place for the Euler parameters ``y[i0:i0 + 4]`` (``Quaternion.normalize``)."""
    n = math.sqrt(y[i0] * y[i0] + y[i0 + 1] * y[i0 + 1] + y[i0 + 2] * y[i0 + 2] + y[i0 + 3] * y[i0 + 3])
    for i in range(4):
        y[i0 + i] = y[i0 + i] / n


@jit
def _check_frames(nq, n_rot, switching, frame_body, centre, centre_R, R, y, chart, switches, h, max_speed):
    for f in range(frame_body.shape[0]):
        status, st = _frame_health(nq, n_rot, switching, y, f, h, max_speed)
        if status != OK:
            return status
        i0 = (3 + n_rot) * f + 3
        if n_rot == 4:
            unit_parameters(y, i0)
        elif switching == 1 and st < SWITCH_SIN:
            rotation(chart[f], y[i0:i0 + 3], R)
            for i in range(3):
                for j in range(3):  # chart = R @ R_centre^T
                    chart[f, i, j] = R[i, 0] * centre_R[j, 0] + R[i, 1] * centre_R[j, 1] + R[i, 2] * centre_R[j, 2]
            y[i0], y[i0 + 1], y[i0 + 2] = centre[0], centre[1], centre[2]
            switches[frame_body[f]] += 1
    return OK


@entry
def rk_step(t, h, y, chart, f0, use_f0, ta, tb, te, tc, group, m, v, w, forces, rows, k, yi, y1, err):
    """``step``, called from Python."""
    return step(t, h, y, chart, f0, use_f0, ta, tb, te, tc, group, m, v, w, forces, rows, k, yi, y1, err)


@inline
def step(t, h, y, chart, f0, use_f0, ta, tb, te, tc, group, m, v, w, forces, rows, k, yi, y1, err):
    """One step of the tableau ``(ta, tb, tc)`` from ``y`` (what ``viz3d.integrators.explicit_rk``
    does, for adaptive runs and steps taken one at a time): the stages into ``k`` (stages, n), with
    ``f0`` as the first one when ``use_f0``; ``y1 = y + h sum b_i k_i`` and ``err = h sum e_i k_i``
    (``te = b - b_hat``). With ``group`` 1 Euler parameters advance on the group as in ``advance``, and
    ``k`` holds the stages' rates ``p_dot`` again at the end (``_stage_rates``). Returns the status of
    the first failed evaluation (``OK`` when none)."""
    n = y.shape[0]
    turns = group == 1 and m.n_rot == 4
    n_turned = 7 * m.frame_body.shape[0] if turns else 0
    if use_f0:
        for j in range(n):
            k[0, j] = f0[j]
    status = stages(t, h, y, chart, ta, tc, 1 if use_f0 else 0, turns, m, v, w, forces, rows, k, yi)
    if status != OK:
        return status
    for f in range(n_turned // 7):
        i0 = 7 * f + 3
        u1, u2, u3 = rotation_increment(tb, tb.shape[0], h, k, i0)
        for c in range(4):
            y1[i0 + c] = y[i0 + c]
        turn_quaternion(y1, i0, u1, u2, u3)
    for j in range(n):
        if j < n_turned and j % 7 >= 3:
            err[j] = 0.0
            continue
        acc = y[j]
        e = 0.0
        for i in range(tb.shape[0]):
            if tb[i] != 0.0:
                acc += h * tb[i] * k[i, j]
            if te[i] != 0.0:
                e += te[i] * k[i, j]
        y1[j] = acc
        err[j] = h * e
    if turns:
        _stage_rates(h, y, ta, m, k, yi)
    return OK


@inline
def _stage_rates(h, y, ta, m, k, yi):
    """``k``'s Euler-parameter entries of a group step back from ``K`` to the stages' ``p_dot``, as
    ``evaluate`` gave them: each stage's ``p`` and ``B_omega`` rebuilt as ``stages`` built them,
    last stage first (stage ``i``'s ``p`` needs the ``K`` of the stages before it)."""
    nf = m.frame_body.shape[0]
    for i in range(ta.shape[0] - 1, -1, -1):
        for f in range(nf):
            i0, o = 7 * f + 3, m.n_q + 6 * f + 3
            u1, u2, u3 = rotation_increment(ta[i], i, h, k, i0)
            for c in range(4):
                yi[i0 + c] = y[i0 + c]
            turn_quaternion(yi, i0, u1, u2, u3)
            for c in range(3):
                acc = y[o + c]
                for l in range(i):
                    if ta[i, l] != 0.0:
                        acc += h * ta[i, l] * k[l, o + c]
                yi[o + c] = acc
            d = coordinate_rates(4, yi, i0, yi[o], yi[o + 1], yi[o + 2])
            for c in range(4):
                k[i, i0 + c] = d[c]


@entry
def state_ok(n_q, n_v, n_rot, switching, n_frames, y, h, max_speed):
    """True when ``viz3d.diagnosis.check_state`` would pass ``y`` after a step ``h``: finite
    positions and velocities and every frame's ``_frame_health`` ``OK`` (the NumPy check then runs
    only to write the diagnosis)."""
    for j in range(n_q + n_v):
        if not math.isfinite(y[j]):
            return False
    for f in range(n_frames):
        if _frame_health(n_q, n_rot, switching, y, f, h, max_speed)[0] != OK:
            return False
    return True
