"""Integrator protocol: a vector field in, a step out. Integrators never see bodies or joints."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Callable, ClassVar, Protocol

from viz3d._typing import FloatArray


class Rhs(Protocol):
    """``y_dot = rhs(t, y)``; ``n_q`` is where partitioned methods split ``y = [q, v]``."""

    n_q: int

    def __call__(self, t: float, y: FloatArray) -> FloatArray: ...


@dataclass(frozen=True)
class StepResult:
    """Outcome of one step.

    Attributes
    ----------
    y : ndarray, shape (n_y,)
        State at ``t + h``.
    error : ndarray or None
        Embedded local error estimate, ``None`` when the method has none.
    f0, f1 : ndarray or None
        ``rhs`` at the start and at the end of the step when the method evaluated them (FSAL
        methods give ``f1`` for free); used for the next step and for dense output.
    """

    y: FloatArray
    error: FloatArray | None = None
    f0: FloatArray | None = None
    f1: FloatArray | None = None


class Integrator(ABC):
    """One-step method. Subclasses set ``name`` and ``order`` and implement ``step``.

    Register the class (or a tableau instance) in ``viz3d.integrators.INTEGRATORS``; the
    convergence-order test then measures ``order`` automatically.
    """

    name: ClassVar[str]
    order: ClassVar[int]

    @abstractmethod
    def step(self, rhs: Callable[[float, FloatArray], FloatArray], t: float, y: FloatArray, h: float,
             f0: FloatArray | None = None) -> StepResult:
        """Advance ``y`` from ``t`` to ``t + h``; ``f0 = rhs(t, y)`` may be passed if known."""
