"""The points of a study: a cartesian grid (``--grid key=v1,v2,...`` or ``key=a:b:n[:log]``) and/or a
random sample (``--sample key=dist(args) --n N --seed S``); each point is a set of scene overrides.

With both, every draw of the sample runs at every grid point (the same draws at each: common random
numbers, so grid values compare on equal terms).
"""

from __future__ import annotations

import itertools
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from viz3d.scene.load import parse_value

#: Distributions of ``--sample`` and the arguments each takes.
DISTRIBUTIONS = {"uniform": "low, high", "loguniform": "low, high (both > 0)", "normal": "mean, std",
                 "int": "low, high (integers, both included)", "choice": "v1, v2, ..."}
#: The expected form of each flag, for messages.
GRID_FORM = "key.path=V1,V2,... or key.path=A:B:N (N values from A to B; A:B:N:log for log spacing)"
SAMPLE_FORM = "key.path=DIST(ARGS) with DIST one of " + ", ".join(f"{k}({v})" for k, v in DISTRIBUTIONS.items())


class PlanError(ValueError):
    """A study flag that cannot be used: names the flag, what was expected and what was given."""

    def __init__(self, flag: str, expected: str, got: str):
        super().__init__(f"{flag}: expected {expected}, got {got!r}")


@dataclass(frozen=True)
class Point:
    """One run of a study.

    Attributes
    ----------
    values : tuple
        The value of each study key at this point (in the study's key order).
    overrides : tuple of str
        ``key.path=value`` overrides that set them (``--set`` syntax).
    """

    values: tuple
    overrides: tuple[str, ...]


@dataclass(frozen=True)
class Axis:
    """A grid key and its values, with the override text of each value."""

    key: str
    values: tuple
    texts: tuple[str, ...]


@dataclass(frozen=True)
class Distribution:
    """A sampled key: ``kind`` one of ``DISTRIBUTIONS`` with its arguments."""

    key: str
    kind: str
    args: tuple

    def draw(self, rng: np.random.Generator, n: int) -> list:
        """``n`` values drawn with ``rng``."""
        a = self.args
        if self.kind == "uniform":
            return [float(x) for x in rng.uniform(a[0], a[1], n)]
        if self.kind == "loguniform":
            return [float(x) for x in np.exp(rng.uniform(np.log(a[0]), np.log(a[1]), n))]
        if self.kind == "normal":
            return [float(x) for x in rng.normal(a[0], a[1], n)]
        if self.kind == "int":
            return [int(x) for x in rng.integers(a[0], a[1], n, endpoint=True)]
        return [a[i] for i in rng.integers(0, len(a), n)]


def parse_grid(text: str) -> Axis:
    """``key=v1,v2,...`` (TOML values, bare words as strings) or ``key=a:b:n[:log]``."""
    key, values = _split(text, "--grid", GRID_FORM)
    parts = values.split(":")
    if len(parts) in (3, 4) and all(_is_number(p) for p in parts[:2]):
        return _range_axis(key, parts, text)
    items = [v.strip() for v in values.split(",") if v.strip()]
    if not items:
        raise PlanError("--grid", GRID_FORM, text)
    return Axis(key, tuple(parse_value(v) for v in items), tuple(items))


def _range_axis(key: str, parts: list[str], text: str) -> Axis:
    a, b = float(parse_value(parts[0])), float(parse_value(parts[1]))
    n = parse_value(parts[2])
    spacing = parts[3] if len(parts) == 4 else "lin"
    if isinstance(n, bool) or not isinstance(n, int) or n < 1 or spacing not in ("lin", "log"):
        raise PlanError("--grid", GRID_FORM + " (N a positive integer)", text)
    if spacing == "log" and (a <= 0 or b <= 0):
        raise PlanError("--grid", "A:B:N:log with A > 0 and B > 0", text)
    values = np.geomspace(a, b, n) if spacing == "log" else np.linspace(a, b, n)
    values = tuple(float(v) for v in values)
    return Axis(key, values, tuple(repr(v) for v in values))


def parse_sample(text: str) -> Distribution:
    """``key=dist(args)``, ``dist`` one of ``DISTRIBUTIONS``."""
    key, spec = _split(text, "--sample", SAMPLE_FORM)
    m = re.fullmatch(r"\s*([a-z_]+)\s*\((.*)\)\s*", spec)
    if not m or m.group(1) not in DISTRIBUTIONS:
        raise PlanError("--sample", SAMPLE_FORM, text)
    kind, args = m.group(1), tuple(parse_value(a.strip()) for a in m.group(2).split(",") if a.strip())
    if not _valid_args(kind, args):
        raise PlanError("--sample", f"{kind}({DISTRIBUTIONS[kind]})", text)
    return Distribution(key, kind, args)


def _valid_args(kind: str, args: tuple) -> bool:
    if kind == "choice":
        return len(args) >= 1
    numeric = len(args) == 2 and all(_number_value(a) for a in args)
    if kind == "int":
        return numeric and all(isinstance(a, int) for a in args) and args[0] <= args[1]
    if kind == "loguniform":
        return numeric and 0 < args[0] <= args[1]
    if kind == "normal":
        return numeric and args[1] >= 0
    return numeric and args[0] <= args[1]


def plan_points(axes: list[Axis], samples: list[Distribution], n: int, seed: int) -> tuple[tuple[str, ...], list[Point]]:
    """The study's keys (grid keys, then sampled keys) and its points: the grid's cartesian product
    (first key slowest), times ``n`` draws of the sample (drawn once with ``seed``)."""
    keys = tuple(a.key for a in axes) + tuple(d.key for d in samples)
    if len(set(keys)) < len(keys):
        dup = next(k for k in keys if keys.count(k) > 1)
        raise PlanError("--grid/--sample", "each key once", dup)
    rng = np.random.default_rng(seed)
    drawn = [d.draw(rng, n) for d in samples]
    draws = list(zip(*drawn)) if samples else [()]
    points = []
    for cell in itertools.product(*(list(zip(a.values, a.texts)) for a in axes)):
        for draw in draws:
            values = tuple(v for v, _ in cell) + tuple(draw)
            texts = tuple(t for _, t in cell) + tuple(_text(v) for v in draw)
            points.append(Point(values, tuple(f"{k}={t}" for k, t in zip(keys, texts))))
    return keys, points


def grid_points(grid: dict[str, list]) -> list[Point]:
    """The cartesian product of ``grid`` (key path -> values, first key slowest) as points."""
    axes = [Axis(k, tuple(v), tuple(_text(x) for x in v)) for k, v in grid.items()]
    return plan_points(axes, [], 1, 0)[1]


def _split(text: str, flag: str, form: str) -> tuple[str, str]:
    key, sep, rest = text.partition("=")
    if not sep or not key.strip() or not rest.strip():
        raise PlanError(flag, form, text)
    return key.strip(), rest.strip()


def _text(value: Any) -> str:
    """Override text of a drawn value (TOML: strings quoted)."""
    return f'"{value}"' if isinstance(value, str) else repr(value)


def _is_number(text: str) -> bool:
    return _number_value(parse_value(text.strip()))


def _number_value(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x)
