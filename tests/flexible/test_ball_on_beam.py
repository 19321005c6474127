"""A ball dropped on the midspan of a pinned-pinned beam (scenes/ball_on_flexible_beam.toml): the
multiple-impact sequence of a strike against an independent integration of the same model, the beam
as analytic modes against the beam as finite elements, and the energy ledger.

The reference (``BallBeam``) is written here from the textbook model, sharing nothing with viz3d but
the scene's numbers: a point mass on the pinned-pinned Euler-Bernoulli beam's closed-form modes
``phi_n = sin(n pi x / L)``, ``omega_n = (n pi / L)^2 sqrt(EI / rho A)``, modal mass ``rho A L / 2``,
modal damping ``2 zeta omega_n``, the beam's weight as modal loads ``-rho A g int phi_n``, and the
Hertz force ``F = 4/3 E* sqrt(R) alpha^1.5`` (Johnson, Contact Mechanics, 1985, sec. 4.2) at midspan,
integrated by scipy's DOP853 with contact onset and separation located as events. At midspan the
slope of every excited (odd) mode is zero, so the contact normal stays vertical and the ball's motion
is a straight line: the 1-D reference is the whole 3-D scene.

Error bounds, all from two resolutions of the same computation:

* integration (viz3d's adaptive dopri5 and the reference's DOP853): the run at the scene's tolerance
  against one at 1/100 of it. With errors ~ tol^q and q >= log 2 / log 100 = 0.15 (dopri5's global
  error goes about like tol) the finer run's error is at most half the coarser one's, so the coarse error is at most 2x the difference
  (``INTEGRATION_SAFETY``);
* finite elements: Hermite cubics converge like h^4 in the frequencies (Strang & Fix, An Analysis of
  the Finite Element Method, ch. 6: h^(2(k-m)) for elements of order k = 4, degree 3, and energy of
  order m = 2) and in what the strike depends on (observed 3.85-4.0 from 8 to 16 elements); Richardson: the error of the finer mesh is
  ``|X_h - X_h/2| / (2^4 - 1)``, times ``FE_SAFETY`` for the next term of the expansion.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import viz3d

from conftest import SCENES

SCENE = SCENES / "ball_on_flexible_beam.toml"

#: Runs of the first strike end here [s]: the drop from 2 mm reaches the beam at 20.19 ms, the strike's
#: last contact ends at 21.28 ms, the next strike starts at 55.4 ms (reference, scene values).
T_STRIKE = 0.0216
#: Force samples [s]: every viz3d frame on this grid is compared with the reference at the same instant,
#: so the sampling error of a peak (~(pi dt / t_c)^2 / 8 = 6e-3 for t_c = 140 us) is the same on both
#: sides and cancels; only the frames on the grid are used (event frames fall between them).
SAMPLE_DT = 1e-5
#: Tolerances of the finer runs: 1/100 of the scene's.
TOL_CUT = 100.0
#: A run's integration error is at most this times its difference from the 1/100-tolerance run (see
#: the module docstring: e_fine <= e_coarse / 2).
INTEGRATION_SAFETY = 2.0
#: Finite-element meshes of the modes-versus-elements comparison (midspan is a node of both).
FE_MESHES = (8, 16)
#: Convergence order of Hermite cubic beam elements (frequencies, nodal shapes, consistent loads).
FE_ORDER = 4
#: The h^4 term's estimate covers the next term of the expansion within this factor (8 -> 16
#: elements: observed ratio 14.6-16 of the errors against the analytic modes, i.e. the estimate is off
#: by < 10 %).
FE_SAFETY = 2.0
#: Reference (DOP853) tolerances; the finer run at 1/100 of them estimates its error as above.
REF_RTOL = 1e-10
REF_ATOL = 1e-15
#: Reference steps are at most this fraction of the shortest modal period, so that a contact longer
#: than ~1/8 of it (a 5-us graze here) cannot fall between two steps unseen by the event location.
REF_STEP_FRACTION = 1.0 / 8.0
#: Round-off floors (10x the estimates; all far below the integration errors they are added to). Times:
#: the gap is a difference of heights of ~3e-2 m, known to a few eps x 3e-2 m ~ 1e-17 m, divided by the
#: slowest gap rate at an event (> 0.1 m/s): ~1e-16 s. Forces: F = K alpha^1.5 with alpha ~ 6e-6 m the
#: same difference: relative 3/2 x 1e-17 / 6e-6 ~ 3e-12. Speeds: eps x 1 m/s. Dissipated energy: the
#: rounding of its sum, 10 eps relative.
FLOOR_T = 1e-15
FLOOR_F_REL = 1e-11
FLOOR_V = 1e-15
EPS = np.finfo(float).eps


# ------------------------------------------------------------------------ independent reference


@dataclass(frozen=True)
class BallBeam:
    """Point mass on a pinned-pinned Euler-Bernoulli beam's analytic modes, Hertz contact at ``x_c``.

    State ``y = [z, z_dot, q (N), q_dot (N), D]``: ball centre height [m] and speed [m/s], modal
    coordinates of ``w(x) = sum q_n sin(n pi x / L)`` [m] and their rates, energy dissipated by the
    modal damping [J]. Indentation ``alpha = top + R + w(x_c) - z`` (``top``: the beam's top face above
    its axis).
    """

    m: float            # ball mass [kg]
    R: float            # ball radius [m]
    K: float            # Hertz constant [N/m^1.5]
    g: float            # gravity, downwards [m/s^2]
    top: float          # half depth [m]
    omega: np.ndarray   # (N,) modal frequencies [rad/s]
    M: float            # modal mass rho A L / 2 [kg]
    phi_c: np.ndarray   # (N,) mode shapes at the contact section [-]
    Q_g: np.ndarray     # (N,) modal loads of the beam's weight [N]
    zeta: float         # modal damping ratio [-]
    z0: float           # initial ball height [m]
    v0: float           # initial ball velocity, upwards [m/s]

    @property
    def n(self) -> int:
        return self.omega.size

    def alpha(self, y) -> float:
        return self.top + self.R + self.phi_c @ y[2:2 + self.n] - y[0]

    def alpha_dot(self, y) -> float:
        return self.phi_c @ y[2 + self.n:2 + 2 * self.n] - y[1]

    def force(self, y) -> float:
        a = self.alpha(y)
        return self.K * a**1.5 if a > 0.0 else 0.0

    def rhs(self, t, y):
        n, F = self.n, self.force(y)
        q, qd = y[2:2 + n], y[2 + n:2 + 2 * n]
        c = 2.0 * self.zeta * self.omega
        qdd = (self.Q_g - self.phi_c * F) / self.M - c * qd - self.omega**2 * q
        return np.concatenate(([y[1], F / self.m - self.g], qd, qdd, [self.M * c @ qd**2]))

    def y0(self):
        y = np.zeros(3 + 2 * self.n)
        y[0], y[1] = self.z0, self.v0
        return y


def ball_beam_from_scene(data: dict) -> BallBeam:
    """The reference model from the scene's numbers (resolved tables of ``viz3d.load_scene``)."""
    beam = next(b for b in data["bodies"] if b.get("type") == "flexible")
    ball = next(b for b in data["bodies"] if b.get("type") != "flexible")
    hit = data["contacts"][0]
    assert beam["supports"] == ["pinned", "pinned"] and beam["frame"] == "fixed"
    assert list(beam["bending_direction"]) == [0, 0, 1] and list(hit["normal"]) == [0, 0, 1]
    L, mat, sec = beam["length"], beam["material"], beam["section"]
    A, I = sec["width"] * sec["depth"], sec["width"] * sec["depth"] ** 3 / 12.0
    n = np.arange(1, beam["modes"] + 1)
    R = ball["shape"]["radius"]
    ball_mat = hit["material1"]
    E_star = 1.0 / ((1 - ball_mat["nu"] ** 2) / ball_mat["E"] + (1 - mat["nu"] ** 2) / mat["E"])
    g = -data["sim"]["gravity"][2]
    return BallBeam(
        m=ball["density"] * 4.0 / 3.0 * np.pi * R**3, R=R, K=4.0 / 3.0 * E_star * np.sqrt(R), g=g,
        top=sec["depth"] / 2.0, omega=(n * np.pi / L) ** 2 * np.sqrt(mat["E"] * I / (mat["rho"] * A)),
        M=mat["rho"] * A * L / 2.0, phi_c=np.sin(n * np.pi * hit["x2"] / L),
        Q_g=-mat["rho"] * A * g * L * (1.0 - np.cos(n * np.pi)) / (n * np.pi), zeta=beam["damping"],
        z0=ball["position"][2], v0=ball["velocity"][2])


@dataclass(frozen=True)
class Strike:
    """A contact history: per contact onset and end times [s], approach and separation speeds
    [m/s]; force samples on the grid ``t`` [s] -> ``F`` [N]; energy dissipated at the end [J]."""

    on: np.ndarray
    off: np.ndarray
    v_in: np.ndarray
    v_out: np.ndarray
    t: np.ndarray
    F: np.ndarray
    dissipated: float

    def peaks(self) -> np.ndarray:
        """Largest force sample of each contact [N]."""
        return np.array([self.F[(self.t >= a) & (self.t <= b)].max(initial=0.0) for a, b in zip(self.on, self.off)])


def integrate_reference(model: BallBeam, t_end: float, rtol: float, atol: float, sample_dt: float = SAMPLE_DT) -> Strike:
    """DOP853 from contact event to contact event; force sampled every ``sample_dt``."""
    grid = sample_dt * np.arange(int(np.floor(t_end / sample_dt * (1 + 1e-12))) + 1)
    grid = grid[grid <= t_end]
    max_step = REF_STEP_FRACTION * 2.0 * np.pi / model.omega.max()
    t, y, touching = 0.0, model.y0(), False
    events, samples = [], {}
    while t < t_end:
        gap_event = lambda t, y: model.alpha(y)  # noqa: E731
        gap_event.terminal, gap_event.direction = True, (-1.0 if touching else 1.0)
        sol = solve_ivp(model.rhs, (t, t_end), y, method="DOP853", rtol=rtol, atol=atol, events=gap_event,
                        max_step=max_step, t_eval=grid[grid >= t])
        ys = np.reshape(sol.y, (y.size, -1)).T  # a segment between two samples returns none
        samples.update({round(ti / sample_dt): model.force(yi) for ti, yi in zip(sol.t, ys)})
        if sol.status != 1:
            y = sol.y[:, -1]
            break
        t, y = sol.t_events[0][0], sol.y_events[0][0]
        events.append((t, model.alpha_dot(y)))
        touching = not touching
    keys = np.array(sorted(samples))
    ev = np.array(events).reshape(-1, 2)
    return Strike(on=ev[0::2, 0], off=ev[1::2, 0], v_in=ev[0::2, 1], v_out=-ev[1::2, 1],
                  t=keys * sample_dt, F=np.array([samples[k] for k in keys]), dissipated=float(y[-1]))


# ------------------------------------------------------------------------ viz3d runs


@dataclass(frozen=True)
class Run:
    """A viz3d run of the scene: its contact history, and the ledger's balance error and scale."""

    strike: Strike
    balance_error: float   # max |E + dissipated - W_in - E0| over the frames [J]
    E0: float              # initial total energy [J]
    n_steps: int


@functools.lru_cache(maxsize=None)
def run_scene(t_end: float = T_STRIKE, tol_cut: float = 1.0, elements: int | None = None,
              sample_dt: float = SAMPLE_DT) -> Run:
    """The scene to ``t_end`` with its tolerances divided by ``tol_cut``, optionally as FE; frames
    every ``sample_dt``."""
    sim = viz3d.load_scene(SCENE).data["sim"]
    over = {"sim.t_end": t_end, "sim.dt": sample_dt, "sim.output_dt": sample_dt,
            "sim.rtol": sim["rtol"] / tol_cut, "sim.atol": sim["atol"] / tol_cut}
    if elements:
        over |= {"bodies.beam.model": "fe", "bodies.beam.elements": elements}
    tr = viz3d.simulate(SCENE, overrides=over)
    assert tr.status == "ok", tr.status
    x = tr.extras
    c = np.asarray(x["contacts"]).reshape(-1, 4)
    k = np.rint(tr.t / sample_dt)
    on_grid = np.abs(tr.t - k * sample_dt) <= 1e-9 * sample_dt
    strike = Strike(on=c[:, 0], off=c[:, 2], v_in=c[:, 1], v_out=c[:, 3], t=tr.t[on_grid],
                    F=x["contact_force"][on_grid, 0], dissipated=float(x["energy_dissipated"][-1]))
    return Run(strike, float(np.abs(x["energy_balance_error"]).max()), float(tr.energy_total[0]), tr.n_steps)


@functools.lru_cache(maxsize=None)
def reference(t_end: float = T_STRIKE, tol_cut: float = 1.0, sample_dt: float = SAMPLE_DT) -> Strike:
    return integrate_reference(ball_beam_from_scene(viz3d.load_scene(SCENE).data), t_end,
                               REF_RTOL / tol_cut, REF_ATOL / tol_cut, sample_dt)


# ------------------------------------------------------------------------ comparisons


def strikes(s: Strike, t_gap: float) -> list[np.ndarray]:
    """Indices of the contacts of each strike: contacts closer than ``t_gap`` belong together."""
    if s.on.size == 0:
        return []
    breaks = np.flatnonzero(s.on[1:] - s.off[:-1] > t_gap) + 1
    return np.split(np.arange(s.on.size), breaks)


def fundamental_period() -> float:
    """Period of the beam's first mode [s] (closed form): strikes are separated by flights longer."""
    return 2.0 * np.pi / ball_beam_from_scene(viz3d.load_scene(SCENE).data).omega[0]


def differences(a: Strike, b: Strike) -> dict[str, float]:
    """Largest differences of two histories with the same contacts: times [s], speeds [m/s], force
    samples (on the common grid) and peaks [N], dissipated energy [J]."""
    assert a.on.size == b.on.size, f"contact counts differ: {a.on.size} vs {b.on.size}"
    common, ia, ib = np.intersect1d(np.rint(a.t / SAMPLE_DT), np.rint(b.t / SAMPLE_DT), return_indices=True)
    assert common.size >= 0.99 * max(a.t.size, b.t.size), "force samples missing from the grid"
    return {"t": max(np.abs(a.on - b.on).max(), np.abs(a.off - b.off).max()),
            "v": max(np.abs(a.v_in - b.v_in).max(), np.abs(a.v_out - b.v_out).max()),
            "F": np.abs(a.F[ia] - b.F[ib]).max(), "peak": np.abs(a.peaks() - b.peaks()).max(),
            "dissipated": abs(a.dissipated - b.dissipated)}


def floors(s: Strike) -> dict[str, float]:
    F_max = s.F.max()
    return {"t": FLOOR_T, "v": FLOOR_V, "F": FLOOR_F_REL * F_max, "peak": FLOOR_F_REL * F_max,
            "dissipated": 10 * EPS * s.dissipated}


def viz3d_integration_error() -> dict[str, float]:
    """Bound of viz3d's integration error at the scene's tolerances (two tolerances, see above)."""
    e = differences(run_scene().strike, run_scene(tol_cut=TOL_CUT).strike)
    return {k: INTEGRATION_SAFETY * v for k, v in e.items()}


def reference_integration_error() -> dict[str, float]:
    """Bound of the reference's integration error (the same estimate)."""
    e = differences(reference(), reference(tol_cut=TOL_CUT))
    return {k: INTEGRATION_SAFETY * v for k, v in e.items()}


def assert_within(d: dict, bound: dict, what: str) -> None:
    for k in d:
        assert d[k] <= bound[k], f"{what}: {k} differs by {d[k]:.3g} > bound {bound[k]:.3g}"


# ------------------------------------------------------------------------ tests


def test_the_reference_has_a_multiple_impact_strike():
    """The scene shows what it is for: the first strike is several contacts, none of them a graze that
    a small change of the model could remove (each peak at least a tenth of the strike's largest)."""
    ref = reference()
    first = strikes(ref, fundamental_period())[0]
    assert first.size >= 2
    peaks = ref.peaks()[first]
    assert peaks.min() > 0.1 * peaks.max(), peaks


def test_first_strike_matches_the_independent_reference():
    """viz3d's contact history of the first strike (onset and end times, approach and separation
    speeds, force at every sample, peaks, energy dissipated) against the reference, within the two
    integrations' error bounds."""
    viz, ref = run_scene().strike, reference()
    e_viz, e_ref, floor = viz3d_integration_error(), reference_integration_error(), floors(ref)
    bound = {k: e_viz[k] + e_ref[k] + floor[k] for k in e_viz}
    assert_within(differences(viz, ref), bound, "viz3d vs reference")


def test_multiple_impact_sequence_is_found():
    """The number of contacts of the first strike is the reference's (4: the ball is slowed, stopped,
    thrown up and pushed once more by the vibrating beam). Times: test_first_strike_matches_..."""
    viz, ref = run_scene().strike, reference()
    T1 = fundamental_period()
    n_viz = [s.size for s in strikes(viz, T1)]
    n_ref = [s.size for s in strikes(ref, T1)]
    assert n_viz == n_ref, (n_viz, n_ref)
    assert n_ref[0] >= 2


def test_modes_and_finite_elements_give_the_same_strike():
    """The beam as 5 analytic modes and as Hermite elements reduced to 5 modes: the same contacts,
    times, speeds and forces within the elements' Richardson bound plus the integration errors (the
    truncation to 5 modes is the same on both sides)."""
    modal = run_scene().strike
    coarse, fine = (run_scene(elements=n).strike for n in FE_MESHES)
    richardson = differences(coarse, fine)
    e_int, floor = viz3d_integration_error(), floors(modal)
    bound = {k: FE_SAFETY * richardson[k] / (2**FE_ORDER - 1) + 2 * e_int[k] + floor[k] for k in richardson}
    d = differences(fine, modal)
    assert_within(d, bound, f"{FE_MESHES[1]} elements vs analytic modes")
    # The elements converge to the modes, not merely near them: the coarse mesh is further off.
    assert differences(coarse, modal)["t"] > d["t"]


def test_energy_ledger_closes():
    """The ledger's balance error (energy + dissipated - work in - E0) is integration error: within the
    sum of the local error bounds of the run, and it falls with the tolerance. Its dissipation (the
    beam's modal damping) is the reference's."""
    sim = viz3d.load_scene(SCENE).data["sim"]
    run, fine = run_scene(), run_scene(tol_cut=TOL_CUT)
    # Sum of local errors: each accepted step changes each of the n_y state components by at most
    # sqrt(n_y) (atol + rtol |y_i|) (rms error norm <= 1), so the energy by at most sqrt(n_y) (rtol
    # sum_i |dE/dy_i y_i| + atol |grad E|_1); sum_i |dE/dy_i y_i| <= 2 (T + U) + |V_g| <= 3 E_scale and
    # |grad E|_1 <= |momenta| + |weights| + |elastic forces| <= 4e3 (F < 400 N, m g < 3 N, 5 modes; x 4 =
    # 1 / sqrt(modal mass 0.06 kg) if the modal coordinates are mass-normalised). A loose bound (~1e-2 J):
    # the two checks after it are the sharp ones.
    n_y, E_scale = 2 * (6 + 5) + 3, abs(run.E0)  # ball 6 + beam 5 coordinates and rates, 3 work integrals
    per_step = np.sqrt(n_y) * (sim["rtol"] * 3 * E_scale + sim["atol"] * 4e3)
    assert run.balance_error <= run.n_steps * per_step
    roundoff = 10 * EPS * fine.n_steps * E_scale
    assert fine.balance_error <= run.balance_error / INTEGRATION_SAFETY + roundoff, \
        f"balance error {fine.balance_error:.3g} J at tol/100 vs {run.balance_error:.3g} J: not integration error"
    ref = reference()
    bound = viz3d_integration_error()["dissipated"] + reference_integration_error()["dissipated"] \
        + floors(ref)["dissipated"]
    assert abs(run.strike.dissipated - ref.dissipated) <= bound
    assert ref.dissipated > 1e3 * bound  # the damping term is not vacuous


@pytest.mark.slow
def test_several_bounces_match_the_reference():
    """The whole scene (4 strikes): the same strikes, each with the reference's number of contacts,
    starting where the reference's do."""
    t_end = viz3d.load_scene(SCENE).data["sim"]["t_end"]
    dt = 1e-3  # contact times only: few frames
    viz, viz_fine = run_scene(t_end, sample_dt=dt).strike, run_scene(t_end, TOL_CUT, sample_dt=dt).strike
    ref, ref_fine = reference(t_end, sample_dt=dt), reference(t_end, TOL_CUT, sample_dt=dt)
    T1 = fundamental_period()
    n_viz, n_ref = [s.size for s in strikes(viz, T1)], [s.size for s in strikes(ref, T1)]
    assert n_viz == n_ref and len(n_ref) >= 3, (n_viz, n_ref)
    bound = INTEGRATION_SAFETY * (np.abs(viz.on - viz_fine.on).max() + np.abs(ref.on - ref_fine.on).max()) + FLOOR_T
    assert np.abs(viz.on - ref.on).max() <= bound
