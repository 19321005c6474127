"""The anchor-hoist generator (seed 004, issue 11): a ``[ship]`` table expands into an ordinary scene
-- the bow's shell, anchor pocket and hawse pipe as ground triangle meshes, the anchor (shank and
flukes on a revolute joint with the +-30 deg stop of eq. 3.50, a shackle), the stud-link chain, the
windlass that hauls it, the contacts, the water, and the stowed pose the run's verdict is judged by.

Frames (docs/notation.md, "Anchor hoist"): the ship frame has x forward, y to port, z up, its origin
at the hawse ``O`` (where the pipe's axis pierces the pocket floor) of the starboard anchor; the
world is the ship frame turned by ``heel`` (starboard down, about x) then ``trim`` (bow down, about
y), so gravity stays ``-z`` and the water surface stays level, ``hawse_height`` below ``O``. The shell
frame of ``viz3d.anchoring`` has ``f = x``, ``u`` up along the shell (``flare`` from vertical,
leaning outboard) and ``n`` its outward normal.

Sources of the numbers:
* ship 176.1 x 29.8 x 9.9 m, equipment number 3063 (seed 004, eq. 2.2);
* anchor 9300 kg and stud-link chain 84 mm grade 2 for EN 3040-3210 (IACS UR A1, Table 1);
* stud link proportions: pitch (inside length) 4 d, width 3.6 d; mass 0.0219 d^2 kg/m (d in mm),
  the usual stud-link chain tables;
* hauling speed 9 m/min, the least mean speed IACS UR A3 asks of a windlass hoisting its anchor;
  capacity 1.5 x the continuous duty pull 42.5 d^2 N of grade 2 (IACS UR A3's overload pull), where
  the windlass stalls (a limited drive, below; its speed droop under load is ours);
* contact: Flores' law, K = 4/3 E* sqrt(R) of a steel sphere of the link's bar radius d/2 on a steel
  plane (eqs. 3.37-3.39), and bristle stick-slip friction (eqs. 3.40-3.49; the coefficients and the
  bristles' stiffness are ours, documented in ``SHIP``);
* the hull geometry (flare, pipe angle and size, pocket) and the anchor's proportions are generic
  design values of ours, documented in ``SHIP`` (the seed's CAD models are not published).

The windlass is a limited drive (``viz3d.forces.DriveServo``; ``ship.droop``, ``capacity``): a
velocity servo that tracks its ramp to ``hauling_speed`` and stalls at its ``capacity``, where a
rigid drive would pull a wedged anchor into the hull at the hauling speed (the run then diverges).
Its gain ``g`` trades the speed it loses under load (``droop``: ``F / g`` at the load ``F``) against
the stability of its pole ``-g / m`` under RK4 (``g dt / m <= 2.785``), ``m`` the effective mass it
drives along its guide (the windlass head, chain, shackle and anchor through the joints:
``1 / (e^T P e)``, ``P`` the inverse mass matrix projected onto the other joints' constraints).
Along the default haul, computed at every 0.25 s frame, m runs from 2180 kg (t = 27.25 s, the anchor
turning at the hull) to 9530 kg, 2760 kg at t = 0. ``droop = 0.10`` gives g = 6.9e6 N s/m and
g dt / m <= 1.6 at dt = 5e-4 s (a margin of 1.8 for a lower mass between frames or on a heeled or
trimmed ship); 0.05 would give 3.2, unstable. At its capacity the servo's speed is at least
capacity / g = 0.065 m/s (43 %) below the ramp's: a windlass at its capacity has stalled.
"""

from __future__ import annotations

import math

import numpy as np

from viz3d import anchoring
from viz3d.rotations import euler_from_matrix, frame_with_z, matrix_from_rotation_vector
from viz3d.scene.budget import LIMITS, check_generated_bodies
from viz3d.scene.chainpath import path_nodes
from viz3d.scene.schema import (OPTIONAL, Field, SceneError, Table, boolean, count, nonnegative, number, positive,
                                validate)

STEEL_E, STEEL_NU, STEEL_RHO = 2.1e11, 0.3, 7850.0
G_STANDARD = 9.80665
#: The chain starts this fraction of a link's radius clear of the pocket's rim (no overlap at t = 0).
RIM_CLEARANCE = 1e-3

SHIP = Table({
    "length": Field(positive, 176.1, "ship length [m] (seed 004)"),
    "breadth": Field(positive, 29.8, "breadth [m]"),
    "draught": Field(positive, 9.9, "draught [m]"),
    "heel": Field(number, 0.0, "heel [deg], starboard (the anchor's side) down"),
    "trim": Field(number, 0.0, "trim [deg], bow down"),
    "hawse_height": Field(positive, 4.0, "height of the hawse O above the waterline [m]"),
    "flare": Field(number, 15.0, "shell angle from vertical at the hawse [deg], leaning outboard"),
    "pipe_angle": Field(positive, 25.0, "hawse pipe axis to the shell [deg] (the flukes stow turned this much from "
                        "the shank: at most stop_angle)"),
    "pipe_diameter": Field(positive, 0.70, "hawse pipe inner diameter [m]"),
    "pipe_length": Field(positive, 4.0, "pipe length along its axis from O [m]"),
    "pocket_width": Field(positive, 2.8, "anchor pocket width along the shell [m] (flukes: 2.2 m at 9300 kg)"),
    "pocket_top": Field(positive, 1.6, "pocket extent above O along the shell [m]"),
    "pocket_bottom": Field(positive, 1.4, "pocket extent below O along the shell [m]"),
    "pocket_depth": Field(positive, 0.35, "pocket recess into the shell [m]"),
    "anchor_mass": Field(positive, 9300.0, "[kg] (IACS UR A1 for EN 3040-3210); shank + flukes, density from the meshes"),
    "chain_diameter": Field(positive, 0.084, "stud-link bar diameter d [m] (IACS UR A1 for EN 3040-3210, grade 2)"),
    "link_tolerance": Field(positive, 0.05, "largest sagitta of a simulated link where the chain wraps the pipe's "
                            "lip (radius pipe_diameter / 2) [m]: a simulated link is k real links, k the largest "
                            "with (k 4d)^2 / (8 r) <= this"),
    "hang": Field(positive, 0.5, "chain hanging below the pocket's lower rim at the start [m]"),
    "payout": Field(number, 0.0, "the windlass starts this much paid out [m] (the chain moves this much along its "
                    "path, the anchor as much lower): a perturbation of the starting pose (stowage ensembles), at "
                    "most the chain's clearance on the rim (1e-3 of a link's radius) in magnitude"),
    "hauling_speed": Field(positive, 0.15, "windlass nominal speed [m/s] (9 m/min, IACS UR A3)"),
    "ramp_time": Field(positive, 2.0, "time to reach the hauling speed [s]"),
    "overhaul": Field(nonnegative, 0.5, "the windlass may haul this much beyond the haul of the level ship to the "
                      "stowed pose (heel and trim change the path) before it stops and the run ends [m] "
                      "(stowage.haul_limit)"),
    "settle_time": Field(positive, 0.5, "the windlass stops once the anchor has stayed seated this long [s]"),
    "capacity": Field(positive, OPTIONAL, "windlass capacity [N] (default 1.5 x 42.5 d^2 N, d in mm): it stalls there"),
    "droop": Field(positive, 0.10, "the windlass's speed falls this fraction of hauling_speed under the hanging "
                   "weight (anchor, shackle and chain): its servo gain is that weight / (droop hauling_speed); RK4's "
                   "stability of the servo pole bounds it (viz3d/scene/ship.py)"),
    "mu": Field(nonnegative, 0.25, "steel on steel: sliding friction coefficient (bristle law, eqs. 3.40-3.49)"),
    "mu_static": Field(nonnegative, 0.30, "steel on steel: static friction coefficient"),
    "stick_stiffness": Field(positive, 1e7, "bristles' k_stick [N/m]: 0.5 mm of stick under the rim's 15 kN"),
    "stick_damping": Field(nonnegative, 2e4, "bristles' c_stick [N s/m] (near critical for a link)"),
    "restitution": Field(positive, 0.5, "Flores' coefficient of restitution at the reference speed"),
    "reference_speed": Field(positive, 0.5, "approach speed at which the contact's damping gives `restitution` [m/s]"),
    "water": Field(boolean, False, "buoyancy and drag below the waterline"),
    "stop_stiffness": Field(positive, 1e7, "flukes' stop k_m [N m/rad] (eq. 3.50)"),
    "stop_damping": Field(nonnegative, 1e5, "flukes' stop c_m [N m s/rad]"),
    "stop_angle": Field(positive, 30.0, "flukes' stop +-phi_max [deg] (eq. 3.50)"),
    "position_tolerance": Field(positive, 0.10, "seated: crown within this of its stowed position [m]"),
    "angle_tolerance": Field(positive, 5.0, "seated: shank and flukes within this of their stowed directions [deg]"),
    "stall_time": Field(positive, 2.0, "jammed: the anchor moves less than stall_distance in this time while the "
                        "windlass hauls [s]"),
    "stall_distance": Field(positive, 0.02, "[m]"),
    "overload_time": Field(nonnegative, 0.25, "jammed: the windlass was at its capacity (stalled) for this long [s] "
                           "(an impact of the anchor on the hull lasts about 10 ms, Hertz; a jam holds it)"),
    "sections": Field(count(1024), 32, "points round the pipe's section in the meshes"),
}, "generator: a ship's anchor hoisted by its windlass into the hawse pipe and pocket (seed 004)")


def ship_rotation(heel_deg: float, trim_deg: float) -> np.ndarray:
    """World from ship axes: ``Ry(trim) Rx(heel)`` (starboard down, then bow down)."""
    heel, trim = math.radians(heel_deg), math.radians(trim_deg)
    return matrix_from_rotation_vector(np.array([0.0, trim, 0.0])) @ matrix_from_rotation_vector(np.array([heel, 0.0, 0.0]))


def shell_axes(flare_deg: float) -> np.ndarray:
    """Columns ``f, u, n`` of the shell frame in ship axes."""
    b = math.radians(flare_deg)
    return np.column_stack([[1.0, 0.0, 0.0], [0.0, -math.sin(b), math.cos(b)], [0.0, -math.cos(b), -math.sin(b)]])


def chain_links(d: float, lip_radius: float, tolerance: float) -> tuple[int, float, float]:
    """``(k, pitch, mass)``: real links per simulated link (the largest with sagitta ``(k p)^2 / 8r``
    at most ``tolerance``, at least 1), the real pitch ``4 d`` [m] and a real link's mass [kg]."""
    pitch = 4.0 * d
    k = max(1, int(math.floor(math.sqrt(8.0 * lip_radius * tolerance) / pitch)))
    return k, pitch, 0.0219 * (d * 1e3) ** 2 * pitch


def flores_stiffness(bar_radius: float) -> float:
    """Hertz K = 4/3 E* sqrt(R) of a steel sphere of radius R on a steel plane [N/m^1.5]."""
    E_star = 1.0 / (2.0 * (1.0 - STEEL_NU**2) / STEEL_E)
    return 4.0 / 3.0 * E_star * math.sqrt(bar_radius)


def _mesh_volume(name: str, mass: float) -> tuple[float, np.ndarray]:
    import trimesh

    V, F = anchoring.MESHES[name](mass=mass)
    m = trimesh.Trimesh(V, F, process=False)
    return float(m.volume), np.asarray(m.center_mass, float)


def expand(raw: dict, ship: dict, source: str) -> dict:
    """``raw`` with the bodies, joints, drive, stop, chain, collision, water, stowage and run settings
    of the validated ``ship`` table added (entries the file gives itself are kept)."""
    p = ship
    _check(p, source)
    R_world = ship_rotation(p["heel"], p["trim"])
    S = R_world @ shell_axes(p["flare"])            # world <- shell
    f, u, n = S.T
    gamma = math.radians(p["pipe_angle"])
    a = math.cos(gamma) * u - math.sin(gamma) * n    # pipe axis, world
    e2 = math.sin(gamma) * u + math.cos(gamma) * n   # normal to a in the (u, n) plane
    r_pipe, L_pipe = p["pipe_diameter"] / 2, p["pipe_length"]
    s = (p["anchor_mass"] / 9300.0) ** (1 / 3)
    k, pitch, link_mass = chain_links(p["chain_diameter"], r_pipe, p["link_tolerance"])
    ell = k * pitch
    T = L_pipe * a                                   # windlass end of the pipe (O is the origin)
    # the chain runs straight from the windlass down the pipe to the pocket's lower rim C (the
    # bolster) and hangs from there, both stretches tangent to the rim: at rest but for its sag in
    # the pipe and the rim's Hertz indentation
    down = np.array([0.0, 0.0, -1.0])
    r_link = 1.8 * p["chain_diameter"]
    C = S @ np.array([0.0, -p["pocket_bottom"], p["pocket_depth"]])
    try:
        T, V, m = bend_over(C, T, a, down, r_link * (1 + RIM_CLEARANCE), ell, f)
    except ValueError as exc:
        raise SceneError(source, "ship", f"a hull whose chain path from the windlass over the pocket's rim is finite "
                         f"({exc})") from None
    T = T - _payout(p, r_link, source) * a
    n_links = m + max(1, math.ceil(p["hang"] / ell))
    check_generated_bodies(n_links + 4, validate(raw.get("limits", {}), LIMITS, source, "limits"), source, "ship",
                           f"{n_links} chain links of {ell:.3g} m from the pipe, pocket and hang sizes, and 4 more")
    chain_len = n_links * ell
    path = [V, V + 4 * (chain_len + ell) * down]
    nodes_end = path_nodes(np.vstack([T, *path]), n_links, ell, source)[0][-1]
    shackle_len, eye = anchoring.SHACKLE[2] * s, anchoring.SHANK_EYE * s
    pin_shackle = nodes_end + shackle_len * down
    crown = pin_shackle + eye * down
    x_out = np.array([n[0], n[1], 0.0]) / max(math.hypot(n[0], n[1]), 1e-12)
    x_a, z_a = x_out, -down                          # flukes' plate normal outboard and level, shank up
    y_a = np.cross(z_a, x_a)
    R_anchor = np.column_stack([x_a, y_a, z_a])
    phi0 = math.radians(p["stop_angle"])             # flukes resting on their outer stop
    R_flukes = R_anchor @ matrix_from_rotation_vector(np.array([0.0, phi0, 0.0]))
    V_shank, c_shank = _mesh_volume("anchor_shank", p["anchor_mass"])
    V_flukes, c_flukes = _mesh_volume("anchor_flukes", p["anchor_mass"])
    V_shackle, c_shackle = _mesh_volume("anchor_shackle", p["anchor_mass"])
    rho_anchor = p["anchor_mass"] / (V_shank + V_flukes)
    hanging = p["anchor_mass"] + STEEL_RHO * V_shackle + n_links * link_mass * k   # the windlass's load [kg]
    # stowed: shank along a with the crown on the pipe's axis line, flukes flat on the floor
    h = 0.5 * anchoring.FLUKE_THICKNESS[0] * s
    crown_stowed = -h / math.tan(gamma) * u + h * n
    R_shank_stowed = np.column_stack([e2, np.cross(a, e2), a])
    R_flukes_stowed = R_shank_stowed @ matrix_from_rotation_vector(np.array([0.0, gamma, 0.0]))
    capacity = p.get("capacity", 1.5 * 42.5 * (p["chain_diameter"] * 1e3) ** 2)
    travel = _haul_length(T, crown_stowed + eye * a + shackle_len * a, chain_len)
    v, t_r = p["hauling_speed"], p["ramp_time"]
    # the windlass stops after hauling travel + overhaul (stowage.haul_limit: its speed depends on the
    # load); t_end, a backstop, is that haul at the least speed it keeps below its capacity
    gain = G_STANDARD * hanging / (p["droop"] * v)
    # (a tenth of the ramp's speed at least: a capacity above gain v is reached only when backdriven)
    t_end = t_r / 2 + (travel + p["overhaul"]) / max(v - capacity / gain, 0.1 * v) + p["overload_time"]

    def body(name, mesh, R, origin, centre, color, density):
        return {"name": name, "shape": {"type": "mesh", "generator": mesh, "params": {"mass": p["anchor_mass"]}},
                "density": density, "position": (origin + R @ centre).tolist(),
                "euler": euler_from_matrix(R).tolist(), "color": color}

    out = dict(raw)
    out["bodies"] = list(raw.get("bodies", [])) + [
        {"name": "windlass", "shape": {"type": "box", "extents": [0.3, 0.3, 0.3]}, "mass": link_mass * k,
         "position": T.tolist(), "euler": euler_from_matrix(frame_with_z(a)).tolist(), "color": [90, 90, 100]},
        body("shackle", "anchor_shackle", R_anchor, pin_shackle, c_shackle,
             [120, 120, 130], STEEL_RHO),
        body("shank", "anchor_shank", R_anchor, crown, c_shank, [60, 60, 70], rho_anchor),
        body("flukes", "anchor_flukes", R_flukes, crown, c_flukes, [60, 60, 70], rho_anchor),
    ]
    # links hauled in past the windlass (the pipe's top, T) leave the run (viz3d.departures): the scene
    # models only the chain that still moves
    out["chain"] = {"n": n_links, "link_length": ell, "radius": r_link, "mass": link_mass * k,
                    "anchor": T.tolist(), "path": [q.tolist() for q in path],
                    "joint": "universal", "attach": "windlass", "color": [150, 110, 60], "prefix": "link",
                    "leave": True, **raw.get("chain", {})}
    out["joints"] = list(raw.get("joints", [])) + [
        {"name": "windlass_guide", "type": "prismatic", "body1": "windlass", "body2": "ground", "point": T.tolist(),
         "axis": a.tolist()},
        {"name": "shackle_link", "type": "universal", "body1": "shackle", "body2": f"link{n_links - 1}",
         "point": nodes_end.tolist(), "axis1": y_a.tolist(), "axis2": x_a.tolist()},
        {"name": "shackle_pin", "type": "revolute", "body1": "shank", "body2": "shackle", "point": pin_shackle.tolist(),
         "axis": y_a.tolist()},
        {"name": "crown", "type": "revolute", "body1": "flukes", "body2": "shank", "point": crown.tolist(),
         "axis": y_a.tolist()},
    ]
    out["drives"] = list(raw.get("drives", [])) + [
        {"name": "windlass", "joint": "windlass_guide", "mode": "velocity", "kind": "ramp", "amplitude": v,
         "start": 0.0, "duration": t_r, "capacity": capacity, "capacity_time": p["overload_time"],
         "servo_gain": gain},
    ]
    out["forces"] = list(raw.get("forces", [])) + [
        # the joint's angle is 0 where the flukes start, on their outer stop: phi = phi0 + angle
        {"type": "joint_stop", "name": "flukes_stop", "joint": "crown", "lower": -2 * phi0, "upper": 0.0,
         "stiffness": p["stop_stiffness"], "damping": p["stop_damping"]},
    ]
    K = flores_stiffness(p["chain_diameter"] / 2)
    e = p["restitution"]
    law = {"law": "flores", "stiffness": K, "exponent": 1.5, "damping_factor": 8 * (1 - e) / (5 * e * p["reference_speed"]),
           "friction": "bristle", "mu": p["mu"], "mu_static": p["mu_static"], "stick_stiffness": p["stick_stiffness"],
           "stick_damping": p["stick_damping"]}
    pose = {"position": [0.0, 0.0, 0.0], "euler_deg": np.degrees(euler_from_matrix(S)).tolist()}
    hull = {"pipe_radius": r_pipe, "pipe_angle_deg": p["pipe_angle"], "pocket_width": p["pocket_width"],
            "pocket_top": p["pocket_top"], "pocket_bottom": p["pocket_bottom"]}
    out["collision"] = {
        "groups": {"anchor": ["shank", "flukes", "shackle"], "chain": ["link*"]},
        "pairs": [{"groups": ["anchor", "ground"], **law}, {"groups": ["chain", "ground"], **law}],
        "ground": [
            {"name": "shell", "type": "mesh", "generator": "hull_shell", **pose,
             "params": {k_: hull[k_] for k_ in ("pocket_width", "pocket_top", "pocket_bottom")}
             | {"depth": p["pocket_depth"]}},
            {"name": "pocket", "type": "mesh", "generator": "anchor_pocket", **pose,
             "params": hull | {"depth": p["pocket_depth"], "sections": p["sections"]}},
            {"name": "pipe", "type": "mesh", "generator": "hawse_pipe", **pose,
             "params": hull | {"pipe_length": L_pipe, "sections": p["sections"]}},
        ],
        **raw.get("collision", {}),
    }
    if p["water"]:
        out["water"] = {"level": -p["hawse_height"], "drag_coefficient": 1.0, **raw.get("water", {})}
    out["stowage"] = {
        "bodies": ["shank", "flukes"], "drive": "windlass", "hawse": [0.0, 0.0, 0.0], "chain": "link",
        "position": [(crown_stowed + R_shank_stowed @ c_shank).tolist(),
                     (crown_stowed + R_flukes_stowed @ c_flukes).tolist()],
        "axes": [R_shank_stowed.tolist(), R_flukes_stowed.tolist()],
        "tolerance": p["position_tolerance"], "angle_tolerance": p["angle_tolerance"],
        "stall_time": p["stall_time"], "stall_distance": p["stall_distance"], "settle_time": p["settle_time"],
        "haul_limit": travel + p["overhaul"],
        "report": {"simulated_links": n_links, "real_links_each": k, "pitch": pitch, "real_link_mass": link_mass,
                   "haul": travel, "flukes_joint": "crown", "flukes_angle0": phi0},
    }
    sim = dict(raw.get("sim", {}))
    sim.setdefault("t_end", t_end)
    out["sim"] = sim
    return out


def _payout(p: dict, r_link: float, source: str) -> float:
    """``ship.payout`` [m], refused beyond the chain's clearance on the rim (a link would start in the rim)."""
    clearance = RIM_CLEARANCE * r_link
    if abs(p["payout"]) > clearance:
        raise SceneError(source, "ship.payout", f"at most {clearance:.3g} m in magnitude (the chain's clearance on the "
                         "pocket's rim: a perturbation of the starting pose, not another pose)", p["payout"])
    return p["payout"]


def _check(p: dict, source: str) -> None:
    """Geometry a haul can end in: flukes that can lie flat, a pocket that holds the pipe's opening."""
    if p["droop"] >= 1.0:
        raise SceneError(source, "ship.droop", "below 1 (the fraction of hauling_speed the windlass loses under the "
                         "hanging weight)", p["droop"])
    if p["pipe_angle"] >= 90.0 or p["pipe_angle"] > p["stop_angle"]:
        raise SceneError(source, "ship.pipe_angle", f"below 90 and at most ship.stop_angle = {p['stop_angle']:g} deg (the "
                         "stowed flukes lie on the floor turned pipe_angle from the shank)", p["pipe_angle"])
    r, long = anchoring.opening(p["pipe_diameter"] / 2, p["pipe_angle"])
    for key, need in (("pocket_width", 2 * r), ("pocket_top", long), ("pocket_bottom", long)):
        if p[key] <= need:
            raise SceneError(source, f"ship.{key}", f"more than {need:.3g} m (the pipe's opening, an ellipse of semi-axes "
                             f"{r:.3g} and {long:.3g} m, lies in the pocket)", p[key])


def bend_over(C: np.ndarray, T: np.ndarray, a: np.ndarray, down: np.ndarray, r: float, ell: float,
              edge: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, int]:
    """Where a chain from a point ``T' = T + delta a`` (0 <= delta < ell, on the windlass's line) to
    ``V``, then along ``down``, passes a convex edge through ``C`` (along the unit ``edge``; None: a
    point) at distance ``r`` from both stretches (tangent to it; with a heeled or trimmed ship the
    edge is not normal to the chain's plane) with ``|V - T'|`` a whole number ``m`` of links ``ell``:
    ``(T', V, m)`` [m]. Raises ``ValueError`` when the path is not finite."""
    V, Tp, reach = C.copy(), T, r
    for _ in range(200):
        d1 = (V - Tp) / np.linalg.norm(V - Tp)
        turn = down - d1
        half = 0.5 * math.acos(float(np.clip(d1 @ down, -1.0, 1.0)))
        V_new = C - reach / math.cos(half) * turn / np.linalg.norm(turn)
        links = float(np.linalg.norm(V_new - T)) / ell
        if not math.isfinite(links):
            raise ValueError(f"the windlass is {links * ell} m from the rim")
        m = math.ceil(links)
        # T' on T's line a whole number of links from V
        w = V_new - T
        delta = (w @ a) + math.sqrt(max((w @ a) ** 2 - (w @ w) + (m * ell) ** 2, 0.0))
        Tp_new = T + delta * a
        clearance = r if edge is None else min(_line_distance(V_new, d, C, edge) for d in (d1, down))
        if np.linalg.norm(V_new - V) + np.linalg.norm(Tp_new - Tp) < 1e-12 and abs(clearance - r) < 1e-12:
            break
        if not clearance > 0.0:  # (a rim so far off that the chain's line meets it to round-off: no tangent path)
            raise ValueError(f"the chain passes {clearance} m from the rim")
        V, Tp, reach = V_new, Tp_new, reach * r / clearance
    return Tp, V, m


def _line_distance(p: np.ndarray, d: np.ndarray, q: np.ndarray, e: np.ndarray) -> float:
    """Distance between the lines ``p + s d`` and ``q + s e`` [m]."""
    n = np.cross(d, e)
    return float(abs((p - q) @ n) / np.linalg.norm(n))


def _haul_length(T: np.ndarray, shackle_top_stowed: np.ndarray, chain_len: float) -> float:
    """Windlass travel that brings the shackle's top to its stowed place with the chain straight in the
    pipe: ``chain_len`` + the distance from the pipe's end ``T`` back along the axis to it [m]."""
    return float(chain_len - np.linalg.norm(T - shackle_top_stowed))
