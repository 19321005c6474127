"""Headless impact runs: ``simulate_impact(scene) -> Trajectory`` (with the impact fields).

The trajectory keeps the standard fields (bodies "impactor" and "bar" or "wall"; no joints; the
bar's position and velocity are those of its centre of mass) and adds, in ``extras``:
``contact_force`` (n,) [N], ``penetration`` (n,) [m], ``gauge_names`` (ng,), ``gauge_x`` (ng,) [m],
``gauge_strain`` (n, ng), the ledger ``energy_impactor_kinetic``, ``energy_bar_kinetic``,
``energy_bar_strain``, ``energy_contact_elastic``, ``energy_load_potential``, ``energy_dissipated``,
``energy_balance_error`` (n,) [J], ``impactor_velocity`` (n,) [m/s] along the contact normal and
``impactor_velocity_uncertainty``, ``events_t`` / ``events_text``, ``restitution`` (the bodies',
first impact; ``Restitution``), ``restitution_uncertainty``, ``impact_restitution`` (ni,),
``impact_speeds`` (ni, 2), ``restitution_requested`` (nan when none was requested),
``contact_count``, ``contacts`` (k, 4): t_start, approach speed, t_end, separation speed of each
contact as the physics defines it (``viz3d.contact.intervals.physical_contacts``),
``contact_restitution`` (k,), ``contact_breaks_unresolved`` (k,), ``contact_touches_unresolved``
(u, 4), ``contact_events`` (m, 4): every located interval, ``time_resolution``,
``contact_resolution``, ``model_choice``. See docs/trajectory.md.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field

import numpy as np

from viz3d._typing import FloatArray
from viz3d.contact.intervals import impacts, physical_contacts
from viz3d.impact.bodies import centre_of_mass_row
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


def contact_resolution(setup: ImpactSetup) -> float:
    """Time resolution at which contacts are counted [s].

    Kinematic contact on a truncated modal bar opens and closes within the period of the highest
    retained mode (Gibbs ringing): contacts are merged at that resolution
    (``viz3d.contact.intervals.physical_contacts``). Law contacts are resolved at their own time
    scale by the step bound, and restitution impulses are instants by definition: 0 (every
    located contact counts).
    """
    return setup.time_resolution if setup.problem.contact.model == "rigid" else 0.0


@dataclass(frozen=True)
class Restitution:
    """The bodies' restitution, impact by impact (``viz3d.contact.intervals.impacts``).

    Attributes
    ----------
    values : ndarray, shape (ni,)
        ``-v_after / v_before`` of each impact: ``v`` the rigid relative normal velocity of the
        bodies (approaching > 0; for a bar its centre-of-mass motion), before the first contact
        of the impact (before any impulse) and after its last (at the end of the run if that
        contact is still going on).
    speeds : ndarray, shape (ni, 2)
        ``v_before``, ``v_after`` [m/s].
    uncertainty : ndarray, shape (ni,)
        What the model cannot resolve: the change of ``v`` by the instantaneous impulses of a
        kinematic contact on a flexible body, over ``v_before``. In the continuum a rigid mass
        on an elastic bar meets an impedance, not a mass, and its velocity is continuous; the
        jumps the truncated model gives are shorter than its time resolution, their sum bounds
        how far the truncation can have moved the result (0 when the model has no such jumps).
    velocity_uncertainty : float
        The same for the impactor's final velocity [m/s].
    impacts : list of list of int
        Indices of the located contacts of each impact.
    """

    values: FloatArray
    speeds: FloatArray
    uncertainty: FloatArray
    velocity_uncertainty: float
    impacts: list = field(default_factory=list)

    @property
    def first(self) -> float:
        return float(self.values[0]) if len(self.values) else float("nan")


def restitution(setup: ImpactSetup, run: ImpactRun) -> Restitution:
    """The bodies' restitution of every impact of ``run`` (see ``Restitution``)."""
    p = setup.problem
    rigid = np.array(run.contact_rigid, float).reshape(-1, 2)
    if not len(rigid) or not run.samples:
        return Restitution(np.zeros(0), np.zeros((0, 2)), np.zeros(0), 0.0, [])
    last = run.samples[-1]
    v_now = p.rigid_relative_velocity(p.join(last.z1, last.z2, last.z1d, last.z2d, 0.0))
    groups = impacts(rigid[:, 0], rigid[:, 1])
    speeds = np.array([[rigid[g[0], 0], v_now if np.isnan(rigid[g[-1], 1]) else rigid[g[-1], 1]] for g in groups])
    unresolved = p.contact.model == "rigid" and (p.b1.elastic or p.b2.elastic)
    P = np.array([abs(P) for _, P in run.impulses]) if unresolved and run.impulses else np.zeros(0)
    t_P = np.array([t for t, _ in run.impulses]) if len(P) else np.zeros(0)
    starts = np.array([c[0] for c in run.contacts])
    owner = np.searchsorted(starts, t_P, side="right") - 1  # the contact each impulse opened
    mobility = (p.b1.rigid_mobility if p.n1 else 0.0) + (p.b2.rigid_mobility if p.n2 else 0.0)
    du = np.array([mobility * P[np.isin(owner, g)].sum() for g in groups])
    with np.errstate(divide="ignore", invalid="ignore"):
        values = -speeds[:, 1] / speeds[:, 0]
        uncertainty = du / np.abs(speeds[:, 0])
    v_unc = (p.b1.rigid_mobility if p.n1 else 0.0) * float(P.sum())
    return Restitution(values, speeds, uncertainty, v_unc, groups)


def trajectory(scene: Scene, setup: ImpactSetup, geo, run: ImpactRun, status: str, wall: float) -> Trajectory:
    samples = run.samples
    n = len(samples)
    p = setup.problem
    has_bar = setup.bar is not None
    names = ["impactor", "bar" if has_bar else "wall"]
    masses = [p.b1.M[0, 0], setup.bar.mass if has_bar else np.inf]
    gap = scene.data["impactor"]["gap"]
    centre = np.array([geo.impactor_centre(gap, float(s.z1[0])) for s in samples]).reshape(n, 3)
    v1 = np.array([float(s.z1d[0]) for s in samples])
    bar_position, bar_velocity = _target_centre_of_mass(setup, geo, samples)
    position = np.stack([centre, bar_position], axis=1)
    velocity = np.stack([v1[:, None] * geo.n, bar_velocity], axis=1)
    rotation = np.broadcast_to(np.eye(3), (n, 2, 3, 3)).copy()
    led = {k: np.array([s.ledger[k] for s in samples]) for k in (*LEDGER, "total", "total_plus_dissipated")}
    kinetic = led["impactor_kinetic"] + led["bar_kinetic"]
    e0 = p.initial_energy
    rest = restitution(setup, run)
    opens = np.isin(np.arange(len(run.contacts)), [g[0] for g in rest.impacts])
    phys = physical_contacts(run.contacts, contact_resolution(setup), opens)
    extras = {
        "contact_force": np.array([s.force for s in samples]),
        "penetration": np.array([max(s.alpha, 0.0) for s in samples]),
        "impactor_velocity": v1,
        "impactor_velocity_uncertainty": np.array(rest.velocity_uncertainty),
        "gauge_names": np.array(setup.gauge_names, dtype=str),
        "gauge_x": setup.gauge_x,
        "gauge_strain": _gauges(setup, samples),
        **{f"energy_{k}": led[k] for k in LEDGER},
        "energy_balance_error": led["total_plus_dissipated"] - e0,
        "events_t": np.array([t for t, _ in run.events]),
        "events_text": np.array([x for _, x in run.events], dtype=str),
        "restitution": np.array(rest.first),
        "restitution_uncertainty": np.array(rest.uncertainty[0] if len(rest.uncertainty) else np.nan),
        "impact_restitution": rest.values,
        "impact_speeds": rest.speeds,
        "restitution_requested": np.array(np.nan if setup.requested_restitution is None else setup.requested_restitution),
        "contact_count": np.array(phys.count),
        "contacts": phys.rows,
        "contact_restitution": _per_contact(phys.rows),
        "contact_breaks_unresolved": phys.breaks,
        "contact_touches_unresolved": phys.touches,
        "contact_events": np.array(run.contacts, float).reshape(-1, 4),
        "time_resolution": np.array(setup.time_resolution),
        "contact_resolution": np.array(phys.resolution),
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


def _target_centre_of_mass(setup: ImpactSetup, geo, samples) -> tuple[FloatArray, FloatArray]:
    """World centre of mass of the target and its velocity, (n, 3) each [m, m/s]: the bar's
    undeformed centre moved along its deformation direction by ``centre_of_mass_row @ z2``; a
    wall stays at its origin."""
    n = len(samples)
    if setup.bar is None:
        return np.broadcast_to(geo.origin, (n, 3)).copy(), np.zeros((n, 3))
    bar = setup.bar
    row = centre_of_mass_row(bar, setup.reference)
    x_G = bar.static_moment / bar.mass
    u = np.array([row @ s.z2 for s in samples])
    ud = np.array([row @ s.z2d for s in samples])
    return (geo.origin + x_G * geo.axis)[None] + u[:, None] * geo.d, ud[:, None] * geo.d


def _per_contact(contacts) -> np.ndarray:
    """Separation over approach speed of the contact points, per contact (nan if unfinished)."""
    c = np.array(contacts, float).reshape(-1, 4)
    with np.errstate(divide="ignore", invalid="ignore"):
        return c[:, 3] / c[:, 1] if len(c) else np.zeros(0)


def _gauges(setup: ImpactSetup, samples) -> np.ndarray:
    if setup.bar is None or not len(setup.gauge_x):
        return np.zeros((len(samples), 0))
    nf = setup.problem.b2.n - setup.bar.n
    S = setup.bar.strain(setup.gauge_x)
    return np.array([S @ s.z2[nf:] for s in samples]).reshape(len(samples), len(setup.gauge_x))


def _version() -> str:
    from viz3d import __version__

    return __version__
