"""Flexible bodies of a scene: the bar model (analytic modes or finite elements, their size given or
chosen from a tolerance) and its floating-frame body, placed in the world.

The bar's frame: origin at its undeformed centre of mass, body ``x`` along ``axis`` (from the end
``x = 0`` at ``position``), body ``y`` along the bending direction (positive deflection ``w``), body
``z = x cross y``; a bending field deflects along body ``y``, an axial field along body ``x``
(``viz3d.flexible.floating``).
"""

from __future__ import annotations

import numpy as np

from viz3d._typing import FloatArray
from viz3d.bodies import FlexibleBody
from viz3d.flexible.bar import BarModel, Material, PointMass, Section, reduce, rigid_mode_count
from viz3d.flexible.fe import fe_model
from viz3d.flexible.floating import E_X, E_Y, floating_bar, with_geometric_stiffening
from viz3d.scene.schema import SceneError

#: Reference model used to choose a mode count from a tolerance: this many analytic modes.
SELECTION_REFERENCE_MODES = 160


def material_section(bar: dict, src: str, where: str) -> tuple[Material, Section]:
    m = bar["material"]
    if "rho" not in m:
        raise SceneError(src, f"{where}.material.rho", "the bar's density [kg/m^3]")
    sec = bar["section"]
    k = {"shear_coefficient": sec["shear_coefficient"]} if "shear_coefficient" in sec else {}
    try:
        if sec["type"] == "rectangle":
            section = Section.rectangle(sec["width"], sec["depth"], **k)
        elif sec["type"] == "circle":
            section = Section.circle(sec["diameter"], **k)
        else:
            section = Section(sec["area"], sec["second_moment"], sec["depth"], **k)
    except (ValueError, ArithmeticError) as exc:  # e.g. a second moment that underflows to 0, or overflows
        raise SceneError(src, f"{where}.section", f"a section with positive area and second moment (here: {exc})") from None
    return Material(m["E"], m["rho"], m["nu"]), section


def point_masses(bar: dict, src: str, where: str) -> tuple[PointMass, ...]:
    out = []
    for i, pm in enumerate(bar["point_masses"]):
        if pm["x"] > bar["length"]:
            raise SceneError(src, f"{where}.point_masses[{i}].x", f"a section in [0, {bar['length']}] m", pm["x"])
        out.append(PointMass(pm["x"], pm["mass"]))
    return tuple(out)


def bar_model(bar: dict, src: str, where: str) -> tuple[BarModel, str]:
    """The bar's ``BarModel`` and a sentence saying how its size was chosen."""
    material, section = material_section(bar, src, where)
    args = (bar["theory"], bar["length"], material, section)
    supports = tuple(bar["supports"])
    masses = point_masses(bar, src, where)
    floating = bar["frame"] == "floating"
    try:
        if bar["model"] == "fe":
            return _fe(bar, args, supports, masses, floating, src, where)
        if ("modes" in bar) == ("tolerance" in bar):
            raise SceneError(src, f"{where}.modes", "either modes (a count) or tolerance (a truncation error), not both")
        if masses:
            raise SceneError(src, f"{where}.point_masses", "finite elements (model = fe) for a bar with point masses")
        if "modes" in bar:
            from viz3d.flexible.modes import analytic_modes  # (a scene with bars only: 8 ms with the selection)

            return analytic_modes(*args, bar["modes"], supports), f"{bar['modes']} analytic modes (given)"
        return _economical(args, supports, bar.get("resolve_x", bar["length"]), bar.get("resolve_time"), bar["tolerance"])
    except SceneError:
        raise
    except (ValueError, RuntimeError, ArithmeticError) as exc:  # e.g. no mode found in floating point
        raise SceneError(src, where, _uncomputable(bar, exc)) from None


def _fe(bar, args, supports, masses, floating, src, where) -> tuple[BarModel, str]:
    if "elements" not in bar:
        raise SceneError(src, f"{where}.elements", "an element count for model = fe")
    model = fe_model(*args, bar["elements"], supports, point_masses=masses, element=bar.get("element"))
    what = f"{bar['elements']} {model.theory} elements"
    if "modes" in bar:
        return reduce(model, bar["modes"], drop_rigid=floating), f"{what} reduced to {bar['modes']} modes"
    n_rigid = rigid_mode_count(model.kind, supports)
    if floating and n_rigid:  # the frame carries the rigid motion: keep every elastic mode, drop the rigid ones
        n = model.n - n_rigid
        return reduce(model, n, drop_rigid=True), f"{what} ({n} elastic modes: the frame carries the rigid motion)"
    return model, f"{what} (nodal)"


def _economical(args, supports, x_c: float, t_c: float | None, tol: float) -> tuple[BarModel, str]:
    """Fewest analytic modes that resolve the contact's band and meet the truncation tolerance."""
    from viz3d.flexible.modes import analytic_modes
    from viz3d.flexible.selection import contact_band, select_modes

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


def bar_frame(bar: dict) -> tuple[FloatArray, FloatArray]:
    """World axis (3,) and the rotation of the bar's frame (3, 3) (columns: axis, bending direction, their cross product)."""
    axis = np.asarray(bar["axis"], float)
    axis = axis / np.linalg.norm(axis)
    bend = np.asarray(bar["bending_direction"], float)
    bend = bend - (bend @ axis) * axis
    if np.linalg.norm(bend) < 1e-12:
        bend = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    bend = bend / np.linalg.norm(bend)
    return axis, np.column_stack([axis, bend, np.cross(axis, bend)])


def _uncomputable(bar: dict, exc: Exception) -> str:
    """What a bar the physics cannot compute should have been."""
    return (f"a bar whose model can be computed (length {bar['length']:g} m, section and material of a physical bar; "
            f"here: {exc})")


def flexible_body(index: int, bar: dict, src: str, where: str) -> tuple[FlexibleBody, str]:
    """The scene's flexible body ``index`` and how its model was chosen."""
    model, choice = bar_model(bar, src, where)
    direction = E_X if model.kind == "axial" else E_Y
    if bar["geometric_stiffening"] and model.kind != "bending":
        raise SceneError(src, f"{where}.geometric_stiffening", "false for a rod: it stiffens bending fields", True)
    try:
        body = floating_bar(model, direction, depth_axis=E_Y, modal_damping=bar["damping"])
        if bar["geometric_stiffening"]:
            body = with_geometric_stiffening(body)
    except (ValueError, ArithmeticError) as exc:  # e.g. inertia invariants out of floating-point range
        raise SceneError(src, where, _uncomputable(bar, exc)) from None
    axis, R0 = bar_frame(bar)
    W_r0 = np.asarray(bar["position"], float) + body.x_G * axis
    try:
        with np.errstate(all="ignore"):
            fb = FlexibleBody(index, body, bar["frame"] == "floating", W_r0, R0, choice, bar["coupling"] == "ked")
            finite = np.isfinite(fb.mass_matrix(R0, np.zeros(fb.n))).all() and np.isfinite(fb.M_ee_inv).all()
    except (ValueError, ArithmeticError) as exc:  # (LinAlgError is a ValueError: M_ee singular)
        raise SceneError(src, where, _uncomputable(bar, exc)) from None
    if not finite:  # sizes whose mass overflows floating point (a 1e102 m deep section)
        raise SceneError(src, where, _uncomputable(bar, "its mass matrix is not finite"))
    return fb, choice


def modal_time_resolution(fb: FlexibleBody) -> float:
    """Period of the bar model's highest mode [s]: nothing shorter is resolved (0 without modes)."""
    omega = np.concatenate([m.frequencies() for m in fb.bar.fields]) if fb.bar.fields else np.zeros(0)
    return float(2.0 * np.pi / omega.max()) if omega.size and omega.max() > 0 else 0.0
