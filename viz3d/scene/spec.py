"""The scene file format: every table and key a scene may hold (SI units throughout).

``docs/scene_format.md`` is generated from this module (``viz3d list --format``).
"""

from __future__ import annotations

from viz3d.contact.contacts import HYPOTHESES
from viz3d.contact.friction import FRICTION_LAWS
from viz3d.contact.laws import NORMAL_LAWS
from viz3d.coordinates import ROTATIONS
from viz3d.flexible.bar import SUPPORTS
from viz3d.flexible.bar import THEORIES as THEORIES_BY_KIND
from viz3d.flexible.fe import ELEMENT_TYPES
from viz3d.formulation import FORMULATIONS
from viz3d.integrators import INTEGRATORS
from viz3d.scene.budget import LIMITS
from viz3d.scene.ship import SHIP
from viz3d.scene.schema import (
    OPTIONAL,
    ArrayOf,
    Field,
    Invalid,
    Table,
    boolean,
    color,
    count,
    any_table,
    dict_of_numbers,
    mat3_or_diag,
    name,
    nonnegative,
    nonnegative_int,
    nonzero_vec3,
    number,
    one_of,
    poisson_ratio,
    positive,
    positive_int,
    rotation3,
    rotation_matrices,
    string,
    unit_fraction,
    unit_interval,
    vec3,
    vec3_list,
)
from viz3d.timefunctions import PROFILE_KINDS, TIME_FUNCTIONS

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
    "formulation": Field(one_of(*FORMULATIONS), "projection", f"one of {list(FORMULATIONS)}"),
    "rotation": Field(one_of(*ROTATIONS), "euler_switching", f"one of {list(ROTATIONS)}"),
    "gravity": Field(vec3, [0.0, 0.0, -9.81], "gravitational acceleration [m/s^2]"),
    "baumgarte_alpha": Field(nonnegative, 10.0, "Baumgarte damping rate [1/s] (formulation = baumgarte)"),
    "baumgarte_beta": Field(nonnegative, 10.0, "Baumgarte frequency [rad/s] (formulation = baumgarte)"),
    "compiled": Field(boolean, True, "fixed explicit Runge-Kutta steps and ALI3-P steps through the compiled kernel when it covers the scene"),
    "projection_tol": Field(positive, 1e-12, "position tolerance of projections and of ali3p's iteration [m]"),
    "rtol": Field(positive, OPTIONAL, "relative tolerance: adaptive steps with error control (integrators dopri5, "
                  "dop853); sim.dt is then the interval between returned states, sampled by dense output"),
    "atol": Field(positive, 1e-9, "absolute tolerance of adaptive steps [m, rad, m/s, rad/s] (with sim.rtol)"),
    "max_step": Field(positive, OPTIONAL, "largest adaptive step [s] (with sim.rtol; default: unbounded)"),
    "rho_inf": Field(unit_interval, 0.8, "spectral radius at infinity of gen_alpha, in [0, 1] (1: no damping)"),
    "penalty_alpha": Field(positive, 1e7, "penalty factor [kg] (formulation = penalty; seed 004: 1e6 to 1e11)"),
    "penalty_xi": Field(positive, 1.0, "damping ratio of the penalty springs [-] (formulation = penalty)"),
    "penalty_omega": Field(positive, 10.0, "natural frequency of the penalty springs [rad/s] (formulation = penalty)"),
    "ali3p_alpha": Field(positive, 1e9, "augmented-Lagrangian penalty factor [N/m] (formulation = ali3p); its "
                         "multiplier iteration converges linearly, more slowly on longer chains: a larger alpha "
                         "takes fewer iterations (benchmarks/bench_ali3p.py: 1e10-1e11 for 100-400 links)"),
    "blowup_violation": Field(positive, 0.1, "stop with a diagnosis when max |C| exceeds this [m]"),
    "blowup_speed": Field(positive, 1e4, "stop with a diagnosis when a body's speed exceeds this [m/s]"),
    "blowup_energy": Field(positive, 0.5, "stop with a diagnosis when a conservative scene's total energy grows by more "
                           "than this fraction of the largest kinetic energy, or a scene's energy ledger (contacts, "
                           "drives) is off by more than this fraction of the energy that moved [-]"),
}, "how to integrate")

SHAPES = {
    "box": Table({"extents": Field(nonzero_vec3, doc="edge lengths along body x, y, z [m]")}, "box centred on the body origin"),
    "cylinder": Table({"radius": Field(positive, doc="[m]"), "height": Field(positive, doc="along body z [m]")},
                      "cylinder along body z"),
    "sphere": Table({"radius": Field(positive, doc="[m]")}, "sphere"),
    "capsule": Table({"radius": Field(positive, doc="[m]"),
                      "height": Field(positive, doc="of the cylindrical part, along body z [m]")}, "capsule along body z"),
    "mesh": Table({
        "file": Field(string, OPTIONAL, "STL, OBJ, GLB or PLY path, relative to the scene file (or a generator)"),
        "generator": Field(string, OPTIONAL, "a parametric mesh instead of a file: one of viz3d.anchoring.MESHES "
                           "(hull_shell, anchor_pocket, hawse_pipe, anchor_shank, anchor_flukes, anchor_shackle)"),
        "params": Field(dict_of_numbers, OPTIONAL, "the generator's parameters (its keyword arguments) [m, deg, kg]"),
        "scale": Field(positive, 1.0, "multiplies the vertex coordinates (e.g. 0.001 for mm)"),
    }, "triangle mesh; with `density` its centre of mass becomes the body origin"),
}
SHAPE = Table({"type": Field(one_of(*SHAPES), doc=f"one of {list(SHAPES)}")}, "geometry", tag="type", variants=SHAPES)

#: Bar theories of every deformation kind, in ``viz3d.flexible.bar.THEORIES`` order.
THEORIES = tuple(theory for theories in THEORIES_BY_KIND.values() for theory in theories)


def supports(x):
    if not (isinstance(x, list) and len(x) == 2 and all(s in SUPPORTS for s in x)):
        raise Invalid(f"two end conditions [at x = 0, at x = L], each one of {list(SUPPORTS)}")
    return list(x)


MATERIAL = Table({
    "E": Field(positive, doc="Young's modulus [Pa]"),
    "rho": Field(positive, OPTIONAL, "density [kg/m^3]"),
    "nu": Field(poisson_ratio, 0.3, "Poisson's ratio, in (-1, 0.5)"),
}, "elastic material")

SECTIONS = {
    "rectangle": Table({"width": Field(positive, doc="[m]"), "depth": Field(positive, doc="in the bending plane [m]")},
                       "rectangular section"),
    "circle": Table({"diameter": Field(positive, doc="[m]")}, "solid circular section"),
    "general": Table({"area": Field(positive, doc="[m^2]"), "second_moment": Field(positive, doc="[m^4]"),
                      "depth": Field(positive, doc="extreme-fibre distance x 2 [m]")}, "any section"),
}
SECTION = Table({"type": Field(one_of(*SECTIONS), doc=f"one of {list(SECTIONS)}"),
                 "shear_coefficient": Field(unit_fraction, OPTIONAL,
                                            "Timoshenko k in (0, 1] (default 5/6 rectangle, 9/10 circle)")},
                "cross-section", tag="type", variants=SECTIONS)

POINT_MASS = Table({
    "x": Field(nonnegative, doc="section [m]"),
    "mass": Field(positive, doc="[kg]"),
}, "a rigid point mass on the bar's axis")

_BODY_COMMON = {
    "name": Field(name, doc="unique body name"),
    "type": Field(one_of("rigid", "flexible"), "rigid", "rigid or flexible"),
    "velocity": Field(vec3, ZERO3, "velocity of the centre of mass (flexible: of the frame origin, the undeformed "
                      "centre of mass), world [m/s]"),
    "omega": Field(vec3, ZERO3, "angular velocity, world axes [rad/s]"),
    "color": Field(color, OPTIONAL, 'display colour, [r, g, b] or "#rrggbb"'),
}
BODY_TYPES = {
    "rigid": Table({
        "shape": Field(SHAPE, OPTIONAL, "geometry (drawn, and used for mass properties with density)"),
        "mass": Field(positive, OPTIONAL, "[kg]"),
        "inertia": Field(mat3_or_diag, OPTIONAL, "about the centre of mass, body axes [kg m^2]"),
        "density": Field(positive, OPTIONAL, "[kg/m^3]: mass and inertia from the shape"),
        "position": Field(vec3, doc="centre of mass, world [m]"),
        "euler": Field(vec3, OPTIONAL, "ZXZ angles (psi, theta, phi) [rad]"),
        "euler_deg": Field(vec3, OPTIONAL, "ZXZ angles (psi, theta, phi) [deg]"),
    }, "a rigid body (6 velocity coordinates)"),
    "flexible": Table({
        "length": Field(positive, doc="L [m]"),
        "material": Field(MATERIAL, doc="E, rho, nu"),
        "section": Field(SECTION, doc="cross-section"),
        "theory": Field(one_of(*THEORIES), doc="rod (axial deformation), euler_bernoulli or timoshenko (bending)"),
        "supports": Field(supports, ["free", "free"],
                          "end conditions of the mode set / mesh at x = 0 and x = L: the reference condition of a "
                          "floating frame (free-free: mean axes; clamped at x = 0: tangent frame)"),
        "frame": Field(one_of("floating", "fixed"), "floating",
                       "floating: the bar's frame moves (6 + n coordinates); fixed: clamped in the world (n coordinates)"),
        "model": Field(one_of("modal", "fe"), "modal", "analytic modes or finite elements"),
        "modes": Field(positive_int, OPTIONAL, "number of modes (modal; with fe: keep this many FE modes)"),
        "elements": Field(positive_int, OPTIONAL, "number of finite elements (model = fe)"),
        "element": Field(one_of(*ELEMENT_TYPES), OPTIONAL, "finite element (default: the theory's; 'quintic' for "
                         "euler_bernoulli with curvature dofs)"),
        "tolerance": Field(positive, OPTIONAL, "truncation error target: choose the mode count from the physics"),
        "resolve_time": Field(positive, OPTIONAL, "with tolerance: the shortest time the modes must resolve (a "
                              "contact's duration) [s]"),
        "resolve_x": Field(nonnegative, OPTIONAL, "with tolerance: the section whose flexibility matters [m]"),
        "damping": Field(nonnegative, 0.0, "modal damping ratio of every mode"),
        "coupling": Field(one_of("coupled", "ked"), "coupled", "coupled: the floating frame and the deformation "
                          "act on each other; ked: kineto-elastodynamic (seed 003), the frame moves as the rigid "
                          "body (joints at the undeformed sections) and the structural equations are loaded by "
                          "that rigid motion only, without feedback or motion-dependent stiffness (docs/notation.md)"),
        "geometric_stiffening": Field(boolean, False, "centrifugal stiffening of bending: the foreshortening's "
                                      "kinetic energy about the supported end (docs/notation.md); a bending bar"),
        "point_masses": Field(ArrayOf(POINT_MASS), list, "rigid point masses on the axis"),
        "position": Field(vec3, doc="world position of the end x = 0 [m]"),
        "axis": Field(nonzero_vec3, [1.0, 0.0, 0.0], "world direction of the bar axis (x = 0 to x = L)"),
        "bending_direction": Field(nonzero_vec3, [0.0, 0.0, 1.0], "world direction of positive deflection w "
                                   "(the depth of the section; made normal to the axis)"),
    }, "a flexible bar on a floating or fixed frame (6 + n or n velocity coordinates)"),
}
BODY = Table(_BODY_COMMON, "a body", tag="type", variants=BODY_TYPES)

_SECTIONS = {
    "x1": Field(nonnegative, OPTIONAL, "flexible body 1: the section of the point [m] (with local1: the offset in the section)"),
    "x2": Field(nonnegative, OPTIONAL, "flexible body 2: the section of the point [m] (with local2: the offset in the section)"),
}
JOINT_TYPES = {
    "ball": Table({
        "point": Field(vec3, OPTIONAL, "joint point, world, in the initial configuration [m]"),
        "local1": Field(vec3, OPTIONAL, "joint point in body 1 axes from its centre of mass [m]"),
        "local2": Field(vec3, OPTIONAL, "joint point in body 2 axes (world if ground) [m]"),
        **_SECTIONS,
    }, "ball joint (rotula): give `point`, or `local1` and `local2` (on a flexible body: `x1`/`x2`)"),
}
_FRAME_POINT = Field(vec3, OPTIONAL, "joint point, world, in the initial configuration [m] (default: body 1's "
                     "centre of mass)")
_AXIS = Field(nonzero_vec3, [0.0, 0.0, 1.0], "joint axis, world direction in the initial configuration")
_FRAMED_SECTIONS = {
    "x1": Field(nonnegative, OPTIONAL, "flexible body 1: the section of the joint (its frame turns with the "
                "section) [m]; default: the section nearest `point`"),
    "x2": Field(nonnegative, OPTIONAL, "flexible body 2: the section of the joint [m]; default: the section "
                "nearest the joint point"),
}
#: A framed joint given on each body instead (a joint point and frame fixed in each side's axes, as
#: MuJoCo's and URDF's are): the two sides need not meet in the initial configuration (the start is
#: assembled like any other: ``consistent_state``). ``viz3d.departures`` writes its joints so.
_BODY_FRAMES = {
    "frame1": Field(rotation3, OPTIONAL, "with local1, local2 and frame2: the joint frame's axes in body 1 axes, "
                    "a rotation matrix whose columns are its x, y, z (a list of its 3 rows), instead of world "
                    "axes in the initial configuration"),
    "frame2": Field(rotation3, OPTIONAL, "with frame1: the joint frame in body 2 axes (world if ground)"),
    "local1": Field(vec3, OPTIONAL, "with frame1: the joint point in body 1 axes from its centre of mass [m]"),
    "local2": Field(vec3, OPTIONAL, "with frame2: the joint point in body 2 axes (world if ground) [m]"),
}
#: Joints with a frame on each side (``viz3d.joints.FramedJoint``): both sides' frames coincide in the
#: initial configuration, where every relative coordinate is zero (unless given on each body:
#: ``_BODY_FRAMES``). A side on a flexible body is a section, whose frame turns with the section's rotation.
JOINT_TYPES.update({
    "revolute": Table({"point": _FRAME_POINT, "axis": _AXIS, **_FRAMED_SECTIONS, **_BODY_FRAMES},
                      "revolute joint (hinge): turns about `axis` through `point`; coordinate `angle` [rad]"),
    "universal": Table({
        "point": _FRAME_POINT, **_FRAMED_SECTIONS,
        "axis1": Field(nonzero_vec3, [1.0, 0.0, 0.0], "first axis, fixed in body 1, world direction in the "
                       "initial configuration"),
        "axis2": Field(nonzero_vec3, [0.0, 1.0, 0.0], "second axis, fixed in body 2 (made normal to axis1)"),
        **_BODY_FRAMES,
    }, "universal (Cardan) joint: two relative rotations, `angle1` about axis1 and `angle2` about axis2 [rad]"),
    "prismatic": Table({"point": _FRAME_POINT, "axis": _AXIS, **_FRAMED_SECTIONS, **_BODY_FRAMES},
                       "prismatic joint (slider) along `axis`; coordinate `distance` [m]"),
    "cylindrical": Table({"point": _FRAME_POINT, "axis": _AXIS, **_FRAMED_SECTIONS, **_BODY_FRAMES},
                         "cylindrical joint: turns about and slides along `axis`; coordinates `angle` [rad], "
                         "`distance` [m]"),
    "fixed": Table({"point": _FRAME_POINT, **_FRAMED_SECTIONS, **_BODY_FRAMES}, "fixed joint (weld): no relative motion"),
})
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
        **_SECTIONS,
    }, "linear spring-damper between two points"),
    "force": Table({**_LOAD, "point": Field(vec3, OPTIONAL, "point of application, world, initial configuration [m]"),
                    "local": Field(vec3, OPTIONAL,
                                   "point of application, body axes from the centre of mass [m] (default: centre of mass)"),
                    "x": Field(nonnegative, OPTIONAL, "flexible body: the section of the point [m]")},
                   "applied force = value + amplitude * f(t)"),
    "torque": Table(dict(_LOAD), "applied couple = value + amplitude * f(t)"),
    "joint_stop": Table({
        "name": Field(name, OPTIONAL, "default joint_stop<index>"),
        "joint": Field(string, doc="name of a revolute, universal, prismatic or cylindrical joint"),
        "coordinate": Field(string, OPTIONAL, "its coordinate (angle, angle1, angle2, distance; default: the first)"),
        "lower": Field(number, OPTIONAL, "lower limit [rad or m] (default: none)"),
        "upper": Field(number, OPTIONAL, "upper limit [rad or m] (default: none)"),
        "stiffness": Field(positive, doc="k [N m/rad or N/m]"),
        "damping": Field(nonnegative, 0.0, "c [N m s/rad or N s/m]"),
    }, "stop on a joint coordinate: zero inside [lower, upper], -k (q - limit) - c q_dot outside (never pulling)"),
    "joint_motor": Table({
        "name": Field(name, OPTIONAL, "default joint_motor<index>"),
        "joint": Field(string, doc="name of a revolute, universal, prismatic or cylindrical joint"),
        "coordinate": Field(string, OPTIONAL, "its coordinate (default: the first)"),
        "kp": Field(nonnegative, doc="proportional gain [N m/rad or N/m]"),
        "kd": Field(nonnegative, 0.0, "rate gain [N m s/rad or N s/m]"),
        "max_effort": Field(positive, OPTIONAL, "saturation [N m or N] (default: none)"),
        "kind": Field(one_of(*TIME_FUNCTIONS), "constant",
                      f"profile q_ref(t) = value + amplitude * f(t): {list(TIME_FUNCTIONS)}"),
        "value": Field(number, 0.0, "constant part of the profile [rad or m]"),
        "amplitude": Field(number, 0.0, "amplitude of the profile [rad or m]"),
        "frequency": Field(nonnegative, 0.0, "[Hz] (sine)"),
        "phase": Field(number, 0.0, "[rad] (sine)"),
        "start": Field(number, 0.0, "[s] (step, ramp, pulse)"),
        "duration": Field(nonnegative, 0.0, "[s] (ramp, pulse)"),
    }, "motor on a joint coordinate: f = clip(kp (q_ref(t) - q) - kd q_dot, -max_effort, max_effort)"),
}
FORCE = Table({"type": Field(one_of(*FORCE_TYPES), doc=f"one of {list(FORCE_TYPES)}")}, "a force element",
              tag="type", variants=FORCE_TYPES)

CONTACT_MODELS = ("rigid", "restitution")
CONTACT = Table({
    "name": Field(name, OPTIONAL, "default contact<index>"),
    "body1": Field(string, doc="the body carrying the sphere (or point, or flat face)"),
    "body2": Field(string, "ground", "the body carrying the surface, or ground"),
    "geometry": Field(one_of("sphere", "body_shape"), "sphere", "sphere: the sphere (or point) below; body_shape: the "
                      "spheres of body 1's own shape against body 2's surface (box: 8 corners, capsule: 2 end spheres, "
                      "sphere, cylinder: rim_points on each rim), one contact each, named <name>_<k>"),
    "rim_points": Field(count(1000), 16, "body_shape of a cylinder: points on each end rim"),
    "radius": Field(nonnegative, 0.0, "sphere radius on body 1 [m] (0: a point or a flat face)"),
    "point1": Field(vec3, OPTIONAL, "sphere centre, world, initial configuration [m] (default: body 1's centre of mass)"),
    "local1": Field(vec3, OPTIONAL, "sphere centre, body 1 axes from its centre of mass [m]"),
    "x1": Field(nonnegative, OPTIONAL, "flexible body 1: section of the sphere centre [m]"),
    "point2": Field(vec3, OPTIONAL, "a point of the surface, world, initial configuration [m] (default: the origin)"),
    "local2": Field(vec3, OPTIONAL, "a point of the surface, body 2 axes (world if ground) [m]"),
    "x2": Field(nonnegative, OPTIONAL, "flexible body 2: section of the surface point [m]"),
    "normal": Field(nonzero_vec3, [0.0, 0.0, 1.0], "outward normal of body 2's surface, world, initial configuration"),
    "law": Field(one_of(*CONTACT_MODELS, *NORMAL_LAWS), "hertz",
                 f"one of {[*CONTACT_MODELS, *NORMAL_LAWS]}: a force law, kinematic contact, or impulses"),
    "stiffness": Field(positive, OPTIONAL, "K [N/m^n] (default: Hertz from the materials and the radius)"),
    "exponent": Field(positive, OPTIONAL, "n (default 1 linear, 1.5 otherwise)"),
    "damping": Field(nonnegative, 0.0, "linear dashpot added to the law [N s/m], never pulls"),
    "restitution": Field(positive, OPTIONAL, "restitution: e; rate laws: the target e they are calibrated to"),
    "damping_factor": Field(positive, OPTIONAL, "rate laws (hunt_crossley, lankarani_nikravesh, flores): fixed c [s/m] "
                            "in F = K alpha^n (1 + c alpha_dot), instead of a target restitution"),
    "hypothesis": Field(one_of(*HYPOTHESES), "newton", "restitution impulses: velocity ratio or impulse ratio"),
    "yield_stress": Field(positive, OPTIONAL, "sigma_Y of the softer body [Pa] (elastoplastic laws)"),
    "material1": Field(MATERIAL, OPTIONAL, "body 1's E, nu for Hertz-type laws (default: a flexible body's, else steel)"),
    "material2": Field(MATERIAL, OPTIONAL, "body 2's E, nu (default: a flexible body's, else steel; rigid ground: rigid)"),
    "friction": Field(one_of("none", *FRICTION_LAWS), "none", f"tangential law: none or one of {list(FRICTION_LAWS)} "
                      "(force laws between rigid bodies or ground)"),
    "mu": Field(nonnegative, OPTIONAL, "friction coefficient (stribeck: the dynamic one)"),
    "mu_static": Field(nonnegative, OPTIONAL, "stribeck, bristle: static coefficient (default mu)"),
    "slip_speed": Field(positive, 1e-4, "regularisation: F_t = mu F_n tanh(s / slip_speed) [m/s]"),
    "stribeck_speed": Field(positive, 1e-2, "stribeck: decay speed from mu_static to mu [m/s]"),
    "viscous": Field(nonnegative, 0.0, "stribeck, bristle: viscous friction coefficient [N s/m]"),
    "stick_speed": Field(positive, 1e-3, "bristle: v_stick, slip speed of the stick-slip transition [m/s]"),
    "stick_stiffness": Field(positive, OPTIONAL, "bristle: k_stick [N/m] (required with friction = 'bristle')"),
    "stick_damping": Field(nonnegative, 0.0, "bristle: c_stick [N s/m]"),
    "stick_alpha": Field(positive, 1.0, "bristle: alpha_stick, the deflection kept when the anchor moves (eq. 3.49)"),
    "events": Field(boolean, True, "locate onset, maximum indentation and separation in time (false: the law acts "
                    "whenever the bodies overlap, stepped through; memoryless laws only)"),
}, "a contact between a sphere (or point) on body 1 and a surface of body 2 or ground")

def group_table(x):
    if not (isinstance(x, dict) and all(isinstance(v, list) and v and all(isinstance(p, str) for p in v)
                                        for v in x.values())):
        raise Invalid("a table of group name -> non-empty list of body names or fnmatch patterns "
                      "(e.g. { links = [\"link*\"] })")
    return {str(k): list(v) for k, v in x.items()}


def two_names(x):
    if not (isinstance(x, list) and len(x) == 2 and all(isinstance(v, str) for v in x)):
        raise Invalid('two group names, e.g. ["links", "ground"]')
    return list(x)


def names(x):
    if not (isinstance(x, list) and all(isinstance(v, str) for v in x)):
        raise Invalid("a list of body names or fnmatch patterns")
    return list(x)


_PLACED = {
    "name": Field(name, OPTIONAL, "default ground<index>"),
    "position": Field(vec3, ZERO3, "origin of the shape, world [m]"),
    "euler_deg": Field(vec3, ZERO3, "ZXZ angles of the shape's axes (psi, theta, phi) [deg]"),
}
GROUND_SHAPES = {
    **{kind: Table({**t.fields, **_PLACED}, t.doc) for kind, t in SHAPES.items() if kind != "mesh"},
    "mesh": Table({**SHAPES["mesh"].fields, **_PLACED,
                   "convex": Field(boolean, False, "collide as its convex hull instead of its triangles")},
                  "triangle mesh (hull, pipe, pocket): collides as its triangles, or its convex hull"),
    "plane": Table({"point": Field(vec3, ZERO3, "a point of the plane, world [m]"),
                    "normal": Field(nonzero_vec3, [0.0, 0.0, 1.0], "outward normal, world"),
                    "name": Field(name, OPTIONAL, "default ground<index>")}, "infinite plane (half-space below it)"),
}
GROUND_SHAPE = Table({"type": Field(one_of(*GROUND_SHAPES), doc=f"one of {list(GROUND_SHAPES)}")},
                     "a collision shape fixed to ground", tag="type", variants=GROUND_SHAPES)

COLLISION_PAIR = Table({
    "groups": Field(two_names, doc='the two groups that collide (a group with itself: ["links", "links"]; '
                    '"ground": the ground shapes)'),
    "law": Field(one_of(*NORMAL_LAWS), "hertz", "normal law, one without contact memory: linear, hertz, or a rate "
                 "law with damping_factor"),
    "stiffness": Field(positive, OPTIONAL, "K [N/m^n] (default: Hertz from the materials, spheres and planes only)"),
    "exponent": Field(positive, OPTIONAL, "n (default 1 linear, 1.5 otherwise)"),
    "damping": Field(nonnegative, 0.0, "linear dashpot added to the law [N s/m] (linear law: its own), never pulls"),
    "damping_factor": Field(positive, OPTIONAL, "rate laws: c [s/m] in F = K alpha^n (1 + c alpha_dot)"),
    "material1": Field(MATERIAL, OPTIONAL, "first group's E, nu (default steel; ground rigid)"),
    "material2": Field(MATERIAL, OPTIONAL, "second group's E, nu (default steel; ground rigid)"),
    "friction": Field(one_of("none", *FRICTION_LAWS), "none", f"tangential law: none or one of {list(FRICTION_LAWS)} "
                      "(bristle: each contact keeps a stick anchor from step to step)"),
    "mu": Field(nonnegative, OPTIONAL, "friction coefficient (stribeck: the dynamic one)"),
    "mu_static": Field(nonnegative, OPTIONAL, "stribeck, bristle: static coefficient (default mu)"),
    "slip_speed": Field(positive, 1e-4, "regularisation: F_t = mu F_n tanh(s / slip_speed) [m/s]"),
    "stribeck_speed": Field(positive, 1e-2, "stribeck: decay speed from mu_static to mu [m/s]"),
    "viscous": Field(nonnegative, 0.0, "stribeck, bristle: viscous friction coefficient [N s/m]"),
    "stick_speed": Field(positive, 1e-3, "bristle: v_stick, slip speed of the stick-slip transition [m/s]"),
    "stick_stiffness": Field(positive, OPTIONAL, "bristle: k_stick per contact point [N/m] (required with "
                             "friction = 'bristle')"),
    "stick_damping": Field(nonnegative, 0.0, "bristle: c_stick per contact point [N s/m]"),
    "stick_alpha": Field(positive, 1.0, "bristle: alpha_stick, the deflection kept when the anchor moves (eq. 3.49)"),
}, "what acts where two collision groups touch")

COLLISION = Table({
    "groups": Field(group_table, {}, "group name -> bodies (names or fnmatch patterns); default: one group "
                    "'bodies' with every rigid body that has a shape. 'ground' is the ground shapes"),
    "pairs": Field(ArrayOf(COLLISION_PAIR), list, "which groups collide, and the law where they touch"),
    "ground": Field(ArrayOf(GROUND_SHAPE), list, "collision shapes fixed to ground"),
    "skip_joined": Field(boolean, True, "bodies joined to each other never collide"),
    "max_contacts": Field(count(256), 4, "contacts kept per pair of shapes"),
    "merge_distance": Field(nonnegative, 0.0, "contacts of one pair closer than this are one [m] (0: a tenth of the "
                            "smaller shape's size)"),
    "rim_points": Field(count(1000), 16, "cylinders against planes: points on each end rim"),
    "triangle_meshes": Field(names, [], "bodies whose mesh shape collides as its triangles (default: its convex "
                             "hull)"),
}, "contacts between body shapes found by the collision library (FCL): broad phase, groups, laws")

WATER = Table({
    "enabled": Field(boolean, True, "false: no water (the table stays in the scene)"),
    "level": Field(number, 0.0, "height of the surface along its normal [m]"),
    "normal": Field(nonzero_vec3, OPTIONAL, "unit normal of the surface, up out of the water (default: against "
                    "sim.gravity)"),
    "density": Field(positive, 1025.0, "[kg/m^3] (sea water)"),
    "drag_coefficient": Field(nonnegative, 0.0, "C_d of quadratic drag on the frontal area of the sphere of the body's "
                              "volume (0: no drag)"),
    "bodies": Field(names, [], "bodies in the water, names or fnmatch patterns, each rigid with a shape (default: "
                    "every rigid body with a sphere, capsule, box or cylinder shape, or a closed, outward mesh; open "
                    "meshes stay dry)"),
    "cells": Field(count(100_000), 512, "cells per body for the buoyancy (the wet fraction of each is linear in its "
                   "depth across one cell size): a grid of about this many over a primitive's bounding box, or of "
                   "cell volume V / cells over a mesh's, centres inside kept"),
}, "still water: buoyancy and quadratic drag on submerged parts (viz3d.water)")

GAUGE = Table({
    "name": Field(name, doc="gauge name"),
    "body": Field(string, OPTIONAL, "flexible body (default: the only one)"),
    "x": Field(nonnegative, doc="section [m]"),
    "quantity": Field(one_of("strain", "deflection"), "strain", "strain: axial strain plus the bending surface "
                      "strain on the +w fibre [-] (plot strain/<name>); deflection: transverse displacement of the "
                      "axis along the bending direction, from the body's reference frame (pinned-pinned: the chord "
                      "through the pins) [m] (plot deflection/<name>; a bending bar)"),
}, "a gauge on a flexible body: strain or deflection at a section")

DISPLAY = Table({
    "amplification": Field(positive, 1.0, "deformation of flexible bodies drawn this many times larger"),
    "frame_dt": Field(positive, OPTIONAL, "simulated time between drawn frames in recordings [s]"),
    "plot_dt": Field(positive, OPTIONAL, "simulated time between plot samples in recordings [s] (default: every "
                     "step; long runs of many joints: a recording's size)"),
    "speed": Field(positive, 1.0, "live viewer: simulated seconds per wall-clock second"),
    "stress_scale": Field(positive, OPTIONAL, "flexible bodies are coloured by their surface bending stress: the "
                          "stress [Pa] drawn at the ends of the diverging colour map (-scale blue, 0 light grey, +scale "
                          "red); default: the largest |stress| drawn so far in the run (a running maximum)"),
}, "how the run is drawn")

CHAIN = Table({
    "n": Field(positive_int, doc="number of links"),
    "link_length": Field(positive, 0.2, "[m] (joint to joint)"),
    "radius": Field(positive, 0.02, "capsule radius of each link [m]"),
    "mass": Field(positive, OPTIONAL, "per link [kg] (default: from density)"),
    "density": Field(positive, 1000.0, "[kg/m^3], used when mass is not given"),
    "anchor": Field(vec3, ZERO3, "world point of the first ball joint (to ground) [m]"),
    "direction": Field(nonzero_vec3, [1.0, 0.0, 0.0], "initial direction of the chain, world"),
    "path": Field(vec3_list, [], "points the chain runs through from the anchor (a polyline in one plane; "
                  "the links' joints lie on it, and past its end the chain goes straight on)"),
    "omega": Field(vec3, ZERO3, "initial rigid rotation of the whole chain about the anchor [rad/s]"),
    "color": Field(color, [200, 120, 40], "display colour"),
    "prefix": Field(name, "link", "body names are <prefix><index>"),
    "attach": Field(string, "ground", "the body the first link hangs from (a ball joint at anchor)"),
    "end": Field(vec3, OPTIONAL, "second anchor: the chain hangs between anchor and end (ball joints to ground at "
                 "both), starting as a circular arc below their chord (needs n * link_length > the span)"),
    "joint": Field(one_of("ball", "universal"), "ball", "joints between links: ball, or universal (two relative "
                   "rotations, as seed 004's links: in the hanging plane and out of it; with attach a body, the first "
                   "link's joint too: no twist)"),
    "joint_damping": Field(nonnegative, 0.0, "universal joints: a damper on both angles [N m s/rad] (a joint_motor "
                           "with kp = 0): lets a hanging chain settle"),
    "leave": Field(boolean, False, "with attach a body that hauls the chain in: a link whose far joint has passed the "
                   "anchor point leaves the run, its next link held to attach (viz3d.departures): the scene models "
                   "only the chain that still moves"),
    "leave_dt": Field(positive, 0.05, "with leave: how often the first link is checked [s of simulated time] (a "
                      "multiple of sim.dt)"),
}, "generator: an N-link spatial chain of capsules, hanging from the anchor (or between anchor and end)")

INCLINE = Table({
    "angle_deg": Field(number, doc="tilt of gravity about the world y axis [deg]: a level floor becomes an incline "
                       "descending along +x"),
    "mu": Field(nonnegative, OPTIONAL, "friction coefficient of every contact with friction that gives none"),
}, "generator: an incline, as gravity tilted about y (sim.gravity's magnitude kept), and one mu for its contacts")

CHECKS = Table({
    "t_end": Field(positive, OPTIONAL, "duration of the headless test run [s] (default: sim.t_end)"),
    "status": Field(string, "ok", "expected final status"),
    "max_constraint_violation": Field(positive, OPTIONAL, "bound on max |C| over the run [m]"),
    "max_energy_drift_rel": Field(positive, OPTIONAL, "bound on max |E - E0| / max T (conservative scenes)"),
    "min_chart_switches": Field(nonnegative_int, OPTIONAL, "at least this many chart switches in the run"),
    "max_energy_balance_error": Field(positive, OPTIONAL, "bound on |ledger balance error| / largest energy (contacts)"),
    "restitution": Field(number, OPTIONAL, "expected achieved restitution (contacts)"),
    "restitution_tol": Field(positive, 0.01, "absolute tolerance on it"),
    "min_contacts": Field(positive_int, OPTIONAL, "at least this many contacts"),
    "no_warnings": Field(boolean, False, "fail if the run emits warnings"),
}, "what the headless test of this scene asserts")

DRIVE = Table({
    "name": Field(name, OPTIONAL, "default drive<index>"),
    "joint": Field(string, doc="name of a revolute, universal, prismatic or cylindrical joint"),
    "coordinate": Field(string, OPTIONAL, "its coordinate (angle, angle1, angle2, distance; default: the first)"),
    "mode": Field(one_of(*PROFILE_KINDS), "velocity", "what the profile prescribes: the coordinate's velocity "
                  "(integrated from 0 at t = 0) or its position"),
    "kind": Field(one_of(*TIME_FUNCTIONS), "constant", "profile = value + amplitude * f(t); position: constant, "
                  "sine or smooth_ramp; velocity: constant, sine, ramp or smooth_ramp"),
    "value": Field(number, 0.0, "constant part [rad, m or per s]"),
    "amplitude": Field(number, 0.0, "amplitude [rad, m or per s]"),
    "frequency": Field(nonnegative, 0.0, "[Hz] (sine)"),
    "phase": Field(number, 0.0, "[rad] (sine)"),
    "start": Field(number, 0.0, "[s] (ramp, smooth_ramp)"),
    "duration": Field(nonnegative, 0.0, "[s] (ramp, smooth_ramp)"),
    "capacity": Field(positive, OPTIONAL, "largest |effort| the drive can give [N or N m] (a windlass's): the run "
                      "ends once it has been at it for capacity_time (a rigid drive needing more: with a diagnosis; a "
                      "limited drive: stalled, status ok)"),
    "capacity_time": Field(nonnegative, 0.0, "[s] how long the drive may be at its capacity (judged on the output "
                           "frames: the least |effort| over this time); 0: not at all"),
    "servo_gain": Field(positive, OPTIONAL, "[N s/m or N m s/rad] a limited drive: a velocity servo with the force "
                        "range +-capacity (viz3d.forces.DriveServo: effort clip(gain (profile - rate)), tracking with "
                        "the speed error effort / gain, stalling at its capacity) instead of a rigid constraint; needs "
                        "mode = 'velocity' and a capacity"),
}, "a drive: a rheonomic constraint prescribing a joint coordinate, or a limited drive (servo_gain); reports the "
   "effort it takes")

STOWAGE = Table({
    "bodies": Field(names, doc="the bodies that must reach their stowed poses (the anchor's shank and flukes)"),
    "position": Field(vec3_list, doc="their stowed centres of mass, world [m]"),
    "axes": Field(rotation_matrices, doc="their stowed orientations (world from body, 3x3 each)"),
    "drive": Field(string, doc="the drive that hauls them (its effort is the hauling force; its capacity the jam "
                   "limit)"),
    "tolerance": Field(positive, 0.1, "seated: every body within this of its stowed position [m]"),
    "angle_tolerance": Field(positive, 5.0, "seated: every body within this of its stowed orientation [deg]"),
    "stall_time": Field(positive, 2.0, "jammed: the bodies move less than stall_distance over this time while the "
                        "drive hauls [s]"),
    "stall_distance": Field(positive, 0.02, "[m]"),
    "settle_time": Field(nonnegative, OPTIONAL, "the windlass stops once the bodies have stayed seated this long [s] "
                         "(the run ends there); absent: it hauls until sim.t_end"),
    "haul_limit": Field(positive, OPTIONAL, "the windlass stops once its coordinate has moved this far from 0 [m or "
                        "rad] (the run ends there: a limited drive's speed depends on its load, so a haul of given "
                        "length has no given duration); absent: it hauls until sim.t_end"),
    "hawse": Field(vec3, OPTIONAL, "where the chain enters the hull, world [m]: the chain's tension there is saved "
                   "(stowage_hawse_tension)"),
    "chain": Field(string, "link", "the chain's body-name prefix (its joints are <prefix>_j<i>)"),
    "report": Field(any_table, OPTIONAL, "what the generator chose (simulated links, haul length), shown in the summary"),
}, "the goal of a haul: the verdict seated / jammed / not reached at the end of the run")

SCENE_FILE = Table({
    "scene": Field(SCENE, dict, "about the scene"),
    "sim": Field(SIM, dict, "integration settings"),
    "bodies": Field(ArrayOf(BODY), list, "rigid and flexible bodies"),
    "joints": Field(ArrayOf(JOINT), list, "joints"),
    "drives": Field(ArrayOf(DRIVE), list, "drives (prescribed joint coordinates)"),
    "forces": Field(ArrayOf(FORCE), list, "force elements"),
    "contacts": Field(ArrayOf(CONTACT), list, "contacts"),
    "collision": Field(COLLISION, OPTIONAL, "contacts between shapes (collision library)"),
    "water": Field(WATER, OPTIONAL, "still water: buoyancy and drag"),
    "gauges": Field(ArrayOf(GAUGE), list, "strain and deflection gauges on flexible bodies"),
    "display": Field(DISPLAY, dict, "drawing"),
    "chain": Field(CHAIN, OPTIONAL, "chain generator"),
    "incline": Field(INCLINE, OPTIONAL, "incline generator (gravity tilt and friction coefficient)"),
    "ship": Field(SHIP, OPTIONAL, "anchor-hoist generator (hull, pipe, pocket, anchor, chain, windlass)"),
    "stowage": Field(STOWAGE, OPTIONAL, "the stowed poses a haul is judged by"),
    "checks": Field(CHECKS, dict, "headless test checks"),
    "limits": Field(LIMITS, dict, "size limits checked before building"),
})
