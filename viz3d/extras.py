"""The trajectory fields of runs with contacts, flexible bodies and gauges (``Trajectory.extras``;
docs/trajectory.md, "Contacts, flexible bodies and gauges").

Per frame (n frames, k contacts, ng strain gauges, nd deflection gauges): ``contact_force`` (n, k)
[N], ``penetration`` (n, k) [m], ``approach_velocity`` (n, k) [m/s] (relative normal velocity of
each contact's bodies' centres of mass, positive approaching), ``gauge_strain`` (n, ng),
``deflection`` (n, nd) [m], the ledger ``energy_strain``, ``energy_contact_elastic``,
``energy_dissipated``, ``energy_work_in``, ``energy_balance_error`` (n,) [J]. Per run:
``contact_names`` (k,), ``gauge_names``, ``gauge_x``, ``deflection_names``, ``deflection_x`` (nd,),
``events_t`` / ``events_text``, and from ``viz3d.contact.report``: ``contacts`` (m, 4) as the physics defines
them, ``contact_touch_names`` (m,), ``contact_count``, ``contact_restitution`` (m,),
``contact_breaks_unresolved`` (m,), ``contact_touches_unresolved`` (u, 4), ``contact_events`` (r, 4),
``restitution`` (the bodies', first impact), ``restitution_uncertainty``, ``impact_restitution``
(ni,), ``impact_speeds`` (ni, 2), ``velocity_uncertainty``, ``relative_velocity_uncertainty``, ``restitution_requested``,
``time_resolution``, ``contact_resolution``, ``model_choice``.
"""

from __future__ import annotations

import numpy as np

from viz3d.outputs import DeflectionGauges, StrainGauges

LEDGER = ("strain", "contact_elastic", "dissipated", "work_in", "balance_error")


def run_extras(sim, scene, frames) -> dict:
    """The extra trajectory fields of a finished (or stopped) run of ``sim`` on ``scene``; ``frames``:
    its ``viz3d.columns.FrameColumns``."""
    system = sim.system
    names = [n for c in system.contacts for n in c.names]
    gauges = [(n, float(x)) for g in system.outputs if isinstance(g, StrainGauges) for n, x in zip(g.names, g.x)]
    sags = [(n, float(x)) for g in system.outputs if isinstance(g, DeflectionGauges) for n, x in zip(g.names, g.x)]
    out = {
        "contact_names": np.array(names, dtype=str),
        "contact_force": _series(frames, [f"contact/{n}/force" for n in names]),
        "penetration": _series(frames, [f"contact/{n}/indentation" for n in names]),
        "gauge_names": np.array([n for n, _ in gauges], dtype=str),
        "gauge_x": np.array([x for _, x in gauges], float),
        "gauge_strain": _series(frames, [f"strain/{n}" for n, _ in gauges]),
        "deflection_names": np.array([n for n, _ in sags], dtype=str),
        "deflection_x": np.array([x for _, x in sags], float),
        "deflection": _series(frames, [f"deflection/{n}" for n, _ in sags]),
        "model_choice": np.array("; ".join(f"{system.bodies.names[fb.index]}: {fb.model_choice}"
                                           for fb in system.bodies.flexible) or "rigid bodies"),
    }
    if any(c.located for c in system.contacts):
        out.update(_contact_fields(sim, scene, frames, names))
    return out


def ledger_fields(system, frames) -> dict:
    """The energy ledger as trajectory fields ``energy_strain``, ``energy_contact_elastic``,
    ``energy_dissipated``, ``energy_work_in``, ``energy_balance_error`` (n,) [J], when the state carries
    work integrals (``System.n_aux``: located contacts or drives); else none."""
    return {f"energy_{k}": _series(frames, [f"energy/{k}"])[:, 0] for k in LEDGER} if system.n_aux else {}


def joint_fields(system, frames) -> dict:
    """The joints' relative coordinates and the drives' efforts as trajectory fields (none when no
    joint has one): ``joint_coordinate_names`` (m,) ``<joint>/<coordinate>``, ``joint_coordinates`` and
    ``joint_coordinate_rates`` (n, m) [rad, m; rad/s, m/s] (``viz3d.joints.relative_coordinates``);
    ``drive_names`` (d,), ``drive_effort`` (n, d) [N m or N] (``viz3d.joints.drive_efforts``; limited drives:
    ``viz3d.forces.DriveServo.scalars``)."""
    out = {}
    names = [f"{n}/{c}" for js in system.joints.joints for n in js.names for c in getattr(js, "coordinate_names", ())]
    if names:
        out.update({"joint_coordinate_names": np.array(names, dtype=str),
                    "joint_coordinates": _series(frames, [f"joint/{n}" for n in names]),
                    "joint_coordinate_rates": _series(frames, [f"joint/{n}_rate" for n in names])})
    drives = system.drive_names
    if drives:
        out.update({"drive_names": np.array(drives, dtype=str),
                    "drive_effort": _series(frames, [f"drive/{n}/effort" for n in drives])})
    return out


def element_fields(system, frames) -> dict:
    """Force elements' frame scalars as trajectory fields, ``a/b`` saved as ``a_b`` (n,): shape contacts
    (``collision_contacts``, ``collision_max_depth`` [m], ``collision_normal_force`` [N]) and water
    (``water_submerged_volume`` [m^3], ``water_buoyancy`` [N]); none without such elements."""
    keys = [k for e in system.forces for k in getattr(e, "scalar_names", ())]
    return {k.replace("/", "_"): _series(frames, [k])[:, 0] for k in keys}


def _series(frames, keys: list[str]) -> np.ndarray:
    """Frame scalars ``keys`` as columns, shape (n, len(keys)) (nan where the frames lack one)."""
    n = len(frames)
    return np.array([frames.scalars.get(k, np.full(n, np.nan)) for k in keys], float).reshape(len(keys), n).T


def _contact_fields(sim, scene, frames, names: list[str]) -> dict:
    from viz3d.contact.report import contact_report, per_contact_restitution  # (runs with contacts only)

    system, cs = sim.system, sim.contacts
    final = sim.state
    rigid_now = {}
    for k, c in enumerate(system.contacts):
        v = cs.rigid_velocity(final, k)
        rigid_now.update({n: float(v[i]) for i, n in enumerate(c.names)})
    resolutions, mobilities = _resolutions(system)
    rep = contact_report(cs.records, cs.impulses, rigid_now, resolutions, mobilities)
    requested = [c.get("restitution", np.nan) for c in scene.data["contacts"] if c["law"] != "rigid"]
    return {
        "approach_velocity": _approach_velocities(sim, frames),
        "events_t": np.array([t for t, _ in cs.log], float),
        "events_text": np.array([x for _, x in cs.log], dtype=str),
        "contacts": rep.rows,
        "contact_touch_names": rep.names,
        "contact_count": np.array(rep.count),
        "contact_restitution": per_contact_restitution(rep.rows),
        "contact_breaks_unresolved": rep.breaks,
        "contact_touches_unresolved": rep.touches,
        "contact_events": rep.events,
        "restitution": np.array(rep.restitution[0] if len(rep.restitution) else np.nan),
        "restitution_uncertainty": np.array(rep.uncertainty[0] if len(rep.uncertainty) else np.nan),
        "impact_restitution": rep.restitution,
        "impact_speeds": rep.speeds,
        "velocity_uncertainty": np.array(rep.velocity_uncertainty),
        "relative_velocity_uncertainty": np.array(rep.relative_velocity_uncertainty),
        "restitution_requested": np.array(requested[0] if requested else np.nan, float),
        "time_resolution": np.array(max(resolutions.values(), default=0.0)),
        "contact_resolution": np.array(rep.resolution),
    }


def _resolutions(system) -> tuple[dict, dict]:
    """Per contact: its time resolution (kinematic contacts on a modal body: the period of its
    highest mode) and the rigid mobilities ``(1 / m_1, 1 / m_1 + 1 / m_2)`` of its bodies (for the
    uncertainty of unresolved impulses, 0 when there are none)."""
    from viz3d.scene.bars import modal_time_resolution

    resolution, mobility = {}, {}
    flexible = {fb.index: fb for fb in system.bodies.flexible}
    nb = system.n_bodies
    for c in system.contacts:
        for i, name in enumerate(c.names):
            pair = [b for b in c.body[i] if b < nb]
            tau = max((modal_time_resolution(flexible[b]) for b in pair if b in flexible), default=0.0)
            rigid_on_flexible = c.models[i] == "rigid" and tau > 0.0
            resolution[name] = tau if c.models[i] == "rigid" else 0.0
            inv = [1.0 / system.bodies.mass[b] if (b not in flexible or flexible[b].floating) else 0.0 for b in c.body[i]
                   if b < nb]
            mobility[name] = (inv[0], sum(inv)) if rigid_on_flexible and inv else (0.0, 0.0)
    return resolution, mobility


def _approach_velocities(sim, frames) -> np.ndarray:
    """Relative normal velocity of each contact's bodies' centres of mass per frame (n, k) [m/s]:
    ``n . (v_B - v_A)`` with ``n`` the contact normal (positive approaching)."""
    system = sim.system
    n_frames, ground = len(frames), system.n_bodies
    cols = []
    for c in system.contacts:
        for i in range(c.k):
            a, b = c.body[i]
            if b == ground:
                n, v_b = np.broadcast_to(c.normal[i], (n_frames, 3)), np.zeros((n_frames, 3))
            else:
                n, v_b = frames.R_WB[:, b] @ c.normal[i], frames.W_v[:, b]
            cols.append(np.einsum("ni,ni->n", n, v_b - frames.W_v[:, a]))
    return np.array(cols, float).T.reshape(n_frames, -1)
