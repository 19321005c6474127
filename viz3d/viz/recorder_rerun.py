"""Rerun ``.rrd`` recorder: a ``Sink`` that writes a run to a file the rerun viewer replays.

Layout of the recording (timeline ``sim_time``, a duration in seconds; no ``log_time``):

* ``/world`` (static): view coordinates, z up; ``/world/bodies/<name>/mesh`` (static meshes);
  ``/world/<static>`` (static world geometry, e.g. ``/world/posts`` under springs' ground ends);
* ``/world/bodies/<name>``: pose (``Transform3D``), at display rate; ``/world/<deformable>``
  (``Mesh3D`` with the current vertices, e.g. the deformed bar, and ``vertex_colors`` of its surface
  bending stress on the map of ``viz3d.viz.colors``), at display rate;
* ``/world/joints`` (points), ``/world/springs`` (line strips), ``/world/reactions`` (arrows),
  at display rate; ``/world/contacts`` (arrows of the contacts acting, cleared when none act);
* ``/plots/energy/{kinetic,potential,total}``, ``/plots/constraint_violation``,
  ``/plots/reaction_force/<joint>`` (3 components) and ``/plots/<name>`` for extra frame scalars,
  every ``plot_dt`` (default: every step), buffered and written with the columnar API;
* ``/events``: text log (final status, contact events).

The default blueprint (3D view beside the plots) is embedded. The recording is made with the
rerun-sdk version pinned in pyproject.toml (stored as a recording property); open it with the
``rerun`` binary of that same version. Quaternions are converted to rerun's xyzw here only.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from viz3d.frames import Frame, SceneVisuals
from viz3d.rotations import quat_from_matrix
from viz3d.viz.colors import StressColors

#: Buffered plot samples are written to the file (as columns) every this many frames: a
#: 50-link chain's frame holds about 10 kB, so the buffer stays near 20 MB.
FLUSH_EVERY = 2_000
APPLICATION_ID = "viz3d"


def xyzw_from_wxyz(q: np.ndarray) -> np.ndarray:
    """Rerun's quaternion order from ours (docs/notation.md: scalar first)."""
    return np.concatenate([q[..., 1:], q[..., :1]], axis=-1)


class RerunRecorder:
    """Write frames to ``path`` (see the module docstring for the entity layout).

    Parameters
    ----------
    path : str or Path
        ``.rrd`` file to create (parent directories are created).
    display_dt : float, optional
        Simulated time between pose/geometry logs [s]; default the scene's ``display_dt``
        (1/30 s for rigid scenes, ``[display] frame_dt`` for impacts). Plots get every frame it is
        handed, at most one per ``plot_dt`` (``frame_dt`` asks the run for those frames).
    """

    def __init__(self, path: str | Path, display_dt: float | None = None, recording_id: str | None = None):
        self.path = Path(path)
        self.display_dt = display_dt  # None: the scene's (visuals.display_dt)
        self.recording_id = recording_id
        self.rec = None
        self._next_pose_t = self._next_plot_t = -np.inf
        self._buffer: list[Frame] = []
        self._last: Frame | None = None      # the last frame logged
        self._posed_t = -np.inf              # time of the last pose logged [s]
        self._plotted_t = -np.inf            # time of the last plot sample logged [s]
        self._poses: list = []               # (t, W_r, xyzw) not yet sent
        self._left: set[str] = set()         # bodies that have left the run, shown at scale 0 since
        self._joints: list = []              # (joint points, reaction arrows) of those poses, not yet sent
        self._contacts_shown = None          # contact arrows on the timeline now (None: nothing logged yet)

    # ------------------------------------------------------------------ Sink protocol

    @property
    def frame_dt(self) -> float:
        """The frames it needs [s]: every plot sample (``plot_dt``, 0: every step) and pose
        (``display_dt``); of the frames it gets, it draws those ``display_dt`` apart."""
        plot_dt = self.visuals.plot_dt
        return min(plot_dt, self.display_dt) if plot_dt > 0 else 0.0

    def open(self, visuals: SceneVisuals) -> None:
        import rerun as rr

        self.visuals = visuals
        self.display_dt = self.display_dt or visuals.display_dt
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.rec = rr.RecordingStream(APPLICATION_ID, recording_id=self.recording_id or visuals.name)
        self.rec.save(self.path, default_blueprint=self._blueprint())
        self.rec.set_log_time_enabled(False)
        self.rec.send_recording_name(f"{visuals.name} (viz3d, rerun-sdk {rr.__version__})")
        self.rec.send_property("viz3d", rr.AnyValues(scene=visuals.name, rerun_sdk=rr.__version__,
                                                     stress_scale_pa=visuals.stress_scale))  # 0: running maximum
        self._stress_colors = StressColors(visuals.stress_scale)
        self._log_static(visuals)

    def log(self, frame: Frame) -> None:
        if frame.t >= self._next_plot_t - 1e-12:  # plot samples every ``visuals.plot_dt`` (0: every frame)
            self._buffer.append(frame)
            self._next_plot_t, self._plotted_t = frame.t + self.visuals.plot_dt, frame.t
        self._last = frame
        if frame.t >= self._next_pose_t - 1e-12:
            self._log_pose(frame)
            self._next_pose_t, self._posed_t = frame.t + self.display_dt, frame.t
        if len(self._buffer) >= FLUSH_EVERY:
            self._flush_scalars()

    def event(self, t: float, text: str, level: str = "info") -> None:
        import rerun as rr

        self.rec.set_time("sim_time", duration=t)
        lvl = {"info": rr.TextLogLevel.INFO, "warn": rr.TextLogLevel.WARN, "error": rr.TextLogLevel.ERROR}[level]
        self.rec.log("/events", rr.TextLog(text, level=lvl))

    def close(self) -> None:
        if self.rec is None:
            return
        try:
            if self._last is not None and self._last.t > self._posed_t:
                self._log_pose(self._last)  # the last computed state is always on the timeline
            if self._last is not None and self._last.t > self._plotted_t:
                self._buffer.append(self._last)
            self._flush_scalars()
            self.rec.flush()
        finally:
            self.rec.disconnect()  # writes the footer
            self.rec = None

    # ------------------------------------------------------------------ helpers

    def _blueprint(self):
        import rerun.blueprint as rrb

        plots = [rrb.TimeSeriesView(name=title, origin=f"/plots/{origin}") for title, origin in self.visuals.plots]
        return rrb.Blueprint(
            rrb.Horizontal(
                rrb.Spatial3DView(name="Scene", origin="/world"),
                rrb.Vertical(*plots, rrb.TextLogView(name="Events", origin="/events"),
                             row_shares=[3] * len(plots) + [1]),
                column_shares=[3, 2]),
            collapse_panels=True)

    def _log_static(self, visuals: SceneVisuals) -> None:
        import rerun as rr

        rec = self.rec
        rec.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        for b in visuals.bodies:
            if not b.vertices.size:  # a flexible body: recorded as a deformable mesh
                continue
            rec.log(f"/world/bodies/{b.name}/mesh", rr.Mesh3D(
                vertex_positions=b.vertices, triangle_indices=b.faces,
                albedo_factor=[*b.color.tolist(), 255]), static=True)
        for st in visuals.statics:
            rec.log(f"/world/{st.name}", rr.Mesh3D(vertex_positions=st.vertices, triangle_indices=st.faces,
                                                  albedo_factor=[*st.color.tolist(), 255]), static=True)
        for name, color in (("kinetic", [220, 60, 60]), ("potential", [60, 90, 220]), ("total", [30, 30, 30])):
            rec.log(f"/plots/energy/{name}", rr.SeriesLines(colors=color, names=name), static=True)
        rec.log("/plots/constraint_violation", rr.SeriesLines(colors=[150, 60, 180], names="max |C|"), static=True)
        for j in visuals.joint_names:
            rec.log(f"/plots/reaction_force/{j}", rr.SeriesLines(
                colors=[[220, 60, 60], [60, 160, 60], [60, 90, 220]], names=[f"{j} x", f"{j} y", f"{j} z"]), static=True)

    def _log_pose(self, frame: Frame) -> None:
        import rerun as rr

        rec, vis = self.rec, self.visuals
        rec.set_time("sim_time", duration=frame.t)
        # body poses are sent as columns at each flush (one chunk per body, not one per pose: a
        # chunk costs ~1.5 kB, which made 20 of the 27 MB of a 30-s, 23-body recording)
        self._poses.append((frame.t, np.array(frame.W_r, float), xyzw_from_wxyz(quat_from_matrix(frame.R_WB))))
        self._stress_colors.observe(frame.stress.values())
        for d in vis.deformables:
            stress = frame.stress.get(d.name)
            color = ({"albedo_factor": [*d.color.tolist(), 255]} if stress is None
                     else {"vertex_colors": self._stress_colors(stress)})
            rec.log(f"/world/{d.name}", rr.Mesh3D(vertex_positions=frame.deformed[d.name], triangle_indices=d.faces,
                                                  **color))
        if len(frame.contact_points):
            vectors = frame.contact_forces * self._force_scale(frame)
            rec.log("/world/contacts", rr.Arrows3D(origins=frame.contact_points, vectors=vectors, colors=[220, 30, 30]))
            self._contacts_shown = True
        elif self._contacts_shown is not False:  # cleared when contacts stop acting (and at the first pose)
            rec.log("/world/contacts", rr.Clear(recursive=False))
            self._contacts_shown = False
        if len(frame.joint_points):  # sent as columns at each flush, with the body poses
            held = ~np.isnan(frame.joint_points[:, 0])  # (joints that left the run with a body: NaN)
            self._joints.append((frame.joint_points[held],
                                 frame.reaction_force[held] * (vis.length_scale / vis.force_scale)))
        if len(frame.springs):
            rec.log("/world/springs", rr.LineStrips3D(list(frame.springs), radii=0.1 * vis.thickness, colors=[90, 90, 90]))

    def _force_scale(self, frame: Frame) -> float:
        """Metres of arrow per newton: the largest contact force so far draws 3 length scales."""
        peak = float(np.max(np.linalg.norm(frame.contact_forces, axis=1)))
        self._peak_force = max(getattr(self, "_peak_force", 0.0), peak)
        return 3.0 * self.visuals.length_scale / self._peak_force if self._peak_force > 0 else 0.0

    def _flush_poses(self) -> None:
        import rerun as rr

        if not self._poses:
            return
        poses, self._poses = self._poses, []
        times = np.array([p[0] for p in poses])
        t = rr.TimeColumn("sim_time", duration=times)
        W_r, quats = np.array([p[1] for p in poses]), np.array([p[2] for p in poses])
        for i, b in enumerate(self.visuals.bodies):
            if not b.vertices.size or b.name in self._left:
                continue
            here = ~np.isnan(W_r[:, i, 0])
            if here.all():
                self.rec.send_columns(f"/world/bodies/{b.name}", indexes=[t],
                                      columns=rr.Transform3D.columns(translation=W_r[:, i], quaternion=quats[:, i]))
                continue
            # the body left the run (viz3d.departures): its poses up to then, and scale 0 from its first NaN pose
            k = int(np.argmin(here)) + 1
            translation = np.where(here[:k, None], W_r[:k, i], 0.0)
            quaternion = np.where(here[:k, None], quats[:k, i], [0.0, 0.0, 0.0, 1.0])
            self.rec.send_columns(f"/world/bodies/{b.name}", indexes=[rr.TimeColumn("sim_time", duration=times[:k])],
                                  columns=rr.Transform3D.columns(translation=translation, quaternion=quaternion,
                                                                 scale=np.repeat(here[:k, None], 3, axis=1).astype(float)))
            self._left.add(b.name)
        if self._joints:
            self._flush_joints(t)

    def _flush_joints(self, t) -> None:
        """Joint points and reaction arrows of the poses since the last flush, as columns (a
        ``log`` call costs about 0.4 ms: three per pose were most of a rigid scene's recording)."""
        import rerun as rr

        joints, self._joints = self._joints, []
        n = [len(p) for p, _ in joints]
        points, arrows = np.concatenate([p for p, _ in joints]), np.concatenate([a for _, a in joints])
        k = len(points)
        radius = np.full(k, 0.7 * self.visuals.thickness, np.float32)
        self.rec.send_columns("/world/joints", indexes=[t], columns=rr.Points3D.columns(
            positions=points, radii=radius, colors=np.tile([40, 40, 40], (k, 1))).partition(n))
        self.rec.send_columns("/world/reactions", indexes=[t], columns=rr.Arrows3D.columns(
            origins=points, vectors=arrows, colors=np.tile([200, 40, 40], (k, 1))).partition(n))

    def _flush_scalars(self) -> None:
        import rerun as rr

        self._flush_poses()
        if not self._buffer:
            return
        frames, self._buffer = self._buffer, []
        t = rr.TimeColumn("sim_time", duration=np.array([f.t for f in frames]))
        columns = {
            "/plots/energy/kinetic": [f.energy_kinetic for f in frames],
            "/plots/energy/potential": [f.energy_potential for f in frames],
            "/plots/energy/total": [f.energy_total for f in frames],
            "/plots/constraint_violation": [f.constraint_violation for f in frames],
        }
        for key in frames[0].scalars:  # (a joint that left the run with a body: NaN from then on)
            columns[f"/plots/{key}"] = [f.scalars.get(key, np.nan) for f in frames]
        for path, values in columns.items():
            self.rec.send_columns(path, indexes=[t], columns=rr.Scalars.columns(scalars=np.asarray(values, float)))
        reactions = np.array([f.reaction_force for f in frames])
        for j, name in enumerate(self.visuals.joint_names):
            self.rec.send_columns(f"/plots/reaction_force/{name}", indexes=[t],
                                  columns=rr.Scalars.columns(scalars=reactions[:, j]))
