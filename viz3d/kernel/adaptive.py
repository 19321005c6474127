"""Adaptive explicit Runge-Kutta runs in the kernel: what ``viz3d.simulate.Simulation`` does with a
step-size ``viz3d.integrators.adaptive.Controller`` (trial steps, the weighted RMS error norm,
rejections, the next step's proposal and the orientation-turn limit), the accepted steps'
continuous extension (``viz3d.integrators.tableaus.DenseOutput``) sampled at the output times, and
between steps what ``viz3d.kernel.stepping.advance`` does (the ``projection`` formulation's
projections, health checks, chart switches).

A call stops *before committing* whatever needs Python, which then redoes it from the same carry
(the kernel is deterministic) exactly as on a run without the kernel: an event function of the
contacts changing sign over a step (``EVENT``: Python locates and handles the event), a failed
evaluation, projection or health check, a step below ``min_step`` (``UNDERFLOW``): Python writes
the diagnosis. While a law contact acts (``record``), each accepted step's end time, settled state,
chart and error estimate go to the step records (``rec_t`` (R,), ``rec_y`` (R, n), ``rec_chart``
(R, nf, 3, 3), ``rec_err`` (R, n), ``n_rec`` (1,)), from which Python brings the contacts' memory
up to date after the call (``viz3d.events.ContactStepping.after_step``: bookkeeping and checks that
do not change the vector field); a call whose records are full stops before the next step (``FULL``).

The carry (arrays updated in place, see ``viz3d.kernel.KernelStepper.adaptive``):

* ``y`` (n,), ``chart`` (nf, 3, 3): the state after the last accepted step ("inner" state);
* ``f`` (n,): the vector field there when ``flags[HAS_F]``;
* ``times``: ``[t, h, span t0, span t1, span h]`` [s]: the inner time, the next step to try, the
  last accepted step (its length as taken: ``t1 - t0`` within round-off);
* ``y0`` (n,), ``chart0`` (nf, 3, 3), ``K`` (s + m, n), ``Q`` (degree, n): the last accepted step's
  start, its stages (then its continuous extension's extra stages) and dense-output coefficients
  (``y(t0 + x h) = y0 + sum_d x^(d + 1) Q[d]``) when ``flags[DENSE]``; ``f1`` (n,) the field at its end;
* ``counts``: accepted steps, rejected trial steps, vector-field evaluations.
"""

from __future__ import annotations

import math

from viz3d.compiled import entry, inline, jit
from viz3d.kernel.field import NONFINITE, OK, evaluate, gaps
from viz3d.kernel.projection import project
from viz3d.kernel.stepping import _check_frames, rk_step, state_ok, unit_parameters

#: Status codes beyond ``viz3d.kernel.field``'s: an event function changed sign over the step
#: about to be committed; the controller asked for a step below ``min_step``; the step records are
#: full (the next step needs a record).
EVENT, UNDERFLOW, FULL = 6, 7, 8
#: Indices of ``times``, ``flags`` and ``counts``.
T, H, T0, T1, SPAN_H = 0, 1, 2, 3, 4
HAS_F, SPAN, DENSE = 0, 1, 2
STEPS, REJECTED, EVALS = 0, 1, 2
#: Event kinds (``viz3d.events.ContactStepping.event_rows``): a contact's ``alpha`` less its floor,
#: its ``alpha_dot``, a kinematic contact's multiplier.
GAP, GAP_RATE, MULTIPLIER = 0, 1, 2


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
    """The event functions at ``(t, y)`` into ``out`` (E,): ``GAP`` ``alpha - floor``, ``GAP_RATE``
    ``alpha_dot`` of contact ``index``, ``MULTIPLIER`` the multiplier of row ``index``; returns the
    status of the evaluation the multipliers need (``OK`` when none)."""
    n_ev = kind.shape[0]
    if n_ev == 0:
        return OK
    gaps(t, y, chart, m, v, w, geometry, gap_out)
    status = OK
    solved = False
    for e in range(n_ev):
        if kind[e] == GAP:
            out[e] = gap_out[index[e], 0] - floor[e]
        elif kind[e] == GAP_RATE:
            out[e] = gap_out[index[e], 1]
        else:
            if not solved:
                status = evaluate(t, y, chart, m, v, w, forces, rows, ydot)
                solved = True
                if status != OK:
                    return status
            out[e] = w.lam[index[e]]
    return status


@inline
def crosses(direction, g0, g1):
    """``viz3d.integrators.adaptive.Event.crosses``."""
    rising = g0 < 0.0 <= g1
    falling = g0 > 0.0 >= g1
    if direction > 0:
        return rising
    if direction < 0:
        return falling
    return rising or falling


@jit
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


@jit
def accepted_step(t, y, chart, f, h, ctrl, ta, tb, te, tc, m, v, w, forces, rows, k, yi, y1, err):
    """``viz3d.integrators.adaptive.accepted_step``: trial steps from ``(t, y)`` until the error
    test passes; returns (step taken, next step proposed, rejections, status)."""
    rtol, atol, min_step, q = ctrl[0], ctrl[1], ctrl[3], ctrl[4]
    safety, fac_min, fac_max = ctrl[5], ctrl[6], ctrl[7]
    n_rejected = 0
    while True:
        status = rk_step(t, h, y, chart, f, True, ta, tb, te, tc, m, v, w, forces, rows, k, yi, y1, err)
        if status != OK:
            return h, h, n_rejected, status
        norm = error_norm(err, y, y1, rtol, atol, yi)
        if norm <= 1.0:
            return h, next_step(h, norm, q, safety, fac_min, fac_max), n_rejected, OK
        n_rejected += 1
        h = next_step(h, norm, q, safety, fac_min, fac_max) if math.isfinite(norm) else fac_min * h
        if h < min_step or t + h == t:
            return h, h, n_rejected, UNDERFLOW


@entry
def adaptive_frames(n_frames, every, n0, t_start, dt, contact_mode, max_speed, max_turn, ctrl, ta, tb, te, tc, fsal,
                    P, c_extra, a_extra, reuse, ev_kind, ev_index, ev_floor, ev_dir, record, rec_t, rec_y, rec_chart,
                    rec_err, n_rec, m, v, w, forces, rows, geometry,
                    y, chart, f, times, flags, counts, switches, y0, chart0, K, Q, f1,
                    k, yi, y1, err, ys, chart1, sw, gap_out, g0, g1, Y, charts, Ts):
    """Up to ``n_frames`` output frames, ``every`` samples apart, of an adaptive run (the carry in
    place, see the module docstring): sample ``i`` of the run is at ``t_start + i dt``, the first
    here is ``n0 + 1``. Frame ``f``'s time, state and chart go to ``Ts[f]``, ``Y[f]``,
    ``charts[f]``. ``contact_mode``: the sampling of a run with contacts (``Simulation._event_steps``:
    no projection or check of samples, the inner state itself within round-off of the output time)
    and the sign checks of the event functions ``(ev_kind, ev_index, ev_floor, ev_dir)``; with
    ``record`` every accepted step goes to the step records (module docstring).

    Returns (frames done, samples done in the next frame, status); on a status other than ``OK``
    nothing of the step or sample that stopped the call is committed."""
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
                status = _commit_step(contact_mode, max_speed, max_turn, ctrl, ta, tb, te, tc, fsal, ev_kind,
                                      ev_index, ev_floor, ev_dir, m, v, w, forces, rows, geometry, y, chart, f,
                                      times, flags, counts, switches, y0, chart0, K, f1, k, yi, y1, err, chart1,
                                      sw, gap_out, g0, g1)
                if status != OK:
                    return frame, sample, status
                if record:
                    _record(times[T], y, chart, err, rec_t, rec_y, rec_chart, rec_err, n_rec)
            if contact_mode and abs(times[T] - target) <= slack:
                t_s = times[T]
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
def _record(t, y, chart, err, rec_t, rec_y, rec_chart, rec_err, n_rec):
    """The step just committed (end time, settled state and chart, error estimate) as the next record."""
    r = n_rec[0]
    rec_t[r] = t
    _copy(rec_y[r], y)
    _copy(rec_err[r], err)
    _copy_chart(rec_chart[r], chart)
    n_rec[0] = r + 1


@jit
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
def _commit_step(contact_mode, max_speed, max_turn, ctrl, ta, tb, te, tc, fsal, ev_kind, ev_index, ev_floor, ev_dir,
                 m, v, w, forces, rows, geometry, y, chart, f, times, flags, counts, switches, y0, chart0, K, f1,
                 k, yi, y1, err, chart1, sw, gap_out, g0, g1):
    """One accepted step from the inner state, then what ``Simulation._accept`` does after it;
    committed to the carry only when nothing needs Python (see the module docstring)."""
    t = times[T]
    if flags[HAS_F] == 0:
        status = evaluate(t, y, chart, m, v, w, forces, rows, f)
        if status != OK:
            return status
        flags[HAS_F] = 1  # the field at the inner state, kept whatever follows (as Simulation._f)
        counts[EVALS] += 1
    h, h_next, n_rejected, status = accepted_step(t, y, chart, f, min(times[H], ctrl[2]), ctrl, ta, tb, te, tc, m, v,
                                                  w, forces, rows, k, yi, y1, err)
    if status != OK:
        return status
    n_evals = (n_rejected + 1) * (tb.shape[0] - 1)
    if fsal:
        _copy(f1, k[tb.shape[0] - 1])
    else:
        n_evals += 1
        status = evaluate(t + h, y1, chart, m, v, w, forces, rows, f1)
        if status != OK:
            return status
    if contact_mode:
        status = _event_crossed(t, h, y, y1, chart, ev_kind, ev_index, ev_floor, ev_dir, m, v, w, forces, rows,
                                geometry, gap_out, yi, g0, g1)
        if status != OK:
            return status
    status = _settled(t + h, h, y1, chart, max_speed, m, v, w, rows, yi, chart1, sw)
    if status != OK:
        return status
    _commit(t, h, h_next, n_rejected, n_evals, max_turn, m, y, chart, f, times, flags, counts, switches, y0, chart0,
            K, f1, k, yi, chart1, sw)
    return OK


@jit
def _event_crossed(t, h, y, y1, chart, ev_kind, ev_index, ev_floor, ev_dir, m, v, w, forces, rows, geometry, gap_out,
                   scratch, g0, g1):
    """``EVENT`` when an event function changes sign (``crosses``) between ``(t, y)`` and
    ``(t + h, y1)``, both in the step's ``chart`` (as ``Simulation._event_step`` evaluates them);
    else ``OK``, or the status of a failed evaluation."""
    if ev_kind.shape[0] == 0:
        return OK
    status = event_values(t, y, chart, ev_kind, ev_index, ev_floor, m, v, w, forces, rows, geometry, gap_out, scratch,
                          g0)
    if status != OK:
        return status
    status = event_values(t + h, y1, chart, ev_kind, ev_index, ev_floor, m, v, w, forces, rows, geometry, gap_out,
                          scratch, g1)
    if status != OK:
        return status
    for e in range(ev_kind.shape[0]):
        if crosses(ev_dir[e], g0[e], g1[e]):
            return EVENT
    return OK


@jit
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
def _commit(t, h, h_next, n_rejected, n_evals, max_turn, m, y, chart, f, times, flags, counts, switches, y0, chart0, K,
            f1, k, y_end, chart_end, sw):
    """The accepted step into the carry: its span (start, stages, length), the settled end state as
    the inner state, the next step (``min(h_next, turn_limit)``), the field kept when the end state
    is the step's own (no projection, no chart switch, no Euler parameters to normalise:
    ``Simulation._settle``), the counters."""
    switched = False
    for b in range(sw.shape[0]):
        switches[b] += sw[b]
        switched = switched or sw[b] != 0
    times[T0], times[T1], times[SPAN_H] = t, t + h, h
    _copy(y0, y)
    _copy(y, y_end)
    for i in range(k.shape[0]):
        _copy(K[i], k[i])
    _copy_chart(chart0, chart)
    _copy_chart(chart, chart_end)
    times[T] = t + h
    times[H] = min(h_next, turn_limit(m.frame_body.shape[0], m.n_rot, f1, max_turn))
    keep = m.projects != 1 and not switched and m.n_rot != 4  # (Euler parameters are normalised: a new state)
    flags[HAS_F] = 1 if keep else 0
    if keep:
        _copy(f, f1)
    flags[SPAN], flags[DENSE] = 1, 0
    counts[STEPS] += 1
    counts[REJECTED] += n_rejected
    counts[EVALS] += n_evals


@inline
def _copy(dst, src):
    """``dst[:] = src`` (n,) without numba's overlap check, which would allocate."""
    for j in range(dst.shape[0]):
        dst[j] = src[j]


@inline
def _copy_chart(dst, src):
    """``dst[:] = src`` (nf, 3, 3)."""
    for b in range(dst.shape[0]):
        for i in range(3):
            for c in range(3):
                dst[b, i, c] = src[b, i, c]
