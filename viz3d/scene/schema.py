"""A small declarative validator for scene files: tables of typed fields with defaults.

Validation returns a new, fully resolved dict (defaults filled in) or raises ``SceneError``
naming the file, the key path and what was expected. Unknown keys are errors.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

REQUIRED = object()
#: ``default=OPTIONAL`` leaves the key out of the resolved table when absent.
OPTIONAL = object()


class SceneError(ValueError):
    """A scene file that cannot be used, with the file, the key path and what was expected."""

    def __init__(self, source: str, path: str, expected: str, got: Any = REQUIRED):
        self.source, self.path, self.expected = source, path, expected
        got_txt = "" if got is REQUIRED else f", got {got!r}"
        super().__init__(f"{source}: {path or '<top level>'}: expected {expected}{got_txt}")


class Invalid(Exception):
    """Raised by a checker: ``expected`` describes a valid value."""

    def __init__(self, expected: str):
        self.expected = expected


Checker = Callable[[Any], Any]


@dataclass(frozen=True)
class Field:
    """One key of a table: a checker (value -> normalized value), a default and a description."""

    check: Checker
    default: Any = REQUIRED
    doc: str = ""


@dataclass(frozen=True)
class Table:
    """A table with known keys; ``variants`` selects extra keys by the value of ``tag``."""

    fields: dict[str, Field]
    doc: str = ""
    tag: str | None = None
    variants: dict[str, "Table"] = field(default_factory=dict)


@dataclass(frozen=True)
class ArrayOf:
    """An array of tables (``[[name]]`` in TOML)."""

    table: Table
    default: Any = field(default_factory=list)


def validate(value: Any, spec: Table | ArrayOf, source: str, path: str = "") -> Any:
    """Check ``value`` against ``spec``; return the resolved copy or raise ``SceneError``."""
    if isinstance(spec, ArrayOf):
        if not isinstance(value, list):
            raise SceneError(source, path, "an array of tables ([[...]])", value)
        return [validate(item, spec.table, source, f"{path}[{i}]") for i, item in enumerate(value)]
    if not isinstance(value, dict):
        raise SceneError(source, path, "a table", value)
    fields = dict(spec.fields)
    if spec.tag is not None:
        tag = value.get(spec.tag, fields[spec.tag].default)
        if not isinstance(tag, str) or tag not in spec.variants:
            raise SceneError(source, _join(path, spec.tag), f"one of {sorted(spec.variants)}", tag)
        fields.update(spec.variants[tag].fields)
    unknown = sorted(set(value) - set(fields))
    if unknown:
        raise SceneError(source, _join(path, unknown[0]), f"one of the known keys {sorted(fields)} (unknown key)")
    out = {}
    for key, f in fields.items():
        sub = _join(path, key)
        if key not in value:
            if f.default is REQUIRED:
                raise SceneError(source, sub, f"a value ({f.doc or 'required key'}); the key is missing")
            if f.default is OPTIONAL:
                continue
            if isinstance(f.check, Table):
                out[key] = validate({}, f.check, source, sub)
            elif isinstance(f.check, ArrayOf):
                out[key] = []
            else:
                out[key] = copy.deepcopy(f.default)
            continue
        if isinstance(f.check, (Table, ArrayOf)):
            out[key] = validate(value[key], f.check, source, sub)
            continue
        try:
            out[key] = f.check(value[key])
        except Invalid as exc:
            raise SceneError(source, sub, exc.expected, value[key]) from None
    return out


def allowed_path(base_dir: Path, name: str, allowed: tuple[Path, ...], source: str, key: str) -> Path:
    """The file ``name`` (relative to the scene's folder ``base_dir``), if it lies below that folder or
    below one of the ``allowed`` folders (``--mesh-dir``); else ``SceneError`` naming ``key``: a scene
    only reads files its user put within reach."""
    roots = [base_dir.resolve(), *(Path(d).resolve() for d in allowed)]
    target = (base_dir / name).resolve()
    if not any(target.is_relative_to(root) for root in roots):
        where = " or ".join(str(r) for r in roots)
        raise SceneError(source, key, f"a file inside {where} (allow another folder explicitly with --mesh-dir DIR)", name)
    return target


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


# ---------------------------------------------------------------- checkers


def number(x):
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
        raise Invalid("a finite number")
    return float(x)


def positive(x):
    x = _num(x, "a positive number")
    if not x > 0:
        raise Invalid("a positive number")
    return x


def nonnegative(x):
    x = _num(x, "a number >= 0")
    if x < 0:
        raise Invalid("a number >= 0")
    return x


def poisson_ratio(x):
    """Poisson's ratio of an isotropic elastic material: -1 < nu < 0.5 (positive definite
    elasticity: E > 0 with a positive shear modulus E / (2 (1 + nu)) and bulk modulus E / (3 (1 - 2 nu)))."""
    x = _num(x, "a Poisson's ratio in (-1, 0.5)")
    if not -1.0 < x < 0.5:
        raise Invalid("a Poisson's ratio in (-1, 0.5)")
    return x


def unit_fraction(x):
    """A number in (0, 1] (a Timoshenko shear coefficient)."""
    x = _num(x, "a number in (0, 1]")
    if not 0.0 < x <= 1.0:
        raise Invalid("a number in (0, 1]")
    return x


def unit_interval(x):
    """A number in [0, 1] (``sim.rho_inf``)."""
    x = _num(x, "a number in [0, 1]")
    if not 0.0 <= x <= 1.0:
        raise Invalid("a number in [0, 1]")
    return x


def _num(x, expected):
    try:
        return number(x)
    except Invalid:
        raise Invalid(expected) from None


def positive_int(x):
    if isinstance(x, bool) or not isinstance(x, int) or x < 1:
        raise Invalid("an integer >= 1")
    return x


def count(most: int) -> Checker:
    """An integer in 1..``most``: a resolution (points on a rim, cells, sections) whose arrays grow
    with it, bounded far above any use so that a typo cannot exhaust the machine's memory."""
    expected = f"an integer from 1 to {most}"

    def check(x):
        if isinstance(x, bool) or not isinstance(x, int) or not 1 <= x <= most:
            raise Invalid(expected)
        return x

    return check


def nonnegative_int(x):
    if isinstance(x, bool) or not isinstance(x, int) or x < 0:
        raise Invalid("an integer >= 0")
    return x


def string(x):
    if not isinstance(x, str):
        raise Invalid("a string")
    return x


def name(x):
    if not isinstance(x, str) or not x or x == "ground" or "/" in x:
        raise Invalid("a non-empty name without '/', other than 'ground'")
    return x


def boolean(x):
    if not isinstance(x, bool):
        raise Invalid("true or false")
    return x


def numbers(x):
    if not (isinstance(x, list) and all(isinstance(e, (int, float)) and not isinstance(e, bool) for e in x)):
        raise Invalid("a list of numbers")
    return [float(e) for e in x]


def dict_of_numbers(x):
    if not (isinstance(x, dict) and all(isinstance(k, str) and isinstance(v, (int, float)) and not isinstance(v, bool)
                                        for k, v in x.items())):
        raise Invalid("a table of numbers")
    return {k: float(v) if isinstance(v, float) else v for k, v in x.items()}


def vec3(x):
    if not (isinstance(x, list) and len(x) == 3):
        raise Invalid("a list of 3 numbers")
    try:
        return [number(e) for e in x]
    except Invalid:
        raise Invalid("a list of 3 numbers") from None


def rotation_matrices(x):
    if not (isinstance(x, list) and all(isinstance(m, list) and len(m) == 3 for m in x)):
        raise Invalid("a list of 3x3 rotation matrices (columns: the body's axes in world)")
    out = [[vec3(r) for r in m] for m in x]
    for m in out:
        if not np.allclose(np.asarray(m) @ np.asarray(m).T, np.eye(3), atol=1e-9):
            raise Invalid("a list of 3x3 rotation matrices (columns: the body's axes in world)")
    return out


def any_table(x):
    if not isinstance(x, dict):
        raise Invalid("a table")
    return x


def vec3_list(x):
    if not isinstance(x, list):
        raise Invalid("a list of points [[x, y, z], ...]")
    try:
        return [vec3(p) for p in x]
    except Invalid:
        raise Invalid("a list of points [[x, y, z], ...]") from None


def nonzero_vec3(x):
    v = vec3(x)
    if np.linalg.norm(v) == 0:
        raise Invalid("a nonzero list of 3 numbers")
    return v


def mat3_or_diag(x):
    """Inertia: a 3x3 matrix or the 3 diagonal entries."""
    expected = "an inertia tensor: 3 principal moments [Ixx, Iyy, Izz] or a 3x3 matrix [kg m^2]"
    if isinstance(x, list) and len(x) == 3 and all(isinstance(r, list) for r in x):
        try:
            return [vec3(r) for r in x]
        except Invalid:
            raise Invalid(expected) from None
    try:
        d = vec3(x)
    except Invalid:
        raise Invalid(expected) from None
    return [[d[0], 0.0, 0.0], [0.0, d[1], 0.0], [0.0, 0.0, d[2]]]


def rotation3(x):
    """A rotation matrix: 3 rows of 3 numbers, orthonormal with determinant +1 (to 1e-9)."""
    expected = "a rotation matrix: 3 rows [[.., .., ..], ...], orthonormal, determinant +1"
    if not (isinstance(x, list) and len(x) == 3):
        raise Invalid(expected)
    try:
        R = np.array([vec3(r) for r in x], float)
    except Invalid:
        raise Invalid(expected) from None
    if np.abs(R.T @ R - np.eye(3)).max() > 1e-9 or np.linalg.det(R) < 0:
        raise Invalid(expected)
    return R.tolist()


def color(x):
    """RGB as three 0-255 integers or "#rrggbb"."""
    expected = 'a colour: [r, g, b] with 0-255 integers or "#rrggbb"'
    if isinstance(x, str) and len(x) == 7 and x[0] == "#":
        try:
            return [int(x[i:i + 2], 16) for i in (1, 3, 5)]
        except ValueError:
            raise Invalid(expected) from None
    if isinstance(x, list) and len(x) == 3 and all(isinstance(c, int) and not isinstance(c, bool) and 0 <= c <= 255 for c in x):
        return list(x)
    raise Invalid(expected)


def one_of(*choices: str) -> Checker:
    def check(x):
        if x not in choices:
            raise Invalid(f"one of {list(choices)}")
        return x

    return check


def describe(spec: Table | ArrayOf, indent: str = "") -> str:
    """Plain-text reference of a schema (used by docs and ``viz3d list``)."""
    table = spec.table if isinstance(spec, ArrayOf) else spec
    lines = []
    for key, f in table.fields.items():
        if isinstance(f.check, (Table, ArrayOf)):
            title = f"[[{key}]]" if isinstance(f.check, ArrayOf) else f"[{key}]"
            lines.append(f"{indent}{title}{' (optional)' if f.default is OPTIONAL else ''}: {f.doc}")
            lines.append(describe(f.check, indent + "  "))
            continue
        default = "" if f.default in (REQUIRED, OPTIONAL) else f" (default {f.default!r})"
        req = " (required)" if f.default is REQUIRED else ""
        lines.append(f"{indent}{key}{req}{default}: {f.doc}")
    for tag, variant in table.variants.items():
        lines.append(f"{indent}[{table.tag} = {tag!r}] {variant.doc}")
        lines.append(describe(variant, indent + "  "))
    return "\n".join(lines)
