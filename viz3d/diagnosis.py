"""Health checks between steps, and diagnoses that name the body, joint, time and quantity.

A run never continues into NaNs: ``check_state`` raises ``SimulationFailure`` with a message
such as "t = 1.234 s: body 'link3': speed 2.1e+04 m/s exceeds sim.blowup_speed = 1e+04 m/s".
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from viz3d.constraints import constraint_residual, dense_jacobian
from viz3d.system import State, System


class SimulationFailure(RuntimeError):
    """A run that cannot go on; ``str(exc)`` is the diagnosis. ``frame``: the index of the failing
    frame among those a check was given (None when the failure is the state being stepped)."""

    def __init__(self, message: str, frame: int | None = None):
        super().__init__(message)
        self.frame = frame


class RunComplete(Exception):
    """A frame check that ends a run successfully (a goal reached: an anchor seated); ``str(exc)``
    says why, ``frame`` is the index of the last frame kept among those the check was given."""

    def __init__(self, message: str, frame: int):
        super().__init__(message)
        self.frame = frame


#: A body whose orientation coordinates change faster than this per step [rad] is unresolved.
MAX_COORDINATE_TURN = 1.0


def check_state(system: System, state: State, blowup_speed: float, dt: float) -> None:
    """Raise ``SimulationFailure`` on non-finite values, runaway speeds or singular coordinates.

    Orientation coordinates are singular where their rate map is (``rotation.singular_bodies``)
    and unresolved where ``|theta_dot| dt`` exceeds ``MAX_COORDINATE_TURN``: near the gimbal lock
    of plain Euler angles the precession and spin rates grow like ``1 / sin(theta)``.
    """
    if not (np.all(np.isfinite(state.q)) and np.all(np.isfinite(state.v))):
        raise SimulationFailure(_nonfinite(system, state))
    W_v, B_omega = system.split_v(state.v)
    speed = np.linalg.norm(W_v, axis=1)
    b = int(np.argmax(speed)) if speed.size else 0
    if speed.size and speed[b] > blowup_speed:
        raise SimulationFailure(
            f"t = {state.t:.6g} s: body {_frame_name(system, b)!r}: speed {speed[b]:.3g} m/s exceeds sim.blowup_speed = "
            f"{blowup_speed:.3g} m/s (diverged; try a smaller sim.dt){_worst_joint(system, state)}")
    _, theta = system.split_q(state.q)
    turn = np.max(np.abs(system.rotation.rates(theta, B_omega)), axis=1) * dt
    bad = np.flatnonzero(system.rotation.singular_bodies(theta) | (turn > MAX_COORDINATE_TURN))
    if bad.size:
        raise SimulationFailure(_singular(system, state, int(bad[0]), theta, turn))


def _frame_name(system: System, k: int) -> str:
    """Name of the body of floating frame ``k``."""
    return system.bodies.names[int(system.frame_body[k])]


def check_chart(system: System, state: State) -> None:
    """Raise ``SimulationFailure`` if a body's orientation coordinates are singular at ``state``
    (plain Euler angles at nutation 0 or pi: a step from there would divide by sin(theta)).
    Checked before every step, so a body that starts or lands exactly on the pole is diagnosed
    instead of producing infinities."""
    _, theta = system.split_q(state.q)
    bad = np.flatnonzero(system.rotation.singular_bodies(theta))
    if bad.size:
        raise SimulationFailure(_singular(system, state, int(bad[0]), theta, None))


def _singular(system: System, state: State, b: int, theta, turn) -> str:
    name = _frame_name(system, b)
    if turn is None or system.rotation.near_singular(theta)[b]:
        turning = "" if turn is None else f" (coordinates turn {turn[b]:.3g} rad per step)"
        return (f"t = {state.t:.6g} s: body {name!r}: singular Euler chart: nutation theta = {theta[b, 1]:.3e} rad at "
                f"the gimbal lock of {system.rotation.name}, where the Euler-angle rate map divides by sin(theta)"
                f"{turning}; use sim.rotation = 'euler_switching' or 'quaternion'")
    return (f"t = {state.t:.6g} s: body {name!r}: orientation coordinates turn {turn[b]:.3g} rad per step "
            f"(> {MAX_COORDINATE_TURN} rad): the step cannot resolve the rotation; try a smaller sim.dt")


def check_violation(system_of: Callable[[State], System], states, violation, limit: float) -> None:
    """Raise ``SimulationFailure`` at the first of ``states`` whose ``violation`` = max |C| [m]
    (one per state) exceeds ``limit``, naming the worst joint of its system (``system_of(state)``)."""
    bad = np.flatnonzero(np.asarray(violation) > limit)
    if bad.size:
        i = int(bad[0])
        state = states[i]
        raise SimulationFailure(f"t = {state.t:.6g} s: constraint violation {violation[i]:.3g} m exceeds sim.blowup_violation = "
                                f"{limit:.3g} m{_worst_joint(system_of(state), state)}; try a smaller sim.dt or a stabilizing formulation",
                                frame=i)


def held_effort(t: np.ndarray, effort: np.ndarray, window: float) -> np.ndarray:
    """The effort each frame has held for the last ``window`` seconds: ``min |effort_j|`` over the
    frames from the last one at or before ``t_i - window`` to frame i (so that they span at least
    ``window``), shape (n,) [N or N m]; NaN where no frame is that old. ``window = 0``: ``|effort|``
    itself. Times ``t`` (n,) ascending [s]."""
    t, e = np.asarray(t, float), np.abs(np.asarray(effort, float))
    if window <= 0.0:
        return e
    start = _window_start(t, window)
    return np.array([e[a:i + 1].min() if a >= 0 else np.nan for i, a in enumerate(start)])


def overload_start(effort: np.ndarray, limit: float, i: int) -> int:
    """First index of the run of consecutive frames at or over ``limit`` (|effort| >= limit) that ends
    at frame ``i``: where the overload of frame ``i`` began. ``effort`` (n,) [N or N m]."""
    over = np.abs(np.asarray(effort[:i + 1], float)) >= limit
    return 0 if over.all() else i + 1 - int(np.argmin(over[::-1]))


def _window_start(t: np.ndarray, window: float) -> np.ndarray:
    """Index of the last of the times ``t`` (n,) at or before each ``t_i - window`` (-1: none), (n,)."""
    return np.searchsorted(t, t - window + 1e-9, side="right") - 1


class CapacityWatch:
    """Ends a run whose drive has been at its capacity for its ``capacity_time``.

    A drive's frame scalar ``drive/<name>/effort`` is held against ``capacity`` [N or N m] over the
    last ``capacity_time`` [s] of frames (``held_effort``), across the chunks of frames a run checks;
    one rule for both kinds of drive: **at its limit** is ``|effort| >= capacity``, held that long it
    jams. A rigid drive (a constraint) then needs more than it can give, so its run stops with
    ``SimulationFailure`` (its model no longer holds); a limited drive (``servo_gain``,
    ``viz3d.forces.DriveServo``) gives exactly its capacity there and its servo law puts its speed at
    least ``capacity / servo_gain`` below its profile: it has stalled, its model still holds, and the
    run ends with ``RunComplete`` (status ok; the verdict says jammed). Either says since when.
    ``capacity_time = 0``: the first frame at it. Rigid bodies on a rigid velocity drive pass a
    contact's impact to the drive within a step; a capacity held over a time longer than the impact
    (a few ms for steel on steel) and shorter than a stall is what jams a windlass.

    Parameters
    ----------
    limits : dict
        ``name -> (capacity, capacity_time, limited)`` of the drives that have a capacity
        (``limited``: a limited drive).
    """

    def __init__(self, limits: dict[str, tuple[float, float, bool]]):
        self.limits = limits
        self._tail = {name: (np.zeros(0), np.zeros(0)) for name in limits}  # the last window's frames

    def check(self, t: np.ndarray, scalars: dict) -> None:
        """Check the next frames: times ``t`` (n,) [s] and their ``scalars`` (frame columns)."""
        t = np.asarray(t, float)
        for name, (limit, window, limited) in self.limits.items():
            effort = np.abs(np.asarray(scalars.get(f"drive/{name}/effort", np.zeros(t.size)), float))
            t_all, e_all = (np.concatenate(x) for x in zip(self._tail[name], (t, effort)))
            held = held_effort(t_all, e_all, window)[-t.size:] if t.size else np.zeros(0)
            bad = np.flatnonzero(held >= limit)
            if bad.size:
                i = int(bad[0])
                since = overload_start(e_all, limit, len(t_all) - t.size + i)
                held_text = f" since t = {t_all[since]:.6g} s" if window > 0.0 else ""
                if limited:
                    raise RunComplete(f"t = {t[i]:.6g} s: drive {name!r} stalled at its capacity {limit:.4g} (N or N m)"
                                      f"{held_text}: the mechanism jams or the drive is too small", i)
                raise SimulationFailure(f"t = {t[i]:.6g} s: drive {name!r} needs {effort[i]:.4g} (N or N m), over its "
                                        f"capacity {limit:.4g}{held_text}: the mechanism jams or the drive is too "
                                        "small", frame=i)
            first = max(int(_window_start(t_all[-1:], window)[0]), 0) if t_all.size else 0
            self._tail[name] = (t_all[first:], e_all[first:])


class EnergyFailure(SimulationFailure):
    """A run whose energy is not accounted for: it grew in a conservative scene, or the energy
    ledger no longer balances. Its numbers are wrong from the failing frame on, so no verdict is
    drawn from it (``viz3d.stowage.run_verdict``)."""


#: A ledger balance error below this fraction of the largest energy term is rounding, whatever it
#: is relative to the energy that moved: sqrt(eps), the rounding of the potential's datum summed
#: over up to 1e16 steps, far above what any run accumulates (eps |E| per step).
LEDGER_ROUNDOFF = float(np.sqrt(np.finfo(float).eps))


class EnergyWatch:
    """Stops a run whose energy is not accounted for (``EnergyFailure``): a step beyond the method's
    stability limit on a stiff force (a hard contact, a stiff spring, a servo's gain) pumps energy
    into the motion long before anything becomes non-finite, and a one-sided contact may even
    return the body intact with the energy it gained.

    ``check(frames)`` raises at the first frame where, in a conservative scene, ``E - E0`` exceeds
    ``limit`` times the largest kinetic energy seen so far; or where, in a non-conservative scene with
    an energy ledger (contacts or drives: ``energy/balance_error`` among the frame scalars), the ledger's
    |balance error| exceeds ``limit`` times the energy that has moved so far (the largest of the
    kinetic energy, |E - E0|, |work in| and the energy dissipated; ``sim.blowup_energy``). Healthy
    runs balance to their integrator's error, orders of magnitude below (the scenes' checks:
    3e-9 to 2e-3 of it). Conservative scenes keep the first rule only (a method's own numerical
    damping, trapezoidal's or gen_alpha's on an unresolved elastic contact, loses energy without
    diverging); non-conservative scenes without a ledger are not watched (their energy may
    legitimately grow)."""

    def __init__(self, system: System, limit: float, conservative: bool):
        self.system, self.limit, self.conservative = system, float(limit), conservative
        self.E0: float | None = None
        self.T_max = 0.0
        self.moved = 0.0

    def check(self, frames) -> None:
        """Watch the next frames of the run, in order (``viz3d.columns.FrameColumns``: arrays over
        instants of ``t``, ``energy_kinetic``, ``energy_potential``, ``R_WB``, ``W_v``, ``W_omega`` and
        ``scalars``)."""
        ledger = not self.conservative and "energy/balance_error" in frames.scalars
        if not (self.conservative or ledger) or not len(frames.t):
            return
        T = frames.energy_kinetic
        E = T + frames.energy_potential
        self.E0 = float(E[0]) if self.E0 is None else self.E0
        T_max = np.maximum.accumulate(np.maximum(T, self.T_max))
        bad = [np.inf, np.inf]
        if self.conservative:
            growth = E - self.E0
            bad[0] = _first(((T_max > 0.0) & (growth > self.limit * T_max)))
        if ledger:
            s = frames.scalars
            moved = np.maximum.accumulate(np.maximum.reduce([
                np.full(T.shape, self.moved), T_max, np.abs(E - self.E0), np.abs(s["energy/work_in"]),
                np.abs(s["energy/dissipated"])]))
            balance = np.abs(s["energy/balance_error"])
            floor = LEDGER_ROUNDOFF * np.maximum(np.abs(E), abs(self.E0))
            bad[1] = _first(~(balance <= np.maximum(self.limit * moved, floor)))  # (NaN fails)
        if min(bad) == np.inf:
            self.T_max = float(T_max[-1])
            self.moved = float(moved[-1]) if ledger else 0.0
            return
        i = int(min(bad))
        self.T_max = float(T_max[i])
        body = self._most_energetic(frames, i)
        if bad[0] <= bad[1]:
            growth_i = float(E[i] - self.E0)
            raise EnergyFailure(
                f"t = {frames.t[i]:.6g} s: total energy grew by {growth_i:.3g} J = {growth_i / self.T_max:.3g} of the "
                f"largest kinetic energy (> sim.blowup_energy = {self.limit:g}) in a conservative scene: diverged, the "
                f"step is beyond the method's stability limit; body {body!r} carries the most kinetic energy; try a "
                "smaller sim.dt or an implicit integrator", frame=i)
        s = frames.scalars
        raise EnergyFailure(
            f"t = {frames.t[i]:.6g} s: the energy ledger does not balance: error {s['energy/balance_error'][i]:.3g} J "
            f"= {abs(s['energy/balance_error'][i]) / moved[i]:.3g} of the energy that moved ({moved[i]:.4g} J: work in "
            f"{s['energy/work_in'][i]:.4g} J, dissipated {s['energy/dissipated'][i]:.4g} J, kinetic up to "
            f"{self.T_max:.4g} J; > sim.blowup_energy = {self.limit:g}): the step does not resolve a stiff force (a "
            f"contact, a spring, a drive's servo gain) or is beyond its stability limit; body {body!r} carries the most "
            "kinetic energy; try a smaller sim.dt", frame=i)

    def _most_energetic(self, frames, i: int) -> str:
        b = self.system.bodies
        B_omega = np.einsum("nji,nj->ni", frames.R_WB[i], frames.W_omega[i])
        W_v = frames.W_v[i]
        T = 0.5 * b.mass * np.sum(W_v**2, axis=1) + 0.5 * np.einsum("ni,nij,nj->n", B_omega, b.inertia, B_omega)
        return b.names[int(np.argmax(T))]


def _first(mask: np.ndarray) -> float:
    """Index of the first True of ``mask`` (inf when none)."""
    hit = np.flatnonzero(mask)
    return float(hit[0]) if hit.size else np.inf


def _nonfinite(system: System, state: State) -> str:
    q_ok, v_ok = _finite_per_body(system, state.q, system.n_q_body), _finite_per_body(system, state.v, 6)
    bad = np.flatnonzero(~(q_ok & v_ok))
    names = ", ".join(repr(system.bodies.names[b]) for b in bad[:5])
    what = "position/orientation" if not q_ok[bad[0]] else "velocity"
    return f"t = {state.t:.6g} s: non-finite {what} of body {names} (diverged; try a smaller sim.dt)"


def _finite_per_body(system: System, x: np.ndarray, per_frame: int) -> np.ndarray:
    """Per body (nb,): all its entries of ``x`` (a ``q``- or ``v``-like vector) are finite."""
    ok = np.ones(system.n_bodies, dtype=bool)
    nf = system.n_frames
    ok[system.frame_body] = np.all(np.isfinite(x[: nf * per_frame].reshape(nf, per_frame)), axis=1)
    offset = nf * per_frame
    for fb in system.bodies.flexible:
        ok[fb.index] &= bool(np.all(np.isfinite(x[offset:offset + fb.n])))
        offset += fb.n
    return ok


def _worst_joint(system: System, state: State) -> str:
    if system.n_c == 0:
        return ""
    from viz3d.dynamics import body_state

    with np.errstate(all="ignore"):
        C = constraint_residual(system.joints, body_state(system, state.q, state.v, state.chart))
    if not np.all(np.isfinite(C)):
        return ""
    per_joint = _per_joint(system, np.abs(C))
    j = int(np.argmax(per_joint))
    return f"; largest violation at joint {_row_names(system)[j]!r} (|C| = {per_joint[j]:.3g} m)"


def _row_names(system: System) -> tuple[str, ...]:
    """Names of every row provider's members (joints, then kinematic contacts)."""
    return tuple(n for js in system.joints.joints for n in js.names)


def _per_joint(system: System, row_values: np.ndarray) -> np.ndarray:
    out = []
    for js, sl in zip(system.joints.joints, system.joints.row_slices()):
        out.append(row_values[sl].reshape(js.n_joints, js.n_eq).max(axis=1))
    return np.concatenate(out)


def redundant_joints(system: System, J: np.ndarray, Je: np.ndarray | None = None, rel_tol: float = 1e-9) -> list[str]:
    """Names of the joints involved in a rank deficiency of ``C_v`` (frame blocks (n_c, 2, 6) and
    elastic blocks (n_c, 2, n_e))."""
    n_c = system.n_c
    Je = np.zeros((n_c, 2, system.n_elastic)) if Je is None else Je
    U, s, _ = np.linalg.svd(dense_jacobian(system, J, Je))
    null = U[:, s <= rel_tol * max(s.max(), 1e-300)] if s.size else U
    if null.shape[1] == 0 and n_c > s.size:
        null = U[:, s.size:]
    if null.shape[1] == 0:
        return []
    weight = _per_joint(system, np.abs(null).max(axis=1))
    return [_row_names(system)[j] for j in np.flatnonzero(weight > 1e-6)]
