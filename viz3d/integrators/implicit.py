"""Implicit one-step methods: the trapezoidal rule and the generalized-alpha method, their stage
equations solved by a (simplified) Newton iteration with a finite-difference Jacobian.

They see only the vector field (and ``rhs.n_q``; ``GeneralizedAlpha`` also the optional
``rhs.retract``, see base.py). The Newton matrix is kept in the solver state and reused from step
to step while the iteration contracts fast; it is rebuilt when it does not, and a step whose
iteration fails even with a fresh matrix returns a failed ``Status`` with the reason.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, ClassVar

import numpy as np

from viz3d._typing import FloatArray
from viz3d.integrators.base import Integrator, Status, StepResult

#: Newton iterations allowed per attempt (with a reused, then with a fresh matrix).
NEWTON_MAX_ITER = 12
#: Converged when an update moves the step's result by at most ``NEWTON_TOL * max(1, max |y|)``:
#: far below the truncation errors the convergence tests measure (1e-8 at their finest steps).
NEWTON_TOL = 1e-11
#: Iterations of the damped full Newton tried when the simplified one fails.
NEWTON_DAMPED_ITER = 30
#: An iteration whose update shrinks by less than this factor is too slow: rebuild the matrix.
NEWTON_MAX_RATE = 0.5
#: Relative finite-difference step of the Jacobian (square root of machine epsilon), applied to
#: ``max(|x_j|, floor)``; each method gives the floor that moves its state by about one SI unit
#: times FD_REL (1 m, 1 rad, 1 m/s): smaller steps drown in the round-off of stiff forces.
FD_REL = np.sqrt(np.finfo(float).eps)


@dataclass(frozen=True)
class NewtonMatrix:
    """LU factors of the Jacobian of a step's residual, kept in the solver state.

    Attributes
    ----------
    lu : tuple
        ``scipy.linalg.lu_factor`` output.
    h : float
        Step it was built for [s] (rebuilt when the step changes).
    """

    lu: tuple
    h: float


def fd_jacobian(residual: Callable[[FloatArray], FloatArray], x: FloatArray, r0: FloatArray,
                floor: float = 1.0) -> FloatArray:
    """Forward-difference Jacobian ``d residual / d x``, shape (n, n); ``r0 = residual(x)``; the step
    of ``x_j`` is ``FD_REL * max(|x_j|, floor)``."""
    J = np.empty((r0.size, x.size))
    for j in range(x.size):
        dx = FD_REL * max(abs(x[j]), floor)
        xp = x.copy()
        xp[j] += dx
        J[:, j] = (residual(xp) - r0) / dx
    return J


def newton_solve(residual, guesses, matrix: NewtonMatrix | None, h: float, what: str,
                 effect: float = 1.0, scale: float = 1.0) -> tuple[FloatArray, NewtonMatrix | None, Status]:
    """Solve ``residual(x) = 0`` from the first of ``guesses`` that works; return ``(x, matrix,
    status)``.

    From each guess, first with the reused ``matrix`` (if built for this ``h``), then, if that
    fails or contracts slower than ``NEWTON_MAX_RATE``, with a fresh finite-difference matrix
    (abandoned only if its updates grow). Converged when an update changes the step's result by at
    most ``NEWTON_TOL * max(1, scale)``, the result moving by ``effect`` times the update of ``x``
    (e.g. ``h gamma`` when ``x`` are accelerations and the result velocities): a criterion on the
    state, not on ``x``, whose round-off floor can be far larger (stiff springs). The finite
    differences step ``x`` by at least ``FD_REL / effect`` (the state by ``FD_REL``).
    """
    from scipy.linalg import lu_factor
    size, tol = np.inf, NEWTON_TOL * max(1.0, scale) / effect
    for x0 in guesses:
        for fresh in ((False, True) if matrix is not None and matrix.h == h else (True,)):
            r = residual(x0)
            if fresh:
                if not np.all(np.isfinite(r)):
                    break
                matrix = NewtonMatrix(lu_factor(fd_jacobian(residual, x0, r, 1.0 / effect)), h)
            x, size = _iterate(residual, x0, r, matrix, tol, fresh)
            if size <= tol:
                return x, matrix, Status.OK
    x, last, size = _damped_newton(residual, guesses[0], tol, 1.0 / effect, h)
    if size <= tol:
        return x, last, Status.OK
    return guesses[0], matrix, Status.failed(f"{what}: Newton iteration did not converge with h = {h:.3g} s "
                                             f"(last update {size * effect:.2e} against a tolerance {tol * effect:.2e}); "
                                             f"try a smaller sim.dt")


def _iterate(residual, x0, r, matrix, tol, fresh):
    """Simplified Newton from ``x0`` (``r = residual(x0)``): ``(x, size)``, ``size`` below ``tol``
    on success (the update, or the error still ahead of a contracting iteration:
    rate / (1 - rate) times the update, Hairer & Wanner, Solving ODEs II, IV.8)."""
    from scipy.linalg import lu_solve
    x, prev, size = x0.copy(), np.inf, np.inf
    for _ in range(NEWTON_MAX_ITER):
        if not np.all(np.isfinite(r)):
            return x0, np.inf
        dx = lu_solve(matrix.lu, -r)
        x = x + dx
        size = np.max(np.abs(dx))
        rate = size / prev if np.isfinite(prev) else np.inf
        if size <= tol or (rate < 1.0 and rate / (1.0 - rate) * size <= tol):
            return x, 0.0
        if size > (prev if fresh else NEWTON_MAX_RATE * prev):
            break
        prev = size
        r = residual(x)
    return x0, size


def _damped_newton(residual, x0, tol, floor, h):
    """Last resort when simplified Newton fails (large steps across a nonlinearity, a contact
    opening or closing inside the step): full Newton, the matrix rebuilt at every iterate, each
    update halved until the residual norm falls (Armijo backtracking, Dennis & Schnabel, sec. 6.3).
    Returns ``(x, matrix at x, size)``, ``size <= tol`` on success."""
    from scipy.linalg import lu_factor, lu_solve
    x, r, matrix, size = x0.copy(), residual(x0), None, np.inf
    for _ in range(NEWTON_DAMPED_ITER):
        if not np.all(np.isfinite(r)):
            break
        matrix = NewtonMatrix(lu_factor(fd_jacobian(residual, x, r, floor)), h)
        dx = lu_solve(matrix.lu, -r)
        norm, lam = np.linalg.norm(r), 1.0
        while True:
            r_new = residual(x + lam * dx)
            if np.all(np.isfinite(r_new)) and np.linalg.norm(r_new) <= (1.0 - 1e-4 * lam) * norm or lam < 2.0**-6:
                break
            lam *= 0.5
        x, r, size = x + lam * dx, r_new, lam * np.max(np.abs(dx))
        if size <= tol:
            return x, matrix, size
    return x0, matrix, size


@dataclass(frozen=True)
class TrapezoidalState:
    """Solver state of ``Trapezoidal``.

    Attributes
    ----------
    matrix : NewtonMatrix or None
    dy : ndarray or None, shape (n_y,)
        The last step's change of ``y`` (the predictor extrapolates it).
    h : float
        That step [s].
    """

    matrix: NewtonMatrix | None = None
    dy: FloatArray | None = None
    h: float = 0.0


class Trapezoidal(Integrator):
    """Implicit trapezoidal rule, ``y1 = y0 + h/2 (f(t0, y0) + f(t1, y1))``.

    Order 2. One stage equation of size ``n_y``, solved by simplified Newton (matrix
    ``I - h/2 df/dy`` by finite differences, reused across steps) from the last step's change
    extrapolated or, failing that, from positions moved by explicit Euler with velocities
    unchanged (which never overshoots a stiff mode). Implicit, A-stable, not L-stable (no damping of unresolved stiff
    modes); symmetric; conserves quadratic invariants of linear systems. No error estimate.
    Solver state: ``TrapezoidalState``.

    References
    ----------
    E. Hairer, G. Wanner, Solving ODEs II, sec. IV.3 (stability) and IV.8 (simplified Newton).
    """

    name = "trapezoidal"
    order = 2
    implicit = True

    def step(self, rhs, t, y, h, f0=None, state=None):
        state = TrapezoidalState() if state is None else state
        f0 = rhs(t, y) if f0 is None else f0
        y_rest = y + 0.5 * h * f0
        # Predictors: the last step's change extrapolated, and positions by explicit Euler with
        # velocities unchanged (never overshoots a stiff mode; tried if the first fails).
        safe = y.copy()
        safe[: rhs.n_q] += h * f0[: rhs.n_q]
        guesses = [safe] if state.dy is None or state.dy.shape != y.shape else [y + (h / state.h) * state.dy, safe]

        def residual(y1):
            return y1 - y_rest - 0.5 * h * rhs(t + h, y1)

        with np.errstate(all="ignore"):
            y1, matrix, status = newton_solve(residual, guesses, state.matrix, h, f"trapezoidal step at t = {t:.6g} s",
                                              scale=np.max(np.abs(y)))
        if not status.ok:
            return StepResult(y, f0=f0, status=status, state=TrapezoidalState(matrix))
        return StepResult(y1, f0=f0, f1=rhs(t + h, y1), state=TrapezoidalState(matrix, y1 - y, h))


@dataclass(frozen=True)
class AlphaState:
    """Solver state of ``GeneralizedAlpha``.

    Attributes
    ----------
    v_dot : ndarray, shape (n_v,)
        Accelerations ``f_v(t_n, y_n)`` at the last step [m/s^2, rad/s^2].
    a : ndarray, shape (n_v,)
        The method's pseudo-accelerations ``a_n`` (differ from ``v_dot`` by ``O(h)``).
    matrix : NewtonMatrix or None
    """

    v_dot: FloatArray
    a: FloatArray
    matrix: NewtonMatrix | None = None


class GeneralizedAlpha(Integrator):
    """Chung-Hulbert generalized-alpha method on ``y = [q, v]``, positions on a Lie group.

    Order 2. One stage equation of size ``n_v`` (the accelerations at ``t1``), simplified Newton
    with a finite-difference matrix reused across steps. Implicit, unconditionally stable on
    linear problems, with numerical damping of unresolved frequencies set by the spectral radius
    at infinity ``rho_inf`` (1: none, the trapezoidal rule; 0: asymptotic annihilation). Not
    symplectic. No error estimate. Solver state: ``AlphaState``.

    In the form of Arnold & Bruls, with ``f_v`` the acceleration part of ``rhs``:

        (1 - alpha_m) a1 + alpha_m a0 = (1 - alpha_f) v_dot1 + alpha_f v_dot0,   v_dot1 = f_v(t1, y1)
        v1 = v0 + h ((1 - gamma) a0 + gamma a1)
        q1 = retract(q0, h v0 + h^2 ((1/2 - beta) a0 + beta a1))

    ``alpha_m = (2 rho - 1) / (rho + 1)``, ``alpha_f = rho / (rho + 1)``, ``gamma = 1/2 + alpha_f -
    alpha_m``, ``beta = (gamma + 1/2)^2 / 4``. Positions move by a velocity-space increment
    through ``rhs.retract`` (Lie-group generalized-alpha of Bruls & Cardona: ``R1 = R0 exp(skew(
    h B_omega-increment))``); for ``q_dot = v`` systems without it, ``q1 = q0 + increment``. The
    state ``(v_dot, a)`` lives in velocity space, so it stays valid across a change of position
    coordinates between steps (a chart switch).

    Parameters
    ----------
    rho_inf : float
        Spectral radius at infinite step, in [0, 1].

    References
    ----------
    J. Chung, G. M. Hulbert, J. Appl. Mech. 60 (1993) 371-375.
    M. Arnold, O. Bruls, Multibody Syst. Dyn. 18 (2007) 185-202.
    O. Bruls, A. Cardona, J. Comput. Nonlinear Dyn. 5 (2010) 031002.
    """

    name = "gen_alpha"
    order = 2
    implicit = True
    #: Default spectral radius at infinity (moderate damping of unresolved modes).
    RHO_INF: ClassVar[float] = 0.8

    def __init__(self, rho_inf: float = RHO_INF):
        if not 0.0 <= rho_inf <= 1.0:
            raise ValueError(f"gen_alpha: rho_inf must be in [0, 1], got {rho_inf}")
        self.rho_inf = float(rho_inf)
        self.alpha_m = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0)
        self.alpha_f = rho_inf / (rho_inf + 1.0)
        self.gamma = 0.5 + self.alpha_f - self.alpha_m
        self.beta = 0.25 * (self.gamma + 0.5) ** 2

    def init(self, rhs, t, y):
        _check_second_order(rhs, y)
        v_dot = rhs(t, y)[rhs.n_q:]
        return AlphaState(v_dot, v_dot.copy())

    def step(self, rhs, t, y, h, f0=None, state=None):
        state = self.init(rhs, t, y) if state is None else state
        n_q = rhs.n_q
        q0, v0 = y[:n_q], y[n_q:]
        retract = getattr(rhs, "retract", lambda q, w: q + w)

        def advance(v_dot1):
            a1 = ((1.0 - self.alpha_f) * v_dot1 + self.alpha_f * state.v_dot - self.alpha_m * state.a) / (1.0 - self.alpha_m)
            v1 = v0 + h * ((1.0 - self.gamma) * state.a + self.gamma * a1)
            q1 = retract(q0, h * v0 + h * h * ((0.5 - self.beta) * state.a + self.beta * a1))
            return np.concatenate([q1, v1]), a1

        def residual(v_dot1):
            return v_dot1 - rhs(t + h, advance(v_dot1)[0])[n_q:]

        with np.errstate(all="ignore"):
            v_dot1, matrix, status = newton_solve(residual, [state.v_dot], state.matrix, h, f"gen_alpha step at t = {t:.6g} s",
                                                  effect=h * self.gamma * (1.0 - self.alpha_f) / (1.0 - self.alpha_m),
                                                  scale=np.max(np.abs(y)))
        if not status.ok:
            return StepResult(y, status=status, state=AlphaState(state.v_dot, state.a, matrix))
        y1, a1 = advance(v_dot1)
        return StepResult(y1, state=AlphaState(v_dot1, a1, matrix))

    def __repr__(self):
        return f"GeneralizedAlpha(rho_inf={self.rho_inf})"


def _check_second_order(rhs, y) -> None:
    if not hasattr(rhs, "retract") and 2 * rhs.n_q != y.size:
        raise ValueError("gen_alpha needs y = [q, v] with q_dot = v (n_q = n_v) or an rhs.retract hook")
