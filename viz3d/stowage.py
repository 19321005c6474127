"""The verdict of a haul (``[stowage]``, written by the ``[ship]`` generator; issue 11): did the
hauled bodies reach their stowed poses?

* **seated**: at the end of the run every body is within ``tolerance`` [m] of its stowed centre of
  mass and ``angle_tolerance`` [deg] of its stowed orientation (the angle of ``R_stowed^T R``); the
  time given is when they entered that tolerance for good;
* **jammed**: the drive was at its limit (``|effort| >= capacity``) for its ``capacity_time``
  (``viz3d.diagnosis.held_effort``, ``CapacityWatch``): a limited drive (``servo_gain``) stalled
  there, the run ending cleanly; a rigid drive needed more than it can give, the run stopping with
  a diagnosis (or failing sooner while over it: ``stopped``), or
  the bodies moved less than ``stall_distance`` over the last ``stall_time`` of a run that ended
  short of seated while the drive was still hauling;
* **not reached**: anything else (the haul ended short of the stowed pose, still moving).

The peak hauling force is the largest effort the drive held for its ``capacity_time`` (the one the
jam is judged by; ``|effort|`` itself when that is 0); the largest ``|effort|`` of any frame, an
impact's spike included, is the peak transient.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from viz3d.diagnosis import RunComplete, held_effort, overload_start
from viz3d.outputs import HawseTension
from viz3d.scene.chainpath import link_index

OUTCOMES = ("seated", "jammed", "not reached")


@dataclass(frozen=True)
class Verdict:
    """Outcome of a haul.

    Attributes
    ----------
    outcome : str
        One of ``OUTCOMES``.
    time : float
        When it was decided [s]: seated since, jammed at; the last frame for not reached.
    peak_force : float
        Largest effort the drive held for its ``capacity_time`` [N].
    position_error : float
        Largest distance of a body from its stowed centre of mass at the end [m].
    angle_error : float
        Largest angle of a body from its stowed orientation at the end [deg].
    reason : str
        One line a user reads.
    peak_transient : float
        Largest |effort| of any frame [N] (an impact's spike included).
    """

    outcome: str
    time: float
    peak_force: float
    position_error: float
    angle_error: float
    reason: str
    peak_transient: float = float("nan")

    def line(self) -> str:
        return (f"{self.outcome} at t = {self.time:.3f} s ({self.reason}); peak hauling force "
                f"{self.peak_force / 1e3:.1f} kN ({self.peak_transient / 1e3:.1f} kN transient); at the end "
                f"{self.position_error:.3f} m and {self.angle_error:.2f} deg from stowed")

    def as_dict(self) -> dict:
        return asdict(self)


def pose_errors(spec: dict, t_position: np.ndarray, t_rotation: np.ndarray, index: list[int]
                ) -> tuple[np.ndarray, np.ndarray]:
    """Per frame, the largest distance [m] and angle [deg] of the bodies ``index`` from their stowed
    poses, shapes (n_t,), from positions (n_t, nb, 3) and rotations (n_t, nb, 3, 3)."""
    P = np.asarray(spec["position"], float)             # (k, 3)
    A = np.asarray(spec["axes"], float)                 # (k, 3, 3)
    dist = np.linalg.norm(t_position[:, index] - P[None], axis=-1)
    rel = np.einsum("kji,tkjl->tkil", A, t_rotation[:, index])   # R_stowed^T R
    sin = 0.5 * np.linalg.norm(np.stack([rel[..., 2, 1] - rel[..., 1, 2], rel[..., 0, 2] - rel[..., 2, 0],
                                         rel[..., 1, 0] - rel[..., 0, 1]], axis=-1), axis=-1)
    cos = 0.5 * (np.trace(rel, axis1=-2, axis2=-1) - 1.0)
    return dist.max(axis=1), np.degrees(np.arctan2(sin, cos)).max(axis=1)


def verdict(spec: dict, t: np.ndarray, position: np.ndarray, rotation: np.ndarray, body_names, effort: np.ndarray,
            capacity: float | None, hauling: np.ndarray, capacity_time: float = 0.0, stopped: bool = False) -> Verdict:
    """The ``Verdict`` of a run from its frames: times ``t`` (n_t,), body positions (n_t, nb, 3) and
    rotations (n_t, nb, 3, 3), the drive's effort (n_t,) [N], its capacity [N] (None: unlimited)
    held for ``capacity_time`` [s], and whether it hauls at each frame (n_t,) (its prescribed speed
    is not zero). One rule for rigid and limited drives: at its limit is ``|effort| >= capacity`` (a
    limited drive's effort is exactly its capacity there, stalled). ``stopped``: the run failed after
    its last frame (diverged): a drive at its capacity at that frame jammed (a rigid drive pulling a
    wedged body drives the contact force up until the step cannot follow, sooner than
    ``capacity_time``)."""
    names = list(body_names)
    index = [names.index(b) for b in spec["bodies"]]
    dist, angle = pose_errors(spec, position, rotation, index)
    held = held_effort(t, effort, capacity_time)
    spanned = np.isfinite(held).any()
    peak = float(np.nanmax(held)) if spanned else float(np.max(np.abs(effort), initial=0.0))
    args = (peak, float(dist[-1]), float(angle[-1]))
    extra = {"peak_transient": float(np.max(np.abs(effort), initial=0.0))}
    if capacity is not None and spanned and peak >= capacity:
        i = int(np.argmax(held >= capacity))
        since = overload_start(effort, capacity, i)
        held_text = f" for {t[i] - t[since]:.3g} s" if capacity_time > 0.0 else ""
        return Verdict("jammed", float(t[since]), *args, f"{_at_limit(effort[i], capacity)}{held_text}", **extra)
    if capacity is not None and stopped and effort.size and abs(effort[-1]) >= capacity:
        since = overload_start(effort, capacity, len(effort) - 1)
        return Verdict("jammed", float(t[since]), *args, f"{_at_limit(effort[-1], capacity)} since t = {t[since]:.6g} s "
                       "when the run failed", **extra)
    inside = (dist <= spec["tolerance"]) & (angle <= spec["angle_tolerance"])
    if inside[-1]:
        since = len(inside) - int(np.argmin(inside[::-1])) if not inside.all() else 0
        return Verdict("seated", float(t[since]), *args, f"within {spec['tolerance']:g} m and "
                       f"{spec['angle_tolerance']:g} deg of the stowed pose", **extra)
    window = t >= t[-1] - spec["stall_time"]
    if t[-1] - t[0] >= spec["stall_time"] and hauling[-1]:
        moved = np.linalg.norm(position[window][:, index] - position[window][-1:, index], axis=-1).max()
        if moved < spec["stall_distance"]:
            return Verdict("jammed", float(t[window][0]), *args, f"moved {moved:.3f} m in the last "
                           f"{spec['stall_time']:g} s while the drive hauled", **extra)
    return Verdict("not reached", float(t[-1]), *args, "the haul ended (sim.t_end or haul_limit) short of the stowed "
                   "pose", **extra)


def _at_limit(effort: float, capacity: float) -> str:
    """What a drive at its limit did: stalled at its capacity (a limited drive), or needed more [N]."""
    if abs(effort) <= capacity:
        return f"the drive stalled at its capacity {capacity / 1e3:.1f} kN"
    return f"the drive needs {abs(effort) / 1e3:.1f} kN, over its capacity {capacity / 1e3:.1f} kN"


def seated_stop(spec: dict, body_names, coordinate: str | None = None):
    """The run's frame check that stops the windlass once the ``[stowage]`` bodies have stayed seated
    (``tolerance``, ``angle_tolerance``) for ``settle_time`` [s], or once its ``coordinate`` (the
    frame scalar of the drive's joint coordinate) has moved ``haul_limit`` from 0: ``check(cols,
    states)`` raises ``RunComplete`` at that frame; None when the spec has neither (the haul runs to
    t_end)."""
    settle, limit = spec.get("settle_time"), spec.get("haul_limit")
    if settle is None and limit is None:
        return None
    index = [list(body_names).index(b) for b in spec["bodies"]]
    since = [None]  # when the bodies last came within tolerance (over chunks)

    def check(cols, states):
        dist, angle = pose_errors(spec, cols.W_r, cols.R_WB, index)
        inside = (dist <= spec["tolerance"]) & (angle <= spec["angle_tolerance"])
        hauled = np.abs(np.asarray(cols.scalars[coordinate], float)) if limit is not None else np.zeros(len(cols.t))
        for i, (t, ok) in enumerate(zip(cols.t, inside)):
            since[0] = (since[0] if since[0] is not None else t) if ok else None
            if settle is not None and ok and t - since[0] >= settle - 1e-9:
                raise RunComplete(f"seated since t = {since[0]:.6g} s: the windlass stopped at t = {t:.6g} s", i)
            if limit is not None and hauled[i] >= limit:
                raise RunComplete(f"the windlass hauled its limit {limit:.6g} (haul_limit): it stopped at t = {t:.6g} s",
                                  i)

    return check


def drive_coordinate(data: dict, keys) -> str | None:
    """The frame scalar among ``keys`` of the coordinate the ``[stowage]`` drive of the scene ``data``
    moves (``joint/<joint>/<coordinate>``), None if there is none."""
    drive = next(d for d in data["drives"] if d["name"] == data["stowage"]["drive"])
    prefix, coordinate = f"joint/{drive['joint']}/", drive.get("coordinate")
    return next((k for k in keys if k.startswith(prefix) and not k.endswith("_rate")
                 and (coordinate is None or k == prefix + coordinate)), None)


def run_verdict(data: dict, cols, body_names, stopped: bool = False) -> Verdict | None:
    """The ``Verdict`` of a run of the scene ``data`` from its frame columns (``viz3d.columns``); None
    without a ``[stowage]`` table."""
    spec = data.get("stowage")
    if spec is None or not len(cols):
        return None
    drive = next(d for d in data["drives"] if d["name"] == spec["drive"])
    key = drive_coordinate(data, cols.scalars)
    hauling = np.abs(cols.scalars[f"{key}_rate"]) > 1e-9 if key else np.ones(len(cols), bool)
    effort = np.asarray(cols.scalars.get(f"drive/{spec['drive']}/effort", np.zeros(len(cols))), float)
    v = verdict(spec, cols.t, cols.W_r, cols.R_WB, body_names, effort, drive.get("capacity"), hauling,
                drive.get("capacity_time", 0.0), stopped)
    depth0 = float(np.asarray(cols.scalars.get("collision/max_depth", [0.0]))[0])
    if v.outcome == "jammed" and depth0 > 0.0:  # a scene that starts in contact may 'jam' on its own overlap
        v = replace(v, reason=f"{v.reason}; at t = 0 shapes already overlapped by {depth0:.3g} m (check the "
                    "starting pose)")
    return v


def run_events(data: dict, cols) -> list[tuple[float, str]]:
    """Milestones of a run from its frame columns, as ``(t, text)``: the first shape contact, and
    each joint stop reached for the first time."""
    out = []
    touching = np.flatnonzero(np.asarray(cols.scalars.get("collision/contacts", ()), float) > 0)
    if touching.size:
        out.append((float(cols.t[touching[0]]), "first shape contact (collision)"))
    for f in (f for f in data["forces"] if f["type"] == "joint_stop"):
        key = next((k for k in cols.scalars if k.startswith(f"joint/{f['joint']}/")
                    and not k.endswith("_rate") and (f.get("coordinate") is None or k.endswith(f["coordinate"]))), None)
        if key is None:
            continue
        q = np.asarray(cols.scalars[key], float)
        beyond = (q < f.get("lower", -np.inf)) | (q > f.get("upper", np.inf))
        if beyond.any():
            out.append((float(cols.t[np.argmax(beyond)]), f"{f.get('name', 'joint stop')} reached ({f['joint']})"))
    return sorted(out)


def verdict_fields(v: Verdict, spec: dict, tension: np.ndarray | None = None) -> dict:
    """Trajectory fields of a verdict (docs/trajectory.md): ``stowage_verdict`` (one of
    ``OUTCOMES``), ``stowage_time`` [s], ``stowage_peak_force`` [N], ``stowage_position_error`` [m],
    ``stowage_angle_error`` [deg], ``stowage_reason``, the chain's tension at the hawse
    ``stowage_hawse_tension`` (n,) [N], and the generator's report as ``stowage_<key>``."""
    out = {f"stowage_{k}": val for k, val in v.as_dict().items() if k != "outcome"}
    if tension is not None:
        out["stowage_hawse_tension"] = tension
    out["stowage_verdict"] = v.outcome
    out.update({f"stowage_{k}": val for k, val in spec.get("report", {}).items()})
    return out


def hawse_output(spec: dict, body_names, joint_names, W_r0) -> HawseTension | None:
    """The output element of the chain's tension at ``spec["hawse"]`` (``viz3d.outputs.HawseTension``):
    the links ``<chain><i>`` and their upper joints ``<chain>_j<i>``, half a link's pitch from the
    initial positions ``W_r0`` (nb, 3) [m] (links are one pitch apart); None without a hawse point
    or a chain of at least two links."""
    if "hawse" not in spec:
        return None
    names, joints, prefix = list(body_names), list(joint_names), spec["chain"]
    numbers = sorted(i for n in names if (i := link_index(n, prefix)) is not None)
    links = [(names.index(f"{prefix}{i}"), joints.index(f"{prefix}_j{i}"))  # (the links still in the run)
             for i in numbers if f"{prefix}_j{i}" in joints]
    if len(links) < 2:
        return None
    b, j = np.array(links).T
    half = 0.5 * float(np.linalg.norm(W_r0[b[1]] - W_r0[b[0]]))
    return HawseTension(b, j, half, np.asarray(spec["hawse"], float))
