"""The impact shorthand: ``[impactor]``, ``[bar]`` or ``[wall]``, ``[contact]`` expand to an ordinary
scene (``[[bodies]]``, ``[[joints]]``, ``[[forces]]``, ``[[contacts]]``, ``[[gauges]]``).

A file with an ``[impactor]`` table is validated against ``IMPACT_FILE`` (so errors name the keys the
file has, and ``--set impactor.mass=0.5`` or ``--set bar.modes=40`` vary them), then ``expand``
writes the bodies, the contact and the run settings of the one engine:

* the bar is the flexible body ``bar``: ``reference = "fixed"`` a fixed frame, ``"free"`` a floating
  one, ``"pinned"`` a floating one on a ball joint ``pivot`` at ``x = 0``;
* the impactor is the rigid body ``impactor`` (a pendulum becomes its equivalent mass ``I/a^2`` moving
  at ``omega a``: the real pendulum is an ordinary scene, ``scenes/pendulum_strikes_bar.toml``),
  touching (or ``gap`` away from) the struck surface: the end face for an axial impact, the
  ``side`` face of the section at ``contact_x`` for a transverse one;
* ``[wall]`` is the ground's plane through the origin with normal ``+z``;
* integration is adaptive Dormand-Prince 5(4) with event location, no gravity, frames every
  ``sim.output_dt``.

World directions: the contact normal ``n`` is the struck surface's outward normal, ``side`` times
the bar's deformation direction (its axis for a rod, its bending direction for a beam); the
impactor arrives moving along ``-n``.
"""

from __future__ import annotations

import math

import numpy as np

from viz3d.contact.laws import NORMAL_LAWS
from viz3d.rotations import euler_from_matrix, frame_with_z
from viz3d.scene.bars import bar_frame
from viz3d.scene.budget import LIMITS, check_bar_size
from viz3d.scene.contacts import DEFAULT_MATERIAL, RIGID, contact_law, contact_time_estimate
from viz3d.scene.schema import (
    OPTIONAL,
    ArrayOf,
    Field,
    SceneError,
    Table,
    boolean,
    color,
    name,
    nonnegative,
    nonzero_vec3,
    number,
    numbers,
    one_of,
    positive,
    positive_int,
    string,
    vec3,
)
from viz3d.scene.spec import CONTACT_MODELS, MATERIAL, SCENE, SECTION, THEORIES, supports

#: Motions of the bar's frame: fixed (a structure), free (floating), pinned (a pendulum about x = 0).
REFERENCES = ("fixed", "free", "pinned")
#: Name of the bodies, contact and pivot the shorthand writes.
BAR, IMPACTOR, CONTACT_NAME, PIVOT = "bar", "impactor", "impact", "pivot"
#: Display radius of a flat impactor without one [m].
FLAT_DISPLAY_RADIUS = 0.02


IMPACT_SIM = Table({
    "t_end": Field(positive, doc="simulated duration [s]"),
    "output_dt": Field(positive, doc="interval between stored samples [s]"),
    "rtol": Field(positive, 1e-7, "relative tolerance of the adaptive Dormand-Prince 5(4) steps"),
    "atol": Field(positive, 1e-12, "absolute tolerance (state units: m, m/s, modal)"),
    "max_step": Field(positive, OPTIONAL, "largest step [s]"),
    "compiled": Field(boolean, True, "through the compiled kernel when it covers the scene"),
}, "adaptive integration with event location")

BAR_TABLE = Table({
    "length": Field(positive, doc="L [m]"),
    "material": Field(MATERIAL, doc="E, rho, nu"),
    "section": Field(SECTION, doc="cross-section"),
    "theory": Field(one_of(*THEORIES), doc="rod (axial impact), euler_bernoulli or timoshenko (transverse impact)"),
    "supports": Field(supports, doc="end conditions of the mode set / mesh at x = 0 and x = L"),
    "reference": Field(one_of(*REFERENCES), "fixed",
                       "motion of the bar's frame: fixed (structure), free (floating), pinned (a ball joint at x = 0)"),
    "model": Field(one_of("modal", "fe"), "modal", "analytic modes or finite elements"),
    "modes": Field(positive_int, OPTIONAL, "number of modes (modal; with fe: keep this many FE modes)"),
    "elements": Field(positive_int, OPTIONAL, "number of finite elements (model = fe)"),
    "tolerance": Field(positive, OPTIONAL, "truncation error target: choose the mode count from the physics"),
    "contact_x": Field(nonnegative, OPTIONAL, "struck section [m] (default L)"),
    "frame_velocity": Field(numbers, OPTIONAL, "initial velocities of the frame coordinates: free rod [u]; free "
                            "beam [w at x = 0, rotation]; pinned [rotation] [m/s, rad/s]"),
    "damping": Field(nonnegative, 0.0, "modal damping ratio of every mode"),
    "position": Field(vec3, [0.0, 0.0, 0.0], "world position of the end x = 0 [m]"),
    "axis": Field(nonzero_vec3, [1.0, 0.0, 0.0], "world direction of the bar axis"),
    "bending_direction": Field(nonzero_vec3, [0.0, 0.0, 1.0], "world direction of positive deflection w"),
    "color": Field(color, [180, 140, 90], "display colour"),
}, "the flexible bar")

WALL = Table({
    "material": Field(MATERIAL, OPTIONAL, "for Hertz-type laws (default rigid)"),
    "color": Field(color, [150, 150, 150], "display colour"),
}, "a rigid, fixed flat surface (instead of a bar): the plane z = 0")

PENDULUM = Table({
    "inertia": Field(positive, doc="moment of inertia about the pivot [kg m^2]"),
    "arm": Field(positive, doc="pivot to contact point [m]"),
    "omega": Field(number, doc="angular velocity at impact, towards the target [rad/s]"),
}, "a rigid pendulum: equivalent mass I/arm^2 and speed omega arm at the contact")

IMPACTOR_TABLE = Table({
    "mass": Field(positive, OPTIONAL, "[kg] (or give pendulum)"),
    "velocity": Field(number, OPTIONAL, "approach speed towards the target [m/s] (or give pendulum)"),
    "pendulum": Field(PENDULUM, OPTIONAL, "a rigid pendulum instead of mass and velocity"),
    "shape": Field(one_of("sphere", "flat"), "sphere", "contact surface"),
    "radius": Field(positive, OPTIONAL, "sphere radius [m] (Hertz laws, display)"),
    "material": Field(MATERIAL, OPTIONAL, "for Hertz-type laws (default steel 210 GPa, 0.3)"),
    "gap": Field(nonnegative, 0.0, "initial distance to the target [m]"),
    "force": Field(number, 0.0, "constant force towards the target, e.g. its weight [N]"),
    "color": Field(color, [60, 90, 200], "display colour"),
}, "the rigid impactor, moving along the contact normal")

CONTACT_TABLE = Table({
    "law": Field(one_of(*CONTACT_MODELS, *NORMAL_LAWS), doc=f"one of {[*CONTACT_MODELS, *NORMAL_LAWS]}"),
    "restitution": Field(positive, OPTIONAL, "restitution model: e; rate laws: the target e they are calibrated to"),
    "stiffness": Field(positive, OPTIONAL, "K [N/m^n] (default: Hertz from the materials and radius)"),
    "exponent": Field(positive, OPTIONAL, "n (default 1 linear, 1.5 otherwise)"),
    "damping": Field(nonnegative, 0.0, "linear law dashpot [N s/m]"),
    "yield_stress": Field(positive, OPTIONAL, "sigma_Y of the softer body [Pa] (elastoplastic laws)"),
    "side": Field(one_of("+", "-"), OPTIONAL, "impactor arrives from the +u/+w side or the - side (default +)"),
    "hypothesis": Field(one_of("newton", "poisson"), "newton", "restitution law: velocity ratio or impulse ratio"),
}, "the contact model")

GAUGE = Table({
    "name": Field(name, doc="gauge name"),
    "x": Field(nonnegative, doc="section [m]"),
}, "a strain gauge (axial strain, or surface bending strain on the +w fibre)")

DISPLAY = Table({
    "amplification": Field(positive, 100.0, "deformation drawn this many times larger"),
    "frame_dt": Field(positive, OPTIONAL, "simulated time between drawn frames [s] (default output_dt)"),
    "speed": Field(positive, 1e-4, "live viewer: simulated seconds per wall-clock second"),
}, "how the run is drawn")

IMPACT_CHECKS = Table({
    "t_end": Field(positive, OPTIONAL, "duration of the headless test run [s]"),
    "status": Field(string, "ok", "expected final status"),
    "max_energy_balance_error": Field(positive, OPTIONAL, "bound on |balance error| / largest energy"),
    "restitution": Field(number, OPTIONAL, "expected achieved restitution"),
    "restitution_tol": Field(positive, 0.01, "absolute tolerance on it"),
    "min_contacts": Field(positive_int, OPTIONAL, "at least this many contacts"),
    "no_warnings": Field(boolean, False, "fail if the run emits warnings"),
}, "what the headless test of this scene asserts")

IMPACT_FILE = Table({
    "scene": Field(SCENE, dict, "about the scene"),
    "sim": Field(IMPACT_SIM, doc="integration settings"),
    "impactor": Field(IMPACTOR_TABLE, doc="the impactor"),
    "bar": Field(BAR_TABLE, OPTIONAL, "the struck bar (omit for a rigid wall)"),
    "wall": Field(WALL, OPTIONAL, "a rigid wall (when there is no bar)"),
    "contact": Field(CONTACT_TABLE, doc="contact model"),
    "gauges": Field(ArrayOf(GAUGE), list, "strain gauges on the bar"),
    "display": Field(DISPLAY, dict, "drawing"),
    "checks": Field(IMPACT_CHECKS, dict, "headless test checks"),
    "limits": Field(LIMITS, dict, "size limits checked before building"),
})


# ---------------------------------------------------------------- expansion


def expand(d: dict, src: str) -> dict:
    """The ordinary scene tables (raw, to be validated by ``spec.SCENE_FILE``) of a validated
    shorthand ``d``; errors name the shorthand's keys."""
    bar, imp = d.get("bar"), d["impactor"]
    if bar is not None and "wall" in d:
        raise SceneError(src, "wall", "a bar or a wall, not both")
    if bar is not None:
        check_bar_size(bar, d["limits"], src, "bar")
    mass, speed = impactor_motion(imp, src)
    side = 1.0 if d["contact"].get("side", "+") == "+" else -1.0
    P, n = struck_point(bar, side, src)
    contact = contact_entry(d, P, n, side, src)
    model, law, _ = contact_law(contact, (contact["material1"], contact.get("material2", RIGID)), src, "contact",
                                mass if bar is None else None)
    bodies = [impactor_body(imp, mass, speed, P, n)]
    if bar is not None:
        t_c = contact_time_estimate(model, law, mass, speed)
        bodies.insert(0, bar_body(bar, t_c, src))
    return {
        "scene": d["scene"],
        "sim": sim_table(d["sim"]),
        "bodies": bodies,
        "joints": [pivot(bar)] if bar is not None and bar["reference"] == "pinned" else [],
        "forces": [{"type": "force", "name": "push", "body": IMPACTOR, "value": list(-imp["force"] * n)}]
        if imp["force"] else [],
        "contacts": [contact],
        "gauges": gauges(d["gauges"], bar, src),
        "display": {"amplification": d["display"]["amplification"], "speed": d["display"]["speed"],
                    **({"frame_dt": d["display"]["frame_dt"]} if "frame_dt" in d["display"] else {})},
        "checks": d["checks"],
        "limits": d["limits"],
    }


def impactor_motion(imp: dict, src: str) -> tuple[float, float]:
    """Mass [kg] and approach speed [m/s] of the impactor (a pendulum maps to I/a^2, omega a)."""
    if "pendulum" in imp:
        if "mass" in imp or "velocity" in imp:
            raise SceneError(src, "impactor.pendulum", "either pendulum, or mass and velocity, not both")
        p = imp["pendulum"]
        try:
            mass = p["inertia"] / p["arm"] ** 2
        except (ZeroDivisionError, OverflowError):  # (an arm whose square under- or overflows)
            mass = math.nan
        speed = p["omega"] * p["arm"]
        if not (0.0 < mass < math.inf and math.isfinite(speed)):
            raise SceneError(src, "impactor.pendulum.arm", "an arm giving a finite, positive equivalent mass "
                             "I / arm^2 and a finite speed omega arm", p["arm"])
        return mass, speed
    for key in ("mass", "velocity"):
        if key not in imp:
            raise SceneError(src, f"impactor.{key}", "a value (or give impactor.pendulum)")
    return imp["mass"], imp["velocity"]


def struck_point(bar: dict | None, side: float, src: str) -> tuple[np.ndarray, np.ndarray]:
    """World point of the struck surface (3,) [m] and its outward normal ``n`` (3,)."""
    if bar is None:
        return np.zeros(3), np.array([0.0, 0.0, 1.0])
    x_c = bar.get("contact_x", bar["length"])
    if x_c > bar["length"]:
        raise SceneError(src, "bar.contact_x", f"a section in [0, {bar['length']}] m", x_c)
    axis, R0 = bar_frame(bar)
    P = np.asarray(bar["position"], float) + x_c * axis
    if bar["theory"] == "rod":
        return P, side * axis
    return P + side * 0.5 * section_depth(bar["section"]) * R0[:, 1], side * R0[:, 1]


def section_depth(sec: dict) -> float:
    """Extent of the section along the bending direction [m]."""
    return sec["diameter"] if sec["type"] == "circle" else sec["depth"]


def contact_entry(d: dict, P: np.ndarray, n: np.ndarray, side: float, src: str) -> dict:
    c, imp, bar = d["contact"], d["impactor"], d.get("bar")
    sphere = imp["shape"] == "sphere"
    radius = imp.get("radius", 0.0) if sphere else 0.0
    gap = imp["gap"]
    entry = {"name": CONTACT_NAME, "body1": IMPACTOR, "law": c["law"], "normal": list(n), "radius": radius,
             "damping": c["damping"], "hypothesis": c["hypothesis"],
             "material1": imp.get("material", DEFAULT_MATERIAL),
             **{k: c[k] for k in ("restitution", "stiffness", "exponent", "yield_stress") if k in c}}
    if not sphere:
        entry["point1"] = list(P + gap * n)  # the flat face
    if bar is None:
        entry |= {"body2": "ground", "point2": list(P)}
        if "material" in d.get("wall", {}):
            entry["material2"] = d["wall"]["material"]
    else:
        # the struck face: the end section of a rod; the side face of a beam, half its depth off the axis
        offset = 0.0 if bar["theory"] == "rod" else side * 0.5 * section_depth(bar["section"])
        entry |= {"body2": BAR, "x2": bar.get("contact_x", bar["length"]), "local2": [0.0, offset, 0.0],
                  "material2": bar["material"]}
    if c["law"] in NORMAL_LAWS and not sphere and "stiffness" not in c:
        raise SceneError(src, "contact.stiffness", f"a stiffness, or a spherical impactor with a radius, for {c['law']}")
    return entry


def impactor_body(imp: dict, mass: float, speed: float, P: np.ndarray, n: np.ndarray) -> dict:
    """The rigid impactor touching (or ``gap`` away from) the surface at ``P``, moving along ``-n``."""
    sphere = imp["shape"] == "sphere"
    r = imp.get("radius", FLAT_DISPLAY_RADIUS)
    body = {"name": IMPACTOR, "mass": mass, "position": list(P + (r + imp["gap"]) * n),
            "velocity": list(-speed * n), "color": imp["color"]}
    if sphere:
        return body | {"shape": {"type": "sphere", "radius": r}}
    # a flat-faced cylinder, its axis (body z) along the normal
    return body | {"shape": {"type": "cylinder", "radius": r, "height": 2.0 * r},
                   "euler": list(euler_from_matrix(frame_with_z(n)))}


def bar_body(bar: dict, t_c: float | None, src: str) -> dict:
    out = {"name": BAR, "type": "flexible", "frame": "fixed" if bar["reference"] == "fixed" else "floating",
           **{k: bar[k] for k in ("length", "material", "section", "theory", "supports", "model", "damping",
                                   "position", "axis", "bending_direction", "color") if k in bar},
           **{k: bar[k] for k in ("modes", "elements", "tolerance") if k in bar}}
    if "tolerance" in bar:
        out["resolve_x"] = bar.get("contact_x", bar["length"])
        if t_c:
            out["resolve_time"] = t_c
    if bar["reference"] == "pinned" and bar["theory"] == "rod":
        raise SceneError(src, "bar.reference", "a frame that suits this bar (a pinned frame needs a bending theory)")
    if "frame_velocity" in bar:
        out |= frame_motion(bar, src)
    return out


def frame_motion(bar: dict, src: str) -> dict:
    """Initial ``velocity`` (of the undeformed centre) and ``omega`` of a bar's frame from
    ``frame_velocity``: free rod [u]; free beam [w at x = 0, rotation]; pinned [rotation]."""
    v, ref, L = bar["frame_velocity"], bar["reference"], bar["length"]
    axis, R0 = bar_frame(bar)
    rod = bar["theory"] == "rod"
    need = {"fixed": 0, "free": 1 if rod else 2, "pinned": 1}[ref]
    if len(v) != need:
        raise SceneError(src, "bar.frame_velocity", f"{need} values for reference = {ref}", v)
    if ref == "fixed":
        return {}
    if rod:
        return {"velocity": list(v[0] * axis)}
    w0, theta = (v[0], v[1]) if ref == "free" else (0.0, v[0])
    return {"velocity": list((w0 + 0.5 * L * theta) * R0[:, 1]), "omega": list(theta * R0[:, 2])}


def pivot(bar: dict) -> dict:
    return {"name": PIVOT, "type": "ball", "body1": BAR, "body2": "ground", "x1": 0.0,
            "point": list(map(float, bar["position"]))}


def gauges(entries: list[dict], bar: dict | None, src: str) -> list[dict]:
    for i, g in enumerate(entries):
        if bar is None or g["x"] > bar["length"]:
            raise SceneError(src, f"gauges[{i}].x", "a section of the bar")
    return [{"name": g["name"], "body": BAR, "x": g["x"]} for g in entries]


def sim_table(sim: dict) -> dict:
    return {"t_end": sim["t_end"], "dt": sim["output_dt"], "output_dt": sim["output_dt"], "integrator": "dopri5",
            "rtol": sim["rtol"], "atol": sim["atol"], "gravity": [0.0, 0.0, 0.0], "compiled": sim["compiled"],
            **({"max_step": sim["max_step"]} if "max_step" in sim else {})}
