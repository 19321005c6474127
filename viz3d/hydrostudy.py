"""Dam-reservoir studies of hydrodynamics scenes (``[reservoir]``): what ``viz3d run`` computes, saves,
charts and prints, and the reservoir-section frames that ``viz3d view`` and ``--record`` draw.

Everything is a call of ``viz3d.hydro`` on a ``HydroModel`` (``viz3d.scene.hydro``); docs/hydro.md
derives the physics. Units SI; pressures per unit amplitude of wall (or ground) acceleration in the
frequency domain [Pa / (m/s^2)], in pascals in the time domain.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from viz3d._typing import FloatArray
from viz3d.hydro.dam import (
    dam_pressure,
    frequency_response,
    fundamental_frequency,
    pressure_history,
    time_response,
    wetted_shapes,
    windowed_spectrum,
)
from viz3d.hydro.reservoir import (
    RIGID_FORCE_COEFFICIENT,
    Reservoir,
    added_mass,
    dynamic_stiffness,
    pressure,
    westergaard_pressure,
)
from viz3d.hydro.shapes import uniform
from viz3d.scene.hydro import HydroModel

#: Charts written next to the arrays (file name -> what it shows).
CHARTS = {
    "pressure_profiles.png": "p(0, y) per unit wall acceleration at sweep.profile_omegas (seed figs. 10-12)",
    "dynamic_stiffness.png": "Re and Im of S(omega) of the uniform wall motion (seed fig. 13)",
    "crest_response.png": "crest acceleration per unit ground acceleration: empty / incompressible / compressible",
    "time_response.png": "the record and the crest acceleration, per reservoir",
}
#: Amplitude of the harmonic animation: wall (or ground) acceleration [m/s^2].
HARMONIC_AMPLITUDE = 1.0


# ----------------------------------------------------------------------------------------------
# the sweep
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SweepResult:
    """The reservoir's response over the sweep, for the scene's water.

    Attributes
    ----------
    omega : ndarray, shape (w,)
        [rad/s].
    y : ndarray, shape (p,)
        Heights of the profiles [m].
    profile_omegas : ndarray, shape (k,)
        [rad/s].
    profiles : ndarray, shape (k, p), complex
        p(0, y) of the uniform wall motion per unit acceleration [Pa / (m/s^2)].
    westergaard : ndarray, shape (p,)
        Westergaard's parabola, same units.
    stiffness : ndarray, shape (w, m, m), complex
        S(omega) of the wall shapes [N/m per m of dam, per unit phi_i phi_j].
    stiffness_incompressible : ndarray, shape (w, m, m), complex
        The same for incompressible water.
    shape_names : tuple of str, length m
        "uniform" (a rigid wall), or the dam's modes then "uniform".
    profile_terms, stiffness_terms : int
        Series terms used.
    profile_bound, stiffness_bound : float
        Truncation bounds [Pa / (m/s^2)], [N/m].
    cutoffs : ndarray, shape (c,)
        Cut-off frequencies up to the first above the sweep [rad/s] (empty for incompressible water).
    """

    omega: FloatArray
    y: FloatArray
    profile_omegas: FloatArray
    profiles: np.ndarray
    westergaard: FloatArray
    stiffness: np.ndarray
    stiffness_incompressible: np.ndarray
    shape_names: tuple[str, ...]
    profile_terms: int
    profile_bound: float
    stiffness_terms: int
    stiffness_bound: float
    cutoffs: FloatArray


def incompressible(water: Reservoir) -> Reservoir:
    """The same water without compressibility (c = inf, rigid bottom)."""
    return Reservoir(water.density, water.depth)


def wall_shapes(model: HydroModel):
    """The wall shapes S(omega) is computed for, and their names."""
    if model.dam is None:
        return uniform(model.reservoir.depth), ("uniform",)
    names = tuple(f"mode {i + 1}" for i in range(model.dam.n_modes)) + ("uniform",)
    return wetted_shapes(model.dam, model.reservoir.depth), names


def cutoffs_up_to(water: Reservoir, omega_max: float) -> FloatArray:
    """omega_n <= omega_max, and the next one [rad/s]; empty for incompressible water."""
    if not water.compressible:
        return np.zeros(0)
    n = int(np.floor(omega_max * water.depth / (np.pi * water.sound_speed) + 0.5)) + 1
    return water.cutoff_frequencies(n)


def sweep(model: HydroModel) -> SweepResult:
    """Profiles, S(omega) and cut-offs of ``model``'s water."""
    water, h = model.reservoir, model.reservoir.depth
    shapes, names = wall_shapes(model)
    profiles = pressure(water, uniform(h), model.profile_omegas, model.y, rtol=model.rtol)
    S = dynamic_stiffness(water, shapes, model.omega, rtol=model.rtol)
    S_inc = dynamic_stiffness(incompressible(water), shapes, model.omega, rtol=model.rtol)
    return SweepResult(model.omega, model.y, model.profile_omegas, profiles.value, westergaard_pressure(water, model.y),
                       S.value, S_inc.value, names, profiles.n_terms, profiles.bound, S.n_terms, S.bound,
                       cutoffs_up_to(water, float(model.omega.max())))


# ----------------------------------------------------------------------------------------------
# the dam
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DamResult:
    """The dam's response with each reservoir of ``HydroModel.cases``.

    Attributes
    ----------
    cases : tuple of str, length c
    fundamental : ndarray, shape (c,)
        Lowest undamped natural frequency [rad/s] (nan where there is none: an absorbing bottom).
    crest_displacement, crest_acceleration, base_shear : ndarray, shape (c, w), complex
        Per unit ground acceleration [s^2], [-], [kg] over the sweep.
    n_terms : ndarray, shape (c,)
        Series terms of each case (0: empty).
    t, ground_acceleration : ndarray, shape (n,)
        The record [s], [m/s^2] (empty without one).
    crest_displacement_t, crest_acceleration_t, base_shear_t, hydrodynamic_force_t : ndarray, shape (c, n)
        Time responses [m], [m/s^2], [N], [N].
    """

    cases: tuple[str, ...]
    fundamental: FloatArray
    crest_displacement: np.ndarray
    crest_acceleration: np.ndarray
    base_shear: np.ndarray
    n_terms: np.ndarray
    t: FloatArray
    ground_acceleration: FloatArray
    crest_displacement_t: FloatArray
    crest_acceleration_t: FloatArray
    base_shear_t: FloatArray
    hydrodynamic_force_t: FloatArray


def _fundamental(model: HydroModel, water: Reservoir | None) -> float:
    if water is not None and not water.rigid_bottom:
        return float("nan")  # an absorbing bottom damps every mode
    return fundamental_frequency(model.dam, water, rtol=model.rtol)


def dam_study(model: HydroModel) -> DamResult:
    """Crest frequency responses, natural frequencies and (with a record) time responses per case."""
    cases = model.cases()
    responses = [frequency_response(model.dam, water, model.omega, rtol=model.rtol) for water in cases.values()]
    histories = ([time_response(model.dam, water, model.record, rtol=model.rtol) for water in cases.values()]
                 if model.record is not None else [])
    empty = np.zeros((len(cases), 0))

    def stack(items, key):
        return np.array([getattr(r, key) for r in items]) if items else empty

    return DamResult(tuple(cases), np.array([_fundamental(model, w) for w in cases.values()]),
                     stack(responses, "crest_displacement"), stack(responses, "crest_acceleration"),
                     stack(responses, "base_shear"), np.array([r.n_terms for r in responses]),
                     model.record.t if model.record else np.zeros(0),
                     model.record.acceleration if model.record else np.zeros(0),
                     stack(histories, "crest_displacement"), stack(histories, "crest_acceleration"),
                     stack(histories, "base_shear"), stack(histories, "hydrodynamic_force"))


# ----------------------------------------------------------------------------------------------
# a run: arrays, status, files, summary
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class HydroRun:
    """What ``viz3d run`` computes for a hydrodynamics scene."""

    model: HydroModel
    sweep: SweepResult
    dam: DamResult | None
    wall_time: float
    scene: dict

    def arrays(self) -> dict[str, np.ndarray]:
        """Every array by name (the .npz's contents; docs/hydro.md lists them)."""
        s = self.sweep
        out = {
            "omega": s.omega, "y": s.y, "profile_omegas": s.profile_omegas, "pressure": s.profiles,
            "westergaard": s.westergaard, "S": s.stiffness, "S_incompressible": s.stiffness_incompressible,
            "shape_names": np.array(s.shape_names), "cutoffs": s.cutoffs,
            "pressure_n_terms": np.array(s.profile_terms), "pressure_bound": np.array(s.profile_bound),
            "S_n_terms": np.array(s.stiffness_terms), "S_bound": np.array(s.stiffness_bound),
        }
        if self.dam is not None:
            out.update({f"dam_{k}": np.asarray(v) for k, v in vars(self.dam).items()})
        return out

    @property
    def status(self) -> str:
        """"ok", or which arrays hold NaN."""
        bad = [k for k, v in self.arrays().items() if v.dtype.kind in "fc" and np.isnan(v).any()
               and k != "dam_fundamental"]
        return "ok" if not bad else f"failed: NaN in {', '.join(bad)}"


def run(scene) -> HydroRun:
    """Compute a hydrodynamics scene (``viz3d.scene.load.Scene`` of kind "hydro")."""
    from viz3d.scene.hydro import hydro_model

    start = time.perf_counter()
    model = hydro_model(scene)
    result = sweep(model)
    dam = dam_study(model) if model.dam is not None else None
    return HydroRun(model, result, dam, time.perf_counter() - start,
                    {"scene": scene.data, "source": str(scene.path), "overrides": list(scene.overrides)})


def save(result: HydroRun, out: Path) -> list[Path]:
    """Write the arrays to ``out`` (.npz, with the resolved scene as JSON under "scene") and the charts
    into the folder ``out`` without its suffix; returns the paths written."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out, scene=np.array(json.dumps(result.scene)), **result.arrays())
    return [out, *charts(result, out.with_suffix(""))]


def charts(result: HydroRun, folder: Path) -> list[Path]:
    """The study's charts (``CHARTS``) as PNG files in ``folder``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    drawn = [("pressure_profiles.png", _profiles_chart), ("dynamic_stiffness.png", _stiffness_chart)]
    if result.dam is not None:
        drawn.append(("crest_response.png", _crest_chart))
    if result.dam is not None and result.dam.t.size:
        drawn.append(("time_response.png", _time_chart))
    paths = []
    for name, draw in drawn:
        fig = draw(plt, result)
        fig.tight_layout()
        fig.savefig(folder / name, dpi=110)
        plt.close(fig)
        paths.append(folder / name)
    return paths


def _water_label(water: Reservoir) -> str:
    c = f"c {water.sound_speed:g} m/s" if water.compressible else "incompressible"
    bottom = "" if water.rigid_bottom else f", alpha {water.reflection:g}"
    return f"rho {water.density:g} kg/m^3, h {water.depth:g} m, {c}{bottom}"


def _profiles_chart(plt, result: HydroRun):
    s, water = result.sweep, result.model.reservoir
    scale = water.density * water.depth
    fig, axes = plt.subplots(1, len(s.profile_omegas), figsize=(4 * len(s.profile_omegas), 4.5), sharey=True,
                             squeeze=False)
    for ax, omega, p in zip(axes[0], s.profile_omegas, s.profiles):
        ax.plot(p.real / scale, s.y / water.depth, label="Re p")
        ax.plot(p.imag / scale, s.y / water.depth, label="Im p")
        if omega == 0.0:
            ax.plot(s.westergaard / scale, s.y / water.depth, "k--", lw=1, label="Westergaard")
        ax.axvline(0.0, color="0.7", lw=0.5)
        ax.set_title(f"omega = {omega:g} rad/s")
        ax.set_xlabel("p(0, y) / (rho h a)")
        ax.legend(loc="upper right", fontsize=8)
    axes[0][0].set_ylabel("y / h")
    fig.suptitle(f"Pressure on the dam face, uniform wall acceleration a ({_water_label(water)}; "
                 f"{s.profile_terms} terms)", fontsize=9)
    return fig


def _stiffness_chart(plt, result: HydroRun):
    s = result.sweep
    k = s.shape_names.index("uniform")
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(s.omega, s.stiffness[:, k, k].real / 1e9, label="Re S")
    ax.plot(s.omega, s.stiffness[:, k, k].imag / 1e9, label="Im S")
    ax.plot(s.omega, s.stiffness_incompressible[:, k, k].real / 1e9, "k--", lw=1,
            label=f"Re S incompressible = -{RIGID_FORCE_COEFFICIENT:.4f} rho h^2 omega^2")
    for w in s.cutoffs:
        ax.axvline(w, color="0.6", lw=0.6, ls=":")
    finite = s.stiffness[:, k, k][np.isfinite(s.stiffness[:, k, k])]
    span = float(np.abs(finite).max(initial=1.0)) / 1e9
    ax.set_ylim(-1.1 * span, 1.1 * span)
    ax.set_xlabel("omega [rad/s]")
    ax.set_ylabel("S [GN/m per m of dam]")
    ax.set_title(f"Dynamic stiffness of a uniform wall motion ({s.stiffness_terms} terms); cut-offs dotted", fontsize=9)
    ax.legend(fontsize=8)
    return fig


def _crest_chart(plt, result: HydroRun):
    d, s = result.dam, result.sweep
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for name, a, w1 in zip(d.cases, d.crest_acceleration, d.fundamental):
        label = f"{name} (omega_1 {w1:.3f} rad/s)" if np.isfinite(w1) else name
        ax.plot(s.omega, np.abs(a), lw=1.2, label=label)
    for w in s.cutoffs:
        ax.axvline(w, color="0.6", lw=0.6, ls=":")
    ax.set_xlabel("omega [rad/s]")
    ax.set_ylabel("|total crest acceleration / ground acceleration|")
    dam = result.model.dam
    ax.set_title(f"Dam H {dam.height:g} m, {dam.n_modes} modes, zeta {dam.damping_ratio:g}; water h "
                 f"{result.model.reservoir.depth:g} m", fontsize=9)
    ax.legend(fontsize=8)
    return fig


def _time_chart(plt, result: HydroRun):
    d = result.dam
    fig, axes = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    axes[0].plot(d.t, d.ground_acceleration, "k", lw=0.6)
    axes[0].set_ylabel("a_g [m/s^2]")
    axes[0].set_title(f"{Path(result.model.record.name).name}: ground and crest acceleration", fontsize=9)
    for name, a in zip(d.cases, d.crest_acceleration_t):
        axes[1].plot(d.t, a, lw=0.7, label=name)
    axes[1].set_xlabel("t [s]")
    axes[1].set_ylabel("crest acceleration [m/s^2]")
    axes[1].legend(fontsize=8)
    return fig


def summary(result: HydroRun, paths: list[Path]) -> str:
    """What ``viz3d run`` prints for a hydrodynamics scene."""
    model, s = result.model, result.sweep
    water = model.reservoir
    k = s.shape_names.index("uniform")
    S = s.stiffness[:, k, k]
    finite = np.isfinite(S)
    cut = ", ".join(f"{w:.4g}" for w in s.cutoffs) + " rad/s" if s.cutoffs.size else "none (incompressible)"
    base = ", ".join(f"{p[0].real / (water.density * water.depth):.4f}"
                     + (f"{p[0].imag / (water.density * water.depth):+.4f}j" if p[0].imag else "")
                     for p in s.profiles)
    lines = [
        f"scene       {model.name} ({result.scene['source']})",
        f"reservoir   {_water_label(water)}",
        f"cut-offs    {cut}",
        f"series      pressure {s.profile_terms} terms (bound {s.profile_bound:.2g} Pa per m/s^2); "
        f"S {s.stiffness_terms} terms (bound {s.stiffness_bound:.2g} N/m); rtol {model.rtol:g}",
        f"profiles    p(0, 0) / (rho h a) at omega = {', '.join(f'{w:g}' for w in s.profile_omegas)} rad/s: {base}",
        f"S uniform   min Re S {S[finite].real.min() / 1e9:.4g} GN/m, max Im S {S[finite].imag.max() / 1e9:.4g} GN/m "
        f"over [0, {s.omega.max():g}] rad/s ({len(s.omega)} frequencies); static added mass "
        f"{RIGID_FORCE_COEFFICIENT:.4f} rho h^2 incompressible",
        *(_dam_lines(result) if result.dam is not None else []),
        f"wall time   {result.wall_time:.3f} s",
        f"status      {result.status}",
        *(f"wrote       {p}" for p in paths),
    ]
    return "\n".join(lines)


def _dam_lines(result: HydroRun) -> list[str]:
    d, s = result.dam, result.sweep
    omega1 = " / ".join(f"{w:.4f}" if np.isfinite(w) else "none" for w in d.fundamental)
    peaks = "; ".join(f"{name} {np.abs(a).max():.3g} at {s.omega[np.argmax(np.abs(a))]:.3g} rad/s"
                      for name, a in zip(d.cases, d.crest_acceleration))
    lines = [f"dam         omega_1 {omega1} rad/s ({' / '.join(d.cases)}); terms {', '.join(map(str, d.n_terms))}",
             f"crest FRF   peak |a_crest / a_g|: {peaks}"]
    if d.t.size:
        record = result.model.record
        lines.append(f"record      {Path(record.name).name}: {record.duration:g} s, dt {record.dt:g} s, PGA "
                     f"{record.pga:.4g} m/s^2")
        for name, u, a, v in zip(d.cases, d.crest_displacement_t, d.crest_acceleration_t, d.base_shear_t):
            lines.append(f"  {name:<15} max |u_crest| {1e3 * np.abs(u).max():.3f} mm, max |a_crest| "
                         f"{np.abs(a).max():.3f} m/s^2, max |base shear| {np.abs(v).max() / 1e6:.3f} MN")
    return lines


# ----------------------------------------------------------------------------------------------
# frames of the reservoir section (viewer and recorder)
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SectionFrames:
    """The pressure on the reservoir's vertical section and the dam's face, frame by frame.

    Attributes
    ----------
    t : ndarray, shape (f,)
        [s].
    x, y : ndarray, shapes (n_x,), (n_y,)
        Section grid [m] (``ViewSpec``).
    pressure : ndarray, shape (f, n_x, n_y)
        Hydrodynamic pressure [Pa].
    face_y : ndarray, shape (m,)
        Heights of the face samples, 0 to the dam's (wall's) height [m].
    face : ndarray, shape (f, m)
        Face displacement towards the reservoir at ``face_y`` [m] (total for a rigid wall,
        relative to the ground for a dam).
    crest : ndarray, shape (f,)
        Crest (wall) displacement [m].
    shear : ndarray, shape (f,)
        Base shear of the dam, or the water's force on a rigid wall [N].
    n_terms : int
    label : str
        What is drawn (frequency or record, water).
    """

    t: FloatArray
    x: FloatArray
    y: FloatArray
    pressure: FloatArray
    face_y: FloatArray
    face: FloatArray
    crest: FloatArray
    shear: FloatArray
    n_terms: int
    label: str


def _water_name(water: Reservoir) -> str:
    return "compressible" if water.compressible else "incompressible"


def water_for(model: HydroModel, compressible: bool) -> Reservoir:
    """The scene's water, or the same water incompressible."""
    return model.reservoir if compressible else incompressible(model.reservoir)


def face_heights(model: HydroModel) -> FloatArray:
    """Heights of the drawn face: the view's grid, continued up the dam above the water [m]."""
    top = model.dam.height if model.dam is not None else model.reservoir.depth
    step = float(model.view.y[1] - model.view.y[0])
    return np.linspace(0.0, top, max(2, int(round(top / step)) + 1))


def _grid(model: HydroModel) -> tuple[FloatArray, FloatArray]:
    """Section points flattened x-major: X, Y (n_x n_y,)."""
    X, Y = np.meshgrid(model.view.x, model.view.y, indexing="ij")
    return X.ravel(), Y.ravel()


def harmonic_frames(model: HydroModel, omega: float, compressible: bool = True,
                    rtol: float | None = None) -> SectionFrames:
    """One cycle of Re(X e^{j omega t}) for a wall (ground) acceleration of HARMONIC_AMPLITUDE at ``omega``."""
    water, rtol = water_for(model, compressible), rtol or model.view.rtol
    X, Y = _grid(model)
    w = np.array([float(omega)])
    face_y = face_heights(model)
    if model.dam is None:
        p = pressure(water, uniform(water.depth), w, Y, X, rtol=rtol)
        u = -1.0 / omega**2 if omega > 0 else 0.0  # displacement of a unit acceleration e^{j omega t}
        face, crest = np.full(face_y.size, u + 0j), u + 0j
        shear = added_mass(water, uniform(water.depth), w, rtol=rtol).value[0, 0, 0]
    else:
        p = dam_pressure(model.dam, water, w, Y, X, rtol=rtol)
        r = frequency_response(model.dam, water, w, rtol=rtol)
        face = model.dam.bar.displacement(face_y) @ r.modal[0]
        crest, shear = r.crest_displacement[0], r.base_shear[0]
    n = model.view.frames_per_cycle
    phase = np.exp(1j * 2.0 * np.pi * np.arange(n) / n)
    t = 2.0 * np.pi * np.arange(n) / n / omega if omega > 0 else np.arange(n) / n

    def cycle(amplitude):
        return HARMONIC_AMPLITUDE * np.real(np.multiply.outer(phase, np.asarray(amplitude)))

    return SectionFrames(t, model.view.x, model.view.y, cycle(p.value[0]).reshape(n, model.view.x.size, -1),
                         face_y, cycle(face), cycle(crest), cycle(shear), p.n_terms,
                         f"omega {omega:g} rad/s, {_water_name(water)}")


def earthquake_frames(model: HydroModel, compressible: bool = True,
                      rtol: float | None = None) -> SectionFrames:
    """The record's time response every ``view.frame_dt``, the pressure low-passed at pi / frame_dt."""
    if model.dam is None or model.record is None:
        raise ValueError("an earthquake needs a [dam] and a [ground_motion]")
    water, rtol, view, record = water_for(model, compressible), rtol or model.view.rtol, model.view, model.record
    X, Y = _grid(model)
    _, p, n_terms = pressure_history(model.dam, water, record, Y, X, omega_max=np.pi / view.frame_dt,
                                     rtol=rtol)
    history = time_response(model.dam, water, record, rtol=model.rtol)
    spectrum = windowed_spectrum(model.dam, record)
    modal = spectrum.response(frequency_response(model.dam, water, spectrum.omega, rtol=model.rtol).modal)
    every = max(1, int(round(view.frame_dt / record.dt)))
    pick = np.arange(0, record.acceleration.size, every)
    face_y = face_heights(model)
    face = modal[pick] @ model.dam.bar.displacement(face_y).T
    return SectionFrames(record.t[pick], view.x, view.y, p[pick].reshape(pick.size, view.x.size, -1), face_y, face,
                         history.crest_displacement[pick], history.base_shear[pick], n_terms,
                         f"{Path(record.name).name}, {_water_name(water)}")
