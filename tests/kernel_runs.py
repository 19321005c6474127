"""Runs through the compiled kernel against the NumPy path, and the bound they must agree to.

The kernel computes the NumPy formulas in another order, so one step may differ by the step map's
round-off: eps times its condition number, measured as the NumPy step's change under relative
perturbations of eps of the state (``step_roundoff``). Over N steps each step's difference is carried
by the flow, which amplifies a difference at most by ``growth`` (measured on the kernel with a small
perturbation); so after N steps ``|y_kernel - y_numpy| <= N growth factor step_roundoff``, ``factor``
covering the sampling of the round-off (``ROUNDOFF_FACTOR``).
"""

from __future__ import annotations

import numpy as np

from viz3d.integrators import make_integrator
from viz3d.simulate import Simulation

EPS = np.finfo(float).eps
#: Allowed multiple of the measured round-off of a step (test_kernel.py's factor).
ROUNDOFF_FACTOR = 10.0
#: Sign patterns the round-off of a step is measured with.
SENSITIVITY_SAMPLES = 3
#: Relative size of the perturbation that measures how the flow of N steps amplifies a difference (small enough
#: to be linear, large enough to stand above round-off).
GROWTH_PROBE = 1e-7


def run(system, state, form, n: int, dt: float, compiled: bool, method: str = "rk4") -> Simulation:
    """``n`` steps of ``method`` from ``state`` (through the kernel's many-steps call when ``compiled``)."""
    sim = Simulation(system, state, make_integrator(method), form, dt, compiled=compiled)
    sim.steps(n)
    return sim


def with_y(system, state, y):
    """``state`` with ``y = [q, v, w]``."""
    q, v, w = system.split_y(y)
    return state.replace(q=q, v=v, w=w)


def off_constraints(state, size: float, seed: int = 3):
    """``state`` with random offsets of ``size`` on q and v [m, rad or -, m/s, rad/s]."""
    rng = np.random.default_rng(seed)
    return state.replace(q=state.q + size * rng.normal(size=state.q.shape), v=state.v + size * rng.normal(size=state.v.shape))


def step_roundoff(system, state, form, dt: float, method: str = "rk4") -> float:
    """Round-off scale of one NumPy step of ``method`` from ``state``: max change of its result under
    relative perturbations of eps of ``y`` (random signs), at least eps |y|."""
    ref = run(system, state, form, 1, dt, compiled=False, method=method).state.y
    signs = np.random.default_rng(1).choice([-1.0, 1.0], size=(SENSITIVITY_SAMPLES, state.y.size))
    change = max(np.abs(run(system, with_y(system, state, state.y * (1 + EPS * s)), form, 1, dt, compiled=False,
                            method=method).state.y - ref).max() for s in signs)
    return max(change, EPS * np.abs(ref).max())


def growth(system, state, form, n: int, dt: float, method: str = "rk4") -> float:
    """How much ``n`` kernel steps amplify a small difference of the initial state (max-norm ratio, at least 1)."""
    d = GROWTH_PROBE * np.abs(state.y).max() * np.random.default_rng(2).choice([-1.0, 1.0], size=state.y.size)
    a = run(system, state, form, n, dt, compiled=True, method=method).state.y
    b = run(system, with_y(system, state, state.y + d), form, n, dt, compiled=True, method=method).state.y
    return max(np.abs(a - b).max() / np.abs(d).max(), 1.0)


def agreement_bound(system, state, form, n: int, dt: float, method: str = "rk4") -> float:
    """Bound on ``max |y_kernel - y_numpy|`` after ``n`` steps of ``method``, ``dt`` from ``state``
    (module docstring)."""
    return (n * growth(system, state, form, n, dt, method) * ROUNDOFF_FACTOR
            * step_roundoff(system, state, form, dt, method))


def ali3p_agreement_bound(system, state, form, n: int, dt: float) -> float:
    """Bound on ``max |y_kernel - y_numpy|`` after ``n`` ALI3-P steps of ``dt`` from ``state``: each path
    stops its Newton iteration within ``form.tol`` of the step's root in the increment ``dx`` [m, rad],
    so the two ``dx`` differ by at most ``2 tol`` and the velocities ``v1 = 2 dx / h - v0`` by ``4 tol / h``
    (the positions by less); with the step's round-off (``step_roundoff``, ``ROUNDOFF_FACTOR``) that is one
    step's difference, carried by the flow as in ``agreement_bound``."""
    per_step = 4.0 * form.tol / dt + ROUNDOFF_FACTOR * step_roundoff(system, state, form, dt, "trapezoidal")
    return n * growth(system, state, form, n, dt, "trapezoidal") * per_step


def ali3p_runs_agree(system, state, form, n: int, dt: float) -> tuple[Simulation, Simulation]:
    """``n`` ALI3-P steps of ``dt`` from ``state`` on the compiled kernel and on the NumPy path, checked to
    take the kernel and to end within ``ali3p_agreement_bound``: ``(compiled, numpy)``."""
    compiled = run(system, state, form, n, dt, compiled=True, method="trapezoidal")
    assert compiled.kernel_note == "compiled kernel"
    numpy = run(system, state, form, n, dt, compiled=False, method="trapezoidal")
    bound = ali3p_agreement_bound(system, state, form, n, dt)
    diff = np.abs(compiled.state.y - numpy.state.y).max()
    assert diff <= bound, f"y after {n} steps: {diff:.2e} > {bound:.2e}"
    return compiled, numpy
