"""Integrator protocol: a vector field in, a step out. Integrators never see bodies or joints.

What an integrator may use of the vector field ``rhs`` (all documented on ``Rhs``):

* ``rhs(t, y)``: ``y_dot``, always;
* ``rhs.n_q``: where ``y = [q, v]`` splits (partitioned and second-order methods);
* ``rhs.retract(q, w)``, optional: the positions reached from ``q`` by the velocity-space
  increment ``w`` (shape ``(n_y - n_q,)``), for methods that advance positions on a Lie group
  (``GeneralizedAlpha``). Without it such methods require ``q_dot = v`` and use ``q + w``.
* ``rhs.dexpinv(u, v)`` and ``rhs.n_v``, optional (None: absent): the rate ``u_dot`` (n_v,) of the
  velocity-space increment ``u`` (n_v,) for which ``retract(q, u)`` moves at the velocities ``v =
  y[n_q:n_q + n_v]``. With it, explicit Runge-Kutta methods without an error estimate take
  Munthe-Kaas steps (``ExplicitRK``: positions ``retract(q0, u)``, never a sum of position rates).

Methods with history between steps (the pseudo-accelerations of the generalized-alpha method, a
reused Newton matrix) keep it in a *solver state*, a value returned by ``init`` and by every
``step`` (``StepResult.state``) and passed back into the next ``step`` (diffrax's
``init``/``step(..., solver_state)``). Whoever changes ``y`` between steps in a way the method
cannot know (re-charting, projections) simply passes the solver state on: each method documents
what its state holds and why that stays valid.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, Callable, ClassVar, Protocol

from viz3d._typing import FloatArray


class Rhs(Protocol):
    """``y_dot = rhs(t, y)``; ``n_q`` is where partitioned methods split ``y = [q, v]``.

    Optional hooks: ``retract(q, w) -> q_new``; ``dexpinv(u, v) -> u_dot`` with ``n_v`` (see the
    module docstring).
    """

    n_q: int

    def __call__(self, t: float, y: FloatArray) -> FloatArray: ...


@dataclass(frozen=True)
class Status:
    """Outcome of a step: ``Status.OK`` or a failure carrying a human-readable message.

    Attributes
    ----------
    ok : bool
    message : str
        Why the step failed (empty when ``ok``), e.g. "Newton iteration did not converge ...".
    """

    ok: bool
    message: str = ""
    OK: ClassVar["Status"]

    @classmethod
    def failed(cls, message: str) -> "Status":
        return cls(False, message)


Status.OK = Status(True)


@dataclass(frozen=True)
class StepResult:
    """Outcome of one step.

    Attributes
    ----------
    y : ndarray, shape (n_y,)
        State at ``t + h`` (meaningless unless ``status.ok``).
    error : ndarray or None
        Embedded local error estimate, ``None`` when the method has none.
    f0, f1 : ndarray or None
        ``rhs`` at the start and at the end of the step when the method evaluated them (FSAL
        methods give ``f1`` for free); used for the next step and for dense output.
    status : Status
        ``Status.OK``, or why the step failed (an implicit method whose Newton iteration did not
        converge); a failed step never returns NaN as if it were a state.
    state : object or None
        The method's solver state after the step (``None`` for methods without history).
    stages : ndarray or None, shape (s, n_y)
        Stage derivatives of a Runge-Kutta step, kept for its continuous extension.
    """

    y: FloatArray
    error: FloatArray | None = None
    f0: FloatArray | None = None
    f1: FloatArray | None = None
    status: Status = Status.OK
    state: Any = None
    stages: FloatArray | None = None


class Integrator(ABC):
    """One-step method. Subclasses set ``name`` and ``order`` and implement ``step``.

    Hooks
    -----
    step(rhs, t, y, h, f0=None, state=None) -> StepResult
        Required. Advance from ``t`` to ``t + h``.
    init(rhs, t, y) -> solver state
        Optional; default ``None`` (no history).

    Capabilities read by tests and by ``viz3d.methods``: ``order``; ``embedded`` (an error
    estimate usable by ``adaptive.Controller``); ``implicit``.

    Adding one: subclass (or, for an explicit Runge-Kutta method, add a ``ButcherTableau``),
    register a factory in ``viz3d.integrators.INTEGRATORS``; the convergence-order test then
    measures ``order`` automatically (give it a coarsest step count in ``COARSEST`` of
    tests/numerics/test_convergence.py if its order is new).
    """

    name: ClassVar[str]
    order: ClassVar[int]
    implicit: ClassVar[bool] = False

    @property
    def embedded(self) -> bool:
        """True when ``step`` returns an error estimate (adaptive stepping is possible)."""
        return False

    def init(self, rhs: Rhs, t: float, y: FloatArray) -> Any:
        """Solver state before the first step (default: none)."""
        return None

    @abstractmethod
    def step(self, rhs: Callable[[float, FloatArray], FloatArray], t: float, y: FloatArray, h: float,
             f0: FloatArray | None = None, state: Any = None) -> StepResult:
        """Advance ``y`` from ``t`` to ``t + h``; ``f0 = rhs(t, y)`` may be passed if known,
        ``state`` is the solver state returned by ``init`` or by the previous step."""
