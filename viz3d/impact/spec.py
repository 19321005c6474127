"""Scene format of impact runs: a rigid impactor, a flexible bar (or a rigid wall), a contact law.

A scene is an impact scene when it has an ``[impactor]`` table. Physical parameters are plain
values so that ``--set impactor.mass=0.5`` or ``--set bar.modes=40`` vary them for studies.
"""

from __future__ import annotations

from viz3d.contact.laws import NORMAL_LAWS
from viz3d.flexible.bar import SUPPORTS
from viz3d.flexible.bar import THEORIES as THEORIES_BY_KIND
from viz3d.impact.bodies import REFERENCES
from viz3d.scene.schema import (
    OPTIONAL,
    ArrayOf,
    Field,
    Invalid,
    Table,
    boolean,
    color,
    name,
    nonnegative,
    nonzero_vec3,
    number,
    one_of,
    poisson_ratio,
    positive,
    positive_int,
    string,
    unit_fraction,
    vec3,
)
from viz3d.scene.budget import LIMITS
from viz3d.scene.spec import SCENE

#: Contact models besides the continuous laws of ``NORMAL_LAWS``.
CONTACT_MODELS = ("rigid", "restitution")
#: Bar theories of every deformation kind, in ``viz3d.flexible.bar.THEORIES`` order.
THEORIES = tuple(theory for theories in THEORIES_BY_KIND.values() for theory in theories)


def supports(x):
    if not (isinstance(x, list) and len(x) == 2 and all(s in SUPPORTS for s in x)):
        raise Invalid(f"two end conditions [at x = 0, at x = L], each one of {list(SUPPORTS)}")
    return list(x)


def vector(x):
    if not (isinstance(x, list) and all(isinstance(e, (int, float)) and not isinstance(e, bool) for e in x)):
        raise Invalid("a list of numbers")
    return [float(e) for e in x]


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

IMPACT_SIM = Table({
    "t_end": Field(positive, doc="simulated duration [s]"),
    "output_dt": Field(positive, doc="interval between stored samples [s]"),
    "rtol": Field(positive, 1e-7, "relative tolerance of the adaptive Dormand-Prince 5(4) steps"),
    "atol": Field(positive, 1e-12, "absolute tolerance (state units: m, m/s, modal)"),
    "max_step": Field(positive, OPTIONAL, "largest step [s]"),
}, "adaptive integration with event location")

BAR = Table({
    "length": Field(positive, doc="L [m]"),
    "material": Field(MATERIAL, doc="E, rho, nu"),
    "section": Field(SECTION, doc="cross-section"),
    "theory": Field(one_of(*THEORIES), doc="rod (axial impact), euler_bernoulli or timoshenko (transverse impact)"),
    "supports": Field(supports, doc="end conditions of the mode set / mesh at x = 0 and x = L"),
    "reference": Field(one_of(*REFERENCES), "fixed",
                       "motion of the bar's frame: fixed (structure), free (floating), pinned (pendulum about x = 0)"),
    "model": Field(one_of("modal", "fe"), "modal", "analytic modes or finite elements"),
    "modes": Field(positive_int, OPTIONAL, "number of modes (modal; with fe: keep this many FE modes)"),
    "elements": Field(positive_int, OPTIONAL, "number of finite elements (model = fe)"),
    "tolerance": Field(positive, OPTIONAL, "truncation error target: choose the mode count from the physics"),
    "contact_x": Field(nonnegative, OPTIONAL, "struck section [m] (default L)"),
    "frame_velocity": Field(vector, OPTIONAL, "initial velocities of the frame coordinates [m/s or rad/s]"),
    "damping": Field(nonnegative, 0.0, "modal damping ratio of every mode"),
    "position": Field(vec3, [0.0, 0.0, 0.0], "world position of the end x = 0 (display) [m]"),
    "axis": Field(nonzero_vec3, [1.0, 0.0, 0.0], "world direction of the bar axis (display)"),
    "bending_direction": Field(nonzero_vec3, [0.0, 0.0, 1.0], "world direction of positive deflection w (display)"),
    "color": Field(color, [180, 140, 90], "display colour"),
}, "the flexible bar")

WALL = Table({
    "material": Field(MATERIAL, OPTIONAL, "for Hertz-type laws (default rigid)"),
    "color": Field(color, [150, 150, 150], "display colour"),
}, "a rigid, fixed flat surface (instead of a bar)")

PENDULUM = Table({
    "inertia": Field(positive, doc="moment of inertia about the pivot [kg m^2]"),
    "arm": Field(positive, doc="pivot to contact point [m]"),
    "omega": Field(number, doc="angular velocity at impact, towards the target [rad/s]"),
}, "a rigid pendulum: equivalent mass I/arm^2 and speed omega arm at the contact")

IMPACTOR = Table({
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

CONTACT = Table({
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
    "max_energy_balance_error": Field(positive, OPTIONAL, "bound on |balance error| / initial energy"),
    "restitution": Field(number, OPTIONAL, "expected achieved restitution"),
    "restitution_tol": Field(positive, 0.01, "absolute tolerance on it"),
    "min_contacts": Field(positive_int, OPTIONAL, "at least this many contacts"),
    "no_warnings": Field(boolean, False, "fail if the run emits warnings"),
}, "what the headless test of this scene asserts")

IMPACT_FILE = Table({
    "scene": Field(SCENE, dict, "about the scene"),
    "sim": Field(IMPACT_SIM, doc="integration settings"),
    "impactor": Field(IMPACTOR, doc="the impactor"),
    "bar": Field(BAR, OPTIONAL, "the struck bar (omit for a rigid wall)"),
    "wall": Field(WALL, OPTIONAL, "a rigid wall (when there is no bar)"),
    "contact": Field(CONTACT, doc="contact model"),
    "gauges": Field(ArrayOf(GAUGE), list, "strain gauges on the bar"),
    "display": Field(DISPLAY, dict, "drawing"),
    "checks": Field(IMPACT_CHECKS, dict, "headless test checks"),
    "limits": Field(LIMITS, dict, "size limits checked before building"),
})

__all__ = ["IMPACT_FILE", "CONTACT_MODELS", "string"]
