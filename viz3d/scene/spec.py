"""The scene file format: every table and key a scene may hold (SI units throughout).

``docs/scene_format.md`` is generated from this module (``viz3d list --format``).
"""

from __future__ import annotations

from viz3d.coordinates import ROTATIONS
from viz3d.formulation import FORMULATIONS
from viz3d.integrators import INTEGRATORS
from viz3d.scene.budget import LIMITS
from viz3d.scene.schema import (
    OPTIONAL,
    ArrayOf,
    Field,
    Table,
    boolean,
    color,
    mat3_or_diag,
    name,
    nonnegative,
    nonnegative_int,
    nonzero_vec3,
    number,
    one_of,
    positive,
    positive_int,
    string,
    unit_interval,
    vec3,
)
from viz3d.timefunctions import TIME_FUNCTIONS

ZERO3 = [0.0, 0.0, 0.0]

SCENE = Table({
    "name": Field(string, OPTIONAL, "scene name (default: the file name)"),
    "description": Field(string, "", "one line shown by `viz3d list`"),
}, "what the scene is")


SIM = Table({
    "t_end": Field(positive, 5.0, "simulated duration [s]"),
    "dt": Field(positive, 1e-3, "fixed integration step [s] (with sim.rtol: interval between the dense-output samples)"),
    "output_dt": Field(positive, OPTIONAL, "interval between stored frames [s] (default: 0.01 s, at least dt)"),
    "integrator": Field(one_of(*INTEGRATORS), "rk4", f"one of {list(INTEGRATORS)}"),
    "formulation": Field(one_of(*FORMULATIONS), "index1", f"one of {list(FORMULATIONS)}"),
    "rotation": Field(one_of(*ROTATIONS), "euler_switching", f"one of {list(ROTATIONS)}"),
    "gravity": Field(vec3, [0.0, 0.0, -9.81], "gravitational acceleration [m/s^2]"),
    "baumgarte_alpha": Field(nonnegative, 10.0, "Baumgarte damping rate [1/s] (formulation = baumgarte)"),
    "baumgarte_beta": Field(nonnegative, 10.0, "Baumgarte frequency [rad/s] (formulation = baumgarte)"),
    "compiled": Field(boolean, True, "fixed explicit Runge-Kutta steps through the compiled kernel when it covers the scene"),
    "projection_tol": Field(positive, 1e-12, "position tolerance of projections and of ali3p's iteration [m]"),
    "rtol": Field(positive, OPTIONAL, "relative tolerance: adaptive steps with error control (integrators dopri5, "
                  "dop853); sim.dt is then the interval between returned states, sampled by dense output"),
    "atol": Field(positive, 1e-9, "absolute tolerance of adaptive steps [m, rad, m/s, rad/s] (with sim.rtol)"),
    "max_step": Field(positive, OPTIONAL, "largest adaptive step [s] (with sim.rtol; default: unbounded)"),
    "rho_inf": Field(unit_interval, 0.8, "spectral radius at infinity of gen_alpha, in [0, 1] (1: no damping)"),
    "penalty_alpha": Field(positive, 1e7, "penalty factor [kg] (formulation = penalty; seed 004: 1e6 to 1e11)"),
    "penalty_xi": Field(positive, 1.0, "damping ratio of the penalty springs [-] (formulation = penalty)"),
    "penalty_omega": Field(positive, 10.0, "natural frequency of the penalty springs [rad/s] (formulation = penalty)"),
    "ali3p_alpha": Field(positive, 1e9, "augmented-Lagrangian penalty factor [N/m] (formulation = ali3p)"),
    "blowup_violation": Field(positive, 0.1, "stop with a diagnosis when max |C| exceeds this [m]"),
    "blowup_speed": Field(positive, 1e4, "stop with a diagnosis when a body's speed exceeds this [m/s]"),
    "blowup_energy": Field(positive, 0.5, "conservative scenes: stop with a diagnosis when the total energy grows by more "
                           "than this fraction of the largest kinetic energy [-]"),
}, "how to integrate")

SHAPES = {
    "box": Table({"extents": Field(nonzero_vec3, doc="edge lengths along body x, y, z [m]")}, "box centred on the body origin"),
    "cylinder": Table({"radius": Field(positive, doc="[m]"), "height": Field(positive, doc="along body z [m]")},
                      "cylinder along body z"),
    "sphere": Table({"radius": Field(positive, doc="[m]")}, "sphere"),
    "capsule": Table({"radius": Field(positive, doc="[m]"),
                      "height": Field(positive, doc="of the cylindrical part, along body z [m]")}, "capsule along body z"),
    "mesh": Table({
        "file": Field(string, doc="STL, OBJ, GLB or PLY path, relative to the scene file"),
        "scale": Field(positive, 1.0, "multiplies the vertex coordinates (e.g. 0.001 for mm)"),
    }, "triangle mesh; with `density` its centre of mass becomes the body origin"),
}
SHAPE = Table({"type": Field(one_of(*SHAPES), doc=f"one of {list(SHAPES)}")}, "geometry", tag="type", variants=SHAPES)

BODY = Table({
    "name": Field(name, doc="unique body name"),
    "shape": Field(SHAPE, OPTIONAL, "geometry (drawn, and used for mass properties with density)"),
    "mass": Field(positive, OPTIONAL, "[kg]"),
    "inertia": Field(mat3_or_diag, OPTIONAL, "about the centre of mass, body axes [kg m^2]"),
    "density": Field(positive, OPTIONAL, "[kg/m^3]: mass and inertia from the shape"),
    "position": Field(vec3, doc="centre of mass, world [m]"),
    "euler": Field(vec3, OPTIONAL, "ZXZ angles (psi, theta, phi) [rad]"),
    "euler_deg": Field(vec3, OPTIONAL, "ZXZ angles (psi, theta, phi) [deg]"),
    "velocity": Field(vec3, ZERO3, "centre-of-mass velocity, world [m/s]"),
    "omega": Field(vec3, ZERO3, "angular velocity, world axes [rad/s]"),
    "color": Field(color, OPTIONAL, 'display colour, [r, g, b] or "#rrggbb"'),
}, "a rigid body")

JOINT_TYPES = {
    "ball": Table({
        "point": Field(vec3, OPTIONAL, "joint point, world, in the initial configuration [m]"),
        "local1": Field(vec3, OPTIONAL, "joint point in body 1 axes from its centre of mass [m]"),
        "local2": Field(vec3, OPTIONAL, "joint point in body 2 axes (world if ground) [m]"),
    }, "ball joint (rotula): give `point`, or `local1` and `local2`"),
}
JOINT = Table({
    "name": Field(name, OPTIONAL, "default j<index>"),
    "type": Field(one_of(*JOINT_TYPES), "ball", f"one of {list(JOINT_TYPES)}"),
    "body1": Field(string, doc="body name"),
    "body2": Field(string, "ground", "body name or ground"),
}, "a joint", tag="type", variants=JOINT_TYPES)

_LOAD = {
    "name": Field(name, OPTIONAL, "default <type><index>"),
    "body": Field(string, doc="body name"),
    "frame": Field(one_of("world", "body"), "world", "axes of the value: world, or body (follows the body)"),
    "value": Field(vec3, ZERO3, "constant part (offset) [N or N m]"),
    "kind": Field(one_of(*TIME_FUNCTIONS), "constant", f"time function: {list(TIME_FUNCTIONS)}"),
    "amplitude": Field(vec3, ZERO3, "amplitude of the time function"),
    "frequency": Field(nonnegative, 0.0, "[Hz] (sine)"),
    "phase": Field(number, 0.0, "[rad] (sine)"),
    "start": Field(number, 0.0, "[s] (step, ramp, pulse)"),
    "duration": Field(nonnegative, 0.0, "[s] (ramp, pulse)"),
}
FORCE_TYPES = {
    "spring_damper": Table({
        "name": Field(name, OPTIONAL, "default spring<index>"),
        "body1": Field(string, doc="body name"),
        "body2": Field(string, "ground", "body name or ground"),
        "point1": Field(vec3, OPTIONAL, "attachment on body 1, world, initial configuration [m]"),
        "local1": Field(vec3, OPTIONAL, "attachment on body 1, body axes from the centre of mass [m]"),
        "point2": Field(vec3, OPTIONAL, "attachment on body 2, world, initial configuration [m]"),
        "local2": Field(vec3, OPTIONAL, "attachment on body 2, body axes (world if ground) [m]"),
        "stiffness": Field(nonnegative, doc="[N/m]"),
        "damping": Field(nonnegative, 0.0, "[N s/m]"),
        "rest_length": Field(nonnegative, OPTIONAL, "[m] (default: the initial length)"),
    }, "linear spring-damper between two points"),
    "force": Table({**_LOAD, "point": Field(vec3, OPTIONAL, "point of application, world, initial configuration [m]"),
                    "local": Field(vec3, OPTIONAL,
                                   "point of application, body axes from the centre of mass [m] (default: centre of mass)")},
                   "applied force = value + amplitude * f(t)"),
    "torque": Table(dict(_LOAD), "applied couple = value + amplitude * f(t)"),
    "contact": Table({
        "name": Field(name, OPTIONAL, "default contact<index>"),
        "body": Field(string, doc="body carrying the sphere"),
        "point": Field(vec3, OPTIONAL, "sphere centre, world, initial configuration [m]"),
        "local": Field(vec3, OPTIONAL, "sphere centre, body axes from the centre of mass [m] (default: centre of mass)"),
        "radius": Field(positive, doc="sphere radius [m]"),
        "plane_point": Field(vec3, ZERO3, "a point of the fixed plane [m]"),
        "plane_normal": Field(nonzero_vec3, [0.0, 0.0, 1.0], "plane normal, towards the free side"),
        "law": Field(one_of("hertz", "linear"), "hertz", "normal force law (memoryless)"),
        "stiffness": Field(positive, doc="K [N/m^n] (Hertz: 4/3 E* sqrt(R))"),
        "exponent": Field(positive, 1.5, "n of the Hertz law"),
        "damping": Field(nonnegative, 0.0, "linear dashpot [N s/m], never pulls"),
    }, "a sphere on a body against a fixed plane"),
}
FORCE = Table({"type": Field(one_of(*FORCE_TYPES), doc=f"one of {list(FORCE_TYPES)}")}, "a force element",
              tag="type", variants=FORCE_TYPES)

CHAIN = Table({
    "n": Field(positive_int, doc="number of links"),
    "link_length": Field(positive, 0.2, "[m] (joint to joint)"),
    "radius": Field(positive, 0.02, "capsule radius of each link [m]"),
    "mass": Field(positive, OPTIONAL, "per link [kg] (default: from density)"),
    "density": Field(positive, 1000.0, "[kg/m^3], used when mass is not given"),
    "anchor": Field(vec3, ZERO3, "world point of the first ball joint (to ground) [m]"),
    "direction": Field(nonzero_vec3, [1.0, 0.0, 0.0], "initial direction of the chain, world"),
    "omega": Field(vec3, ZERO3, "initial rigid rotation of the whole chain about the anchor [rad/s]"),
    "color": Field(color, [200, 120, 40], "display colour"),
    "prefix": Field(name, "link", "body names are <prefix><index>"),
}, "generator: an N-link spatial chain of capsules on ball joints, hanging from the anchor")

CHECKS = Table({
    "t_end": Field(positive, OPTIONAL, "duration of the headless test run [s] (default: sim.t_end)"),
    "status": Field(string, "ok", "expected final status"),
    "max_constraint_violation": Field(positive, OPTIONAL, "bound on max |C| over the run [m]"),
    "max_energy_drift_rel": Field(positive, OPTIONAL, "bound on max |E - E0| / max T (conservative scenes)"),
    "min_chart_switches": Field(nonnegative_int, OPTIONAL, "at least this many chart switches in the run"),
    "no_warnings": Field(boolean, False, "fail if the run emits warnings"),
}, "what the headless test of this scene asserts")

SCENE_FILE = Table({
    "scene": Field(SCENE, dict, "about the scene"),
    "sim": Field(SIM, dict, "integration settings"),
    "bodies": Field(ArrayOf(BODY), list, "rigid bodies"),
    "joints": Field(ArrayOf(JOINT), list, "joints"),
    "forces": Field(ArrayOf(FORCE), list, "force elements"),
    "chain": Field(CHAIN, OPTIONAL, "chain generator"),
    "checks": Field(CHECKS, dict, "headless test checks"),
    "limits": Field(LIMITS, dict, "size limits checked before building"),
})
