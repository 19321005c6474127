"""The anchor hoist (scenes/anchor_hoist.toml, issue 11) against references computed here from the
scene's masses and geometry, not from the simulator's forces:

* while the anchor hangs free, the windlass's force is the hanging weight (anchor, shackle, hanging
  links) carried round the pocket's rim by the capstan law ``T_in = T_out exp(mu theta)`` (theta the
  chain's turn at the rim), plus the weight of the chain in the pipe along it, the windlass head's
  own weight along its guide, and all masses times the ramp's acceleration; the chain sways in the
  pipe (a few per cent), so one-second means are compared, within 3 per cent;
* the flukes rest on their outer stop (eq. 3.50) and never pass either stop by more than twice the
  static deflection of their own weight's moment (a suddenly applied load at most doubles it);
* the full hauls (slow): the default ship seats, a pocket narrower than the flukes jams (its windlass
  stalls at its capacity, the run ending cleanly).

The tests of RK4's own behaviour there (its ledger against the step,
its ledger watch at too long a step) set RK4 (``systems.HOIST_RK4``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import viz3d
from systems import HOIST_RK4

SCENE = Path(__file__).resolve().parents[2] / "scenes" / "anchor_hoist.toml"
G = 9.81


@pytest.fixture(scope="module")
def early():
    traj = viz3d.simulate(viz3d.load_scene(SCENE, ["sim.t_end=2.0", "sim.output_dt=0.01"]))
    assert traj.status == "ok", traj.status
    return traj


def _reference_effort(traj, k: int) -> float:
    """Quasi-static windlass force [N] at frame ``k`` (module docstring), without the inertia."""
    d = traj.scene["scene"]
    names = list(traj.body_names)
    m = dict(zip(names, traj.mass))
    links = [n for n in names if n.startswith("link")]
    z = np.array([traj.rotation[k, names.index(n)][:, 2] for n in links])      # each link's axis, downward
    hanging = z[:, 2] < -math.cos(math.radians(3.0))
    W_hang = G * (m["shank"] + m["flukes"] + m["shackle"] + sum(m[n] for n, h in zip(links, hanging) if h))
    d1 = z[~hanging].mean(axis=0)
    d1 /= np.linalg.norm(d1)
    theta = math.acos(float(-d1[2]))                  # the turn from the pipe's stretch to vertical
    W_pipe = G * sum(m[n] for n, h in zip(links, hanging) if not h) * float(-d1[2])
    a = np.array(next(j for j in d["joints"] if j["name"] == "windlass_guide")["axis"])
    return W_hang * math.exp(d["ship"]["mu"] * theta) + W_pipe + m["windlass"] * G * float(a[2])


@pytest.mark.parametrize("window", [(0.5, 1.5), (1.0, 2.0)])
def test_hauling_force_is_the_hanging_weight_round_the_rim_plus_the_pipe_chain(early, window):
    traj, ship = early, early.scene["scene"]["ship"]
    t, effort = traj.t, traj.extras["drive_effort"][:, 0]
    w = np.flatnonzero((t >= window[0]) & (t <= window[1]))
    accel = np.where(t[w] < ship["ramp_time"], ship["hauling_speed"] / ship["ramp_time"], 0.0)
    ref = np.array([_reference_effort(traj, k) for k in w]) + traj.mass.sum() * accel
    assert traj.extras["collision_contacts"][w].min() >= 1            # the chain bears on the rim
    assert effort[w].mean() == pytest.approx(ref.mean(), rel=0.03)


def test_the_flukes_rest_on_their_stop_within_its_compliance(early):
    traj, d = early, early.scene["scene"]
    ship, names = d["ship"], list(early.body_names)
    i = list(traj.extras["joint_coordinate_names"]).index("crown/angle")
    q = traj.extras["joint_coordinates"][:, i]                          # 0 on the outer stop
    stop = next(f for f in d["forces"] if f["type"] == "joint_stop")
    f = names.index("flukes")
    pin = np.array(next(j for j in d["joints"] if j["name"] == "crown")["point"])
    lever = np.linalg.norm(np.cross(traj.position[0, f] - pin, [0.0, 0.0, 1.0]))   # horizontal arm of the weight
    static = traj.mass[f] * G * lever / stop["stiffness"]
    assert static > 0.0
    assert np.max(q) <= 2.0 * static                                    # never through the outer stop
    assert np.min(q) >= -2.0 * math.radians(ship["stop_angle"]) - 2.0 * static
    assert np.mean(q[len(q) // 4:]) >= 0.0                               # leaning on it, not swinging off


@pytest.mark.slow
def test_the_default_ship_seats_its_anchor():
    traj = viz3d.simulate(viz3d.load_scene(SCENE))
    x = traj.extras
    assert traj.status == "ok", traj.status
    assert x["stowage_verdict"] == "seated", (x["stowage_reason"], x["stowage_position_error"], x["stowage_angle_error"])
    capacity = 1.5 * 42.5 * (traj.scene["scene"]["ship"]["chain_diameter"] * 1e3) ** 2
    assert 0.0 < x["stowage_peak_force"] < capacity
    # the windlass stopped settle_time after seating (frames checked every 0.5 s), before sim.t_end
    settle = traj.scene["scene"]["stowage"]["settle_time"]
    assert x["stowage_time"] + settle - 1e-9 <= traj.t[-1] <= x["stowage_time"] + settle + 0.5 + 1e-9
    assert traj.t[-1] < traj.scene["scene"]["sim"]["t_end"]


@pytest.mark.slow
def test_a_pocket_narrower_than_the_flukes_jams():
    """The windlass (a limited drive) stalls at its capacity: the run ends there cleanly, jammed."""
    traj = viz3d.simulate(viz3d.load_scene(SCENE, ["ship.pocket_width=1.6"]))
    x = traj.extras
    assert traj.status == "ok", traj.status
    assert x["stowage_verdict"] == "jammed", x["stowage_reason"]
    assert "stalled at its capacity" in x["stowage_reason"]
    capacity = next(d for d in traj.scene["scene"]["drives"] if d["name"] == "windlass")["capacity"]
    assert x["stowage_peak_force"] == capacity and np.abs(traj.extras["drive_effort"]).max() <= capacity


def test_the_chain_tension_at_the_hawse_is_the_windlass_force_less_the_chain_above_it(early):
    """The saved tension where the chain enters the hull (the joint nearest the hawse) differs from
    the windlass's force by the weight of the links above that joint and of the windlass head, along
    the pipe (the same one-second means and 3 per cent of the force as the haul)."""
    traj, d = early, early.scene["scene"]
    names = list(traj.body_names)
    m = dict(zip(names, traj.mass))
    tension, effort = traj.extras["stowage_hawse_tension"], traj.extras["drive_effort"][:, 0]
    w = np.flatnonzero((traj.t >= 0.5) & (traj.t <= 1.5))
    a = np.array(next(j for j in d["joints"] if j["name"] == "windlass_guide")["axis"])
    gap = []
    for k in w:
        ends = np.array([traj.position[k, names.index(f"link{i}")] - 0.5 * d["chain"]["link_length"]
                         * traj.rotation[k, names.index(f"link{i}")][:, 2] for i in range(d["chain"]["n"])])
        above = int(np.argmin(np.linalg.norm(ends, axis=1)))          # links 0 .. above-1 are above it
        gap.append(G * float(a[2]) * (m["windlass"] + sum(m[f"link{i}"] for i in range(above))))
    assert np.all(tension[w] < effort[w])
    assert (effort[w] - tension[w]).mean() == pytest.approx(np.mean(gap), abs=0.03 * effort[w].mean())


@pytest.mark.slow
def test_the_energy_ledger_closes_as_the_step_shrinks():
    """Windlass work in = kinetic + potential change + losses (the flukes' stop damping, the contacts'
    damping and friction, booked as negative work in by their elements): the ledger's balance error is
    the integrator's, so it falls with the step. The contact laws' kinks (onsets, friction's
    stick-slip) lower RK4's order to about 1-2 here (measured 4.8 J -> 1.5 J over 0.5 s, of 950 J of
    work): halving dt must divide it by at least 2 (order 1)."""
    errors = []
    for dt in (5e-4, 2.5e-4):
        traj = viz3d.simulate(viz3d.load_scene(SCENE, [*HOIST_RK4, f"sim.dt={dt}", "sim.t_end=0.5", "sim.output_dt=0.01"]))
        assert traj.status == "ok", traj.status
        x = traj.extras
        assert x["energy_work_in"][-1] > 0.0 and traj.extras["collision_contacts"].max() > 0
        errors.append(float(np.abs(x["energy_balance_error"]).max()))
    assert errors[1] < errors[0] / 2, errors


def test_the_overload_time_outlasts_an_impact_of_the_anchor_on_the_hull():
    """ship.overload_time (0.25 s) against Hertz's contact time (viz3d.contact.exact.hertz_impact) of the
    9300 kg anchor, or one simulated link, striking the hull with the scene's Flores stiffness at speeds
    from 1 mm/s to the 0.15 m/s hauling speed and above: every impact is over within a fifth of it (the
    contact time grows as v^-1/5: 11 ms for the anchor at 0.15 m/s, 31 ms at 1 mm/s), so an overload
    held that long is no impact's spike."""
    from viz3d.contact.collision import Collisions
    from viz3d.contact.exact import hertz_impact
    from viz3d.scene.build import build

    scene = viz3d.load_scene(SCENE)
    system, _ = build(scene)
    col = next(e for e in system.forces if isinstance(e, Collisions))
    K = max(pl.law.stiffness for pl in col.laws)
    ship = scene.data["ship"]
    masses = [ship["anchor_mass"], float(system.bodies.mass[system.bodies.names.index("link0")])]
    longest = max(hertz_impact(K, m, np.inf, v).contact_time for m in masses for v in (1e-3, 0.15, 0.5))
    assert longest < 0.2 * ship["overload_time"]


def test_a_step_that_does_not_resolve_the_contacts_fails_on_its_ledger_and_gives_no_verdict():
    """On RK4 at twice its step for the hoist the links' Hertz impacts on the rim (about 1 ms long at 1 m/s:
    viz3d.contact.exact.hertz_impact) last one or two steps: the energy ledger stops balancing within
    the first frames and the run stops with its diagnosis; no verdict is drawn from it (a stowage
    study counts it as failed, not as jammed or seated)."""
    from viz3d.stowagestudy import StowageMeasure

    scene = viz3d.load_scene(SCENE, [*HOIST_RK4, "sim.dt=1e-3", "sim.t_end=0.5"])
    traj = viz3d.simulate(scene)
    assert "the energy ledger does not balance" in traj.status, traj.status
    assert "stowage_verdict" not in traj.extras
    assert StowageMeasure()(scene)["outcome"] == "failed"
