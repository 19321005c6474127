"""Integrator registry: name -> factory of an ``Integrator``."""

from __future__ import annotations

from viz3d.integrators.base import Integrator, Rhs, StepResult
from viz3d.integrators.explicit_rk import ExplicitRK
from viz3d.integrators.tableaus import DOPRI5, EULER, HEUN, RK4, ButcherTableau

INTEGRATORS = {
    "euler": lambda: ExplicitRK(EULER),
    "heun": lambda: ExplicitRK(HEUN),
    "rk4": lambda: ExplicitRK(RK4),
}


def make_integrator(name: str) -> Integrator:
    """Instantiate the registered integrator ``name`` (KeyError lists the valid names)."""
    try:
        return INTEGRATORS[name]()
    except KeyError:
        raise KeyError(f"unknown integrator {name!r}; valid: {', '.join(INTEGRATORS)}") from None


__all__ = ["INTEGRATORS", "DOPRI5", "Integrator", "Rhs", "StepResult", "ButcherTableau", "ExplicitRK", "make_integrator"]
