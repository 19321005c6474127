"""Contacts of a scene: their treatment and normal law from the ``[[contacts]]`` keys and the
materials (Hertz constants of a sphere on a locally flat surface, elastoplastic laws from the yield
stress, rate laws calibrated to a target restitution).
"""

from __future__ import annotations

import numpy as np

from viz3d.contact import laws as L
from viz3d.contact.friction import Bristle, RegularizedCoulomb, Stribeck
from viz3d.contact.parameters import effective_modulus, hertz_stiffness
from viz3d.scene.schema import SceneError

#: A body's material when the scene gives none (steel).
DEFAULT_MATERIAL = {"E": 210e9, "nu": 0.3}
#: Ground's material when the scene gives none: rigid.
RIGID = {"E": np.inf, "nu": 0.0}


def contact_law(entry: dict, materials: tuple[dict, dict], src: str, where: str, m_eff: float | None = None):
    """``(model, law, requested restitution)`` of one contact: model ``"law"``, ``"rigid"`` or
    ``"restitution"``; the law (None unless a law); the restitution asked for (None if none).
    ``m_eff`` [kg]: the two bodies' reduced mass, which a linear law calibrated to a target
    restitution needs (None: not known, such a law is refused). Parameters the law's own formulas
    cannot use (overflow, no root in floating point) are refused naming the contact."""
    try:
        return _contact_law(entry, materials, src, where, m_eff)
    except SceneError:
        raise
    except (ValueError, ArithmeticError, RuntimeError) as exc:
        raise SceneError(src, where, f"parameters and materials the {entry['law']} law can be computed from "
                         f"(here: {exc})") from None


def _contact_law(entry: dict, materials: tuple[dict, dict], src: str, where: str, m_eff: float | None = None):
    name = entry["law"]
    if name == "rigid":
        return "rigid", None, None
    if name == "restitution":
        if "restitution" not in entry:
            raise SceneError(src, f"{where}.restitution", "a coefficient of restitution for law = restitution")
        return "restitution", None, entry["restitution"]
    cls = L.NORMAL_LAWS[name]
    if cls.kind == "elastoplastic":
        return "law", _elastoplastic(cls, entry, materials, src, where), None
    stiffness = entry.get("stiffness") or _hertz(entry, materials, src, where)
    if cls is L.Linear:
        if "stiffness" not in entry:
            raise SceneError(src, f"{where}.stiffness", "a stiffness [N/m] for the linear law")
        if "restitution" not in entry:
            return "law", L.Linear(stiffness, entry["damping"]), None
        if entry["damping"] > 0.0:
            raise SceneError(src, f"{where}.damping", "no damping with a target restitution (the linear law's "
                             "dashpot is calibrated to it)", entry["damping"])
        if m_eff is None:
            raise SceneError(src, f"{where}.restitution", "a damping [N s/m] instead: calibrating the linear law to a "
                             "restitution needs the bodies' reduced mass (rigid bodies or ground)", entry["restitution"])
        return "law", L.Linear(stiffness).calibrated(entry["restitution"], m_eff), entry["restitution"]
    exponent = entry.get("exponent", 1.5)
    if cls is L.Hertz:
        return "law", L.Hertz(stiffness, exponent), None
    if "damping_factor" in entry:
        if "restitution" in entry:
            raise SceneError(src, f"{where}.restitution", f"no target restitution with a fixed damping_factor (the "
                             f"{name} law takes one or the other)", entry["restitution"])
        return "law", cls(stiffness, exponent, damping_factor=entry["damping_factor"]), None
    if "restitution" not in entry:
        raise SceneError(src, f"{where}.restitution", f"the target restitution the {name} law is calibrated to, "
                         "or its fixed damping_factor [s/m]")
    return "law", cls(stiffness, exponent, entry["restitution"]), entry["restitution"]


def _hertz(entry: dict, materials, src: str, where: str) -> float:
    """Hertz constant of the sphere on the (locally flat) surface [N/m^1.5]."""
    if entry["radius"] <= 0.0:
        raise SceneError(src, f"{where}.stiffness", f"a stiffness, or a sphere radius > 0, for the {entry['law']} law")
    m1, m2 = materials
    return hertz_stiffness(effective_modulus(m1["E"], m1["nu"], m2["E"], m2["nu"]), entry["radius"])


def _elastoplastic(cls, entry: dict, materials, src: str, where: str):
    if "yield_stress" not in entry:
        raise SceneError(src, f"{where}.yield_stress", f"the yield stress [Pa] for the {cls.name} law")
    if entry["radius"] <= 0.0:
        raise SceneError(src, f"{where}.radius", f"a sphere radius for the {cls.name} law")
    target = materials[1]
    if not np.isfinite(target["E"]):
        raise SceneError(src, f"{where}.material2", "a deformable target material for an elastoplastic law")
    return cls.from_material(entry["radius"], target["E"], target["nu"], entry["yield_stress"])


def materials(entry: dict, bodies: list[dict]) -> tuple[dict, dict]:
    """E and nu of each side: given, a flexible body's, ground rigid, else steel."""
    out = []
    for side in ("1", "2"):
        if f"material{side}" in entry:
            out.append(entry[f"material{side}"])
            continue
        name = entry[f"body{side}"]
        spec = next((b for b in bodies if b["name"] == name), None)
        if spec is None:
            out.append(RIGID)
        elif spec.get("type") == "flexible":
            out.append(spec["material"])
        else:
            out.append(DEFAULT_MATERIAL)
    return out[0], out[1]


def contact_time_estimate(model: str, law, mass: float, speed: float) -> float | None:
    """Quasi-static duration of a contact of ``mass`` [kg] arriving at ``speed`` [m/s] on a rigid
    target [s]; None when it is instantaneous or set by the bodies, not the law. It gives the
    frequency band a flexible body must resolve (``resolve_time``)."""
    if model != "law" or speed <= 0:
        return None
    if isinstance(law, L.Linear):
        return float(np.pi * np.sqrt(mass / law.stiffness))
    stiffness = getattr(law, "stiffness", None) or getattr(law, "K_h", None)
    if stiffness is None:
        return None
    n = getattr(law, "exponent", 1.5)
    # energy balance to the largest indentation, then the duration integral of a power-law spring
    alpha_m = ((n + 1) * mass * speed**2 / (2 * stiffness)) ** (1 / (n + 1))
    from scipy.integrate import quad

    return float(2 * alpha_m / speed * quad(lambda s: 1.0 / np.sqrt(1.0 - s ** (n + 1)), 0.0, 1.0, limit=200)[0])


def friction_law(src: str, entry: dict, where: str, model: str, flexible: bool):
    """The friction law of the contact (or collision pair) at ``where`` (``viz3d.contact.friction``), or
    None for ``friction = "none"``; ``flexible``: a side is a flexible body (refused)."""
    kind = entry["friction"]
    if kind == "none":
        return None
    if model != "law":
        raise SceneError(src, f"{where}.friction", f"'none' with law = {entry['law']!r} (friction needs a force law: its "
                         "normal force)", kind)
    if flexible:
        raise SceneError(src, f"{where}.friction", "'none' on a flexible body (friction acts between rigid bodies "
                         "and ground)", kind)
    if "mu" not in entry:
        raise SceneError(src, f"{where}.mu", "a friction coefficient with friction = " + repr(kind))
    if kind == "coulomb":
        return RegularizedCoulomb(entry["mu"], entry["slip_speed"])
    mu_s = entry.get("mu_static", entry["mu"])
    if mu_s < entry["mu"]:
        raise SceneError(src, f"{where}.mu_static", f"at least mu = {entry['mu']:g}", mu_s)
    if kind == "stribeck":
        return Stribeck(entry["mu"], mu_s, entry["stribeck_speed"], entry["viscous"], entry["slip_speed"])
    if "stick_stiffness" not in entry:
        raise SceneError(src, f"{where}.stick_stiffness", "the bristles' stiffness k_stick [N/m] with friction = 'bristle'")
    if not entry.get("events", False):
        raise SceneError(src, f"{where}.events", "true with friction = 'bristle' (its stick anchor is planted at onset)",
                         entry["events"])
    return Bristle(entry["mu"], mu_s, entry["stick_speed"], entry["stick_stiffness"], entry["stick_damping"],
                   entry["viscous"], entry["stick_alpha"])
