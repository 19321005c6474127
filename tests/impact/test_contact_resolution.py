"""Issue 8: impact runs that said "ok" with wrong numbers.

References nobody here wrote: ballistics, the exact restitution relation of the hysteresis laws
(separation of variables), Hertz's energy balance, Saint-Venant's free bar and the exact wave
recursion of the clamped bar (thesis ch. 4, digest V6/V7), momentum conservation.
"""

import re
from pathlib import Path

import numpy as np
import pytest
from impact_helpers import contact_force, contact_law, impactor_velocity

import viz3d
from viz3d.cli import summary
from viz3d.contact.exact import clamped_bar_rigid_mass, saint_venant_free_bar
from viz3d.contact.parameters import hysteresis_restitution
from viz3d.diagnosis import EnergyWatch
from viz3d import events
from viz3d.events import ContactStepping
from viz3d.stability import stability

from conftest import SCENES

E, RHO, L, A = 210e9, 7900.0, 0.3, 9e-4
C = np.sqrt(E / RHO)
T = 2 * L / C
Z = A * np.sqrt(E * RHO)
M_BAR = RHO * A * L
BALL = SCENES / "bouncing_sphere.toml"
H, M_BALL, WEIGHT = 0.02, 0.0329, 0.3227      # the scene's drop height [m], mass [kg], weight [N]
G = WEIGHT / M_BALL
#: Linear invariants (momentum) are kept by Runge-Kutta steps, impulses and the Hermite
#: interpolant alike: only round-off, relative to the initial momentum.
ROUNDOFF = 1e-12
#: Digest V6: velocities within 1 % of the impact speed.
V6_VELOCITY_TOL = 0.01


def _ball_law():
    return contact_law(viz3d.load_scene(BALL))


def _ballistic_starts(e: float, t_end: float) -> np.ndarray:
    """Contact onsets of a ball dropped from H that keeps e of its speed at each bounce (contacts
    of zero duration: the 80 us contacts shift them by far less than a flight)."""
    t, v, starts = np.sqrt(2 * H / G), np.sqrt(2 * G * H), []
    while t < t_end:
        starts.append(t)
        v *= e
        t += 2 * v / G
    return np.array(starts)


@pytest.mark.parametrize("rtol", [1e-1, 1e-2])
def test_a_coarse_tolerance_still_resolves_every_bounce(rtol):
    """Was: one contact, the ball 0.553 m deep in the plate, restitution 0.0042, status ok."""
    traj = viz3d.simulate(BALL, {"sim.rtol": rtol})
    x, law = traj.extras, _ball_law()
    e = hysteresis_restitution(law.factor())
    assert traj.ok, traj.status
    c = x["contacts"]
    assert len(c) == len(_ballistic_starts(e, 0.4))
    v_in = np.sqrt(2 * G * H)
    assert c[0, 1] == pytest.approx(v_in, rel=1e-4)
    load_slack = 2 * G * (c[:, 2] - c[:, 0]) / c[:, 1]  # a weight acting over the contact
    assert np.all(np.abs(x["contact_restitution"] - e) <= load_slack)
    # Hertz energy balance with everything the fall can give: K alpha^2.5 / 2.5 <= m g (H + alpha)
    alpha_bound = 1e-4
    for _ in range(3):
        alpha_bound = (2.5 * WEIGHT * (H + alpha_bound) / law.stiffness) ** 0.4
    assert x["penetration"].max() <= alpha_bound


#: A diagnosis: "<contact>: contact <number> at t = <time> s: <quantity> ..." (viz3d.contact.resolution).
DIAGNOSIS = re.compile(r"^impact: contact (\d+) at t = ([0-9.e+-]+) s: (\w+) ")
#: The diagnosis names the time within 0.1 ms of the contact's onset (about one contact duration,
#: 80 us; the old engine's assertion "t = 0.0638" pinned it as finely).
DIAGNOSIS_TIME = 1e-4


def _assert_diagnosis(traj, quantity: str) -> tuple[int, float]:
    """The run stopped at a contact that started at most ``DIAGNOSIS_TIME`` before the time named,
    naming the contact, its number, the time and ``quantity``; returns (number, time)."""
    assert not traj.ok
    m = DIAGNOSIS.match(traj.status)
    assert m and m.group(3) == quantity, traj.status
    number, t = int(m.group(1)), float(m.group(2))
    onset = traj.extras["contact_events"][number - 1, 0]        # every located touch, in order
    assert onset <= t <= onset + DIAGNOSIS_TIME, (onset, traj.status)
    return number, t


def test_an_unresolved_contact_stops_the_run_naming_contact_time_and_quantity(monkeypatch):
    """Without the step bound the coarse runs step over the contacts; each check catches it alone.

    Was (one engine, before the fix): a contact beginning and ending inside the step after its
    onset was never closed, and rtol 1e-2 said ok with restitution -2.3."""
    monkeypatch.setattr(ContactStepping, "step_bound", lambda self, state: np.inf)
    t1 = np.sqrt(2 * H / G)
    # t_end far enough that no step before the first contact is clipped to end there (they grow to
    # 1.1 s at rtol 0.1): with t_end 0.4 s the clipped step takes the contact on other steps, whose
    # failure (restitution -0.07) the restitution check names and the energy check alone lets pass
    coarse = {"sim.rtol": 1e-1, "sim.t_end": 2.0, "sim.output_dt": 2e-5}
    for rtol in (1e-1, 1e-2):
        traj = viz3d.simulate(BALL, coarse | {"sim.rtol": rtol})
        assert DIAGNOSIS.match(traj.status) and int(DIAGNOSIS.match(traj.status).group(1)) == 1, traj.status
        assert traj.t[-1] == pytest.approx(t1, rel=1e-3) and len(traj.t) > t1 / 2e-5  # frames kept
    # the restitution check alone (between rigid bodies: the law's free-impact value; the run's
    # ledger watch, sim.blowup_energy, off too: it would stop the run once the ledger is off by half)
    monkeypatch.setattr(EnergyWatch, "check", lambda self, frames: None)
    energy_exceeded = events._energy_exceeded
    monkeypatch.setattr(events, "_energy_exceeded", lambda o, led, balance, error: np.zeros(np.shape(balance), bool))
    for rtol in (1e-1, 1e-2):
        traj = viz3d.simulate(BALL, coarse | {"sim.rtol": rtol})
        assert _assert_diagnosis(traj, "restitution")[0] == 1, traj.status
    # the energy check alone, for any bodies: the coarse steps create energy during the contact,
    # far more than their own error estimates admit
    monkeypatch.setattr(events, "_energy_exceeded", energy_exceeded)
    monkeypatch.setattr(ContactStepping, "_restitution_check", lambda self, *a, **k: None)
    traj = viz3d.simulate(BALL, coarse)
    assert _assert_diagnosis(traj, "energy")[0] == 1, traj.status
    assert "created by the integration" in traj.status and "the error estimates of its" in traj.status
    # an elastic law: the step after onset runs 44 ms deep into the plate and the ball leaves at
    # 8e6 m/s (the controller's error is relative to that speed); the divergence check names it
    traj = viz3d.simulate(BALL, coarse | {"contact.law": "hertz"})
    assert not traj.ok and "body 'impactor': speed" in traj.status and "diverged" in traj.status, traj.status


def test_bouncing_ball_restitution_is_measured_from_the_first_contact():
    """Was nan: the ball starts at rest. Now the rigid relative speed before the first contact
    (the free fall's sqrt(2 g h)) and after it."""
    traj = viz3d.simulate(BALL)
    x = traj.extras
    assert x["impact_speeds"][0, 0] == pytest.approx(np.sqrt(2 * G * H), rel=1e-4)
    assert float(x["restitution"]) == pytest.approx(x["contact_restitution"][0], rel=1e-12)
    np.testing.assert_allclose(x["impact_restitution"], x["contact_restitution"], rtol=1e-12)  # one contact per bounce
    text = summary(traj, Path("out"))
    assert "restitution 0.8327 of the bodies' rigid motion (impact 1 of 5" in text
    # the approach line starts from the speed before the first contact (was "0 ->": the ball at rest at t = 0)
    assert f"impact: {np.sqrt(2 * G * H):.4g} -> " in text, text


def test_bar_trajectory_gives_its_centre_of_mass_position_and_velocity():
    """Was: velocity all zeros while the position moved. Saint-Venant: the bar's centre of mass
    leaves at v (1 - exp(-2 beta)) / beta; momentum is conserved; position and velocity agree."""
    traj = viz3d.simulate(SCENES / "impact_free_bar.toml")
    exact = saint_venant_free_bar(1.0, 1.0, C, L, Z)
    i, j = traj.body("impactor"), traj.body("bar")
    geo_n = traj.velocity[0, i] / np.linalg.norm(traj.velocity[0, i])  # along the impactor's motion (1 m/s)
    v1, v2 = traj.velocity[:, i] @ geo_n, traj.velocity[:, j] @ geo_n
    assert v2[-1] == pytest.approx(exact.v2_plus, abs=V6_VELOCITY_TOL)
    m1 = float(traj.mass[i])
    np.testing.assert_allclose(m1 * v1 + M_BAR * v2, m1 * 1.0, rtol=0, atol=ROUNDOFF * m1)
    _assert_velocity_is_the_derivative_of_position(traj, j, geo_n, max_acceleration=contact_force(traj).max() / M_BAR)


def test_clamped_bar_centre_of_mass_follows_its_elastic_mean_displacement():
    """A clamped bar has no frame motion: its centre of mass moves by (1/m) int rho A u dx."""
    traj = viz3d.simulate(SCENES / "impact_clamped_bar.toml")
    i, j = traj.body("impactor"), traj.body("bar")
    geo_n = traj.velocity[0, i] / np.linalg.norm(traj.velocity[0, i])
    v2 = traj.velocity[:, j] @ geo_n
    assert np.abs(v2).max() > 0.1  # the struck half moves at up to the impact speed
    dv = np.abs(np.diff(v2)).max() / np.diff(traj.t).min()
    _assert_velocity_is_the_derivative_of_position(traj, j, geo_n, max_acceleration=dv)


def _assert_velocity_is_the_derivative_of_position(traj, j, n, max_acceleration):
    """Central differences of the position on the uniform output grid are within h A / 2 of the
    velocity, A the largest acceleration (x(t +- h) = x(t) +- h v(t) + O(h^2 A / 2))."""
    t = traj.t
    h = np.diff(t)
    uniform = np.isclose(h[:-1], h[1:], rtol=1e-9) & np.isclose(h[:-1], np.median(h), rtol=1e-9)
    x, v = traj.position[:, j] @ n, traj.velocity[:, j] @ n
    i = np.flatnonzero(uniform) + 1
    fd = (x[i + 1] - x[i - 1]) / (t[i + 1] - t[i - 1])
    assert np.all(np.abs(fd - v[i]) <= 0.5 * h[i] * max_acceleration * (1 + 1e-9) + 1e-12), np.abs(fd - v[i]).max()


@pytest.mark.parametrize("scene, beta, exact_count", [("impact_free_bar", 2.0, 1), ("impact_free_bar", 4.0, 1),
                                                       ("impact_clamped_bar", 1.0, 2)])
def test_gibbs_chatter_is_not_counted_as_contacts(scene, beta, exact_count):
    """Was 3 at beta = 2, 15 at beta = 4 (free bar), 4 on the clamped bar: breaks shorter than the
    period of the highest mode are Gibbs ringing of the truncated series. Saint-Venant: one
    contact; the clamped bar's exact recursion: two."""
    traj = viz3d.simulate(SCENES / f"{scene}.toml", {"impactor.mass": M_BAR / beta, "sim.t_end": 4e-4})
    x = traj.extras
    if scene == "impact_clamped_bar":
        assert len(clamped_bar_rigid_mass(beta, 1.0, C, L, traj.t, Z).contact_intervals) == exact_count
    assert int(x["contact_count"]) == len(x["contacts"]) == exact_count
    assert len(x["contact_events"]) > exact_count  # the located intervals the model chattered through
    assert int(np.sum(x["contact_breaks_unresolved"])) + len(x["contact_touches_unresolved"]) > 0


def test_run_and_stability_count_contacts_the_same_way():
    scene = SCENES / "impact_clamped_bar.toml"
    traj = viz3d.simulate(scene)
    row, = stability(scene, [], "bar.modes=60", None, None).rows
    assert row.extra["contacts"] == int(traj.extras["contact_count"]) == 2


@pytest.mark.parametrize("scene, beta", [("impact_free_bar", 1.0), ("impact_free_bar", 2.0), ("impact_free_bar", 4.0),
                                         ("impact_clamped_bar", 1.0)])
def test_stated_uncertainty_covers_the_exact_final_velocity_and_restitution(scene, beta):
    """Was: -0.0048 m/s at beta = 4 where the exact answer is +0.0003, said as if right. The
    velocity jumps of the plastic impulses on the modal bar bound what truncation moved."""
    traj = viz3d.simulate(SCENES / f"{scene}.toml", {"impactor.mass": M_BAR / beta, "sim.t_end": 4e-4})
    x = traj.extras
    if scene == "impact_free_bar":
        sv = saint_venant_free_bar(beta, 1.0, C, L, Z)
        v_exact, e_exact = sv.v1_plus, sv.restitution
    else:
        v_exact = clamped_bar_rigid_mass(beta, 1.0, C, L, traj.t, Z).final_velocity
        e_exact = -v_exact
    assert abs(impactor_velocity(traj)[-1] - v_exact) <= float(x["velocity_uncertainty"])
    assert abs(float(x["restitution"]) - e_exact) <= float(x["restitution_uncertainty"])
    if scene == "impact_free_bar":
        # The summary states the bodies' final relative velocity (centres of mass; after separation
        # the free bar's is exactly v2+, by momentum) with its +-: it covers the exact one and says
        # the sign is not resolved exactly when the +- spans 0. (The impact engine's summary stated
        # the impactor's velocity: at beta = 4 "-0.0048 +- ...; the sign of the final motion is not
        # resolved", the exact being +0.0003.)
        line, = [ln for ln in summary(traj, Path("out")).splitlines() if ln.startswith("approach")]
        v_end, dv = map(float, re.search(r"-> (\S+) \+- (\S+) m/s apart", line).groups())
        # the relative velocity's +- counts each impulse's jump on both bodies: sum P (1/m1 + 1/m2),
        # the impactor's sum P / m1 times (1 + m1 / M_BAR) = (1 + 1 / beta) (was the impactor's alone)
        rel = float(x["relative_velocity_uncertainty"])
        assert rel == pytest.approx(float(x["velocity_uncertainty"]) * (1 + 1 / beta), rel=1e-9)
        assert dv == pytest.approx(rel, rel=0.05)  # printed with 2 digits
        assert abs(v_end - (sv.v2_plus - sv.v1_plus)) <= dv, line
        assert ("the sign of the final motion is not resolved" in line) == (abs(v_end) < dv), line


def test_the_uncertainty_falls_with_the_number_of_modes():
    """Impulses on a modal bar scale with its point mass at the contact, m_bar / (2N + 1)."""
    u = [float(viz3d.simulate(SCENES / "impact_free_bar.toml", {"bar.modes": n}).extras["velocity_uncertainty"])
         for n in (20, 80)]
    assert 0 < u[1] < u[0] / 2, u


def test_law_contacts_and_walls_have_no_unresolved_jumps():
    x = viz3d.simulate(BALL).extras
    assert float(x["velocity_uncertainty"]) == 0.0 and float(x["restitution_uncertainty"]) == 0.0
    assert float(x["contact_resolution"]) == 0.0 and float(x["time_resolution"]) == 0.0
