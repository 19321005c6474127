"""Perturbation ensembles (issue 11): ``n`` members per study point, each an ordinary run of the point's
scene with seeded perturbations of stated size, so a verdict that flips at round-off shows up as a
fraction with a confidence interval instead of one run's answer.

A perturbation is a key, a kind and a size (``--perturb KEY=SIZE,...``); a member draws
``u ~ U(-1, 1)`` per key and runs with

* ``relative`` keys (uncertain parameters: friction coefficients, hauling speed, ...):
  ``value = nominal * (1 + SIZE u)``, ``0 < SIZE < 1`` (the sign of the nominal is kept);
* ``absolute`` keys (a key whose nominal is 0, e.g. the starting pose's ``ship.payout`` [m]):
  ``value = nominal + SIZE u``, ``SIZE > 0``.

Member ``m`` draws its ``u`` from ``np.random.default_rng((seed, m))``: the same draws at every grid
point (common random numbers, so cells compare on equal terms) and in an ensemble of any size
(member 3 of 5 is member 3 of 20, so a larger ensemble reuses the smaller one's runs from the
results store). A member's overrides are ``--set`` text (``repr`` floats, read back exactly): it can
be run alone with ``viz3d run SCENE --set ...``.

The fraction of members with an outcome comes with Wilson's score interval (``wilson_interval``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from viz3d.studies.plan import PlanError, Point

#: Kinds of perturbation and the sizes each accepts (for messages).
KINDS = {"relative": "0 < SIZE < 1 (value = nominal x (1 + SIZE u), u uniform in [-1, 1])",
         "absolute": "SIZE > 0 (value = nominal + SIZE u, u uniform in [-1, 1])"}
#: The expected form of ``--perturb``.
PERTURB_FORM = "KEY=SIZE,KEY=SIZE,..."
#: Two-sided 95 % normal quantile, Phi^-1(0.975), of the intervals reported.
Z_95 = 1.959963984540054


@dataclass(frozen=True)
class Perturbation:
    """One perturbed key.

    Attributes
    ----------
    key : str
        Scene key path (``--set`` syntax), e.g. ``ship.mu``.
    kind : str
        One of ``KINDS``.
    size : float
        Half-width of the uniform perturbation: relative (1), or in the key's unit.
    unit : str
        The key's unit (for ``absolute`` sizes; "" when none).
    """

    key: str
    kind: str
    size: float
    unit: str = ""

    def value(self, nominal: float, u: float) -> float:
        """The perturbed value for the draw ``u`` in [-1, 1]."""
        if self.kind == "relative":
            return nominal * (1.0 + self.size * u)
        return nominal + self.size * u

    def describe(self) -> str:
        """``ship.mu +-10 % (relative)``, ``ship.payout +-1e-06 m (absolute)``."""
        if self.kind == "relative":
            return f"{self.key} +-{100 * self.size:.3g} % (relative)"
        return f"{self.key} +-{self.size:.3g}{' ' + self.unit if self.unit else ''} (absolute)"


@dataclass(frozen=True)
class Ensemble:
    """How many members per point, what they perturb, and the seed of their draws."""

    n: int
    perturbations: tuple[Perturbation, ...]
    seed: int = 0

    def draws(self, member: int) -> np.ndarray:
        """Member ``member``'s ``u`` in [-1, 1], one per perturbation, shape (n_perturbations,)."""
        return np.random.default_rng((self.seed, member)).uniform(-1.0, 1.0, len(self.perturbations))

    def describe(self) -> str:
        what = ", ".join(p.describe() for p in self.perturbations) or "nothing"
        return f"ensemble of {self.n} member(s) per point (seed {self.seed}), perturbing {what}"


@dataclass(frozen=True)
class Member:
    """One run of an ensemble: its point, its index and the overrides of its perturbations."""

    point: Point
    index: int
    perturbed: tuple[str, ...]

    @property
    def study_point(self) -> Point:
        """The run as a study point: the grid values and the member index; the point's overrides,
        then the perturbed ones."""
        return Point((*self.point.values, self.index), (*self.point.overrides, *self.perturbed))


def parse_ensemble(n: int, texts: Sequence[str], allowed: Mapping[str, tuple[str, str]], seed: int = 0) -> Ensemble:
    """The ``Ensemble`` of ``--ensemble n``, ``--perturb`` texts (each ``KEY=SIZE,...``) and ``--seed``;
    ``allowed`` maps each key that may be perturbed to its kind and unit. Raises ``PlanError``
    naming the flag, what it expects and what it got."""
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise PlanError("--ensemble", "a positive integer (members per grid point)", str(n))
    items = [item.strip() for text in texts for item in text.split(",") if item.strip()]
    perturbations = tuple(_perturbation(item, allowed) for item in items)
    keys = [p.key for p in perturbations]
    if len(set(keys)) < len(keys):
        raise PlanError("--perturb", "each key once", next(k for k in keys if keys.count(k) > 1))
    if n > 1 and not perturbations:
        raise PlanError("--perturb", f"at least one KEY=SIZE with --ensemble {n} (unperturbed members are one run "
                        f"repeated); keys: {', '.join(allowed)}", "")
    return Ensemble(n, perturbations, seed)


def _perturbation(item: str, allowed: Mapping[str, tuple[str, str]]) -> Perturbation:
    key, sep, size_text = (s.strip() for s in item.partition("="))
    if not sep or not key or not size_text:
        raise PlanError("--perturb", PERTURB_FORM, item)
    if key not in allowed:
        raise PlanError("--perturb", f"a key among {', '.join(allowed)}", key)
    kind, unit = allowed[key]
    try:
        size = float(size_text)
    except ValueError:
        size = math.nan
    ok = 0.0 < size < 1.0 if kind == "relative" else 0.0 < size < math.inf
    if not ok:
        raise PlanError("--perturb", f"for {key} ({kind}{', ' + unit if unit else ''}) a size {KINDS[kind]}", item)
    return Perturbation(key, kind, size, unit)


def members(ensemble: Ensemble, point: Point, nominal: Mapping[str, float]) -> list[Member]:
    """The ensemble's members at ``point``, whose scene has the ``nominal`` value of each perturbed key."""
    out = []
    for m in range(ensemble.n):
        u = ensemble.draws(m)
        perturbed = tuple(f"{p.key}={p.value(float(nominal[p.key]), float(x))!r}"
                          for p, x in zip(ensemble.perturbations, u))
        out.append(Member(point, m, perturbed))
    return out


def wilson_interval(k: int, n: int, z: float = Z_95) -> tuple[float, float]:
    """Wilson's score interval for a binomial proportion: ``k`` successes in ``n`` trials, normal
    quantile ``z`` (``Z_95``: 95 %, two-sided); ``(nan, nan)`` for ``n = 0``.

    ``(p + z^2/2n -+ z sqrt(p (1 - p)/n + z^2/4n^2)) / (1 + z^2/n)`` with ``p = k/n``; unlike the
    normal ('Wald') interval it stays inside [0, 1] and is not empty at ``k = 0`` or ``k = n``.

    References
    ----------
    E. B. Wilson, "Probable inference, the law of succession, and statistical inference", JASA 22
    (1927) 209-212; L. D. Brown, T. T. Cai, A. DasGupta, "Interval estimation for a binomial
    proportion", Statistical Science 16 (2001) 101-133.
    """
    if n <= 0:
        return math.nan, math.nan
    p, z2 = k / n, z * z
    centre = (p + z2 / (2 * n)) / (1 + z2 / n)
    half = z * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n)) / (1 + z2 / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def nominal_values(scene_data: Mapping, keys: Sequence[str]) -> dict[str, float]:
    """The value of each key path (``ship.mu``) in a loaded scene's tables (``Scene.data``)."""
    out = {}
    for key in keys:
        node = scene_data
        for part in key.split("."):
            node = node[part]
        out[key] = float(node)
    return out
