"""Formulations: how accelerations come out of the constrained equations of motion.

A formulation has two hooks: ``solve(system, mass, Q, rows, cfg) -> ((a, a_e), lam)`` with the
accelerations split like every generalized vector (``viz3d.mass``: ``a`` (nb + 1, 6), ``a_e``
(n_e,)), and ``post_step(system, state) -> state`` (identity unless it stabilizes between steps). A formulation that does its own time stepping (``ALI3P``) also sets the class attribute
``integrator`` to the one integrator name it accepts and implements ``init_memory(system, state, kernel)``
and ``step(system, state, h, memory) -> (state, memory, Status)``; ``viz3d.simulate`` then calls
those instead of an integrator. Registry: ``FORMULATIONS``; see docs/extending.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from viz3d.constraints import (
    ConstraintRows,
    apply_jacobian,
    apply_jacobian_transpose,
    schur_solve,
)
from viz3d.integrators.base import Status
from viz3d.kinematics import Configuration
from viz3d.stabilization import project_positions, project_velocities
from viz3d.system import State, System

if TYPE_CHECKING:
    from viz3d.ali3p import ALI3PMemory


def solve_augmented(system: System, mass, Q, rows: ConstraintRows, gamma, compliance: float = 0.0):
    """Solve ``[M C_v^T; C_v -compliance I] [a; lam] = [Q; gamma]`` by the Schur complement.

    ``compliance = 0`` is the rigid augmented system; ``compliance = 1 / alpha`` the penalty
    formulation (``Penalty``). ``Q = (frame (nb + 1, 6), elastic (n_e,))``. Returns ``(a, a_e)``
    [m/s^2, rad/s^2, ...] and ``lam`` (n_c,).
    """
    layout = system.joints
    Q_f, Q_e = Q
    a_free, a_free_e = mass.solve(Q_f, Q_e)
    rhs = apply_jacobian(layout, rows.J, a_free, rows.Je, a_free_e) - gamma
    lam = schur_solve(layout, mass, rows.J, rhs, compliance, rows.Je, rows.inactive)
    CtL, CtL_e = apply_jacobian_transpose(layout, rows.J, lam, Q_f.shape[0], rows.Je)
    d, d_e = mass.solve(CtL, CtL_e)
    return (a_free - d, a_free_e - d_e), lam


@dataclass(frozen=True)
class Index1:
    """The seed's augmented index-1 system, acceleration-level constraints only.

    Constraint drift (|C| and |C_v v|) grows unchecked: the honest baseline.
    """

    name: ClassVar[str] = "index1"
    #: The one integrator this formulation accepts (None: any); set by formulations that step
    #: themselves.
    integrator: ClassVar[str | None] = None

    def solve(self, system: System, mass, Q, rows: ConstraintRows, cfg: Configuration):
        return solve_augmented(system, mass, Q, rows, rows.gamma)

    def post_step(self, system: System, state: State) -> State:
        return state


def _stabilized_gamma(system, rows, cfg: Configuration, damping: float, frequency: float):
    """``gamma - 2 damping C_d - frequency^2 C``, shape (n_c,): the right-hand side that makes the
    violation obey ``C_dd + 2 damping C_d + frequency^2 C = 0`` (Baumgarte; penalty springs)."""
    eta_dot = np.concatenate(cfg.eta_dot) if cfg.eta_dot else np.zeros(0)
    C_d = rows.velocity_residual(system.joints, _per_body_twist(cfg.twist), eta_dot)
    return rows.gamma - 2.0 * damping * C_d - frequency**2 * rows.C


@dataclass(frozen=True)
class Baumgarte(Index1):
    """Index-1 with Baumgarte stabilization: ``C_dd + 2 alpha C_d + beta^2 C = 0``.

    Attributes
    ----------
    alpha : float
        Damping rate [1/s].
    beta : float
        Natural frequency [rad/s].

    References
    ----------
    J. Baumgarte, Comput. Methods Appl. Mech. Eng. 1 (1972) 1-16.
    """

    name: ClassVar[str] = "baumgarte"
    alpha: float = 10.0
    beta: float = 10.0

    def solve(self, system, mass, Q, rows, cfg):
        return solve_augmented(system, mass, Q, rows, _stabilized_gamma(system, rows, cfg, self.alpha, self.beta))


@dataclass(frozen=True)
class Projection(Index1):
    """Index-1 plus mass-orthogonal projection onto ``C = 0`` and ``C_dot = C_v v + C_t = 0`` after each step.

    Attributes
    ----------
    tol : float
        Position tolerance of the Newton projection [m].
    """

    name: ClassVar[str] = "projection"
    tol: float = 1e-12

    def post_step(self, system, state):
        q, _ = project_positions(system, state.q, state.chart, tol=self.tol, memory=state.memory, t=state.t)
        return state.replace(q=q, v=project_velocities(system, q, state.v, state.chart, state.memory, t=state.t))


@dataclass(frozen=True)
class Penalty(Index1):
    """Penalty formulation (seed 004, eq. 3.16): each constraint is a critically damped spring.

    ``M v_dot + C_v^T alpha (C_dd + 2 xi omega C_d + omega^2 C) = Q``, i.e. multipliers
    ``lam = alpha (C_dd + 2 xi omega C_d + omega^2 C)`` proportional to the violation and its
    derivatives, with ``C_dd = C_v v_dot - gamma``. Eliminating ``v_dot`` gives the augmented system
    with a compliance ``1 / alpha`` on its diagonal:

        (C_v M^-1 C_v^T + I / alpha) lam = C_v M^-1 Q - gamma + 2 xi omega C_d + omega^2 C,

    solved by the same Schur-complement factorization as ``Index1`` (positive definite even for
    redundant joints). The violation then obeys ``C_dd + 2 xi omega C_d + omega^2 C = lam / alpha``:
    with ``xi = 1`` its impulse response is positive with integral ``1 / omega^2``, so beyond
    transients ``|C| <= max |lam| / (alpha omega^2)``. ``alpha -> infinity`` is Baumgarte with
    ``alpha_B = xi omega``, ``beta_B = omega``. Not stiff: the eigenvalues of the violation are
    ``-xi omega +- ...``, whatever ``alpha``.

    Attributes
    ----------
    alpha : float
        Penalty factor [kg] (``alpha`` times an acceleration is a force); seed 004: 1e6 - 1e11.
    xi : float
        Damping ratio of the constraint springs [-] (seed 004: 1, critical).
    omega : float
        Their natural frequency [rad/s] (seed 004: 10).

    References
    ----------
    E. Bayo, J. Garcia de Jalon, M. A. Serna, Comput. Methods Appl. Mech. Eng. 71 (1988) 183-195.
    """

    name: ClassVar[str] = "penalty"
    alpha: float = 1e7
    xi: float = 1.0
    omega: float = 10.0

    def solve(self, system, mass, Q, rows, cfg):
        gamma = _stabilized_gamma(system, rows, cfg, self.xi * self.omega, self.omega)
        return solve_augmented(system, mass, Q, rows, gamma, compliance=1.0 / self.alpha)


@dataclass(frozen=True)
class ALI3P(Index1):
    """Index-3 augmented Lagrangian with mass-orthogonal projections (ALI3-P, seed 004 eqs.
    3.17-3.28), on the implicit trapezoidal rule: a formulation that does its own time stepping.

    Order 2. Per step, Newton-Raphson with the approximate tangent on the trapezoidal equations of
    motion ``M v_dot + C_v^T (alpha C + lam*) = Q`` at ``t + h``, the multipliers updated by
    ``lam* += alpha C`` after every iteration until ``max |C| <= tol``; then velocities and
    accelerations are projected (eqs. 3.27, 3.28). Positions move on ``R^3 x SO(3)`` by the
    velocity-space increment ``h (v0 + v1) / 2`` (``viz3d.ali3p``). ``solve`` (used for the
    reaction forces of output frames) is the index-1 solve at the state reached.

    Attributes
    ----------
    alpha : float
        Penalty factor of the augmented Lagrangian [N/m] (``alpha C`` is a force).
    tol : float
        Constraint tolerance of the iteration [m] (and of its velocity-space update [m, rad]).
    start : Penalty
        Formulation of the initial accelerations and multipliers (seed 004: the penalty method).

    References
    ----------
    J. Cuadrado, J. Cardenal, P. Morer, E. Bayo, Multibody Syst. Dyn. 4 (2000) 55-73.
    D. Dopico, F. Gonzalez, J. Cuadrado, J. Kovecses, J. Comput. Nonlinear Dyn. 9 (2014) 041006.
    """

    name: ClassVar[str] = "ali3p"
    integrator: ClassVar[str | None] = "trapezoidal"
    alpha: float = 1e9
    tol: float = 1e-12
    start: Penalty = field(default_factory=Penalty)

    def init_memory(self, system: System, state: State, kernel=None) -> ALI3PMemory:
        """Accelerations and multipliers at ``state`` from ``start``, and the force tangent; the
        steps run in the compiled kernel when ``kernel`` (a ``viz3d.kernel.KernelStepper`` of the
        system) is given, else in NumPy."""
        from viz3d.ali3p import init_memory  # (on first use: a run of another formulation does not import it)

        if kernel is None:
            return init_memory(system, self, state)
        from viz3d.kernel.ali3p import KernelALI3P

        return init_memory(system, self, state, KernelALI3P(system, kernel))

    def step(self, system: System, state: State, h: float, memory: ALI3PMemory, failed=None
             ) -> tuple[State, ALI3PMemory, Status]:
        """Advance ``state`` by ``h`` [s] (see ``viz3d.ali3p``; ``failed``: its first attempts' memory
        and status when already known)."""
        from viz3d.ali3p import ali3p_step

        return ali3p_step(system, self, state, h, memory, failed=failed)


def _per_body_twist(twist):
    return np.concatenate([twist.W_v, twist.B_omega], axis=1)


FORMULATIONS = {cls.name: cls for cls in (Index1, Baumgarte, Projection, Penalty, ALI3P)}
