"""ALI3-P through a change of the shape-contact set within a step (``viz3d.ali3p``: the iteration holds the
contacts found at its predictor, ``Collisions.frozen``, and checks them at its converged point).

A sphere (m = 1 kg, R = 0.1 m, Hertz K = 1e7 N/m^1.5, no damping or friction) falls at 2 m/s onto a
ground plane and touches it halfway through a step of 2 ms. Without spin or friction its height
obeys one scalar equation per trapezoidal step, ``m a1 = -m g + K max(R - z1, 0)^1.5`` with
``v1 = 2 (z1 - z0) / h - v0`` and ``a1 = 2 (v1 - v0) / h - a0``, solved here to round-off by
bracketing (scipy's brentq): the oracle of the step. Held contacts are exact for it (the sphere's
lowest point against the plane).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

import viz3d
from viz3d import ali3p
from viz3d.dynamics import body_state
from viz3d.formulation import ALI3P
from viz3d.scene.build import build

M, R, K, G, V0, H = 1.0, 0.1, 1e7, 9.81, 2.0, 2e-3
TOL = 1e-10  # the iteration's tolerance on its updates and |C| [m]


def _sphere(tmp_path, height: float):
    text = f"""[sim]\nt_end = 0.1\ndt = {H}\nformulation = "ali3p"\nintegrator = "trapezoidal"\n
[[bodies]]\nname = "ball"\nshape = {{ type = "sphere", radius = {R} }}\nmass = {M}\ninertia = [0.004, 0.004, 0.004]
position = [0.0, 0.0, {height}]\nvelocity = [0.0, 0.0, {-V0}]\n
[collision]\n[[collision.ground]]\ntype = "plane"\nnormal = [0.0, 0.0, 1.0]
[[collision.pairs]]\ngroups = ["bodies", "ground"]\nlaw = "hertz"\nstiffness = {K}\n"""
    path = tmp_path / "sphere.toml"
    path.write_text(text)
    return build(viz3d.load_scene(path))


def _oracle(z0: float, v0: float, a0: float) -> float:
    """The trapezoidal step's height z1 [m] from (z0, v0, a0)."""
    def residual(z1):
        a1 = 4.0 / H**2 * (z1 - z0 - H * v0) - a0
        return M * a1 + M * G - K * max(R - z1, 0.0) ** 1.5
    return brentq(residual, z0 - 0.05, z0 + 0.05, xtol=1e-16, rtol=4 * np.finfo(float).eps)


def test_a_step_whose_contact_begins_or_ends_within_it_is_solved_in_one_healthy_iteration(tmp_path, monkeypatch):
    """The steps whose contact set changes (it begins at the first step's middle, and ends later)
    converge at once: no second attempt or halving, at most ``REFRESH_ITER`` trial points (the
    method's own bound for a step that keeps its tangent; the iteration that found the contacts
    afresh at every iterate took 31 at the touch-down), each to its tolerance against the oracle."""
    system, state = _sphere(tmp_path, R + 0.5 * V0 * H)
    formulation = ALI3P(alpha=1e9, tol=TOL)
    memory = formulation.init_memory(system, state)
    points = []
    point = ali3p._point
    monkeypatch.setattr(ali3p, "_point", lambda *a: points.append(1) or point(*a))
    changes = 0
    for _ in range(6):
        z0, v0, a0 = state.q[2], state.v[2], memory.v_dot[2]
        points.clear()
        state, memory, status = ali3p.ali3p_step(system, formulation, state, H, memory)
        assert status.ok, status.message
        assert abs(state.q[2] - _oracle(z0, v0, a0)) <= TOL, "mismatch: z1"
        if (z0 < R) != (state.q[2] < R):
            changes += 1
            assert len(points) <= ali3p.REFRESH_ITER, f"{len(points)} trial points at t = {state.t:.4f} s"
    assert changes == 2  # it touched down and left within these steps


def test_held_contacts_are_those_found_where_they_were_held(tmp_path):
    """At the configuration they were taken at, held contacts (``FrozenTouches.at``) are the contacts
    found there, and so are their forces; a little lower the held contact is deeper by the drop."""
    system, state = _sphere(tmp_path, R - 1e-3)
    collisions = system.forces[-1]
    cfg = body_state(system, state.q, state.v, state.chart, state.t)
    held = collisions.frozen(cfg, None)
    found, at = collisions.detect(cfg), held.at(cfg)
    assert found.m == 1
    for name in ("point", "n", "depth"):
        np.testing.assert_allclose(getattr(at, name), getattr(found, name), rtol=0, atol=1e-15, err_msg=name)
    np.testing.assert_allclose(collisions.wrench(cfg, held)[0], collisions.wrench(cfg)[0], rtol=1e-14)
    q = state.q.copy()
    q[2] -= 2e-4
    lower = body_state(system, q, state.v, state.chart, state.t)
    assert held.at(lower).depth[0] == pytest.approx(1e-3 + 2e-4, abs=1e-15)


def test_a_change_of_the_held_contacts_is_named(tmp_path):
    """``frozen_change`` names the pair whose contact began or ended since the contacts were held, and
    nothing where the held contact is the one found (only deeper)."""
    system, state = _sphere(tmp_path, R - 1e-3)
    collisions = system.forces[-1]
    name = f"{'ball'!r}-{collisions.shapes[-1].name!r}"

    def cfg_at(z):
        q = state.q.copy()
        q[2] = z
        return body_state(system, q, state.v * 0.0, state.chart, state.t)

    touching, apart = collisions.frozen(cfg_at(R - 1e-3), None), collisions.frozen(cfg_at(R + 1e-3), None)
    assert collisions.frozen_change(cfg_at(R - 2e-3), touching) == ""
    assert collisions.frozen_change(cfg_at(R + 1e-3), touching) == f"contacts {name} ended"
    assert collisions.frozen_change(cfg_at(R - 1e-3), apart) == f"contacts {name} began"


@pytest.mark.slow  # its compiled signature (ALI3-P with shape contacts) takes ~124 s of CPU to compile cold
def test_the_compiled_steps_hold_the_contacts_as_the_numpy_steps_do(tmp_path):
    """The compiled ALI3-P (``viz3d.kernel.ali3p``, the contacts held in the kernel's packed data:
    ``viz3d.kernel.collisions``' ``hold_piece``) takes the steps of the touch-down and the lift-off as the
    NumPy path does: each height within ``TOL`` of the oracle, the states within ``ali3p_agreement_bound``
    of the NumPy path's, as many evaluations."""
    from kernel_runs import ali3p_agreement_bound, run

    from viz3d.integrators import make_integrator
    from viz3d.simulate import Simulation

    system, state = _sphere(tmp_path, R + 0.5 * V0 * H)
    formulation, n = ALI3P(alpha=1e9, tol=TOL), 6
    sim = Simulation(system, state, make_integrator("trapezoidal"), formulation, H)
    assert sim.kernel_note == "compiled kernel"
    for _ in range(n):
        z0, v0 = sim.state.q[2], sim.state.v[2]
        a0 = sim._own_memory().v_dot[2]
        sim.output_states(1, 1)  # (ali3p_frames, the kernel's run of steps, as growth's runs: one compiled entry)
        assert abs(sim.state.q[2] - _oracle(z0, v0, a0)) <= TOL, f"mismatch: z1 at t = {sim.state.t:.4f} s"
    numpy = run(system, state, formulation, n, H, compiled=False, method="trapezoidal")
    bound = ali3p_agreement_bound(system, state, formulation, n, H)
    diff = np.abs(sim.state.y - numpy.state.y).max()
    assert diff <= bound, f"y after {n} steps: {diff:.2e} > {bound:.2e}"
    assert sim.n_rhs == numpy.n_rhs
