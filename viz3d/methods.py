"""Method strings (``"ali3p+quaternion"``, ``"dopri5+projection"``) and which combinations of
integrator, formulation and rotation coordinates make sense.

A method string joins registry names with ``+``, at most one per kind (integrators,
formulations, rotations; ``viz3d list`` shows them); the kinds left out keep the scene's values,
except that a formulation which does its own time stepping also selects its integrator
(``"ali3p"`` means ``ali3p+trapezoidal``). ``method_overrides`` turns a method string into
``--set``-style overrides for ``viz3d.load_scene``; ``check_combination`` is what
``viz3d.simulate.Simulation`` asks before it runs.
"""

from __future__ import annotations

from viz3d.coordinates import ROTATIONS, RotationCoordinates
from viz3d.formulation import FORMULATIONS
from viz3d.integrators import INTEGRATORS

#: Registry of each kind, under the scene key it sets.
KINDS = {"sim.integrator": INTEGRATORS, "sim.formulation": FORMULATIONS, "sim.rotation": ROTATIONS}
#: Integrators that move positions by a velocity-space increment (need ``RotationCoordinates.advance``).
LIE_GROUP_INTEGRATORS = ("gen_alpha",)


class MethodError(ValueError):
    """A method string or a combination of methods that cannot run, saying what would.

    Attributes
    ----------
    key : str
        Scene key at fault (``sim.integrator``, ...), or "method" for a malformed string.
    expected : str
        What would be valid.
    got : str
    """

    def __init__(self, key: str, expected: str, got):
        self.key, self.expected, self.got = key, expected, got
        super().__init__(f"{key}: expected {expected}, got {got!r}")


def valid_names() -> str:
    """All registered names by kind, for error messages."""
    return "; ".join(f"{key.split('.')[1]}s: {', '.join(reg)}" for key, reg in KINDS.items())


def parse_method(method: str) -> dict[str, str]:
    """Scene keys set by a method string, e.g. ``{"sim.formulation": "ali3p", "sim.rotation":
    "quaternion", "sim.integrator": "trapezoidal"}`` for ``"ali3p+quaternion"``.

    Raises
    ------
    MethodError
        For an empty or unknown name, two names of one kind, or an explicit combination that
        ``check_combination`` rejects.
    """
    out: dict[str, str] = {}
    for token in (t.strip() for t in method.split("+")):
        keys = [key for key, reg in KINDS.items() if token in reg]
        if not keys:
            raise MethodError("method", f"'+'-joined names from {valid_names()}", token or method)
        if keys[0] in out:
            raise MethodError("method", f"at most one {keys[0].split('.')[1]} in a method string", method)
        out[keys[0]] = token
    own = FORMULATIONS[out["sim.formulation"]].integrator if "sim.formulation" in out else None
    if own is not None:
        out.setdefault("sim.integrator", own)
    if "sim.integrator" in out:
        check_combination(out["sim.integrator"], out.get("sim.formulation"), out.get("sim.rotation"))
    return out


def method_overrides(method: str) -> list[str]:
    """``parse_method`` as ``"key=value"`` overrides for ``viz3d.load_scene``."""
    return [f"{key}={value}" for key, value in parse_method(method).items()]


def check_combination(integrator, formulation, rotation=None, rtol: float | None = None) -> None:
    """Raise ``MethodError`` unless the methods can run together.

    ``integrator``, ``formulation``, ``rotation`` are registry names or the objects (an
    ``Integrator``, a formulation, ``RotationCoordinates``; classes work for the last two);
    ``formulation`` and ``rotation`` may be None (the scene's own).
    Rules: a formulation that steps itself (``ali3p``) runs only with its own integrator;
    adaptive stepping (a tolerance ``rtol``, scene key ``sim.rtol``) needs an integrator with an
    embedded error estimate; Lie-group methods need rotation coordinates that implement
    ``advance``.
    """
    integrator = INTEGRATORS[integrator]() if isinstance(integrator, str) else integrator
    formulation = FORMULATIONS[formulation] if isinstance(formulation, str) else formulation
    rotation = ROTATIONS[rotation] if isinstance(rotation, str) else rotation
    rotation = rotation if rotation is None or isinstance(rotation, type) else type(rotation)
    own = getattr(formulation, "integrator", None)
    if own is not None and integrator.name != own:
        raise MethodError("sim.integrator", f"{own!r} with sim.formulation = {formulation.name!r} (it does its own "
                          f"{own} stepping; method string {formulation.name!r})", integrator.name)
    if rtol is not None and not integrator.embedded:
        embedded = [n for n, make in INTEGRATORS.items() if make().embedded]
        raise MethodError("sim.rtol", f"no tolerance with sim.integrator = {integrator.name!r}: adaptive steps need an "
                          f"embedded error estimate ({', '.join(embedded)})", rtol)
    lie = integrator.name in LIE_GROUP_INTEGRATORS or own is not None
    if lie and rotation is not None and rotation.advance is RotationCoordinates.advance:
        raise MethodError("sim.rotation", f"rotation coordinates with a finite-rotation update (advance) for "
                          f"{formulation.name if own else integrator.name!r}", rotation.name)
