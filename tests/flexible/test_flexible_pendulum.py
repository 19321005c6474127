"""The flexible pendulum (scenes/flexible_pendulum.toml): an aluminium strip pinned at x = 0 by a ball
joint, released from rest horizontal, on a floating frame with pinned-free modes. Checked against
references the engine did not write:

* stiff limit: with E x 100 and x 1000 the frame swings as the rigid cuboid pinned at the centre of its
  end face (Euler's equations about a fixed point, scipy DOP853 at rtol 1e-11), planar and spherical;
  the deviation is within the first-order estimate below and falls like 1 / E;
* quasi-static limit: with critical modal damping the tip deflection follows, mode by mode, the
  closed-form quasi-static response of the swinging beam (pinned-free shapes from tan b = tanh b, the
  static load from the rigid swing), lag included;
* convergence with modes: the tip deflection histories with 1, 2, 4 and 8 analytic modes converge,
  and finite elements reduced to 4 modes agree with the 4 analytic modes, their difference falling
  as h^4;
* energy: kinetic + gravity + strain energy is conserved to the integrator's error (it falls with
  rtol), while the strain energy it includes is ~1e6 times that error.

The quasi-static deflection (sympy, ``_quasi_static_shape``): a rigid pinned rod swings with
``theta'' = 3 g cos(theta) / (2 L)``, so in its frame each section carries the transverse load
``-q0 cos(theta) (1 - 3 x / (2 L))``, ``q0 = rho A g``, balanced about the pin. Its deflection with
w(0) = w''(0) = w''(L) = w'''(L) = 0 and ``int x w dx = 0`` (the pinned-free modes' frame: they are
mass-orthogonal to the rotation about the pin) is ``q0 L^4 / (E I)`` times a quintic in x / L: tip
1/336 (the tip lags the swing), mean -1/1680.

The tip deflection (the elastic transverse displacement at x = L, in the frame) is no trajectory field:
``_swing`` reads it from the states of a ``viz3d.Simulation`` (eta) through the bar model's shapes.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import pytest
import sympy as sp
from conftest import SCENES
from scipy.integrate import quad, solve_ivp
from scipy.optimize import brentq

import viz3d
from viz3d.dynamics import body_state
from viz3d.scene.build import make_controller, make_formulation, make_integrator_from

SCENE = SCENES / "flexible_pendulum.toml"
#: The down-swing from horizontal to just past the bottom (a quarter period of the rigid pendulum
#: released horizontal is 4 sqrt(2 L / 3 g) K(1/sqrt 2) / 4 = 0.483 s).
SWING = 0.5
#: Interval between compared samples [s].
SAMPLE_DT = 0.005
#: Tolerances of the runs compared with references: global errors ~1e-10 of the state, far below
#: every effect checked here (the stiff-limit deviations fall exactly as 1 / E down to 1.7e-7 rad).
ACCURATE = ("sim.rtol=1e-10", "sim.atol=1e-12")
#: Integration error allowed on top of each mathematical bound [rad or m]: rtol = 1e-10 over a few
#: thousand steps of a unit-scale state.
INTEGRATION = 1e-8
#: Stiffness factors of the stiff-limit runs; their deviations must scale as their inverse ratio.
STIFF = (100.0, 1000.0)
#: Relative tolerance of the 1 / E ratio: the next terms are O(w/L) ~ 3e-4 (inertia and gravity of
#: the deflection itself), O((omega_1 t)^-2) ~ 1e-4 (the fast vibration averaged out) and the
#: integration error / deviation ~ 1e-8 / 1.7e-6; 5 % is ~10x their sum.
RATIO_RTOL = 0.05


@dataclass(frozen=True)
class Strip:
    """The scene's strip: length L, width b, depth h [m], density rho, modulus E, gravity g (SI)."""

    L: float
    b: float
    h: float
    rho: float
    E: float
    g: float

    @property
    def mass(self) -> float:
        return self.rho * self.L * self.b * self.h

    @property
    def EI(self) -> float:
        return self.E * self.b * self.h**3 / 12.0

    def deflection_scale(self, factor: float = 1.0) -> float:
        """``q0 L^4 / (E I)`` [m] with E multiplied by ``factor``."""
        return self.rho * self.b * self.h * self.g * self.L**4 / (factor * self.EI)


@functools.lru_cache(maxsize=None)
def _strip() -> Strip:
    scene = viz3d.load_scene(SCENE)
    body = scene.data["bodies"][0]
    assert body["supports"] == ["pinned", "free"] and body["section"]["type"] == "rectangle"
    g = -scene.data["sim"]["gravity"][2]
    return Strip(body["length"], body["section"]["width"], body["section"]["depth"], body["material"]["rho"],
                 body["material"]["E"], g)


@functools.lru_cache(maxsize=None)
def _quasi_static_shape() -> tuple[sp.Expr, sp.Symbol]:
    """w(xi) / (q0 L^4 / (E I)), xi = x / L, under the load -(1 - 3 xi / 2) (module docstring)."""
    xi, c1 = sp.symbols("xi c1")
    w = sp.integrate(-(1 - sp.Rational(3, 2) * xi), xi, xi, xi, xi) + c1 * xi + sum(
        sp.Symbol(f"c{k}") * xi**k for k in (0, 2, 3))
    ends = [w.subs(xi, 0), w.diff(xi, 2).subs(xi, 0), w.diff(xi, 2).subs(xi, 1), w.diff(xi, 3).subs(xi, 1),
            sp.integrate(xi * w, (xi, 0, 1))]
    return w.subs(sp.solve(ends, [sp.Symbol("c0"), c1, sp.Symbol("c2"), sp.Symbol("c3")])), xi


def _static_tip_and_mean() -> tuple[float, float]:
    """Tip and mean of the quasi-static deflection, in units of q0 L^4 / (E I)."""
    w, xi = _quasi_static_shape()
    return float(w.subs(xi, 1)), float(sp.integrate(w, (xi, 0, 1)))


def test_quasi_static_shape_is_the_closed_form():
    w, xi = _quasi_static_shape()
    assert w.subs(xi, 1) == sp.Rational(1, 336)
    assert sp.integrate(w, (xi, 0, 1)) == -sp.Rational(1, 1680)
    assert w.diff(xi, 4) == -(1 - sp.Rational(3, 2) * xi)


def test_modal_expansion_sums_to_the_static_tip():
    """The two references agree: the static shares c_k of 8 pinned-free modes add up to 1/336, to
    within the alternating tail's first term (|c_9| ~ |c_8| (8/9)^4 ~ 5e-5 of it)."""
    shares = np.array([c for _, c in _pinned_free_modes(8)])
    assert np.all(np.diff(np.abs(shares)) < 0) and np.all(shares[:-1] * shares[1:] < 0)
    assert shares.sum() * 336.0 == pytest.approx(1.0, abs=1e-4)


# ---------------------------------------------------------------------------- stiff limit


def _rigid_pendulum(strip: Strip, R0: np.ndarray, W_omega0: np.ndarray, t: np.ndarray) -> np.ndarray:
    """R_WB(t) (n, 3, 3) of the rigid cuboid L x h x b pinned at the centre of its end face:
    ``J_O w' = -w x J_O w + r_G x R^T m g``, ``R' = R skew(w)`` (body axes x along L, y along the
    depth h, z along the width b), integrated by DOP853 at rtol 1e-11."""
    L, b, h, m = strip.L, strip.b, strip.h, strip.mass
    J_O = m * np.diag([(h**2 + b**2) / 12, L**2 / 3 + b**2 / 12, L**2 / 3 + h**2 / 12])
    r_G, W_g = np.array([L / 2, 0.0, 0.0]), np.array([0.0, 0.0, -strip.g])

    def rhs(_, y):
        R, w = y[:9].reshape(3, 3), y[9:]
        w_dot = np.linalg.solve(J_O, np.cross(r_G, R.T @ (m * W_g)) - np.cross(w, J_O @ w))
        W = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        return np.concatenate([(R @ W).ravel(), w_dot])

    y0 = np.concatenate([R0.ravel(), R0.T @ W_omega0])
    sol = solve_ivp(rhs, (0.0, t[-1]), y0, method="DOP853", rtol=1e-11, atol=1e-13, t_eval=t)
    assert sol.success
    return sol.y[:9].T.reshape(-1, 3, 3)


def _initial_frame(scene) -> np.ndarray:
    """R0 (3, 3): columns the strip's axis, its bending direction and their cross product."""
    body = scene.data["bodies"][0]
    axis, d = np.asarray(body["axis"], float), np.asarray(body["bending_direction"], float)
    return np.column_stack([axis, d, np.cross(axis, d)])


def _axis_deviation(factor: float, swirl: float) -> tuple[np.ndarray, np.ndarray]:
    """Times (n,) and |R e_x - R_rigid e_x| (n,) of the strip with E x ``factor``, released
    horizontal with the angular velocity ``swirl`` [rad/s] about the vertical."""
    strip = _strip()
    overrides = [*ACCURATE, f"sim.t_end={SWING}", f"bodies.0.material.E={factor * strip.E}", "bodies.0.modes=1",
                 f"bodies.0.omega=[0.0, 0.0, {swirl}]", f"bodies.0.velocity=[0.0, {swirl * strip.L / 2}, 0.0]"]
    scene = viz3d.load_scene(SCENE, overrides)
    tr = viz3d.simulate(scene)
    assert tr.ok, tr.status
    R_ref = _rigid_pendulum(strip, _initial_frame(scene), np.array([0.0, 0.0, swirl]), tr.t)
    return tr.t, np.linalg.norm(tr.rotation[:, 0, :, 0] - R_ref[:, :, 0], axis=1)


@pytest.mark.parametrize("swirl", [0.0, 2.0], ids=["planar", "spherical"])
def test_stiff_strip_swings_as_the_rigid_pendulum(swirl):
    """The frame's axis against the rigid cuboid's, for E x 100 and E x 1000.

    Bound (first order in the deflection): the frame's pin equation differs from the rigid one by the
    gravity moment on the mean deflection, ``m g w_mean sin(theta)`` (its inertia coupling
    ``int x w_dot dm`` vanishes for pinned-free modes; J(eta) is second order), and the rigid
    dynamics about the swing is restoring, so ``|dtheta| <= (m g / I_O) max|w_mean| t^2 / 2`` with
    ``I_O = m L^2 / 3`` and ``max|w_mean| <= 2 w_mean,static`` (a load applied suddenly at most
    doubles the static response; |w_mean,static| = q0 L^4 / (1680 E I), module docstring): ``3 g w_mean,static t^2 / L^2``,
    of the order rho g L^3 / (E h^2) (here 1/140 of it) times (g t^2 / L). The roll about the strip's
    own axis is left out: its inertia is 1e-4 of the others', so the same O(w/L) inertia changes turn
    it 1e4 times more (it also falls as 1 / E).
    """
    strip = _strip()
    deviations = []
    for factor in STIFF:
        t, dev = _axis_deviation(factor, swirl)
        w_mean = abs(_static_tip_and_mean()[1]) * strip.deflection_scale(factor)
        bound = 3.0 * strip.g * w_mean * t**2 / strip.L**2 + INTEGRATION
        assert np.all(dev <= bound), f"E x {factor:g}: deviation {dev.max():.3g} rad over the bound {bound[np.argmax(dev)]:.3g}"
        deviations.append(dev.max())
    ratio = deviations[0] / deviations[1]
    expected = STIFF[1] / STIFF[0]
    assert ratio == pytest.approx(expected, rel=RATIO_RTOL), f"deviations {deviations}: not ~1/E"


# ---------------------------------------------------------------------------- tip deflection


@dataclass(frozen=True)
class Swing:
    """Samples of a run: times t (n,) [s], tip deflection w (n,) [m], swing angle theta below the
    horizontal (n,) [rad] and its rate theta_dot (n,) [rad/s], the bending modes' frequencies [rad/s]."""

    t: np.ndarray
    w: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    omega: np.ndarray


@functools.lru_cache(maxsize=None)
def _swing(*overrides: str) -> Swing:
    """The down-swing of the scene with ``overrides``, sampled every SAMPLE_DT from the states of a
    ``viz3d.Simulation`` (the trajectory stores neither eta nor the position of a section)."""
    scene = viz3d.load_scene(SCENE, (*ACCURATE, f"sim.t_end={SWING}", f"sim.dt={SAMPLE_DT}", *overrides))
    system, state = viz3d.build(scene)
    cfg = scene.data["sim"]
    sim = viz3d.Simulation(system, state, make_integrator_from(cfg), make_formulation(cfg), cfg["dt"],
                           controller=make_controller(cfg))
    states = [state] + [sim.step() for _ in range(round(SWING / SAMPLE_DT))]
    bar = system.bodies.flexible[0].bar
    phi_L = bar.fields[0].displacement(np.array([bar.length]))[0]
    frames = [body_state(system, s.q, s.v, s.chart, s.t) for s in states]
    e_x = np.array([f.pose.R_WB[0][:, 0] for f in frames])
    return Swing(np.array([s.t for s in states]), np.array([phi_L @ system.elastic_q(s.q)[0] for s in states]),
                 np.arctan2(-e_x[:, 2], e_x[:, 0]),  # R e_x = (cos theta, 0, -sin theta): a turn about +y
                 np.array([f.twist.W_omega[0][1] for f in frames]), bar.fields[0].frequencies())


def _pinned_free_modes(n: int) -> list[tuple[float, float]]:
    """(beta_k L, static share c_k of the tip deflection) of the lowest n pinned-free modes
    ``phi = sin(b xi) + sin(b) / sinh(b) sinh(b xi)``, ``tan b = tanh b``; c_k in units of
    q0 L^4 / (E I) for the load -(1 - 3 xi / 2) (mass-normalised modal expansion)."""
    out = []
    for k in range(1, n + 1):
        beta = brentq(lambda b: np.tan(b) - np.tanh(b), (k + 0.25) * np.pi - 0.3, (k + 0.25) * np.pi + 0.3)
        phi = lambda x, b=beta: np.sin(b * x) + np.sin(b) / np.sinh(b) * np.sinh(b * x)  # noqa: E731
        norm = quad(lambda x: phi(x) ** 2, 0, 1, epsabs=1e-14)[0]
        load = quad(lambda x: -(1 - 1.5 * x) * phi(x), 0, 1, epsabs=1e-14)[0]
        out.append((beta, load * phi(1.0) / (norm * beta**4)))
    return out


def _quasi_static_tip(strip: Strip, factor: float, zeta: float, n_modes: int, s: Swing) -> np.ndarray:
    """Tip deflection (n,) [m] of the first n_modes modes, each following its load ``c_k f(t)``,
    ``f = cos(theta)``, with damping ratio zeta: ``q_k = c_k (f - 2 zeta f' / w_k + (4 zeta^2 - 1)
    f'' / w_k^2 + O(w_k^-3))`` (the slow-load expansion of ``q'' + 2 zeta w q' + w^2 q = w^2 c f``),
    softened by the centrifugal load ``rho A theta_dot^2 w`` (w_k^2 -> w_k^2 - theta_dot^2); the
    swing ``theta_ddot = 3 g cos(theta) / (2 L)`` is the rigid one (to O(w/L))."""
    theta_ddot = 1.5 * strip.g / strip.L * np.cos(s.theta)
    f = np.cos(s.theta)
    f_d = -np.sin(s.theta) * s.theta_dot
    f_dd = -np.cos(s.theta) * s.theta_dot**2 - np.sin(s.theta) * theta_ddot
    omega_0 = np.sqrt(factor * strip.EI / (strip.rho * strip.b * strip.h * strip.L**4))
    tip = np.zeros_like(s.t)
    for beta, c in _pinned_free_modes(n_modes):
        w_k = beta**2 * omega_0
        tip += c * (f - 2 * zeta * f_d / w_k + (4 * zeta**2 - 1) * f_dd / w_k**2) * w_k**2 / (w_k**2 - s.theta_dot**2)
    return tip * strip.deflection_scale(factor)


def test_damped_tip_deflection_follows_the_quasi_static_swing():
    """E x 100 (first mode 227 rad/s, 40 x the swing's rate) and critical damping on every mode: after
    the release transient, ``(1 + w_1 t) exp(-w_1 t) < 1e-8`` for t >= 0.1 s, the tip deflection is
    the quasi-static one of the same 4 modes (so no truncation term). Tolerance 3e-4 of the static
    tip deflection: the neglected terms are O(w_mean / L) = 3e-5 (the deflection's own gravity and
    inertia), the next slow-load term (2 zeta theta_dot / w_1)^3 <= 1.1e-4 and the integration error
    (1e-8 / 1.4e-4 m)."""
    strip, factor, zeta = _strip(), 100.0, 1.0
    s = _swing(f"bodies.0.material.E={factor * strip.E}", f"bodies.0.damping={zeta}", "bodies.0.modes=4")
    assert s.omega[0] == pytest.approx(_pinned_free_modes(1)[0][0] ** 2 * np.sqrt(
        factor * strip.EI / (strip.rho * strip.b * strip.h * strip.L**4)), rel=1e-9)
    w_static = _static_tip_and_mean()[0] * strip.deflection_scale(factor)
    late = s.t >= 0.1
    err = np.abs(s.w - _quasi_static_tip(strip, factor, zeta, 4, s))[late]
    assert err.max() <= 3e-4 * w_static, f"tip deflection off the quasi-static swing by {err.max() / w_static:.3g} of w_static"


def _tip_difference(a: Swing, b: Swing) -> float:
    """max_t |w_a - w_b| [m] on common samples."""
    np.testing.assert_array_equal(a.t, b.t)
    return float(np.max(np.abs(a.w - b.w)))


def test_tip_deflection_converges_with_modes():
    """Undamped scene, 1, 2, 4, 8 analytic modes: d_n = max_t |w_n - w_2n| falls by at least 4 per
    doubling. Mode k's share of the tip response is ~ its static share, which falls like k^-4 (the
    c_k of ``_pinned_free_modes``: 1.05, -0.054, 0.0086, -0.0022, ...), so the tail beyond n modes
    falls like n^-3 or faster (8 per doubling); 4 allows the pre-asymptotic first doubling."""
    runs = {n: _swing(f"bodies.0.modes={n}") for n in (1, 2, 4, 8)}
    d = {n: _tip_difference(runs[n], runs[2 * n]) for n in (1, 2, 4)}
    for n in (1, 2):
        assert d[n] >= 4.0 * d[2 * n], f"modal differences {d}: not converging"


def test_finite_elements_agree_with_analytic_modes():
    """20 and 40 cubic Euler-Bernoulli elements reduced to 4 modes (the rigid rotation about the pin
    dropped: the same frame as the analytic pinned-free modes) against the 4 analytic modes: the
    difference is within the modal truncation estimate d_4 = max|w_4 - w_8| and falls as h^4 (the
    elements' order for shapes and frequencies); the next term is O((beta_4 h)^2) = 0.45 of it at
    20 elements, which moves the observed order by at most 0.4."""
    analytic = _swing("bodies.0.modes=4")
    truncation = _tip_difference(analytic, _swing("bodies.0.modes=8"))
    e = {n: _tip_difference(_swing("bodies.0.model=fe", f"bodies.0.elements={n}", "bodies.0.modes=4"), analytic)
         for n in (20, 40)}
    assert e[40] <= truncation, f"FE vs analytic {e[40]:.3g} m beyond the truncation estimate {truncation:.3g} m"
    order = np.log2(e[20] / e[40])
    assert 3.6 <= order <= 4.4, f"FE differences {e}: order {order:.2f}, not 4"


# ---------------------------------------------------------------------------- energy


def _energy_run(rtol: float):
    """The whole scene at ``rtol`` (atol = rtol / 100: the relative tolerance governs the modes too)."""
    tr = viz3d.simulate(SCENE, overrides=[f"sim.rtol={rtol}", f"sim.atol={rtol / 100}"])
    assert tr.ok, tr.status
    return tr


def test_energy_is_conserved_to_the_integrator_error():
    """Undamped: T + V_gravity + U_strain is a first integral, so its drift is integration error
    only. DOPRI5 with local extrapolation sets steps h ~ tol^(1/5) with local errors ~ tol^(6/5):
    global error ~ tol, 100x for 100x tighter rtol; at least 10x (half the decades) is required. A
    term missing from the equations or from the energy would leave a drift independent of rtol.
    The strain energy, ``energy_potential - m g z_G`` (z_G of the deformed centre of mass), must be
    >= 0 and large against the drift, so the check sees it."""
    coarse, fine = _energy_run(1e-7), _energy_run(1e-9)
    assert coarse.energy_drift >= 10.0 * fine.energy_drift, (coarse.energy_drift, fine.energy_drift)
    strip = _strip()
    U = fine.energy_potential - strip.mass * strip.g * fine.position[:, 0, 2]
    assert U.min() >= -1e-12 * np.abs(fine.energy_potential).max(), f"negative strain energy {U.min():.3g} J"
    assert U.max() >= 1e4 * coarse.energy_drift, f"strain energy {U.max():.3g} J too small to be seen by the check"
