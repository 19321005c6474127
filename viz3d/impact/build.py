"""Impact ``Scene`` -> ``ImpactSetup``: bodies, contact model, gauges and the model choice.

Directions: the contact normal ``n`` points from the impactor into the target. On a bar, ``n`` is
``-side`` times the deformation direction (axial u or deflection w): an impactor arriving from
the ``+`` side pushes the struck section towards ``-u``/``-w``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viz3d.contact import laws as L
from viz3d.contact.parameters import effective_modulus, hertz_stiffness
from viz3d.flexible import BarModel, Material, Section, analytic_modes, contact_band, fe_model, reduce, select_modes
from viz3d.flexible.bar import rigid_mode_count
from viz3d.impact.bodies import bar_body, frame_columns, modal_time_resolution
from viz3d.impact.engine import Contact, ImpactProblem, fixed_body, rigid_mass
from viz3d.scene.load import Scene
from viz3d.scene.schema import SceneError

#: Impactor material when the scene gives none (steel).
DEFAULT_IMPACTOR = {"E": 210e9, "nu": 0.3}
#: Reference model used to choose a mode count from a tolerance: this many analytic modes.
SELECTION_REFERENCE_MODES = 160


@dataclass(frozen=True)
class ImpactSetup:
    """Everything a run needs, built once from the scene.

    Attributes
    ----------
    problem : ImpactProblem
    bar : BarModel or None
    reference : str
    x_contact : float [m]
    side : float
        +1 when the impactor arrives from the +u/+w side.
    gauge_names : tuple of str
    gauge_x : ndarray, shape (ng,) [m]
    requested_restitution : float or None
    model_choice : str
        How the bar was discretized and why (mode count, truncation estimate).
    time_resolution : float
        Period of the bar model's highest mode [s]: nothing shorter is resolved (0 for a wall).
    """

    problem: ImpactProblem
    bar: BarModel | None
    reference: str
    x_contact: float
    side: float
    gauge_names: tuple[str, ...]
    gauge_x: np.ndarray
    requested_restitution: float | None
    model_choice: str
    time_resolution: float = 0.0


def build_impact(scene: Scene) -> ImpactSetup:
    d, src = scene.data, scene.source()
    mass, velocity = impactor_motion(d["impactor"], src)
    bar = d.get("bar")
    side = 1.0 if d["contact"].get("side", "+") == "+" else -1.0
    contact_model, requested = contact_from(d, src)
    if bar is None:
        target, model, x_c, choice, reference = fixed_body("wall"), None, 0.0, "rigid wall", "fixed"
    else:
        x_c = bar.get("contact_x", bar["length"])
        if x_c > bar["length"]:
            raise SceneError(src, "bar.contact_x", f"a section in [0, {bar['length']}] m", x_c)
        t_c = contact_time_estimate(contact_model, mass, velocity)
        model, choice = bar_model(bar, x_c, t_c, src)
        reference = bar["reference"]
        try:
            target = bar_body("bar", model, reference, x_c, -side, _frame_velocity(bar, model, src),
                              modal_damping=bar["damping"])
        except ValueError as exc:
            raise SceneError(src, "bar.reference", f"a frame that suits this bar ({exc})") from None
    impactor = rigid_mass("impactor", mass, velocity, force=d["impactor"]["force"])
    gauges = d["gauges"]
    for i, g in enumerate(gauges):
        if bar is None or g["x"] > bar["length"]:
            raise SceneError(src, f"gauges[{i}].x", "a section of the bar")
    problem = ImpactProblem(impactor, target, Contact(contact_model.model, contact_model.law, contact_model.restitution,
                                                      d["impactor"]["gap"], contact_model.hypothesis))
    return ImpactSetup(problem, model, reference, x_c, side, tuple(g["name"] for g in gauges),
                       np.array([g["x"] for g in gauges], float), requested, choice,
                       modal_time_resolution(model) if model is not None else 0.0)


def impactor_motion(imp: dict, src: str) -> tuple[float, float]:
    """Mass [kg] and approach speed [m/s] of the impactor (a pendulum maps to I/a^2, omega a)."""
    if "pendulum" in imp:
        if "mass" in imp or "velocity" in imp:
            raise SceneError(src, "impactor.pendulum", "either pendulum, or mass and velocity, not both")
        p = imp["pendulum"]
        return p["inertia"] / p["arm"] ** 2, p["omega"] * p["arm"]
    for key in ("mass", "velocity"):
        if key not in imp:
            raise SceneError(src, f"impactor.{key}", "a value (or give impactor.pendulum)")
    return imp["mass"], imp["velocity"]


# ---------------------------------------------------------------- contact


def contact_from(d: dict, src: str):
    """The engine's ``Contact`` (gap filled in later) and the requested restitution, if any."""
    c, name = d["contact"], d["contact"]["law"]
    if name == "rigid":
        return Contact("rigid"), None
    if name == "restitution":
        if "restitution" not in c:
            raise SceneError(src, "contact.restitution", "a coefficient of restitution for law = restitution")
        return Contact("restitution", restitution=c["restitution"], hypothesis=c["hypothesis"]), c["restitution"]
    cls = L.NORMAL_LAWS[name]
    if cls.kind == "elastoplastic":
        return Contact("law", law=_elastoplastic(cls, d, src)), None
    stiffness = c.get("stiffness") or _hertz(d, src, name)
    if cls is L.Linear:
        if "stiffness" not in c:
            raise SceneError(src, "contact.stiffness", "a stiffness [N/m] for the linear law")
        return Contact("law", law=L.Linear(stiffness, c["damping"])), None
    exponent = c.get("exponent", 1.5)
    if cls is L.Hertz:
        return Contact("law", law=L.Hertz(stiffness, exponent)), None
    if "restitution" not in c:
        raise SceneError(src, "contact.restitution", f"the target restitution the {name} law is calibrated to")
    return Contact("law", law=cls(stiffness, exponent, c["restitution"])), c["restitution"]


def _materials(d: dict):
    imp = d["impactor"].get("material", DEFAULT_IMPACTOR)
    if "bar" in d:
        tgt = d["bar"]["material"]
    elif "wall" in d and "material" in d["wall"]:
        tgt = d["wall"]["material"]
    else:
        tgt = {"E": np.inf, "nu": 0.0}
    return imp, tgt


def _hertz(d: dict, src: str, name: str) -> float:
    """Hertz constant of the impactor sphere on the (locally flat) bar or wall [N/m^1.5]."""
    if d["impactor"]["shape"] != "sphere" or "radius" not in d["impactor"]:
        raise SceneError(src, "contact.stiffness", f"a stiffness, or a spherical impactor with a radius, for {name}")
    imp, tgt = _materials(d)
    return hertz_stiffness(effective_modulus(imp["E"], imp["nu"], tgt["E"], tgt["nu"]), d["impactor"]["radius"])


def _elastoplastic(cls, d: dict, src: str):
    c = d["contact"]
    if "yield_stress" not in c:
        raise SceneError(src, "contact.yield_stress", f"the yield stress [Pa] for the {cls.name} law")
    if d["impactor"]["shape"] != "sphere" or "radius" not in d["impactor"]:
        raise SceneError(src, "impactor.radius", f"a sphere radius for the {cls.name} law")
    _, tgt = _materials(d)
    if not np.isfinite(tgt["E"]):
        raise SceneError(src, "wall.material", "a deformable target material for an elastoplastic law")
    return cls.from_material(d["impactor"]["radius"], tgt["E"], tgt["nu"], c["yield_stress"])


def contact_time_estimate(contact: Contact, mass: float, velocity: float) -> float | None:
    """Quasi-static contact duration of the impactor on a rigid target [s] (None: instantaneous or
    governed by the bar, not the law). Used to choose the frequency band the bar must resolve."""
    law = contact.law
    if contact.model != "law" or velocity <= 0:
        return None
    if isinstance(law, L.Linear):
        return np.pi * np.sqrt(mass / law.stiffness)
    stiffness = getattr(law, "stiffness", None) or getattr(law, "K_h", None)
    n = getattr(law, "exponent", 1.5)
    if stiffness is None:
        return None
    # energy balance to the maximum indentation, then the duration integral of a power-law spring
    alpha_m = ((n + 1) * mass * velocity**2 / (2 * stiffness)) ** (1 / (n + 1))
    from scipy.integrate import quad

    integrand = lambda s: 1.0 / np.sqrt(1.0 - s ** (n + 1))  # noqa: E731
    return 2 * alpha_m / velocity * quad(integrand, 0.0, 1.0, limit=200)[0]


# ---------------------------------------------------------------- bar model


def material_section(bar: dict, src: str) -> tuple[Material, Section]:
    m = bar["material"]
    if "rho" not in m:
        raise SceneError(src, "bar.material.rho", "the bar's density [kg/m^3]")
    sec = bar["section"]
    k = {"shear_coefficient": sec["shear_coefficient"]} if "shear_coefficient" in sec else {}
    if sec["type"] == "rectangle":
        section = Section.rectangle(sec["width"], sec["depth"], **k)
    elif sec["type"] == "circle":
        section = Section.circle(sec["diameter"], **k)
    else:
        section = Section(sec["area"], sec["second_moment"], sec["depth"], **k)
    return Material(m["E"], m["rho"], m["nu"]), section


def bar_model(bar: dict, x_c: float, t_c: float | None, src: str) -> tuple[BarModel, str]:
    """The bar's ``BarModel`` and a sentence saying how its size was chosen."""
    material, section = material_section(bar, src)
    args = (bar["theory"], bar["length"], material, section)
    supports = tuple(bar["supports"])
    try:
        if bar["model"] == "fe":
            if "elements" not in bar:
                raise SceneError(src, "bar.elements", "an element count for model = fe")
            model = fe_model(*args, bar["elements"], supports)
            floating = bar["reference"] != "fixed"
            if "modes" in bar:
                model = reduce(model, bar["modes"], drop_rigid=floating)
                return model, f"{bar['elements']} {bar['theory']} elements reduced to {bar['modes']} modes"
            if floating and rigid_mode_count(model.kind, supports):
                # the frame carries the rigid motion: keep every elastic mode, drop the rigid ones
                n = model.n - rigid_mode_count(model.kind, supports)
                return (reduce(model, n, drop_rigid=True),
                        f"{bar['elements']} {bar['theory']} elements ({n} elastic modes: the frame carries the rigid motion)")
            return model, f"{bar['elements']} {bar['theory']} elements (nodal)"
        if ("modes" in bar) == ("tolerance" in bar):
            raise SceneError(src, "bar.modes", "either modes (a count) or tolerance (a truncation error), not both")
        if "modes" in bar:
            return analytic_modes(*args, bar["modes"], supports), f"{bar['modes']} analytic modes (given)"
        return _economical(args, supports, x_c, t_c, bar["tolerance"])
    except SceneError:
        raise
    except ValueError as exc:
        raise SceneError(src, "bar.supports", f"a bar model that exists ({exc})") from None


def _economical(args, supports, x_c: float, t_c: float | None, tol: float) -> tuple[BarModel, str]:
    """Fewest analytic modes that resolve the contact's band and meet the truncation tolerance."""
    reference = analytic_modes(*args, SELECTION_REFERENCE_MODES, supports)
    omega_max = contact_band(t_c) if t_c else None
    sel = select_modes(reference, x_c, omega_max=omega_max, tol=tol)
    n = max(sel.n_modes, 1)
    band = f"band {omega_max:.3g} rad/s from t_c ~ {t_c:.3g} s, " if omega_max else ""
    note = ""
    if args[0] == "euler_bernoulli" and not sel.eb_valid:
        note = f"; Euler-Bernoulli beyond its validity (wavelength {sel.wavelength:.3g} m: use timoshenko)"
    return (analytic_modes(*args, n, supports),
            f"{n} analytic modes chosen for tolerance {tol:g} ({band}truncation error {sel.truncation_error:.2g}){note}")


def _frame_velocity(bar: dict, model: BarModel, src: str):
    v = bar.get("frame_velocity")
    if v is None:
        return None
    nf = frame_columns(model, bar["reference"])
    if len(v) != nf:
        raise SceneError(src, "bar.frame_velocity", f"{nf} values for reference = {bar['reference']}", v)
    return np.asarray(v, float)
