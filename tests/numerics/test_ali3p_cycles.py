"""ALI3-P where the branches it holds cycle (``viz3d.ali3p._solve``, ``_filippov``): a step whose forces
jump between two branch sets, neither of which keeps itself.

A rod (m, length L, radius r) hinged at its top falls from rest onto a joint stop with a stiff damper
(``c h / (2 I_O)`` about 10 at h = 1 ms). The stop's force ``clip(-k delta - c q_dot)`` jumps by ``c q_dot``
where the rod reaches it. The stop is placed so that the step that reaches it starts ``0.8 h w`` short
of it (``w`` the rate there): held free, the rod ends inside the stop (which is then found engaged); held
engaged, its damper stops the rod within ``h w / (2 (1 + c h / (2 I_O)))`` of where it starts, short
of the stop (then found free). The step's solution is on the boundary: the rod at the stop, the stop's
force between none and its damper's (Filippov's convex combination). Before, the step did not settle
and its halvings, from accelerations of the other set, threw the rod back at 4.4 rad/s, 2.6 times the
rate it came in with.
"""

from __future__ import annotations

import numpy as np
import pytest
from kernel_runs import ali3p_runs_agree
from systems import ROD_L, ROD_M, THETA0, rod_on_a_stop

from viz3d.ali3p import ROUND_OFF_FACTOR
from viz3d.dynamics import body_state
from viz3d.integrators import make_integrator
from viz3d.simulate import Simulation

#: The stop's place [rad], stiffness [N m/rad] and damping [N m s/rad] (the rod: ``systems.rod_on_a_stop``).
STOP, STOP_K, STOP_C = np.radians(-30.0), 1e3, 3e3
#: Standard gravity [m/s^2]; the step [s]; the stop's offset [rad] past STOP that puts the start of the
#: step that reaches it 0.8 h w short of it (from the steps of this rod: 121 steps reach STOP - 1.8e-4 rad).
G, H, OFFSET = 9.81, 1e-3, 1.15e-3


def _rod_on_a_damped_stop(tmp_path):
    return rod_on_a_stop(tmp_path, STOP - THETA0 + OFFSET, STOP_K, STOP_C, 0.2, H)


def test_a_step_whose_stop_set_cycles_ends_on_the_stop_and_gives_no_energy_back(tmp_path):
    """Through the cycling step and 70 more, on the NumPy path: one step ends on the stop's boundary,
    within the bisection's ``ROUND_OFF_FACTOR * tol`` (a rotation increment [rad]) plus the iteration's
    ``tol``; and the rod never moves faster than the rate ``w`` the weight's work gives it at the stop (a
    passive stop gives back at most what it took; before: 4.4 rad/s against w = 1.67 rad/s)."""
    system, state, form, I_O = _rod_on_a_damped_stop(tmp_path)
    stop = next(e for e in system.forces if e.branches)
    sim = Simulation(system, state, make_integrator("trapezoidal"), form, H, compiled=False)
    depth, rate = [], []
    for _ in range(190):
        s = sim.step()
        q, q_dot = stop.coordinates(body_state(system, s.q, s.v, s.chart, s.t))
        depth.append(q[0] - stop.upper[0])
        rate.append(q_dot[0])
    d = ROD_L / 2
    w = np.sqrt(2 * ROD_M * G * d * (np.cos(STOP + OFFSET) - np.cos(THETA0)) / I_O)
    assert np.min(np.abs(depth)) <= (ROUND_OFF_FACTOR + 1) * form.tol, np.min(np.abs(depth))
    assert max(depth) > 0.0  # it went on into the stop
    assert np.max(np.abs(rate)) <= w, (np.max(np.abs(rate)), w)


@pytest.mark.slow  # its compiled signature (ALI3-P with a stop) compiles for minutes cold
def test_the_compiled_steps_take_the_numpy_steps_through_a_cycle(tmp_path):
    """The compiled ALI3-P takes the NumPy path's steps through the cycling step (its bisection), to
    ``ali3p_agreement_bound``, with as many evaluations."""
    system, state, form, _ = _rod_on_a_damped_stop(tmp_path)
    n = 130
    compiled, numpy = ali3p_runs_agree(system, state, form, n, H)
    assert abs(compiled.n_rhs - numpy.n_rhs) <= max(2, 0.02 * numpy.n_rhs), (compiled.n_rhs, numpy.n_rhs)
