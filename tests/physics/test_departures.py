"""Links that leave a run past the body that hauls them in (``[chain] leave``, ``viz3d.departures``).

References: the hauling force of a chain hauled up slowly is the weight of what still hangs from the
winch (its links and the winch's own mass), so it drops by one link's weight at each departure; the
energy ledger closes across departures; and a departure is a change of model: the positions and the
constraint residual stay as they were, the velocities take the new joint's plastic impulse (a
mass-orthogonal correction onto its rows, its kinetic energy booked as dissipated), and the ledger's
total and dissipated energy together drop by exactly the leaving link's energy (``m g z + m v^2 / 2 + omega . I omega / 2``,
computed here).
"""

from __future__ import annotations

import numpy as np
import pytest

from viz3d.departures import ChainExit, Generation
from viz3d.scene.build import build
from viz3d.scene.load import load_scene
from viz3d.scene.schema import SceneError
from viz3d.simulate import Simulation, run, simulate
from viz3d.scene.build import make_formulation, make_integrator_from

from departing import G, HAUL, LINK, WINCH, L, N


def _haul(write_scene, *overrides):
    return simulate(load_scene(write_scene(HAUL), list(overrides)))


def test_each_link_leaves_once_its_far_joint_passes_the_winch_and_the_hauling_force_drops_by_its_weight(write_scene):
    tr = _haul(write_scene)
    assert tr.status == "ok"
    names = list(tr.body_names)
    gone = np.isnan(tr.position[:, :, 0])
    # the winch hauls 0.05 + 0.5 (t - 0.2) m by t >= 0.2 s: link k's far joint passes the anchor when that
    # is (k + 1) L, checked every 0.01 s: it has left at the first check after that (frames 0.01 s apart)
    for k in range(N):
        b = names.index(f"link{k}")
        t_pass = 0.2 + ((k + 1) * L - 0.05) / 0.5
        if t_pass + 0.02 > tr.t[-1]:
            assert not gone[:, b].any()
            continue
        left = tr.t[np.argmax(gone[:, b])]
        assert t_pass < left <= t_pass + 0.02 + 1e-9, (k, left, t_pass)
        assert gone[tr.t >= left, b].all() and not gone[tr.t < left, b].any()
        assert np.isnan(tr.reaction_force[tr.t >= left, list(tr.joint_names).index(f"link_j{k}")]).all()
    effort = tr.extras["drive_effort"][:, 0]
    hanging = (~gone[:, [names.index(f"link{k}") for k in range(N)]]).sum(axis=1)
    steady = (tr.t > 0.25) & (np.abs(tr.t - 0.51) > 0.03) & (np.abs(tr.t - 0.91) > 0.03)
    weight = (WINCH + LINK * hanging) * G  # hauled at a constant speed: the weight of what still hangs
    np.testing.assert_allclose(effort[steady], weight[steady], rtol=1e-6)
    assert set(hanging[steady]) == {6, 5, 4}


def test_the_ledger_closes_across_departures(write_scene):
    tr = _haul(write_scene)
    e = tr.extras
    work = e["energy_work_in"]
    assert np.isnan(tr.position[-1, :, 0]).sum() == 2
    # once the ramp has ended (t = 0.2 s, where the trapezoidal rule's work integral is off by 4 mJ with or
    # without departures) the effort and speed are constant between departures, whose work the rule integrates
    # exactly: the balance is round-off of the totals (~1e2 J) through both departures
    scale = np.abs(work).max() + np.abs(tr.energy_total).max()
    assert np.abs(e["energy_balance_error"][tr.t > 0.25]).max() < 1e-10 * scale
    kept = _haul(write_scene, "chain.leave=false").extras["energy_balance_error"]
    np.testing.assert_allclose(e["energy_balance_error"], kept, rtol=0, atol=1e-10 * scale)


def test_a_departure_keeps_the_state_on_the_constraints_and_takes_the_links_energy(write_scene):
    """From a state moving on the joints (random velocities projected onto them), link0 leaves: the
    positions keep their values and residual; the velocities satisfy the new system's velocity rows (the
    joint now holding link1 to the winch did not hold before: link0 turned about the winch) and differ
    from the moved ones by a mass-orthogonal correction (the joint's plastic impulse: its change is
    orthogonal in the kinetic-energy metric to every motion the new joints allow), whose kinetic energy
    is booked as dissipated; the ledger's total and dissipated energy together drop by the link's own
    energy, computed here."""
    from viz3d.constraints import constraint_rows
    from viz3d.departures import moved_state
    from viz3d.dynamics import body_state, energies, split_velocity
    from viz3d.events import ledger
    from viz3d.stabilization import project_velocities

    scene = load_scene(write_scene(HAUL))
    system, state = build(scene)
    rule = ChainExit.of(scene, 1e-3)
    gen = Generation(scene, system, np.arange(system.n_bodies), np.arange(len(system.joint_names)))
    rng = np.random.default_rng(3)
    v = project_velocities(system, state.q, state.v + 0.1 * rng.standard_normal(state.v.size), state.chart)
    state = state.replace(v=v, w=np.zeros(system.n_aux))
    link = system.bodies.index("link0")
    gen1, state1 = rule.without(gen, state, link)
    new = gen1.system
    keep = np.array([b for b in range(system.n_bodies) if b != link])
    moved = moved_state(system, new, state, keep)

    def rows(sys_, st):
        return constraint_rows(sys_.joints, body_state(sys_, st.q, st.v, st.chart, st.t))

    def velocity_residual(sys_, st):
        return np.abs(rows(sys_, st).velocity_residual(sys_.joints, *split_velocity(sys_, st.v))).max()

    def K(x):  # kinetic energy of the velocities x on the new system, 1/2 x^T M x
        return energies(new, state1.replace(v=x))[0]

    assert list(new.bodies.names) == [n for n in system.bodies.names if n != "link0"]
    assert "link_j0" not in new.joint_names and "link_j1" in new.joint_names
    np.testing.assert_array_equal(state1.q, moved.q)
    assert np.abs(rows(new, state1).C).max() <= np.abs(rows(system, state).C).max() + 1e-15
    speed = np.abs(state.v).max()
    assert velocity_residual(system, state) < 1e-12 * speed
    assert velocity_residual(new, moved) > 1e-3 * speed        # the new joint's rows, before the impulse
    assert velocity_residual(new, state1) < 1e-12 * speed
    delta = moved.v - state1.v
    for _ in range(3):  # allowed motions: differences of velocities on the new rows
        u = np.subtract(*(project_velocities(new, state1.q, rng.standard_normal(state1.v.size), state1.chart, t=state1.t)
                          for _ in range(2)))
        cross = K(delta + u) - K(delta) - K(u)                 # = delta^T M u
        assert abs(cross) < 1e-10 * (K(delta) + K(u))
    taken = K(moved.v) - K(state1.v)
    assert taken > 0.0
    assert ledger(new, state1).dissipated - ledger(system, state).dissipated == pytest.approx(taken, rel=1e-12)
    cfg = body_state(system, state.q, state.v, state.chart)
    m, I_B = system.bodies.mass[link], system.bodies.inertia[link]
    w_B = cfg.pose.R_WB[link].T @ cfg.twist.W_omega[link]
    energy = m * G * cfg.pose.W_r[link, 2] + 0.5 * m * cfg.twist.W_v[link] @ cfg.twist.W_v[link] + 0.5 * w_B @ I_B @ w_B
    before, after = ledger(system, state), ledger(new, state1)
    drop = (before.total + before.dissipated) - (after.total + after.dissipated)  # what the link carried out
    assert drop == pytest.approx(energy, rel=1e-12, abs=1e-12 * abs(before.total))


def test_departures_do_not_depend_on_how_the_run_is_stepped_or_sampled(write_scene):
    whole = _haul(write_scene)
    coarse = _haul(write_scene, "sim.output_dt=0.05")
    scene = load_scene(write_scene(HAUL))
    system, state = build(scene)
    cfg = scene.data["sim"]
    from viz3d.departures import Departures

    sim = Simulation(system, state, make_integrator_from(cfg), make_formulation(cfg), cfg["dt"],
                     departures=Departures.of(scene, system))
    for _ in range(1200):
        sim.step()
    layout = sim.layout
    assert list(layout.bodies.names) == list(whole.body_names)
    np.testing.assert_array_equal(coarse.position[-1], whole.position[-1])
    names = list(sim.system.bodies.names)
    here = [list(whole.body_names).index(n) for n in names]
    np.testing.assert_allclose(sim.system.split_q(sim.state.q)[0], whole.position[-1, here], rtol=0, atol=1e-12)
    assert [t for t, _ in sim.departures.log] == pytest.approx([0.51, 0.91])


def test_on_a_tilted_guide_each_departure_leaves_the_velocities_on_the_new_joint(write_scene):
    """The winch hauls along a guide tilted 37 deg from the vertical chain, so each link turns as it
    reaches the winch and the point it held moves otherwise than the winch: after each departure the
    velocities satisfy the new system's rows to round-off, the joint's impulse having taken some kinetic
    energy (booked as dissipated), on Baumgarte's formulation, which does not project velocities itself
    (without the impulse its joints opened to 2.2e-3 m after the first departure, against 3.2e-7 m)."""
    from viz3d.constraints import constraint_rows
    from viz3d.departures import Departures
    from viz3d.dynamics import body_state, split_velocity

    scene = load_scene(write_scene(HAUL.replace("axis = [0.0, 0.0, 1.0]", "axis = [0.6, 0.0, 0.8]")),
                       ["sim.formulation=baumgarte", "sim.integrator=rk4", "sim.dt=5e-4"])
    system, state = build(scene)
    cfg = scene.data["sim"]
    sim = Simulation(system, state, make_integrator_from(cfg), make_formulation(cfg), cfg["dt"],
                     departures=Departures.of(scene, system))
    taken = []
    while sim.state.t < 1.2 - 1e-9:
        left, dissipated = len(sim.departures.log), sim.state.w[-2]
        sim.step()
        if len(sim.departures.log) > left:
            s, sy = sim.state, sim.system
            rows = constraint_rows(sy.joints, body_state(sy, s.q, s.v, s.chart, s.t))
            assert np.abs(rows.velocity_residual(sy.joints, *split_velocity(sy, s.v))).max() < 1e-12 * np.abs(s.v).max()
            taken.append(s.w[-2] - dissipated)
    assert len(taken) == 2 and min(taken) > 0.0


@pytest.mark.parametrize("override, key", [
    ("chain.leave_dt=0.0015", "chain.leave_dt"),
    ('chain.attach="ground"', "chain.leave"),
    ("sim.rtol=1e-6", "sim.rtol"),
])
def test_a_chain_that_cannot_leave_is_refused_naming_the_key(write_scene, override, key):
    with pytest.raises(SceneError) as err:
        _haul(write_scene, override)
    assert key in str(err.value)


def test_a_leaving_link_named_by_another_element_is_refused(write_scene):
    text = HAUL + '\n[[forces]]\ntype = "force"\nbody = "link3"\nvalue = [0.0, 0.0, 1.0]\n'
    with pytest.raises(SceneError) as err:
        simulate(load_scene(write_scene(text)))
    assert "forces[0]" in str(err.value) and "link3" in str(err.value)



def test_the_hawse_tension_is_measured_on_the_links_still_in_the_run():
    """After links 0-12 of 19 have left, the remaining links (numbered past the number of bodies) still
    carry the tension output (it used to look for links 0 .. nb - 1 only, and went missing)."""
    from viz3d.stowage import hawse_output

    names = ["windlass", "shackle", "shank", "flukes"] + [f"link{i}" for i in range(13, 19)]
    joints = ["shackle_pin", "crown", "shackle_link"] + [f"link_j{i}" for i in range(13, 19)]
    W_r0 = np.zeros((len(names), 3))
    W_r0[4:, 2] = -0.336 * np.arange(13, 19)
    out = hawse_output({"hawse": [0.0, 0.0, 0.0], "chain": "link"}, names, joints, W_r0)
    assert out is not None and list(out.links) == list(range(4, 10)) and out.half == pytest.approx(0.168)
