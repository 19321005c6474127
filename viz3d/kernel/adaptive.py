"""Adaptive explicit Runge-Kutta runs in the kernel: what ``viz3d.simulate.Simulation`` does with a
step-size ``viz3d.integrators.adaptive.Controller`` (trial steps, the weighted RMS error norm,
rejections, the next step's proposal and the orientation-turn limit), the accepted steps'
continuous extension (``viz3d.integrators.tableaus.DenseOutput``) sampled at the output times, and
between steps what ``viz3d.kernel.stepping.steps`` does (the ``projection`` formulation's
projections, health checks, chart switches).

A step over which an event function of the contacts changes sign is cut at the first event, as
``Simulation._event_step`` cuts it: the signs looked at at the step's ends and at the extrema of
the event function's cubic Hermite (``viz3d.integrators.adaptive.first_event``: a crossing and its
return inside one step are found too; its ``crosses``, ``armed`` and ``hermite_extrema`` are called
here, compiled there: one source for both paths), each crossing located on the step's cubic Hermite interpolant
(``viz3d.integrators.adaptive.hermite``) by Brent's method with ``brentq``'s iteration and the
Python loop's tolerances, the step redone to the earliest, its end settled and committed, the
call ended (``EVENT``: ``flags[CUT]`` names the event row, Python applies the event's handler,
e.g. a restitution impulse, and takes the next step, whose events start at a root). A call stops
*before committing* whatever else needs Python, which then redoes it from the same carry (the
kernel is deterministic) exactly as on a run without the kernel: an event function not finite on
the interpolant or a root not converging (``UNLOCATED``: Python's ``brentq`` raises), a failed
evaluation, projection or health check, a step below ``min_step`` (``UNDERFLOW``): Python writes
the diagnosis. With ``replant``, after each accepted step (settled) the stick anchors of bristle friction move
(the law contacts' ``replant_piece``, in ``v.mem``: ``ContactStepping._replant``'s rule), and the
field at the step's end is not carried over when one moved. While a law contact acts (``record``),
each accepted step's end time, settled state, chart, error estimate and the contacts' memory rows
go to the step records (``rec_t`` (R,), ``rec_y`` (R, n), ``rec_chart`` (R, nf, 3, 3), ``rec_err``
(R, n), ``rec_mem`` (R, n_contacts, 7), ``n_rec`` (1,)), from which Python brings the contacts'
memory up to date after the call (``viz3d.events.ContactStepping.after_steps``: the anchors,
bookkeeping and checks); a call whose records are full stops before the next step (``FULL``).

Fixed steps (``ctrl[FIXED]`` > 0: ``viz3d.integrators.adaptive.FixedSteps``, runs with contact
events and no controller) go through the same loop as ``Simulation._event_step`` takes them: ``dt``
within the contacts' step bound and within the rest to the next sample, on which the last one ends
(``step_to_try``, ``step_end`` to the sample), one trial with no error test, group steps of Euler
parameters as the Python loop's (``ctrl[GROUP]``); each sample is the inner state at the sample's time.

The carry (arrays updated in place, see ``viz3d.kernel.KernelStepper.adaptive``):

* ``y`` (n,), ``chart`` (nf, 3, 3): the state after the last accepted step ("inner" state);
* ``f`` (n,): the vector field there when ``flags[HAS_F]``;
* ``times``: ``[t, h, span t0, span t1, span h]`` [s]: the inner time, the next step to try, the
  last accepted step (its length as taken: ``t1 - t0`` within round-off);
* ``y0`` (n,), ``chart0`` (nf, 3, 3), ``K`` (s + m, n), ``Q`` (degree, n): the last accepted step's
  start, its stages (then its continuous extension's extra stages) and dense-output coefficients
  (``y(t0 + x h) = y0 + sum_d x^(d + 1) Q[d]``) when ``flags[DENSE]``; ``f1`` (n,) the field at its end;
* ``flags[CUT]``: 0, or 1 + the event row the last accepted step was cut at; ``y_cut`` (n,) that
  step's end before settling (its Hermite interpolant runs from ``(y0, K[0])`` to ``(y_cut, f1)``);
* ``counts``: accepted steps, rejected trial steps, vector-field evaluations.
"""

from __future__ import annotations

import math

import numpy as np

from viz3d.compiled import entry, inline, jit, replant_piece
from viz3d.integrators.adaptive import armed, crosses, hermite_extrema, step_end, step_to_try
from viz3d.kernel.field import NONFINITE, OK, evaluate, frames, gaps, literal_unroll
from viz3d.kernel.projection import project
from viz3d.kernel.stepping import _check_frames, state_ok, step, unit_parameters
from viz3d.points import kinematics

#: Status codes beyond ``viz3d.kernel.field``'s: the last step was cut at a contact event (committed
#: up to it, the handler is Python's); the controller asked for a step below ``min_step``; the step
#: records are full (the next step needs a record); an event function changed sign over the step
#: about to be committed but cannot be located here (not finite on the interpolant, the root finder
#: out of iterations).
EVENT, UNDERFLOW, FULL, UNLOCATED = 6, 7, 8, 9
#: Indices of ``times``, ``flags`` and ``counts``.
T, H, T0, T1, SPAN_H = 0, 1, 2, 3, 4
HAS_F, SPAN, DENSE, CUT = 0, 1, 2, 3
#: Indices of the event tolerances in ``ctrl`` (after the controller's eight): ``brentq``'s
#: ``xtol`` relative to the step, its ``rtol`` and iteration limit, the rounding of an event's cubic
#: (``viz3d.integrators.adaptive.ROUNDING``).
EV_XTOL, EV_RTOL, EV_MAXITER, EV_ROUNDING = 8, 9, 10, 11
#: Indices of the fixed steps in ``ctrl`` (``viz3d.integrators.adaptive.FixedSteps``): their length ``dt`` [s] (0:
#: adaptive steps) and the ``group`` flag of ``viz3d.kernel.stepping.step`` (1: Euler parameters
#: advance on the group, as the Python loop's fixed steps of a tableau without error estimate).
FIXED, GROUP = 12, 13
STEPS, REJECTED, EVALS = 0, 1, 2
#: Event kinds (``viz3d.events.ContactStepping.event_rows``): a contact's ``alpha`` less its floor,
#: its ``alpha_dot``, a kinematic contact's multiplier.
GAP, GAP_RATE, MULTIPLIER = 0, 1, 2
#: Event kinds of ``viz3d.events.EventRow`` as the driver numbers them.
EVENT_KINDS = {"gap": GAP, "gap_rate": GAP_RATE, "multiplier": MULTIPLIER}


#: Block of numpy's pairwise summation (``PW_BLOCKSIZE`` of numpy/_core/src/umath/loops_utils.h).
PAIRWISE_BLOCK = 128


@jit
def _block_sum(x, lo, hi):
    """numpy's sum of one block: sequential below 8 entries, else eight accumulators."""
    n = hi - lo
    if n < 8:
        acc = 0.0
        for j in range(lo, hi):
            acc += x[j]
        return acc
    r0, r1, r2, r3 = x[lo], x[lo + 1], x[lo + 2], x[lo + 3]
    r4, r5, r6, r7 = x[lo + 4], x[lo + 5], x[lo + 6], x[lo + 7]
    j = lo + 8
    while j < hi - n % 8:
        r0 += x[j]
        r1 += x[j + 1]
        r2 += x[j + 2]
        r3 += x[j + 3]
        r4 += x[j + 4]
        r5 += x[j + 5]
        r6 += x[j + 6]
        r7 += x[j + 7]
        j += 8
    acc = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while j < hi:
        acc += x[j]
        j += 1
    return acc


def _halving(inner):
    """A level of numpy's pairwise recursion (numba compiles no recursion here): blocks of up to
    ``PAIRWISE_BLOCK`` entries summed by ``_block_sum``, longer ranges split in two halves (the
    first a multiple of 8 long) summed by ``inner``."""

    def level(x, lo, hi):
        n = hi - lo
        if n <= PAIRWISE_BLOCK:
            return _block_sum(x, lo, hi)
        half = n // 2
        half -= half % 8
        return inner(x, lo, lo + half) + inner(x, lo + half, hi)

    return jit(level)


#: numpy's order to ``PAIRWISE_BLOCK * 2^7`` entries (16384); beyond, the deepest blocks are longer
#: than numpy's, which changes the sum by round-off only.
pairwise_sum = _block_sum
for _ in range(7):
    pairwise_sum = _halving(pairwise_sum)
pairwise_sum.__doc__ = """``x[lo:hi].sum()`` added in numpy's order (pairwise, eight accumulators per block), so the
controller's error norm is the one ``np.mean`` gives to the last bit."""


@inline
def error_norm(err, y0, y1, rtol, atol, sq):
    """``Controller.error_norm``: ``rms(err / (atol + rtol max(|y0|, |y1|)))`` (``sq`` (n,) scratch)."""
    n = err.shape[0]
    for j in range(n):
        e = err[j] / (atol + rtol * max(abs(y0[j]), abs(y1[j])))
        sq[j] = e * e
    return math.sqrt(pairwise_sum(sq, 0, n) / n)


@inline
def next_step(h, norm, q, safety, fac_min, fac_max):
    """``Controller.next_step``."""
    factor = fac_max if norm == 0.0 else safety * norm ** (-1.0 / (q + 1))
    return h * min(fac_max, max(fac_min, factor))


@inline
def turn_limit(n_frames, n_rot, f, max_turn):
    """``Simulation._turn_limit``: the longest step turning no orientation coordinate (``n_rot`` per
    frame: Euler angles or parameters) by more than ``max_turn`` at the rates in ``f``."""
    fastest = 0.0
    for fr in range(n_frames):
        for i in range(n_rot):
            fastest = max(fastest, abs(f[(3 + n_rot) * fr + 3 + i]))
    return max_turn / fastest if fastest > 0.0 else math.inf


@jit
def event_values(t, y, chart, kind, index, floor, m, v, w, forces, rows, geometry, gap_out, ydot, out):
    """The event functions at ``(t, y)`` and their rates (``Event.rate``) into ``out`` (E, 2): ``GAP``
    ``alpha - floor`` and ``alpha_dot``, ``GAP_RATE`` ``alpha_dot``, ``MULTIPLIER`` the multiplier
    of row ``index`` (these two without a rate: nan); returns the status of the evaluation the
    multipliers need (``OK`` when none)."""
    n_ev = kind.shape[0]
    if n_ev == 0:
        return OK
    gaps(t, y, chart, m, v, w, geometry, gap_out)
    status = OK
    solved = False
    for e in range(n_ev):
        out[e, 1] = math.nan
        if kind[e] == GAP:
            out[e, 0] = gap_out[index[e], 0] - floor[e]
            out[e, 1] = gap_out[index[e], 1]
        elif kind[e] == GAP_RATE:
            out[e, 0] = gap_out[index[e], 1]
        else:
            if not solved:
                status = evaluate(t, y, chart, m, v, w, forces, rows, ydot)
                solved = True
                if status != OK:
                    return status
            out[e, 0] = w.lam[index[e]]
    return status


@inline
def _bracket(direction, t0, g0, s_lo, t_lo, g_lo, s_hi, t_hi, g_hi, t1, g1):
    """``viz3d.integrators.adaptive._bracket`` over the step's start, the cubic's extrema (``s < 0``
    for none) and its end: (found, t_a, t_b, g_b)."""
    found, t_a, g_a = armed(direction, g0), t0, g0
    if s_lo >= 0.0:
        if found and crosses(direction, g_a, g_lo):
            return True, t_a, t_lo, g_lo
        if armed(direction, g_lo):
            found, t_a, g_a = True, t_lo, g_lo
    if s_hi >= 0.0:
        if found and crosses(direction, g_a, g_hi):
            return True, t_a, t_hi, g_hi
        if armed(direction, g_hi):
            found, t_a, g_a = True, t_hi, g_hi
    if found and crosses(direction, g_a, g1):
        return True, t_a, t1, g1
    return False, t_a, t1, g1


@inline
def _extrema_times(t, t1, g0, g1, rounding):
    """The step's ``hermite_extrema`` from the event values and rates ``g0``, ``g1`` (2,) at its ends
    ``t`` and ``t1``: (s_lo, t_lo, p_lo, s_hi, t_hi, p_hi), ``s = -1`` for none."""
    hs = t1 - t
    s_lo, p_lo, s_hi, p_hi = hermite_extrema(g0[0], hs * g0[1], g1[0], hs * g1[1], rounding)
    return s_lo, t + s_lo * hs, p_lo, s_hi, t + s_hi * hs, p_hi


@jit
def event_value(e, t, y, chart, kind, index, floor, m, v, w, forces, rows, geometry, gap_out, ydot):
    """Event function ``e`` alone at ``(t, y)`` (as ``event_values`` evaluates it, and as the Python
    loop's ``ContactStepping._probe``: a multiplier only for a multiplier): (value, status)."""
    if kind[e] == MULTIPLIER:
        status = evaluate(t, y, chart, m, v, w, forces, rows, ydot)
        return w.lam[index[e]], status
    gaps(t, y, chart, m, v, w, geometry, gap_out)
    if kind[e] == GAP:
        return gap_out[index[e], 0] - floor[e], OK
    return gap_out[index[e], 1], OK


@inline
def hermite_state(t, t0, t1, y0, f0, y1, f1, out):
    """``viz3d.integrators.adaptive.hermite`` at the scalar ``t`` into ``out``: its operations in its
    order, so the same bits."""
    h = t1 - t0
    s = (t - t0) / h
    u2 = (1.0 - s) * (1.0 - s)
    h00, h10 = (1.0 + 2.0 * s) * u2, s * u2
    h01, h11 = s * s * (3.0 - 2.0 * s), s * s * (s - 1.0)
    a, b = h10 * h, h11 * h
    for j in range(out.shape[0]):
        out[j] = h00 * y0[j] + a * f0[j] + h01 * y1[j] + b * f1[j]


@jit
def _on_interpolant(e, t, t0, t1, y0, f0, y1, f1, chart, kind, index, floor, m, v, w, forces, rows, geometry, gap_out,
                    ydot, yh):
    """Event function ``e`` on the step's cubic Hermite interpolant at ``t`` (``first_event``'s
    ``g_of``): (value, status); ``UNLOCATED`` for a NaN (``brentq`` raises on one)."""
    hermite_state(t, t0, t1, y0, f0, y1, f1, yh)
    g, status = event_value(e, t, yh, chart, kind, index, floor, m, v, w, forces, rows, geometry, gap_out, ydot)
    if status == OK and g != g:
        return g, UNLOCATED
    return g, status


@jit
def _brent(e, lo, hi, xtol, rtol, maxiter, t0, t1, y0, f0, y1, f1, chart, kind, index, floor, m, v, w, forces, rows,
           geometry, gap_out, ydot, yh):
    """Root of event ``e`` on the step's interpolant between ``lo`` and ``hi`` (where its values have
    opposite signs): Brent's method (R. P. Brent, Algorithms for Minimization without Derivatives,
    1973, ch. 4) in the form of ``scipy.optimize.brentq``: keep the root bracketed by the latest
    estimate and a contrapoint, try inverse quadratic or secant interpolation, take it when it lands
    well inside the bracket and shrinks fast enough, else bisect; never step less than the tolerance
    ``(xtol + rtol |x|) / 2``. The same arithmetic in the same order as ``brentq``, so the Python
    loop and the driver cut their steps at the same time. Returns (root, status): ``UNLOCATED``
    after ``maxiter`` iterations (``brentq`` raises)."""
    x_pre, x_cur = lo, hi
    g_pre, status = _on_interpolant(e, x_pre, t0, t1, y0, f0, y1, f1, chart, kind, index, floor, m, v, w, forces, rows,
                                    geometry, gap_out, ydot, yh)
    if status != OK:
        return x_cur, status
    g_cur, status = _on_interpolant(e, x_cur, t0, t1, y0, f0, y1, f1, chart, kind, index, floor, m, v, w, forces, rows,
                                    geometry, gap_out, ydot, yh)
    if status != OK:
        return x_cur, status
    if g_pre == 0.0:
        return x_pre, OK
    if g_cur == 0.0:
        return x_cur, OK
    x_blk, g_blk, s_pre, s_cur = 0.0, 0.0, 0.0, 0.0
    for _ in range(maxiter):
        if g_pre != 0.0 and g_cur != 0.0 and (g_pre < 0.0) != (g_cur < 0.0):  # a new bracket
            x_blk, g_blk = x_pre, g_pre
            s_pre = s_cur = x_cur - x_pre
        if abs(g_blk) < abs(g_cur):  # the best estimate is the one of least |g|
            x_pre, x_cur, x_blk = x_cur, x_blk, x_cur
            g_pre, g_cur, g_blk = g_cur, g_blk, g_cur
        delta = (xtol + rtol * abs(x_cur)) / 2
        s_bis = (x_blk - x_cur) / 2
        if g_cur == 0.0 or abs(s_bis) < delta:
            return x_cur, OK
        s_pre, s_cur = _brent_step(x_pre, x_cur, x_blk, g_pre, g_cur, g_blk, s_pre, s_cur, s_bis, delta)
        x_pre, g_pre = x_cur, g_cur
        if abs(s_cur) > delta:
            x_cur += s_cur
        else:
            x_cur += delta if s_bis > 0 else -delta
        g_cur, status = _on_interpolant(e, x_cur, t0, t1, y0, f0, y1, f1, chart, kind, index, floor, m, v, w, forces,
                                        rows, geometry, gap_out, ydot, yh)
        if status != OK:
            return x_cur, status
    return x_cur, UNLOCATED


@inline
def _brent_step(x_pre, x_cur, x_blk, g_pre, g_cur, g_blk, s_pre, s_cur, s_bis, delta):
    """``_brent``'s next (previous step, step): interpolated (secant when the contrapoint is the
    previous estimate, else inverse quadratic) when that step is short enough, else bisection."""
    if abs(s_pre) > delta and abs(g_cur) < abs(g_pre):
        if x_pre == x_blk:
            trial = -g_cur * (x_cur - x_pre) / (g_cur - g_pre)
        else:
            d_pre = (g_pre - g_cur) / (x_pre - x_cur)
            d_blk = (g_blk - g_cur) / (x_blk - x_cur)
            trial = -g_cur * (g_blk * d_blk - g_pre * d_pre) / (d_blk * d_pre * (g_blk - g_pre))
        if 2 * abs(trial) < min(abs(s_pre), 3 * abs(s_bis) - delta):
            return s_cur, trial
    return s_bis, s_bis


@jit
def _first_event(t, t1, y, f, y1, f1, chart, ctrl, kind, index, floor, direction, g0, g1, m, v, w, forces, rows,
                 geometry, gap_out, ydot, yh):
    """``viz3d.integrators.adaptive.first_event`` over the step from ``(t, y)`` (field ``f``) to
    ``(t1, y1)`` (field ``f1``), the event values and rates ``g0`` and ``g1`` (E, 2) at its ends,
    no event fresh: (row, time, status) of the earliest crossing, the first row of the earliest
    time; row -1 when the cubic's crossing is not on the interpolant (``_bracket`` finds none on it)."""
    xtol = ctrl[EV_XTOL] * (t1 - t) + 1e-300
    best, t_best = -1, t1
    for e in range(kind.shape[0]):
        s_lo, t_lo, p_lo, s_hi, t_hi, p_hi = _extrema_times(t, t1, g0[e], g1[e], ctrl[EV_ROUNDING])
        found, t_a, t_b, g_b = _bracket(direction[e], t, g0[e, 0], s_lo, t_lo, p_lo, s_hi, t_hi, p_hi, t1, g1[e, 0])
        if not found:
            continue
        if s_lo >= 0.0:  # the event function on the interpolant at the cubic's extrema
            p_lo, status = _on_interpolant(e, t_lo, t, t1, y, f, y1, f1, chart, kind, index, floor, m, v, w, forces,
                                           rows, geometry, gap_out, ydot, yh)
            if status != OK:
                return best, t_best, status
        if s_hi >= 0.0:
            p_hi, status = _on_interpolant(e, t_hi, t, t1, y, f, y1, f1, chart, kind, index, floor, m, v, w, forces,
                                           rows, geometry, gap_out, ydot, yh)
            if status != OK:
                return best, t_best, status
        found, t_a, t_b, g_b = _bracket(direction[e], t, g0[e, 0], s_lo, t_lo, p_lo, s_hi, t_hi, p_hi, t1, g1[e, 0])
        if not found:
            continue
        g_lo, status = _on_interpolant(e, t_a, t, t1, y, f, y1, f1, chart, kind, index, floor, m, v, w, forces, rows,
                                       geometry, gap_out, ydot, yh)
        if status != OK:
            return best, t_best, status
        t_e = t_b
        if g_b != 0.0 and _sign(g_lo) != _sign(g_b):
            t_e, status = _brent(e, t_a, t_b, xtol, ctrl[EV_RTOL], int(ctrl[EV_MAXITER]), t, t1, y, f, y1, f1, chart,
                                 kind, index, floor, m, v, w, forces, rows, geometry, gap_out, ydot, yh)
            if status != OK:
                return best, t_best, status
        if best < 0 or t_e < t_best:
            best, t_best = e, t_e
    return best, t_best, OK


@inline
def _sign(x):
    """``np.sign`` of a number that is not NaN."""
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


@inline
def dense_coefficients(t0, h, y0, chart0, f1, s, P, c_extra, a_extra, reuse, m, v, w, forces, rows, K, yi, Q):
    """``ExplicitRK.dense_coefficients``: the extra stages into ``K[s:]`` (``reuse[i]``: the stage is
    ``f1``) and ``Q = h P^T K``; returns (evaluations, status)."""
    n = y0.shape[0]
    n_evals = 0
    for i in range(c_extra.shape[0]):
        if reuse[i]:
            for j in range(n):
                K[s + i, j] = f1[j]
            continue
        for j in range(n):
            acc = 0.0
            for l in range(s + i):
                if a_extra[i, l] != 0.0:
                    acc += a_extra[i, l] * K[l, j]
            yi[j] = y0[j] + h * acc
        n_evals += 1
        status = evaluate(t0 + c_extra[i] * h, yi, chart0, m, v, w, forces, rows, K[s + i])
        if status != OK:
            return n_evals, status
    for d in range(P.shape[1]):
        for j in range(n):
            acc = 0.0
            for l in range(P.shape[0]):
                acc += P[l, d] * K[l, j]
            Q[d, j] = h * acc
    return n_evals, OK


@inline
def dense_sample(t, t0, h, y0, Q, out):
    """``y(t)`` of the step's continuous extension into ``out``."""
    x = (t - t0) / h
    for j in range(y0.shape[0]):
        acc = 0.0
        for d in range(Q.shape[0]):
            acc += x ** (d + 1.0) * Q[d, j]
        out[j] = y0[j] + acc


@inline
def accepted_step(t, y, chart, f, h, ctrl, ta, tb, te, tc, m, v, w, forces, rows, k, yi, y1, err):
    """``viz3d.integrators.adaptive.accepted_step``: trial steps from ``(t, y)`` until the error
    test passes (fixed steps: the one step ``h``); returns (step taken, next step proposed,
    rejections, status)."""
    rtol, atol, min_step, q = ctrl[0], ctrl[1], ctrl[3], ctrl[4]
    safety, fac_min, fac_max = ctrl[5], ctrl[6], ctrl[7]
    n_rejected = 0
    while True:
        status = step(t, h, y, chart, f, True, ta, tb, te, tc, np.int64(ctrl[GROUP]), m, v, w, forces, rows, k, yi, y1,
                      err)
        if status != OK or ctrl[FIXED] > 0.0:  # (fixed steps: no error test)
            return h, h, n_rejected, status
        norm = error_norm(err, y, y1, rtol, atol, yi)
        if norm <= 1.0:
            return h, next_step(h, norm, q, safety, fac_min, fac_max), n_rejected, OK
        n_rejected += 1
        h = next_step(h, norm, q, safety, fac_min, fac_max) if math.isfinite(norm) else fac_min * h
        if h < min_step or t + h == t:
            return h, h, n_rejected, UNDERFLOW


@entry
def adaptive_frames(n_frames, every, n0, t_start, dt, t_end, contact_mode, max_speed, max_turn, ctrl, ta, tb, te, tc,
                    fsal, P, c_extra, a_extra, reuse, ev_kind, ev_index, ev_floor, ev_dir, record, rec_t, rec_y, rec_chart,
                    rec_err, rec_mem, n_rec, m, v, w, forces, rows, geometry, replants, replant,
                    y, chart, f, times, flags, counts, switches, y0, chart0, K, Q, f1, y_cut,
                    k, yi, y1, err, ys, chart1, sw, gap_out, g0, g1, yh, mem0, Y, charts, Ts):
    """Up to ``n_frames`` output frames, ``every`` samples apart, of an adaptive run (the carry in
    place, see the module docstring): sample ``i`` of the run is at ``t_start + i dt``, the first
    here is ``n0 + 1``; no step goes past ``t_end`` (``Simulation.t_end``). Frame ``f``'s time,
    state and chart go to ``Ts[f]``, ``Y[f]``, ``charts[f]``. ``contact_mode``: the sampling of a
    run with contacts (``Simulation._event_steps``: no projection or check of samples, the inner
    state itself within round-off of the output time)
    and the sign checks of the event functions ``(ev_kind, ev_index, ev_floor, ev_dir)``; with
    ``record`` every accepted step goes to the step records (module docstring); with ``replant`` the
    contacts' stick anchors move after every accepted step (``replant_piece`` of ``replants``:
    ``viz3d.contact.contacts._replant``, in ``v.mem``; ``mem0`` scratch of its shape).

    Returns (frames done, samples done in the next frame, status); on a status other than ``OK`` and
    ``EVENT`` (the step cut at the event committed and recorded) nothing of the step or sample that
    stopped the call is committed."""
    s = tb.shape[0]
    t_s = 0.0
    for frame in range(n_frames):
        for sample in range(every):
            target = t_start + (n0 + frame * every + sample + 1) * dt
            slack = 1e-12 * max(abs(target), dt)
            while True:  # accepted steps until the last one reaches the sample
                if flags[SPAN] == 1 and times[T1] >= target:
                    break
                if contact_mode and times[T] >= target - slack:
                    break
                if record and n_rec[0] == rec_t.shape[0]:
                    return frame, sample, FULL
                status = _commit_step(target, t_end, contact_mode, max_speed, max_turn, ctrl, ta, tb, te, tc, fsal, ev_kind,
                                      ev_index, ev_floor, ev_dir, m, v, w, forces, rows, geometry, replants, replant, y,
                                      chart, f, times, flags, counts, switches, y0, chart0, K, f1, y_cut, k, yi, y1,
                                      err, chart1, sw, gap_out, g0, g1, yh, mem0)
                if status != OK and status != EVENT:
                    return frame, sample, status
                if record:
                    _record(times[T], y, chart, err, v.mem, rec_t, rec_y, rec_chart, rec_err, rec_mem, n_rec)
                if status == EVENT:
                    return frame, sample, status
            if contact_mode and abs(times[T] - target) <= slack:
                t_s = target if ctrl[FIXED] > 0.0 else times[T]  # (the Python loop's sample times)
                _copy(ys, y)
                _copy_chart(chart1, chart)
            else:
                t_s = target
                status = _span_sample(contact_mode, target, max_speed, P, c_extra, a_extra, reuse, s, m, v, w,
                                      forces, rows, times, flags, counts, y0, chart0, K, Q, f1, yi, ys)
                if status != OK:
                    return frame, sample, status
                _copy_chart(chart1, chart0)
        Ts[frame] = t_s
        _copy(Y[frame], ys)
        _copy_chart(charts[frame], chart1)
    return n_frames, every, OK


@jit
def _record(t, y, chart, err, mem, rec_t, rec_y, rec_chart, rec_err, rec_mem, n_rec):
    """The step just committed (end time, settled state and chart, error estimate, the contacts'
    memory rows after it) as the next record."""
    r = n_rec[0]
    rec_t[r] = t
    _copy(rec_y[r], y)
    _copy(rec_err[r], err)
    _copy_chart(rec_chart[r], chart)
    _copy_rows(rec_mem[r], mem)
    n_rec[0] = r + 1


@inline
def _span_sample(contact_mode, target, max_speed, P, c_extra, a_extra, reuse, s, m, v, w, forces, rows, times,
                 flags, counts, y0, chart0, K, Q, f1, yi, ys):
    """The last accepted step's dense output at ``target`` into ``ys`` (its coefficients built on
    first use); without contacts projected and checked as ``Simulation._adaptive_samples`` does."""
    t0, h = times[T0], times[SPAN_H]
    if flags[DENSE] == 0:
        n_evals, status = dense_coefficients(t0, h, y0, chart0, f1, s, P, c_extra, a_extra, reuse, m, v, w, forces,
                                             rows, K, yi, Q)
        if status != OK:
            return status
        counts[EVALS] += n_evals
        flags[DENSE] = 1
    dense_sample(target, t0, h, y0, Q, ys)
    if not contact_mode:
        if m.projects == 1:
            status = project(target, ys, chart0, m, v, w, rows)
            if status != OK:
                return status
        if not state_ok(m.n_q, m.n_v, m.n_rot, m.switching, m.frame_body.shape[0], ys, times[T1] - t0, max_speed):
            return NONFINITE  # or another failed check: Python's check_state names it
    _unit_parameters(m.n_rot, m.frame_body.shape[0], ys)
    return OK


@inline
def _unit_parameters(n_rot, n_frames, y):
    """Euler parameters (``n_rot`` 4) of every frame of ``y`` divided by their norm, as the Python
    path's samples (``rotation.normalize``); Euler angles are left alone."""
    if n_rot != 4:
        return
    for f in range(n_frames):
        unit_parameters(y, 7 * f + 3)


@jit
def _commit_step(target, t_end, contact_mode, max_speed, max_turn, ctrl, ta, tb, te, tc, fsal, ev_kind, ev_index, ev_floor,
                 ev_dir, m, v, w, forces, rows, geometry, replants, replant, y, chart, f, times, flags, counts, switches,
                 y0, chart0, K, f1, y_cut, k, yi, y1, err, chart1, sw, gap_out, g0, g1, yh, mem0):
    """One accepted step from the inner state, not past ``t_end`` (cut at the first contact event it
    crosses: ``_cut_at_event``), then what ``Simulation._accept`` does after it; committed to the
    carry only when nothing needs Python (see the module docstring). Fixed steps (``ctrl[FIXED]``):
    ``dt`` within the contacts' bound ``ctrl[2]`` and the rest to the sample at ``target`` [s],
    ending there when it is that rest, as ``Simulation._event_step`` takes them."""
    t = times[T]
    if flags[HAS_F] == 0:
        status = evaluate(t, y, chart, m, v, w, forces, rows, f)
        if status != OK:
            return status
        flags[HAS_F] = 1  # the field at the inner state, kept whatever follows (as Simulation._f)
        counts[EVALS] += 1
    fixed = ctrl[FIXED] > 0.0
    reach = target if fixed else t_end
    h, h_next, n_rejected, status = accepted_step(t, y, chart, f, step_to_try(ctrl[FIXED] if fixed else times[H], ctrl[2],
                                                                              t, reach),
                                                  ctrl, ta, tb, te, tc, m, v, w, forces, rows, k, yi, y1, err)
    if status != OK:
        return status
    t1 = step_end(t, h, reach)
    n_evals = (n_rejected + 1) * (tb.shape[0] - 1)
    if fsal:
        _copy(f1, k[tb.shape[0] - 1])
    else:
        n_evals += 1
        status = evaluate(t1, y1, chart, m, v, w, forces, rows, f1)
        if status != OK:
            return status
    if contact_mode:
        status = _event_crossed(t, t1, y, y1, chart, ev_kind, ev_index, ev_floor, ev_dir, ctrl[EV_ROUNDING], m, v, w,
                                forces, rows, geometry, gap_out, yi, g0, g1)
        if status == EVENT:  # cut and committed (EVENT), a failure, or no crossing on the interpolant (OK)
            status = _cut_at_event(t, t1, h_next, n_rejected, n_evals, max_speed, ctrl, ta, tb, te, tc, fsal, ev_kind,
                                   ev_index, ev_floor, ev_dir, m, v, w, forces, rows, geometry, replants, replant, y,
                                   chart, f, times, flags, counts, switches, y0, chart0, K, f1, y_cut, k, yi, y1, err,
                                   chart1, sw, gap_out, g0, g1, yh, mem0)
        if status != OK:
            return status
    status = _settled(t1, h, y1, chart, max_speed, m, v, w, rows, yi, chart1, sw)
    if status != OK:
        return status
    moved = replant == 1 and _replanted(t1, m, v, w, yi, chart1, replants, mem0)
    _commit(t, t1, h, h_next, n_rejected, n_evals, 0, max_turn, moved, m, y, chart, f, times, flags, counts, switches, y0,
            chart0, K, f1, k, yi, chart1, sw)
    return OK


@jit
def _cut_at_event(t, t1, h_next, n_rejected, n_evals, max_speed, ctrl, ta, tb, te, tc, fsal, ev_kind, ev_index,
                  ev_floor, ev_dir, m, v, w, forces, rows, geometry, replants, replant, y, chart, f, times, flags, counts,
                  switches, y0, chart0, K, f1, y_cut, k, yi, y1, err, chart1, sw, gap_out, g0, g1, yh, mem0):
    """The accepted step from ``(t, y)`` to ``(t1, y1)`` (``h_next`` proposed after it, ``n_rejected``
    trials and ``n_evals`` evaluations before it), over which an event function changes sign, cut
    as ``Simulation._event_step`` cuts it: the first event located (``_first_event``), the step
    redone from ``(t, y)`` to it (its own error estimate into ``err``, its end field into ``f1``),
    settled and committed with ``flags[CUT]`` (the next step as the controller proposed it, no turn
    limit, no field kept: the event's handler changes the state). Returns ``EVENT``, ``OK`` when no
    crossing is on the interpolant after all (nothing committed, the step stands), or the status of
    what failed (nothing committed)."""
    e, t_ev, status = _first_event(t, t1, y, f, y1, f1, chart, ctrl, ev_kind, ev_index, ev_floor, ev_dir, g0, g1, m, v,
                                   w, forces, rows, geometry, gap_out, yi, yh)
    if status != OK or e < 0:
        return status
    s = tb.shape[0]
    h_ev = t_ev - t
    status = step(t, h_ev, y, chart, f, True, ta, tb, te, tc, np.int64(ctrl[GROUP]), m, v, w, forces, rows, k, yi, y1,
                  err)
    if status != OK:
        return status
    n_evals += s - 1
    if fsal:
        _copy(f1, k[s - 1])
    else:
        n_evals += 1
        status = evaluate(t_ev, y1, chart, m, v, w, forces, rows, f1)
        if status != OK:
            return status
    status = _settled(t_ev, h_ev, y1, chart, max_speed, m, v, w, rows, yi, chart1, sw)
    if status != OK:
        return status
    if replant == 1:
        _replanted(t_ev, m, v, w, yi, chart1, replants, mem0)
    _copy(y_cut, y1)
    _commit(t, t_ev, h_ev, h_next, n_rejected, n_evals, e + 1, 0.0, False, m, y, chart, f, times, flags, counts, switches,
            y0, chart0, K, f1, k, yi, chart1, sw)
    return EVENT


@jit
def _event_crossed(t, t1, y, y1, chart, ev_kind, ev_index, ev_floor, ev_dir, rounding, m, v, w, forces, rows, geometry,
                   gap_out, scratch, g0, g1):
    """``EVENT`` when an event function may cross between ``(t, y)`` and ``(t1, y1)``, both in the
    step's ``chart`` (as ``Simulation._event_step`` evaluates them): its signs at the ends and at its
    cubic's extrema show a crossing (``_bracket``); else ``OK``, or the status of a failed
    evaluation. The values and rates at the ends go to ``g0``, ``g1`` (E, 2)."""
    if ev_kind.shape[0] == 0:
        return OK
    status = event_values(t, y, chart, ev_kind, ev_index, ev_floor, m, v, w, forces, rows, geometry, gap_out, scratch,
                          g0)
    if status != OK:
        return status
    status = event_values(t1, y1, chart, ev_kind, ev_index, ev_floor, m, v, w, forces, rows, geometry, gap_out,
                          scratch, g1)
    if status != OK:
        return status
    for e in range(ev_kind.shape[0]):
        s_lo, t_lo, p_lo, s_hi, t_hi, p_hi = _extrema_times(t, t1, g0[e], g1[e], rounding)
        if _bracket(ev_dir[e], t, g0[e, 0], s_lo, t_lo, p_lo, s_hi, t_hi, p_hi, t1, g1[e, 0])[0]:
            return EVENT
    return OK


@inline
def _settled(t1, h, y1, chart, max_speed, m, v, w, rows, y_end, chart_end, sw):
    """The step's end state ``y1`` after the projection (``m.projects``), the health checks and the
    chart switches, into ``y_end`` and ``chart_end`` (switches per body into ``sw``); the status of
    the first that fails."""
    _copy(y_end, y1)
    _copy_chart(chart_end, chart)
    for b in range(sw.shape[0]):
        sw[b] = 0
    if m.projects == 1:
        status = project(t1, y_end, chart_end, m, v, w, rows)
        if status != OK:
            return status
    for j in range(m.n_q + m.n_v):  # (what check_state checks: positions and velocities)
        if not math.isfinite(y_end[j]):
            return NONFINITE
    return _check_frames(m.n_q, m.n_rot, m.switching, m.frame_body, m.centre, m.centre_R, w.m3[3], y_end, chart_end, sw, h,
                         max_speed)


@jit
def _replanted(t, m, v, w, y, chart, replants, mem0):
    """The contacts' stick anchors moved after the step ending at ``(t, y)`` (the ``replant_piece``
    of ``replants``); True when one moved (the field there is then another)."""
    _copy_rows(mem0, v.mem)
    frames(m, v, w, y, chart)
    kinematics(m, v, w)
    for d in literal_unroll(replants):
        if d.i.shape[0] > 0:
            replant_piece(d, t, v)
    for kg in range(mem0.shape[0]):
        for c in range(4, 7):
            if v.mem[kg, c] != mem0[kg, c]:
                return True
    return False


@inline
def _commit(t, t1, h, h_next, n_rejected, n_evals, cut, max_turn, moved, m, y, chart, f, times, flags, counts, switches,
            y0, chart0, K, f1, k, y_end, chart_end, sw):
    """The accepted step ``[t, t1]`` of length ``h`` into the carry: its span (start, stages, length,
    ``cut``: 0 or 1 + the event row it was cut at), the settled end state as the inner state, the
    next step (``min(h_next, turn_limit)``; ``h_next`` after a cut), the field kept when the end
    state is the step's own (no cut, no projection, no chart switch, no Euler parameters to
    normalise, no stick anchor ``moved``: ``Simulation._settle``), the counters."""
    switched = False
    for b in range(sw.shape[0]):
        switches[b] += sw[b]
        switched = switched or sw[b] != 0
    times[T0], times[T1], times[SPAN_H] = t, t1, h
    _copy(y0, y)
    _copy(y, y_end)
    for i in range(k.shape[0]):
        _copy(K[i], k[i])
    _copy_chart(chart0, chart)
    _copy_chart(chart, chart_end)
    times[T] = t1
    times[H] = h_next if cut else min(h_next, turn_limit(m.frame_body.shape[0], m.n_rot, f1, max_turn))
    keep = cut == 0 and m.projects != 1 and not switched and m.n_rot != 4 and not moved  # (Euler parameters: normalised)
    flags[HAS_F] = 1 if keep else 0
    if keep:
        _copy(f, f1)
    flags[SPAN], flags[DENSE], flags[CUT] = 1, 0, cut
    counts[STEPS] += 1
    counts[REJECTED] += n_rejected
    counts[EVALS] += n_evals


@inline
def _copy(dst, src):
    """``dst[:] = src`` (n,) without numba's overlap check, which would allocate."""
    for j in range(dst.shape[0]):
        dst[j] = src[j]


@inline
def _copy_rows(dst, src):
    """``dst[:] = src`` (r, c)."""
    for i in range(dst.shape[0]):
        for j in range(dst.shape[1]):
            dst[i, j] = src[i, j]


@inline
def _copy_chart(dst, src):
    """``dst[:] = src`` (nf, 3, 3)."""
    for b in range(dst.shape[0]):
        for i in range(3):
            for c in range(3):
                dst[b, i, c] = src[b, i, c]
