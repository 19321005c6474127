"""The flexible slider-crank (scenes/flexible_slider_crank.toml, Simeon's benchmark data) against
references the engine did not write:

* Simeon's equations of motion as the Test Set for IVP Solvers prints them (crank.f, transcribed in
  simeon_slider_crank.py): the transcription reproduces the test set's printed reference solution at
  t = 0.1 s, and the engine's midspan deflection history equals that of Simeon's model driven by the
  scene's ramp (axially rigid: the engine's bar; and with Simeon's axial field, within the bound the
  ratio of bending to axial frequencies sets);
* rigid limit: the slider follows the closed form x = r cos(theta) + sqrt(L^2 - r^2 sin^2(theta)) to the
  integrator's tolerance, and the rod's deflection falls as 1 / E;
* energy: the drive's work (quadrature of effort x crank rate) equals the change of kinetic + strain
  energy (no gravity in the benchmark);
* convergence: the midspan deflection with n cubic or quintic elements (two modes kept) approaches that
  of the exact pinned-pinned modes at the orders the elements' theory gives.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from simeon_slider_crank import INI1, REFERENCE_T01, SimeonCrank, constant_speed, ini1_state, smooth_ramp

import viz3d
from viz3d.dynamics import body_state
from viz3d.scene.build import make_controller, make_formulation, make_integrator_from

from conftest import SCENES

SCENE = SCENES / "flexible_slider_crank.toml"
CRANK, ROD = 0.15, 0.30
OMEGA, RAMP = 150.0, 0.05          # the scene's drive: [rad/s], [s]
E_STEEL = 2.0e11
ACCURATE = ("sim.rtol=1e-10", "sim.atol=1e-13")
#: Ramp, then more than two crank turns at speed (sampled every 5 ms).
RUN, SAMPLE = 0.15, 5e-3


def _simulation(*overrides: str, t_end: float, dt: float):
    """(system, initial state, viz3d.Simulation) of the scene with ``overrides``, stepping ``dt`` [s]."""
    scene = viz3d.load_scene(SCENE, (f"sim.t_end={t_end}", f"sim.dt={dt}", *overrides))
    system, state = viz3d.build(scene)
    cfg = scene.data["sim"]
    sim = viz3d.Simulation(system, state, make_integrator_from(cfg), make_formulation(cfg), cfg["dt"],
                           controller=make_controller(cfg))
    return system, state, sim


def _midspan(system):
    """Index of the rod among the flexible bodies and its displacement shapes at midspan (n_e,)."""
    rod = system.bodies.names.index("rod")
    i = next(j for j, f in enumerate(system.bodies.flexible) if f.index == rod)
    return i, system.bodies.flexible[i].bar.fields[0].displacement(np.array([ROD / 2]))[0]


@functools.lru_cache(maxsize=None)
def _midspan_history(*overrides: str, t_end: float = RUN, dt: float = SAMPLE):
    """Times (n,) [s] and the rod's transverse deflection at midspan relative to its chord (n,) [m]."""
    system, state, sim = _simulation(*ACCURATE, *overrides, t_end=t_end, dt=dt)
    states = [state] + [sim.step() for _ in range(round(t_end / dt))]
    i, phi = _midspan(system)
    return np.array([s.t for s in states]), np.array([phi @ system.elastic_q(s.q)[i] for s in states])


# ---- Simeon's model: the printed reference and the engine ------------------------------------------

#: Bound on the transcription's error at t = 0.1 s in the test set's own measure, the mixed error
#: |y - y_ref| / (1 + |y_ref|) (its "scd" digits are -log10 of it; the R driver uses atol / rtol = 1).
#: INI1 carries 9 significant digits, so it is consistent only to ~5e-10 (x3 on 0.45 m), an inconsistency
#: the test set's index-2 solver and our index-1 integration treat differently; the undamped vibration
#: neither damps nor grows it. Bound: 60 x that resolution, 3e-8 (7.5 digits; measured: 7.8e-9 on the
#: slider's velocity, 4e-12 on q1, the midspan deflection).
PRINTED_MIXED_ERROR = 3e-8


@pytest.mark.slow
def test_transcription_reproduces_the_printed_reference():
    y = SimeonCrank(constant_speed, axial=True).solve(ini1_state(), np.array([0.0, 0.1]), rtol=1e-12,
                                                      atol=1e-15)[-1]
    ours = np.concatenate([[OMEGA * 0.1], y[:6], [INI1[7]], y[6:]])
    mixed = np.abs(ours - REFERENCE_T01) / (1.0 + np.abs(REFERENCE_T01))
    assert mixed.max() <= PRINTED_MIXED_ERROR, mixed


def _simeon_from_rest(axial: bool, t: np.ndarray) -> np.ndarray:
    """Simeon's midspan deflection q1 [m] at t, the mechanism at rest at the dead centre at t = 0 and
    the crank driven by the scene's ramp."""
    n = 4 if axial else 2
    y0 = np.zeros(2 * (2 + n))
    y0[1] = CRANK + ROD
    return SimeonCrank(smooth_ramp(OMEGA, RAMP), axial=axial).solve(y0, t)[:, 2]


#: Engine against Simeon's axially rigid model: both integrated to rtol 1e-10 (DOP853 at 1e-11), the
#: same equations (two sine modes, Euler-Bernoulli, chord frame, point-mass slider), so they agree to a
#: few hundred times the integrators' tolerance of the peak (the error of the vibration phase grows
#: over the ~30 periods of the run): 1e-6 of the peak (measured: 8e-8).
RIGID_AXIS_RTOL = 1e-6
#: Simeon's axial field changes the lateral response by terms of the order of the squared ratio of the
#: first bending frequency (1277 rad/s) to the first axial one (the rod fixed at the crank pin, the
#: slider's mass M3 = M2 / 2 at its end: k L tan(k L) = 2, k L = 1.0769, 18096 rad/s), relative to the
#: peak: 5.0e-3 (measured: 1.9e-4). It bounds the quasi-static response the smooth ramp leaves; a free
#: vibration's phase would drift by that ratio x omega_1 t (from crank.f's INI1, with its 0.44 m/s lateral
#: rate, the axially rigid and the full model differ by 17 % of the peak at t = 0.1 s).
AXIAL_RTOL = (1277.0 / 18096.0) ** 2


@pytest.mark.slow
def test_midspan_deflection_matches_simeons_model():
    t, w = _midspan_history()
    peak = np.abs(w).max()
    rigid_axis, axial = _simeon_from_rest(False, t), _simeon_from_rest(True, t)
    assert np.abs(w - rigid_axis).max() <= RIGID_AXIS_RTOL * peak, (np.abs(w - rigid_axis).max(), peak)
    assert np.abs(w - axial).max() <= AXIAL_RTOL * peak, (np.abs(w - axial).max(), peak)
    # the run reaches the benchmark's quasi-steady deflections (about 1.6 mm at 150 rad/s)
    assert 1e-3 < peak < 3e-3, peak


# ---- rigid limit ---------------------------------------------------------------------------------

def _stiff_run(factor: float, t_end: float = 0.08, dt: float = 1e-3):
    """Crank angle (n,) [rad], slider position x (n,) [m] and midspan deflection (n,) [m] of the scene
    with the rod's E x ``factor`` and its lowest mode, at the scene's tolerance (rtol 1e-8)."""
    system, state, sim = _simulation("bodies.rod.modes=1", f"bodies.rod.material.E={E_STEEL * factor}",
                                     t_end=t_end, dt=dt)
    states = [state] + [sim.step() for _ in range(round(t_end / dt))]
    slider = system.bodies.names.index("slider")
    i, phi = _midspan(system)
    theta, x, w = [], [], []
    for s in states:
        c = body_state(system, s.q, s.v, s.chart, s.t)
        values = {n: v for js in system.joint_sets if hasattr(js, "coordinates")
                  for n, v in zip(js.names, js.coordinates(c)[0][:, 0])}
        theta.append(values["main_bearing"])
        x.append(c.pose.W_r[slider][0])
        w.append(phi @ system.elastic_q(s.q)[i])
    return np.array(theta), np.array(x), np.array(w)


#: Stiffness factors of the rigid-limit runs (E x factor, one mode): first frequencies 7000 and 22000 rad/s.
STIFF = (30.0, 300.0)
#: The slider's position follows from the constraints alone (the chord is the rigid rod: the bending bar
#: is axially rigid and w = 0 at the pins), so its error is the constraint violation, which the scene's
#: checks bound by 1e-8 m (measured: 1e-14).
RIGID_ATOL = 1e-8


@pytest.mark.slow
def test_stiff_rod_moves_as_the_rigid_slider_crank():
    peaks = []
    for factor in STIFF:
        theta, x, w = _stiff_run(factor)
        rigid = CRANK * np.cos(theta) + np.sqrt(ROD**2 - CRANK**2 * np.sin(theta) ** 2)
        np.testing.assert_allclose(x, rigid, atol=RIGID_ATOL)
        peaks.append(np.abs(w).max())
    # the deflection is quasi-static, w ~ F / k ~ 1 / E, up to the dynamic amplification
    # 1 / (1 - (OMEGA / omega_1)^2): 4.6e-4 and 4.6e-5 here, and the vibration the smooth ramp leaves
    # (its spectrum at omega_1 T > 350: negligible). 1 % as the bound (measured ratio: 10.013).
    assert peaks[0] / peaks[1] == pytest.approx(STIFF[1] / STIFF[0], rel=1e-2), peaks


# ---- energy --------------------------------------------------------------------------------------

def _simpson(t, p):
    """Cumulative composite Simpson integral of p(t) at t[0::2] (len(t) odd)."""
    return np.concatenate([[0.0], np.cumsum((t[2::2] - t[:-2:2]) / 6 * (p[:-2:2] + 4 * p[1:-1:2] + p[2::2]))])


def _simpson_and_error(t, p):
    """Cumulative Simpson integral of p(t) at t[0::2] and Richardson's estimate of its error, the
    difference from Simpson on every other sample / 15 (O(dt^4)); len(t) - 1 a multiple of 4."""
    w = _simpson(t, p)
    return w, np.abs(w[0::2] - _simpson(t[0::2], p[0::2])).max() / 15


@functools.lru_cache(maxsize=None)
def _drive_run(t_end: float = 0.1, dt: float = 5e-5):
    """The scene's trajectory sampled every ``dt`` [s] (ramp and three crank half-turns at speed; the
    drive's power, with the rod's vibration at 1277 rad/s in it, resolved for Simpson's rule)."""
    scene = viz3d.load_scene(SCENE, (f"sim.t_end={t_end}", f"sim.dt={dt}", f"sim.output_dt={dt}", *ACCURATE))
    return viz3d.simulate(scene)


def _crank_rate(traj) -> np.ndarray:
    names = list(traj.extras["joint_coordinate_names"])
    return traj.extras["joint_coordinate_rates"][:, names.index("main_bearing/angle")]


@pytest.mark.slow
def test_drive_work_equals_the_energy_change():
    traj = _drive_run()
    work, quad_err = _simpson_and_error(traj.t, traj.extras["drive_effort"][:, 0] * _crank_rate(traj))
    energy = (traj.energy_kinetic + traj.energy_potential)[0::2]     # potential: the rod's strain energy only
    change = energy - energy[0]
    scale = np.abs(work).max()
    # quadrature error (estimated) + integration error (rtol 1e-10 on energies of this scale) + a margin of 10
    # (measured: 2.5e-8 J of 97 J; the rod's strain energy peaks at 0.17 J; 2 % modal damping: 8e-3 J)
    assert np.abs(change - work).max() <= 10 * (quad_err + 1e-9 * scale), (np.abs(change - work).max(), quad_err, scale)
    assert traj.extras["energy_strain"].max() > 0.0


#: The drive's torque against Simeon's multiplier of the crank's constraint (axially rigid model, the
#: same ramp): the same equations integrated to rtol 1e-10 and 1e-11, so 1e-6 of the peak torque, as
#: for the deflection (measured: 2.5e-9).
TORQUE_RTOL = 1e-6


@pytest.mark.slow
def test_drive_torque_matches_simeons_multiplier():
    traj = _drive_run()
    crank = smooth_ramp(OMEGA, RAMP)
    model = SimeonCrank(crank, axial=False)
    y0 = np.zeros(8)
    y0[1] = CRANK + ROD
    torque = []
    for t, y in zip(traj.t, model.solve(y0, traj.t)):
        phi1, phi1_dot, _ = crank(t)
        _, lam = model.accelerations(t, np.array([phi1, y[0], y[1]]), np.array([phi1_dot, y[4], y[5]]), y[2:4], y[6:])
        torque.append(-lam[2])       # Simeon: M w + G^T lam = f, the crank's constraint row G = (1, 0, ...)
    # the engine's effort is about the bearing's axis +y, the crank turns about -y (Simeon's +phi1)
    effort = -traj.extras["drive_effort"][:, 0]
    torque = np.array(torque)
    assert np.abs(effort - torque).max() <= TORQUE_RTOL * np.abs(torque).max(), np.abs(effort - torque).max()


# ---- convergence with elements -------------------------------------------------------------------

def _final_midspan(*overrides: str, t_end: float = 0.03) -> float:
    """The rod's midspan deflection [m] at t_end (the ramp's first 0.03 s), one output step."""
    return float(_midspan_history(*overrides, t_end=t_end, dt=t_end)[1][-1])


#: Two modes kept by every model (the FE runs keep their two lowest modes). Theory: an element of degree
#: p for a fourth-order operator (m = 2) has eigenvalue errors O(h^(2 (p + 1 - m))): h^4 for the cubic
#: Hermite, h^8 for the quintic; the deflection's error at a fixed time is that of the phase of the
#: vibration, of the same order. Measured (1, 2, 4, 8 cubic; 1, 2, 4 quintic elements): slopes 7.5, 5.8,
#: 5.4 and 10.5, 7.9 (pre-asymptotic above the theory). Asserted: 7/8 of the theory's order over each
#: halving of h, on meshes whose errors stay well above the integration error (rtol 1e-10: ~1e-13 m).
@pytest.mark.slow
@pytest.mark.parametrize("element, meshes, order", [("hermite", (2, 4, 8), 4.0), ("quintic", (1, 2), 8.0)])
def test_midspan_deflection_converges_with_elements(element, meshes, order):
    reference = _final_midspan()
    errors = [abs(_final_midspan("bodies.rod.model=fe", f"bodies.rod.element={element}",
                                 f"bodies.rod.elements={n}") - reference) for n in meshes]
    slopes = -np.diff(np.log(errors)) / np.diff(np.log(meshes))
    assert np.all(slopes >= 7 / 8 * order), (errors, slopes)
