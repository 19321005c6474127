"""Still water (``[water]``, ``viz3d.water``) against closed forms:

* a submerged sphere sinks with ``m dv/dt = (m - rho V) g - 1/2 rho C_d pi r^2 v^2``, so
  ``v(t) = v_t tanh(g' t / v_t)``, ``g' = g (1 - rho V / m)``, ``v_t = sqrt(2 (m - rho V) g /
  (rho C_d pi r^2))`` (buoyancy of a fully wet body is exact: its cells' volumes sum to V);
* a floating sphere settles where the spherical cap under the surface, ``pi d^2 (3 r - d) / 3``,
  displaces its mass: the cells approximate the cap, and the draft converges as they shrink;
* without drag, buoyancy is conservative: kinetic + gravity + the cells' wet potential is constant
  to RK4's truncation while a sphere bobs through the surface.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

import viz3d
from viz3d.scene.schema import SceneError
from viz3d.water import volume_cells, wet_fraction, wet_potential

G, RHO_W = 9.81, 1000.0


def _run(tmp_path, text, name="water", t_end=None):
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    traj = viz3d.simulate(viz3d.load_scene(path), t_end=t_end)
    assert traj.status == "ok", traj.status
    return traj


def _ball(r, rho, z, extra=""):
    return (f'[[bodies]]\nname = "ball"\nshape = {{ type = "sphere", radius = {r} }}\ndensity = {rho}\n'
            f"position = [0.0, 0.0, {z}]\n{extra}")


def test_a_sinking_sphere_follows_the_tanh_law_to_its_terminal_speed(tmp_path):
    r, rho, Cd = 0.05, 3000.0, 0.8
    V = 4 / 3 * np.pi * r**3
    m = rho * V
    g1 = G * (1 - RHO_W * V / m)
    vt = np.sqrt(2 * (m - RHO_W * V) * G / (RHO_W * Cd * np.pi * r * r))
    traj = _run(tmp_path, f"[sim]\nt_end = 1.0\ndt = 1e-3\noutput_dt = 0.05\n\n{_ball(r, rho, -10.0)}\n"
                f"[water]\ndensity = {RHO_W}\ndrag_coefficient = {Cd}\n")
    v = -traj.velocity[:, 0, 2]
    expected = vt * np.tanh(g1 * traj.t / vt)
    # RK4 on a smooth scalar ODE at dt = 1e-3 << v_t / g' (0.07 s): truncation ~ (dt g'/v_t)^4 v_t
    np.testing.assert_allclose(v, expected, rtol=0, atol=1e-8 * vt)
    np.testing.assert_allclose(traj.extras["water_submerged_volume"], V, rtol=1e-12)


def _draft(r, m):
    return brentq(lambda d: RHO_W * np.pi * d * d * (3 * r - d) / 3 - m, 0.0, 2 * r, xtol=1e-15)


def test_a_sphere_at_the_draft_of_archimedes_is_held_by_its_cells_buoyancy(tmp_path):
    """At the cap's draft the cells' buoyancy equals the weight up to their quadrature of the cap. The
    bound comes from the grid itself: the cells' volume w differs from c^3 (they share V exactly),
    and only cells straddling the sphere's surface (centre within sqrt(3)/2 c of it) can be in or out
    wrongly, so |V_wet - V_cap| <= |1 - w / c^3| V_cap + (straddling wet cells) c^3. Density 300:
    not half of the water's, where symmetry alone would put it right."""
    from viz3d.dynamics import body_state

    r, rho = 0.1, 300.0
    m = rho * 4 / 3 * np.pi * r**3
    d = _draft(r, m)
    for cells in (512, 4096):
        path = tmp_path / f"float{cells}.toml"
        path.write_text(f"{_ball(r, rho, r - d)}\n[water]\ndensity = {RHO_W}\ncells = {cells}\n")
        system, state = viz3d.build(viz3d.load_scene(path))
        water = next(e for e in system.forces if e.type_name == "water")
        F, tau, _ = water.wrench(body_state(system, state.q, state.v, state.chart, 0.0))
        X, w, c = volume_cells({"type": "sphere", "radius": r}, 4 / 3 * np.pi * r**3, cells)
        wet_band = X[:, 2] < d - r + 0.5 * c  # cells the surface (at z = d - r in sphere axes) may wet
        straddle = np.abs(np.linalg.norm(X, axis=1) - r) <= np.sqrt(3) / 2 * c
        V_cap = m / RHO_W
        bound = abs(1 - w[0] / c**3) + (straddle & wet_band).sum() * c**3 / V_cap
        assert abs(F[0, 2] / (m * G) - 1) <= bound
        np.testing.assert_allclose(tau[0], 0.0, atol=1e-12 * m * G * r)  # on the vertical through the centre


def test_bobbing_through_the_surface_conserves_energy_without_drag(tmp_path):
    r, rho = 0.1, 500.0
    traj = _run(tmp_path, f"[sim]\nt_end = 2.0\ndt = 5e-4\noutput_dt = 0.01\n\n{_ball(r, rho, 0.15)}\n"
                f"[water]\ndensity = {RHO_W}\n")
    E = traj.energy_total
    assert traj.extras["water_submerged_volume"].max() > 0.5 * 4 / 3 * np.pi * r**3  # it does go under
    assert np.abs(E - E[0]).max() < 1e-6 * np.abs(traj.energy_kinetic).max()


def test_the_wet_potential_integrates_the_wet_fraction():
    t = np.linspace(-1.0, 1.0, 20001)
    c = 0.4
    H, f = wet_potential(t, c), wet_fraction(t, c)
    np.testing.assert_allclose(np.gradient(H, t)[1:-1], f[1:-1], atol=1e-4)
    assert H[0] == 0.0 and H[-1] == pytest.approx(1.0)


@pytest.mark.parametrize("shape", [{"type": "box", "extents": [0.3, 0.2, 0.1]}, {"type": "sphere", "radius": 0.1},
                                   {"type": "capsule", "radius": 0.05, "height": 0.2},
                                   {"type": "cylinder", "radius": 0.05, "height": 0.2}])
def test_cells_sum_to_the_volume_and_sit_inside_the_shape(shape):
    X, w, c = volume_cells(shape, 1.234, 512)
    assert w.sum() == pytest.approx(1.234, rel=1e-12)
    assert 200 < len(X) < 1100
    np.testing.assert_allclose(X.mean(axis=0), 0.0, atol=1e-12)  # symmetric grids: the centroid


def test_water_on_a_mesh_body_is_refused(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('[[bodies]]\nname = "a"\nmass = 1.0\ninertia = [1, 1, 1]\nposition = [0, 0, 0]\n'
                    '[water]\nbodies = ["a"]\n')
    with pytest.raises(SceneError) as err:
        viz3d.simulate(viz3d.load_scene(path), t_end=1e-3)
    assert err.value.path == "water.bodies"
