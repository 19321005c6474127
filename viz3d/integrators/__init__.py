"""Integrator registry: name -> factory of an ``Integrator``."""

from __future__ import annotations

from viz3d.integrators import tableaus
from viz3d.integrators.base import Integrator, Rhs, Status, StepResult
from viz3d.integrators.explicit_rk import ExplicitRK
from viz3d.integrators.implicit import GeneralizedAlpha, Trapezoidal
from viz3d.integrators.tableaus import DOPRI5, EULER, HEUN, RK4, ButcherTableau

INTEGRATORS = {
    "euler": lambda: ExplicitRK(EULER),
    "heun": lambda: ExplicitRK(HEUN),
    "rk4": lambda: ExplicitRK(RK4),
    "dopri5": lambda: ExplicitRK(DOPRI5),
    "dop853": lambda: ExplicitRK(tableaus.DOP853),
    "trapezoidal": Trapezoidal,
    "gen_alpha": GeneralizedAlpha,
}


def make_integrator(name: str) -> Integrator:
    """Instantiate the registered integrator ``name`` with its default parameters (KeyError lists
    the valid names)."""
    try:
        return INTEGRATORS[name]()
    except KeyError:
        raise KeyError(f"unknown integrator {name!r}; valid: {', '.join(INTEGRATORS)}") from None


def __getattr__(name: str):
    """``DOP853`` on first use (``viz3d.integrators.tableaus`` builds it then)."""
    if name != "DOP853":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return tableaus.DOP853


__all__ = ["INTEGRATORS", "DOP853", "DOPRI5", "Integrator", "Rhs", "Status", "StepResult", "ButcherTableau",
           "ExplicitRK", "GeneralizedAlpha", "Trapezoidal", "make_integrator"]
