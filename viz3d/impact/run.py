"""Headless impact runs: ``simulate_impact(scene) -> Trajectory`` (with the impact fields).

The trajectory keeps the standard fields (bodies "impactor" and "bar" or "wall"; no joints) and
adds, in ``extras``: ``contact_force`` (n,) [N], ``penetration`` (n,) [m], ``gauge_names`` (ng,),
``gauge_x`` (ng,) [m], ``gauge_strain`` (n, ng), the ledger ``energy_impactor_kinetic``,
``energy_bar_kinetic``, ``energy_bar_strain``, ``energy_contact_elastic``, ``energy_load_potential``,
``energy_dissipated``, ``energy_balance_error`` (n,) [J], ``impactor_velocity`` (n,) [m/s] along
the contact normal, ``events_t`` / ``events_text``, ``restitution`` and ``restitution_requested``
(nan when none was requested), ``contact_count``, ``contacts`` (k, 4): t_start, approach speed,
t_end, separation speed of each contact, ``contact_restitution`` (k,): separation / approach
speed of the contact points per contact, ``model_choice``.
"""

from __future__ import annotations

import json
import time

import numpy as np

from viz3d.impact.build import ImpactSetup, build_impact
from viz3d.impact.display import geometry, impact_frame, impact_visuals
from viz3d.impact.engine import ImpactRun, run_impact
from viz3d.integrators.adaptive import Controller, StepSizeUnderflow
from viz3d.rotations import euler_from_matrix
from viz3d.scene.load import Scene
from viz3d.simulate import with_sim
from viz3d.trajectory import Trajectory

LEDGER = ("impactor_kinetic", "bar_kinetic", "bar_strain", "contact_elastic", "load_potential", "dissipated")


def simulate_impact(scene: Scene, *, t_end: float | None = None, sinks=(), progress: bool = False) -> Trajectory:
    """Run an impact scene (see ``viz3d.impact.spec``) and return its trajectory."""
    scene = with_sim(scene, t_end=t_end)
    setup = build_impact(scene)
    cfg = scene.data["sim"]
    controller = Controller(cfg["rtol"], cfg["atol"], cfg.get("max_step", np.inf))
    geo = geometry(scene, setup)
    amp, gap = scene.data["display"]["amplification"], scene.data["impactor"]["gap"]
    frames = _FrameFeed(setup, geo, gap, amp, sinks)
    frames.open(impact_visuals(scene, setup, geo))
    wall0 = time.perf_counter()
    status = "ok"
    try:
        run = run_impact(setup.problem, cfg["t_end"], cfg["output_dt"], controller, on_sample=frames.feed)
        status = run.status
    except StepSizeUnderflow as exc:
        run, status = frames.partial(), f"stopped: {exc}"
    except KeyboardInterrupt:
        run, status = frames.partial(), f"interrupted at t = {frames.last_t:.6g} s"
    finally:
        frames.close(status, getattr(locals().get("run"), "events", []))
    wall = time.perf_counter() - wall0
    return trajectory(scene, setup, geo, run, status, wall)


class _FrameFeed:
    """Turns samples into frames for the sinks, keeping what was produced so far."""

    def __init__(self, setup, geo, gap, amp, sinks):
        self.setup, self.geo, self.gap, self.amp, self.sinks = setup, geo, gap, amp, list(sinks)
        self.samples, self.last_t = [], 0.0
        self.opened = []

    def open(self, visuals):
        for s in self.sinks:
            s.open(visuals)
            self.opened.append(s)

    def feed(self, sample):
        self.samples.append(sample)
        self.last_t = sample.t
        if self.sinks:
            frame = impact_frame(self.setup, self.geo, sample, self.gap, self.amp)
            for s in self.sinks:
                s.log(frame)

    def partial(self) -> ImpactRun:
        return ImpactRun(self.samples, [], 0, 0, 0)  # events of an interrupted run are lost

    def close(self, status, events):
        for s in self.opened:
            try:
                for t, text in events:
                    s.event(t, text)
                s.event(self.last_t, f"status: {status}", "info" if status == "ok" else "error")
            finally:
                s.close()


def achieved_restitution(setup: ImpactSetup, samples) -> float:
    """``e = -v_rel(after) / v_rel(before)`` of the rigid-body (momentum-weighted) normal velocities
    of the two bodies at the first and the last sample (thesis 4.6: velocities of the centres of
    mass; for a fixed target, the impactor's own rebound)."""
    p = setup.problem

    def v_rel(s):
        v1 = float(p.b1.r @ s.z1d)
        v2 = _rigid_normal_velocity(p.b2, s.z2d) if p.b2.n else 0.0
        return v1 - v2

    before, after = v_rel(samples[0]), v_rel(samples[-1])
    return -after / before if before != 0 else float("nan")


def _rigid_normal_velocity(body, zd) -> float:
    """Normal velocity of the contact point due to the body's rigid (frame) motion, with the frame
    velocity taken from the rigid part of the momentum (so elastic motion does not count)."""
    rigid = body.rigid
    if not rigid.any():
        return 0.0
    momentum = (body.M @ zd)[rigid]
    v_frame = np.linalg.solve(body.M[np.ix_(rigid, rigid)], momentum)
    return float(body.r[rigid] @ v_frame)


def trajectory(scene: Scene, setup: ImpactSetup, geo, run: ImpactRun, status: str, wall: float) -> Trajectory:
    samples = run.samples
    n = len(samples)
    p = setup.problem
    has_bar = setup.bar is not None
    names = ["impactor", "bar" if has_bar else "wall"]
    masses = [p.b1.M[0, 0], setup.bar.mass if has_bar else np.inf]
    gap = scene.data["impactor"]["gap"]
    centre = np.array([geo.impactor_centre(gap, float(s.z1[0])) for s in samples]).reshape(n, 3)
    bar_origin = np.array([geo.origin + _frame_shift(setup, s.z2) * geo.d if has_bar else geo.origin for s in samples])
    position = np.stack([centre, bar_origin.reshape(n, 3)], axis=1)
    v1 = np.array([float(s.z1d[0]) for s in samples])
    velocity = np.zeros((n, 2, 3))
    velocity[:, 0] = v1[:, None] * geo.n
    rotation = np.broadcast_to(np.eye(3), (n, 2, 3, 3)).copy()
    led = {k: np.array([s.ledger[k] for s in samples]) for k in (*LEDGER, "total", "total_plus_dissipated")}
    kinetic = led["impactor_kinetic"] + led["bar_kinetic"]
    e0 = p.initial_energy
    extras = {
        "contact_force": np.array([s.force for s in samples]),
        "penetration": np.array([max(s.alpha, 0.0) for s in samples]),
        "impactor_velocity": v1,
        "gauge_names": np.array(setup.gauge_names, dtype=str),
        "gauge_x": setup.gauge_x,
        "gauge_strain": _gauges(setup, samples),
        **{f"energy_{k}": led[k] for k in LEDGER},
        "energy_balance_error": led["total_plus_dissipated"] - e0,
        "events_t": np.array([t for t, _ in run.events]),
        "events_text": np.array([x for _, x in run.events], dtype=str),
        "restitution": np.array(achieved_restitution(setup, samples) if n > 1 else np.nan),
        "restitution_requested": np.array(np.nan if setup.requested_restitution is None else setup.requested_restitution),
        "contact_count": np.array(len(run.contacts)),
        "contacts": np.array(run.contacts, float).reshape(-1, 4),
        "contact_restitution": _per_contact(run.contacts),
        "model_choice": np.array(setup.model_choice),
    }
    meta = {"viz3d_version": _version(), "integrator": "dopri5 (adaptive, events)", "dt": scene.data["sim"]["output_dt"],
            "rtol": scene.data["sim"]["rtol"], "atol": scene.data["sim"]["atol"], "source": str(scene.path),
            "overrides": list(scene.overrides), "kind": "impact", "conservative": False,
            "formulation": "impact", "rotation": "none"}
    return Trajectory(
        t=np.array([s.t for s in samples]), body_names=np.array(names), mass=np.array(masses, float),
        inertia_body=np.zeros((2, 3, 3)), position=position, rotation=rotation, euler=euler_from_matrix(rotation),
        velocity=velocity, omega=np.zeros((n, 2, 3)), energy_kinetic=kinetic, energy_potential=led["total"] - kinetic,
        energy_total=led["total"], constraint_violation=np.zeros(n), joint_names=np.array([], dtype=str),
        reaction_force=np.zeros((n, 0, 3)), chart_switches=np.zeros(2, int), status=status,
        scene_json=json.dumps({"scene": scene.data, "run": meta}, sort_keys=True), wall_time=wall,
        n_steps=run.n_accepted, n_rhs=run.n_rhs, extras=extras)


def _per_contact(contacts) -> np.ndarray:
    """Separation over approach speed of the contact points, per contact (nan if unfinished)."""
    c = np.array(contacts, float).reshape(-1, 4)
    return c[:, 3] / c[:, 1] if len(c) else np.zeros(0)


def _frame_shift(setup: ImpactSetup, z2) -> float:
    nf = setup.problem.b2.n - setup.bar.n
    return float(z2[0]) if setup.reference == "free" and nf else 0.0


def _gauges(setup: ImpactSetup, samples) -> np.ndarray:
    if setup.bar is None or not len(setup.gauge_x):
        return np.zeros((len(samples), 0))
    nf = setup.problem.b2.n - setup.bar.n
    S = setup.bar.strain(setup.gauge_x)
    return np.array([S @ s.z2[nf:] for s in samples]).reshape(len(samples), len(setup.gauge_x))


def _version() -> str:
    from viz3d import __version__

    return __version__
