"""A windlass hauls a chain and its anchor straight up through still water (issue 11's quasi-static
haul, without the hull): a velocity drive on a prismatic joint pulls the head the chain hangs from.

The hanging system translates as one body, so the drive's force is, exactly (written here from
Newton's second law, not from the simulator): the weight of head, chain and anchor, minus the
water's buoyancy on their volumes (all under water), plus their mass times the prescribed
acceleration, plus each body's quadratic drag at the hauling speed.
"""

from __future__ import annotations

import numpy as np
import pytest

import viz3d

G, RHO_W, CD = 9.81, 1025.0, 0.6
N, ELL, R_LINK, RHO = 10, 0.1, 0.01, 7800.0
#: Hauling speed profile v = V (1 - cos(2 pi f t)): smooth from rest (a ramp's corners are kinks the
#: steps would have to land on).
V_HAUL, FREQ = 0.1, 2.5


def _scene(tmp_path, water: bool, method: str = "", dt: str = "4e-4", t_end: float = 0.2):
    path = tmp_path / f"haul{water}{method}{dt}.toml"
    text = _scene_text(water).replace("dt = 4e-4", f"dt = {dt}").replace("t_end = 0.2", f"t_end = {t_end}")
    if method == "ali3p":  # its own trapezoidal steps; positions solved to projection_tol at t_{n+1}
        text = text.replace(f"dt = {dt}", f'dt = {dt}\nformulation = "ali3p"\nintegrator = "trapezoidal"')
    path.write_text(text)
    traj = viz3d.simulate(viz3d.load_scene(path))
    assert traj.status == "ok", traj.status
    return traj


def _scene_text(water: bool) -> str:
    text = f"""[sim]\nt_end = 0.2\ndt = 4e-4\noutput_dt = 0.01\n
[[bodies]]\nname = "head"\nshape = {{ type = "box", extents = [0.1, 0.1, 0.1] }}\nmass = 2.0
inertia = [0.00333, 0.00333, 0.00333]\nposition = [0.0, 0.0, 0.0]\n
[[bodies]]\nname = "anchor"\nshape = {{ type = "sphere", radius = 0.05 }}\ndensity = {RHO}
position = [0.0, 0.0, {-0.05 - N * ELL - 0.05}]\n
[[joints]]\nname = "winch"\ntype = "prismatic"\nbody1 = "head"\nbody2 = "ground"\npoint = [0.0, 0.0, 0.0]
axis = [0.0, 0.0, 1.0]\n
[[joints]]\nname = "shackle"\ntype = "ball"\nbody1 = "anchor"\nbody2 = "link{N - 1}"\npoint = [0.0, 0.0, {-0.05 - N * ELL}]\n
[[drives]]\nname = "windlass"\njoint = "winch"\nmode = "velocity"\nkind = "sine"\nvalue = {V_HAUL}
amplitude = {V_HAUL}\nfrequency = {FREQ}\nphase = {-np.pi / 2}\n
[chain]\nn = {N}\nlink_length = {ELL}\nradius = {R_LINK}\ndensity = {RHO}\nanchor = [0.0, 0.0, -0.05]
direction = [0.0, 0.0, -1.0]\nattach = "head"\n"""
    if water:
        text += f"\n[water]\nlevel = 2.0\ndensity = {RHO_W}\ndrag_coefficient = {CD}\ncells = 27\n"  # all wet: any cells
    return text


def _volumes():
    link = np.pi * R_LINK**2 * ELL + 4 / 3 * np.pi * R_LINK**3
    return np.array([0.1**3] + [link] * N + [4 / 3 * np.pi * 0.05**3])


@pytest.mark.parametrize("water, method", [(False, ""), (True, ""), (False, "ali3p"), (True, "ali3p")])
def test_the_windlass_force_is_the_submerged_weight_plus_inertia_plus_drag(tmp_path, water, method):
    """With ALI3-P too: its positions meet the drive's row at t_{n+1}, its velocities C_v v = -C_t."""
    traj = _scene(tmp_path, water, method)
    V = _volumes()
    m = np.concatenate([[2.0], RHO * V[1:]])
    M = m.sum()
    t, w = traj.t, 2 * np.pi * FREQ
    v, a = V_HAUL * (1 - np.cos(w * t)), V_HAUL * w * np.sin(w * t)
    F = M * (G + a)
    if water:
        A = np.pi * (3 * V / (4 * np.pi)) ** (2 / 3)
        F = F - RHO_W * G * V.sum() + 0.5 * RHO_W * CD * A.sum() * v**2
    effort = traj.extras["drive_effort"][:, 0]
    # the state is RK4's (truncation ~ (w dt)^4 of the motion: 1e-10 here); the force follows it exactly
    np.testing.assert_allclose(effort, F, rtol=1e-8)
    np.testing.assert_allclose(traj.position[:, 0, 2], V_HAUL * (t - np.sin(w * t) / w), atol=1e-9)
    if method != "ali3p":  # (ALI3-P's ledger: test_the_ledger_of_ali3p_converges_at_second_order)
        # the drive's work in and the drag's loss, integrated with the motion: RK4's error ~ (w dt)^4
        x = traj.extras
        np.testing.assert_allclose(x["energy_work_in"] - x["energy_dissipated"], _work_in(t, water), rtol=1e-8,
                                   atol=1e-12)
        np.testing.assert_allclose(x["energy_dissipated"], _drag_loss(t) if water else 0.0, rtol=1e-8, atol=1e-12)
        assert np.abs(x["energy_balance_error"]).max() <= 1e-8 * _work_in(t, water)[-1]


def _drag_loss(t):
    """Energy the water's drag took up to ``t`` (n,) [J]: the integral of sum 0.5 rho C_d A v^3 (every
    body's frontal area A; the system translates at the drive's speed v), by quadrature."""
    from scipy.integrate import quad

    V = _volumes()
    A = np.pi * (3 * V / (4 * np.pi)) ** (2 / 3)
    w = 2 * np.pi * FREQ
    power = lambda s: 0.5 * RHO_W * CD * A.sum() * (V_HAUL * (1 - np.cos(w * s))) ** 3  # noqa: E731
    return np.array([quad(power, 0.0, ti, epsabs=1e-14, epsrel=1e-12)[0] for ti in t])


def _work_in(t, water: bool):
    """Work in [J] of drive and drag up to ``t`` (n,), from Newton's law: the hanging system translates
    as one body, so their forces' sum is M (g + a) minus the buoyancy, and its work is
    (M g - B) z + M v^2 / 2 (the drag's work, paid by the drive, cancels)."""
    V = _volumes()
    M = 2.0 + RHO * V[1:].sum()
    B = RHO_W * G * V.sum() if water else 0.0
    w = 2 * np.pi * FREQ
    v, z = V_HAUL * (1 - np.cos(w * t)), V_HAUL * (t - np.sin(w * t) / w)
    return (M * G - B) * z + 0.5 * M * v**2


def test_the_ledger_of_ali3p_converges_at_second_order(tmp_path):
    """ALI3-P integrates the work in by the trapezoidal rule from the drive's power at the states it
    reaches (index-1 multipliers, lam . C_t): second order, like the motion. The error is taken
    against the closed-form work, at dt and dt / 2: order 2 divides it by 4 (3 allowed: the next
    term is relatively O(h^2) = (w dt)^2 = 1e-4 here). Over the first 0.1 s (a quarter of the speed's
    period, the power growing from 0)."""
    errors = []
    for dt in ("8e-4", "4e-4"):
        traj = _scene(tmp_path, False, "ali3p", dt, t_end=0.1)
        errors.append(np.abs(traj.extras["energy_work_in"] - _work_in(traj.t, False)).max())
        assert np.abs(traj.extras["energy_balance_error"]).max() <= 2 * errors[-1]
    assert errors[1] < errors[0] / 3, errors


def test_a_windlass_over_its_capacity_stops_the_run_with_a_diagnosis(tmp_path):
    """Capacity between the dry hanging weight (86.9 N) and the peak hauling force (weight + M a_max,
    100.8 N): the run stops at the first output frame that needs more, naming the drive, the time
    and the force; the trajectory keeps the frames up to that one."""
    path = tmp_path / "haul_capacity.toml"
    text = _scene_text(water=False).replace('frequency = ', 'capacity = 95.0\nfrequency = ')
    path.write_text(text)
    traj = viz3d.simulate(viz3d.load_scene(path))
    assert traj.status.startswith("t = ") and "drive 'windlass' needs" in traj.status
    assert "over its capacity 95" in traj.status
    effort = np.abs(traj.extras["drive_effort"][:, 0])
    assert 0.0 < traj.t[-1] < 0.2 and np.all(effort[:-1] <= 95.0) and effort[-1] > 95.0
    assert f"t = {traj.t[-1]:.6g} s" in traj.status


@pytest.mark.parametrize("water", [False, True])
def test_a_ramp_whose_corners_fall_on_steps_is_followed_without_drift(tmp_path, water):
    """A speed ramp from 0.05 s to 0.15 s at dt = 2e-4 s: both corners are step boundaries. RK4 meets
    each twice (last stage of one step, first of the next, weights 1/6 each), so taking the mean of
    the two one-sided slopes there cancels; either side alone would leave the speed off by h jump / 6
    = 6.7e-5 m/s for good. What is left is a one-time position offset of order h^2 jump (1e-8 m)."""
    text = _scene_text(water).replace("dt = 4e-4", "dt = 2e-4")
    text = text.replace('kind = "sine"', 'kind = "ramp"').replace(f"value = {V_HAUL}\n", "")
    text = text.replace(f"frequency = {FREQ}\nphase = {-np.pi / 2}\n", "start = 0.05\nduration = 0.1\n")
    path = tmp_path / f"ramp{water}.toml"
    path.write_text(text)
    traj = viz3d.simulate(viz3d.load_scene(path))
    assert traj.status == "ok", traj.status
    assert traj.velocity[-1, 0, 2] == pytest.approx(V_HAUL, abs=1e-12)
    jump = V_HAUL / 0.1
    assert traj.max_constraint_violation < 2e-4**2 * jump
