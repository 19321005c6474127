"""Rerun ``.rrd`` recording of a hydrodynamics scene (``viz3d run/view SCENE --record FILE.rrd``).

Layout (no ``log_time``; the SDK version is a recording property, as in ``recorder_rerun``):

* timeline ``sim_time`` (duration): ``/world/section`` (``Mesh3D`` of the reservoir section, vertex
  colours by pressure, one per frame), ``/world/dam`` (the dam or wall, deflection amplified),
  ``/plots/crest_displacement`` [m] and ``/plots/base_shear`` [N] (a rigid wall: the water's force);
* static: ``/world`` (z up), ``/world/water_surface``;
* timeline ``omega_mrad_s`` (sequence, omega in mrad/s): ``/curves/S/real``, ``/curves/S/imag``
  (S(omega) of the uniform wall motion [N/m]) and, with a dam, ``/curves/crest_acceleration/<case>``
  (|a_crest / a_g|);
* timeline ``height_mm`` (sequence, y in mm): ``/profiles/omega_<w>/real``, ``.../imag``
  (p(0, y) / (rho h a) at each profile frequency).

Select the ``omega_mrad_s`` or ``height_mm`` timeline in the rerun viewer to see the curves.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from viz3d.hydrostudy import HydroRun, SectionFrames
from viz3d.viz.hydro_visuals import WATER_COLOR, geometry, pressure_colors, pressure_scale
from viz3d.viz.recorder_rerun import APPLICATION_ID

#: Sequence timelines of the curves: omega in mrad/s, heights in mm.
OMEGA_TIMELINE, HEIGHT_TIMELINE = "omega_mrad_s", "height_mm"


def write_recording(path: str | Path, result: HydroRun, frames: SectionFrames) -> Path:
    """Write ``frames`` (the section over time) and ``result``'s curves to ``path``; returns it."""
    import rerun as rr

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=result.model.name)
    rec.save(path, default_blueprint=_blueprint(result))
    rec.set_log_time_enabled(False)
    rec.send_recording_name(f"{result.model.name} (viz3d, rerun-sdk {rr.__version__})")
    rec.send_property("viz3d", rr.AnyValues(scene=result.model.name, rerun_sdk=rr.__version__, frames=frames.label))
    try:
        _log_frames(rec, result, frames)
        _log_curves(rec, result)
        rec.flush()
    finally:
        rec.disconnect()  # writes the footer
    return path


def _log_frames(rec, result: HydroRun, frames: SectionFrames) -> None:
    import rerun as rr

    geo = geometry(result.model, frames)
    rec.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    rec.log("/world/water_surface", rr.Mesh3D(vertex_positions=geo.surface_vertices, triangle_indices=geo.surface_faces,
                                              albedo_factor=WATER_COLOR.tolist()), static=True)
    p_max = pressure_scale(frames)
    for k, t in enumerate(frames.t):
        rec.set_time("sim_time", duration=float(t))
        rec.log("/world/section", rr.Mesh3D(vertex_positions=geo.section_vertices, triangle_indices=geo.section_faces,
                                            vertex_colors=pressure_colors(frames.pressure[k].ravel(), p_max)))
        rec.log("/world/dam", rr.Mesh3D(vertex_positions=geo.dam_at(frames.face[k]), triangle_indices=geo.dam_faces,
                                        albedo_factor=[170, 170, 165, 255]))
    times = rr.TimeColumn("sim_time", duration=frames.t)
    for name, values in (("crest_displacement", frames.crest), ("base_shear", frames.shear)):
        rec.send_columns(f"/plots/{name}", indexes=[times], columns=rr.Scalars.columns(scalars=np.asarray(values, float)))


def _series(rec, entity: str, timeline: str, keys: np.ndarray, values: np.ndarray) -> None:
    import rerun as rr

    finite = np.isfinite(values)
    rec.send_columns(entity, indexes=[rr.TimeColumn(timeline, sequence=keys[finite])],
                     columns=rr.Scalars.columns(scalars=values[finite]))


def _log_curves(rec, result: HydroRun) -> None:
    s, water = result.sweep, result.model.reservoir
    omega_keys = np.round(1e3 * s.omega).astype(np.int64)
    k = s.shape_names.index("uniform")
    _series(rec, "/curves/S/real", OMEGA_TIMELINE, omega_keys, s.stiffness[:, k, k].real)
    _series(rec, "/curves/S/imag", OMEGA_TIMELINE, omega_keys, s.stiffness[:, k, k].imag)
    if result.dam is not None:
        for name, a in zip(result.dam.cases, result.dam.crest_acceleration):
            _series(rec, f"/curves/crest_acceleration/{name}", OMEGA_TIMELINE, omega_keys, np.abs(a))
    height_keys = np.round(1e3 * s.y).astype(np.int64)
    for omega, p in zip(s.profile_omegas, s.profiles):
        for part in ("real", "imag"):
            _series(rec, f"/profiles/{profile_name(omega)}/{part}", HEIGHT_TIMELINE, height_keys,
                    getattr(p, part) / (water.density * water.depth))


def profile_name(omega: float) -> str:
    """Entity name of a profile: ``omega_20`` (``omega_2p5`` for 2.5 rad/s)."""
    return f"omega_{omega:g}".replace(".", "p")


def _blueprint(result: HydroRun):
    import rerun.blueprint as rrb

    plots = [rrb.TimeSeriesView(name="Crest displacement [m]", origin="/plots/crest_displacement"),
             rrb.TimeSeriesView(name="Base shear [N]" if result.dam else "Force of the water [N]", origin="/plots/base_shear"),
             rrb.TimeSeriesView(name="S(omega) [N/m] (timeline omega_mrad_s)", origin="/curves"),
             rrb.TimeSeriesView(name="p(0, y) / (rho h a) (timeline height_mm)", origin="/profiles")]
    return rrb.Blueprint(rrb.Horizontal(rrb.Spatial3DView(name="Dam and reservoir", origin="/world"), rrb.Vertical(*plots),
                                        column_shares=[3, 2]), collapse_panels=True)
