"""Links that leave a run past the body that hauls them in (``[chain] leave``, ``viz3d.departures``).

References: the hauling force of a chain hauled up slowly is the weight of what still hangs from the
winch (its links and the winch's own mass), so it drops by one link's weight at each departure; the
energy ledger closes across departures; and a departure is a change of model, not of state: the
constraints hold as before, and the ledger's total drops by exactly the leaving link's energy
(``m g z + m v^2 / 2 + omega . I omega / 2``, computed here from the trajectory).
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
    scene = load_scene(write_scene(HAUL))
    system, state = build(scene)
    rule = ChainExit.of(scene, 1e-3)
    gen = Generation(scene, system, np.arange(system.n_bodies), np.arange(len(system.joint_names)))
    rng = np.random.default_rng(3)
    state = state.replace(v=state.v + 0.1 * rng.standard_normal(state.v.size))  # moving, off the velocity rows
    link = system.bodies.index("link0")
    gen1, state1 = rule.without(gen, state, link)
    from viz3d.constraints import constraint_rows
    from viz3d.dynamics import body_state
    from viz3d.events import ledger

    def residual(sys_, st):
        return np.abs(constraint_rows(sys_.joints, body_state(sys_, st.q, st.v, st.chart)).C).max()

    assert residual(gen1.system, state1) <= residual(system, state) + 1e-15
    assert list(gen1.system.bodies.names) == [n for n in system.bodies.names if n != "link0"]
    assert "link_j0" not in gen1.system.joint_names and "link_j1" in gen1.system.joint_names
    cfg = body_state(system, state.q, state.v, state.chart)
    m, I_B = system.bodies.mass[link], system.bodies.inertia[link]
    w_B = cfg.pose.R_WB[link].T @ cfg.twist.W_omega[link]
    energy = m * G * cfg.pose.W_r[link, 2] + 0.5 * m * cfg.twist.W_v[link] @ cfg.twist.W_v[link] + 0.5 * w_B @ I_B @ w_B
    drop = ledger(system, state).total - ledger(gen1.system, state1).total
    assert drop == pytest.approx(energy, rel=1e-12, abs=1e-12 * abs(ledger(system, state).total))


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
