"""Normal contact force laws: force magnitude from local indentation, its rate and a contact memory.

Conventions (SI; see docs/notation.md for the rest of viz3d):

* ``alpha`` [m] is the local indentation (approach of the two bodies' distant points, seed 002
  eq. 3.29): ``alpha > 0`` when they overlap. In a flexible model it is only the *local* part the
  structural model cannot represent (thesis Fig. 7.1).
* ``alpha_dot`` [m/s] is its rate: positive while the bodies approach (compression), negative
  while they separate (restitution).
* ``F`` [N] is the compressive normal force magnitude, ``F >= 0`` always (no adhesion): wherever a
  formula would give a tensile force the law returns 0. It pushes the bodies apart, so in a
  one-degree-of-freedom impact ``m_eff alpha_ddot = -F``.
* ``ContactMemory`` holds the history a law needs, as a frozen value: the approach speed at the
  onset of the current contact (``alpha_dot_0 > 0``; Hunt-Crossley, Lankarani-Nikravesh, Flores)
  and, for elastoplastic laws, the largest indentation ``alpha_m`` ever reached, the residual
  (permanent) indentation ``alpha_r`` it leaves and whether the contact is on its virgin loading
  curve. ``onset(alpha_dot_0, previous)`` starts a contact (a crater from ``previous`` persists);
  ``update(memory, alpha, alpha_dot)`` is pure and returns the advanced memory. ``force`` uses
  ``max(memory.alpha_max, alpha)``, so it is exact as long as ``alpha`` is monotonic between updates.
* ``elastic_energy(alpha, memory)`` [J] is the energy the contact would give back if unloaded from
  ``alpha`` now: the energy ledger of an impact is ``dissipated = work done on the contact -
  elastic_energy``.

Every law is a frozen dataclass registered in ``NORMAL_LAWS``; tests iterate over it.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, replace
from typing import ClassVar, Self

import numpy as np

from viz3d._typing import FloatArray
from viz3d.compiled import Items, compiled_piece, jit, normal_force
from viz3d.contact.parameters import (
    flores_factor,
    fully_plastic_indentation,
    hertz_stiffness,
    hertz_stiffness_thesis,
    hunt_crossley_factor,
    lankarani_nikravesh_factor,
    linear_damping,
    plane_strain_modulus,
    power_plastic_constants,
    yield_force,
    yield_indentation_thesis,
    yield_indentation_yigit,
    yigit_plastic_stiffness,
)

#: Approach speeds below this at contact onset [m/s] are raised to it: the damping term of the
#: onset-velocity laws is chi alpha_dot / alpha_dot_0 and diverges as alpha_dot_0 -> 0. A contact
#: that starts slower than this is quasi-static and should use a law without onset velocity.
MIN_APPROACH_SPEED = 1e-4

Scalar = float | FloatArray


def _pos(x: Scalar) -> Scalar:
    return np.maximum(x, 0.0)


def _result(x) -> Scalar:
    x = np.asarray(x, dtype=float)
    return float(x) if x.ndim == 0 else x


@dataclass(frozen=True)
class ContactMemory:
    """History of one contact pair (a value: laws return new ones).

    Attributes
    ----------
    approach_speed : float
        ``alpha_dot`` at the onset of the current contact [m/s] (0 before any contact).
    alpha_max : float
        Largest indentation ever reached, ``alpha_m`` [m].
    alpha_residual : float
        Permanent indentation ``alpha_r`` left by ``alpha_max`` [m]; 0 for non-plastic laws.
    loading : bool
        True while on the virgin loading curve (``alpha >= alpha_max``, approaching).
    """

    approach_speed: float = 0.0
    alpha_max: float = 0.0
    alpha_residual: float = 0.0
    loading: bool = True


class NormalLaw(ABC):
    """Base class of the normal laws.

    Hooks for a subclass: ``name`` (registry key); ``kind`` (``"elastic"``, ``"viscoelastic"`` or
    ``"elastoplastic"``; a viscoelastic law with zero damping is not ``dissipative``);
    ``_magnitude(alpha, alpha_dot, memory)`` for ``alpha > 0`` (may return a negative value; the
    base clips it); ``elastic_energy``; elastoplastic laws also ``residual_indentation``; laws with a
    damping parameter ``calibrated``. Then add the class to ``NORMAL_LAWS`` and an example instance
    to ``tests/contact/law_examples.py``: the parametrised tests (force >= 0, restitution, energy
    ledger, and for viscoelastic laws a stated calibration accuracy) then cover it. Its compiled
    piece: an ``Items`` subclass as ``compiled_items``, ``params`` and the force registered with
    ``compiled_piece(normal_force, ...)``, checked against ``force`` by ``tests/contact/test_law_pieces.py``.
    """

    name: ClassVar[str]
    kind: ClassVar[str]
    #: The packed data class of the law's compiled piece (``viz3d.compiled.normal_force``), None
    #: when it has none (its contacts then run on the NumPy path).
    compiled_items: ClassVar[type[Items] | None] = None
    #: Methods whose formulas the compiled pieces re-implement: a subclass that overrides one of them
    #: without declaring its own ``compiled_items`` loses the inherited piece (NumPy path), since
    #: that piece would compute its parent's force.
    _PIECE_FORMULAS: ClassVar[tuple[str, ...]] = (
        "force", "_magnitude", "loading_force", "unloading_force", "unloading_stiffness",
        "residual_indentation", "contact_radius_squared", "_offset",
    )

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if "compiled_items" not in vars(cls) and any(name in vars(cls) for name in NormalLaw._PIECE_FORMULAS):
            cls.compiled_items = None

    def params(self) -> FloatArray:
        """The law's parameters in the order its compiled piece reads them (columns from ``p0``)."""
        raise NotImplementedError(f"{self.name!r} has no compiled piece")

    @abstractmethod
    def _magnitude(self, alpha: FloatArray, alpha_dot: FloatArray, memory: ContactMemory) -> FloatArray:
        """Force formula for ``alpha > 0`` [N], before clipping at zero."""

    @abstractmethod
    def elastic_energy(self, alpha: Scalar, memory: ContactMemory) -> Scalar:
        """Recoverable energy at indentation ``alpha`` [J] (released by unloading to zero force)."""

    def force(self, alpha: Scalar, alpha_dot: Scalar, memory: ContactMemory) -> Scalar:
        """Normal force magnitude ``F >= 0`` [N]; zero for ``alpha <= 0``. Arrays broadcast."""
        alpha, alpha_dot = np.broadcast_arrays(np.asarray(alpha, dtype=float), np.asarray(alpha_dot, dtype=float))
        F = self._magnitude(_pos(alpha), alpha_dot, memory)
        return _result(np.where(alpha > 0.0, _pos(F), 0.0))

    def force_unclipped(self, alpha: Scalar, alpha_dot: Scalar, memory: ContactMemory) -> Scalar:
        """The force formula at ``max(alpha, 0)`` [N] without ``force``'s clipping at zero (it may pull):
        the force of a contact that an implicit step's iteration holds active
        (``viz3d.contact.collision.FrozenTouches``), smooth where ``force`` has its kink."""
        alpha, alpha_dot = np.broadcast_arrays(np.asarray(alpha, dtype=float), np.asarray(alpha_dot, dtype=float))
        return _result(self._magnitude(_pos(alpha), alpha_dot, memory))

    def onset(self, alpha_dot_0: float, previous: ContactMemory | None = None) -> ContactMemory:
        """Memory at the start of a contact approached at ``alpha_dot_0`` [m/s]; plastic history persists."""
        previous = ContactMemory() if previous is None else previous
        return replace(previous, approach_speed=max(float(alpha_dot_0), MIN_APPROACH_SPEED), loading=True)

    def update(self, memory: ContactMemory, alpha: float, alpha_dot: float) -> ContactMemory:
        """Memory after the contact has reached ``alpha`` moving at ``alpha_dot`` (pure)."""
        alpha_max = max(memory.alpha_max, float(alpha))
        return replace(memory, alpha_max=alpha_max, alpha_residual=float(self.residual_indentation(alpha_max)),
                       loading=bool(alpha >= memory.alpha_max and alpha_dot > 0.0))

    def residual_indentation(self, alpha_max: Scalar) -> Scalar:
        """Permanent indentation left after unloading from ``alpha_max`` [m]; 0 unless plastic."""
        return 0.0 * np.asarray(alpha_max, dtype=float)

    @property
    def dissipative(self) -> bool:
        """False when loading and unloading follow the same curve (restitution 1)."""
        return self.kind != "elastic"

    @property
    def memoryless(self) -> bool:
        """True when the force needs no contact memory (onset speed, largest indentation): such a law
        may act without located events, and between shapes the collision library finds."""
        return self.kind != "elastoplastic" and not isinstance(self, HysteresisLaw)

    def calibrated(self, restitution: float, m_eff: float) -> NormalLaw:
        """Copy whose damping is set from a target restitution by the law's own formula.

        ``m_eff`` [kg] is used only by laws whose restitution depends on it (linear dashpot).
        """
        raise NotImplementedError(f"{self.name!r} has no damping parameter to calibrate")


# --- elastic and viscoelastic laws -------------------------------------------------------------------


@dataclass(frozen=True)
class Linear(NormalLaw):
    """Linear penalty with an optional dashpot, ``F = max(K alpha + D alpha_dot, 0)`` (thesis eq. 7.1).

    The FE "contact element"; with ``D > 0`` the no-tension Kelvin-Voigt model, whose force jumps to
    ``D alpha_dot_0`` at onset and vanishes before ``alpha`` returns to 0 (Lee & Wang's objections,
    thesis sec. 7.3.1). Restitution from ``D``: ``viz3d.contact.parameters.linear_restitution``.

    Attributes
    ----------
    stiffness : float
        ``K`` [N/m].
    damping : float
        ``D`` [N s/m].
    """

    name = "linear"
    kind = "viscoelastic"
    stiffness: float
    damping: float = 0.0

    @property
    def dissipative(self) -> bool:
        return self.damping > 0.0

    def _magnitude(self, alpha, alpha_dot, memory):
        return self.stiffness * alpha + self.damping * alpha_dot

    def elastic_energy(self, alpha, memory):
        return _result(0.5 * self.stiffness * _pos(alpha) ** 2)

    def calibrated(self, restitution, m_eff):
        return replace(self, damping=linear_damping(self.stiffness, m_eff, restitution))

    def params(self):
        return np.array([self.stiffness, self.damping])


class LinearItems(Items):
    """Contacts with a ``Linear`` law: f[p0:] = [K, D]."""


Linear.compiled_items = LinearItems


@jit
def _clipped(F, clip):
    """``max(F, 0)`` (``NormalLaw.force``) when ``clip``, else ``F`` (``force_unclipped``): the pieces' last step."""
    return max(F, 0.0) if clip else F


@compiled_piece(normal_force, LinearItems)
def _linear(d, k, p0, alpha, alpha_dot, approach_speed, alpha_max, clip):
    if alpha <= 0.0:
        return 0.0
    return _clipped(d.f[k, p0] * alpha + d.f[k, p0 + 1] * alpha_dot, clip)


@dataclass(frozen=True)
class PowerLawElastic(NormalLaw):
    """Laws whose elastic part is ``K alpha^n``: the stiffness, the exponent and their energy.

    Attributes
    ----------
    stiffness : float
        ``K`` [N/m^n].
    exponent : float
        ``n``.
    """

    stiffness: float
    exponent: float = 1.5

    def elastic_energy(self, alpha, memory):
        n = self.exponent
        return _result(self.stiffness * _pos(alpha) ** (n + 1.0) / (n + 1.0))


@dataclass(frozen=True)
class Hertz(PowerLawElastic):
    """Hertz (or any power-law elastic) contact, ``F = K alpha^n`` (thesis eqs. 3.26, 7.4).

    Attributes
    ----------
    stiffness : float
        ``K`` [N/m^n]; ``viz3d.contact.parameters.hertz_stiffness*`` for spheres and flats.
    exponent : float
        ``n``; 1.5 for Hertz.
    """

    name = "hertz"
    kind = "elastic"

    def _magnitude(self, alpha, alpha_dot, memory):
        return self.stiffness * alpha**self.exponent

    def params(self):
        return np.array([self.stiffness, self.exponent])


class HertzItems(Items):
    """Contacts with a ``Hertz`` law: f[p0:] = [K, n]."""


Hertz.compiled_items = HertzItems


@compiled_piece(normal_force, HertzItems)
def _hertz(d, k, p0, alpha, alpha_dot, approach_speed, alpha_max, clip):
    if alpha <= 0.0:
        return 0.0
    return d.f[k, p0] * alpha ** d.f[k, p0 + 1]


@dataclass(frozen=True)
class HysteresisLaw(PowerLawElastic):
    """``F = K alpha^n (1 + chi alpha_dot / alpha_dot_0)``: Hertz times a rate factor.

    ``alpha_dot_0`` is the approach speed at onset (``ContactMemory.approach_speed``); subclasses
    differ only in ``chi`` as a function of the requested restitution ``e``
    (``factor``). Their actual restitution is ``parameters.hysteresis_restitution(chi)`` whatever
    ``K``, ``n``, mass or speed (thesis sec. 1.7-bis of the digest: external laws; do not add them
    to flexible models whose waves already radiate the energy).

    The other parametrisation, fixed constants: ``damping_factor`` ``c > 0`` [s/m] gives
    ``F = K alpha^n (1 + c alpha_dot)`` as written (e.g. Hunt-Crossley steel on steel, c = 0.2664
    s/m); the law then needs no memory and ``restitution`` is not used.

    Attributes
    ----------
    stiffness : float
        ``K`` [N/m^n].
    exponent : float
        ``n``.
    restitution : float
        Requested coefficient of restitution ``e`` in (0, 1].
    damping_factor : float
        ``c`` [s/m]; 0: the rate factor is ``chi / alpha_dot_0`` from ``restitution``.
    """

    kind = "viscoelastic"
    restitution: float = 1.0
    damping_factor: float = 0.0

    @abstractmethod
    def factor(self) -> float:
        """Dimensionless hysteresis factor ``chi`` for ``self.restitution``."""

    @property
    def dissipative(self) -> bool:
        return self.restitution < 1.0 or self.damping_factor > 0.0

    @property
    def memoryless(self) -> bool:
        return self.damping_factor > 0.0

    def _magnitude(self, alpha, alpha_dot, memory):
        if self.damping_factor > 0.0:
            return self.stiffness * alpha**self.exponent * (1.0 + self.damping_factor * alpha_dot)
        if memory is None or memory.approach_speed <= 0.0:
            raise ValueError(f"{self.name}: no approach speed in the contact memory; call onset() first")
        return self.stiffness * alpha**self.exponent * (1.0 + self.factor() * alpha_dot / memory.approach_speed)

    def calibrated(self, restitution, m_eff):
        return replace(self, restitution=restitution)

    def params(self):
        return np.array([self.stiffness, self.exponent, self.factor(), self.damping_factor])


class HysteresisItems(Items):
    """Contacts with a ``HysteresisLaw``: f[p0:] = [K, n, chi, c] (c > 0: fixed constants)."""


HysteresisLaw.compiled_items = HysteresisItems


@compiled_piece(normal_force, HysteresisItems)
def _hysteresis(d, k, p0, alpha, alpha_dot, approach_speed, alpha_max, clip):
    if alpha <= 0.0:
        return 0.0
    if d.f[k, p0 + 3] > 0.0:
        return _clipped(d.f[k, p0] * alpha ** d.f[k, p0 + 1] * (1.0 + d.f[k, p0 + 3] * alpha_dot), clip)
    if not approach_speed > 0.0:
        return math.nan  # no onset in the memory: the step's health check reports it
    F = d.f[k, p0] * alpha ** d.f[k, p0 + 1] * (1.0 + d.f[k, p0 + 2] * alpha_dot / approach_speed)
    return _clipped(F, clip)


@dataclass(frozen=True)
class HuntCrossley(HysteresisLaw):
    """Hunt-Crossley, ``F = K alpha^n + lambda alpha^n alpha_dot``, ``lambda = 3 (1 - e) K / (2 alpha_dot_0)``.

    The estimate of ``lambda`` is first order in ``1 - e``: accurate near ``e = 1`` only.
    """

    name = "hunt_crossley"

    def factor(self):
        return hunt_crossley_factor(self.restitution)


@dataclass(frozen=True)
class LankaraniNikravesh(HysteresisLaw):
    """Lankarani-Nikravesh, ``F = K alpha^n [1 + 3 (1 - e^2) / 4 alpha_dot / alpha_dot_0]``.

    Derived for ``e`` close to 1 (energy loss small compared with the maximum elastic energy).
    """

    name = "lankarani_nikravesh"

    def factor(self):
        return lankarani_nikravesh_factor(self.restitution)


@dataclass(frozen=True)
class Flores(HysteresisLaw):
    """Flores et al. (2011), ``F = K alpha^n [1 + 8 (1 - e) / (5 e) alpha_dot / alpha_dot_0]`` (seed 004)."""

    name = "flores"

    def factor(self):
        return flores_factor(self.restitution)


# --- elastoplastic laws (thesis sec. 7.3.3-7.3.5) ----------------------------------------------------


@dataclass(frozen=True)
class ElastoplasticLaw(NormalLaw):
    """Hertz loading to ``alpha_Y``, plastic loading to ``alpha_m``, elastic unloading to ``alpha_r``.

    The force does not depend on ``alpha_dot``. Below the largest indentation reached the contact
    unloads and reloads elastically along ``unloading_force``; beyond it it follows
    ``loading_force`` (the virgin curve). Hooks: ``loading_force``, ``unloading_force``,
    ``unloading_energy`` (its integral from ``alpha_r``), ``residual_indentation``; all of them
    also for ``alpha_max < alpha_Y`` (never yielded: Hertz both ways, no crater).

    Attributes
    ----------
    K_h : float
        Hertz constant of the elastic loading [N/m^1.5].
    alpha_Y : float
        Indentation at first yield [m].
    """

    kind = "elastoplastic"
    K_h: float
    alpha_Y: float

    @abstractmethod
    def loading_force(self, alpha: Scalar) -> Scalar:
        """Virgin loading curve [N], ``alpha >= 0``."""

    @abstractmethod
    def unloading_force(self, alpha: Scalar, alpha_max: Scalar) -> Scalar:
        """Elastic branch through ``(alpha_r, 0)`` and ``(alpha_max, loading_force(alpha_max))`` [N]."""

    @abstractmethod
    def unloading_energy(self, alpha: Scalar, alpha_max: Scalar) -> Scalar:
        """``integral of unloading_force from alpha_r to alpha`` [J], ``alpha_r <= alpha <= alpha_max``."""

    @property
    def F_Y(self) -> float:
        """Force at first yield, ``K_h alpha_Y^1.5`` [N]."""
        return yield_force(self.K_h, self.alpha_Y)

    def _magnitude(self, alpha, alpha_dot, memory):
        virgin = alpha >= memory.alpha_max
        return np.where(virgin, self.loading_force(alpha), self.unloading_force(alpha, memory.alpha_max))

    def elastic_energy(self, alpha, memory):
        alpha = np.asarray(alpha, dtype=float)
        alpha_max = np.maximum(memory.alpha_max, alpha)
        inside = alpha > self.residual_indentation(alpha_max)
        return _result(np.where(inside, self.unloading_energy(np.maximum(alpha, 0.0), alpha_max), 0.0))


@dataclass(frozen=True)
class YieldThenLinear(ElastoplasticLaw):
    """Loading of Yigit & Christoforou: Hertz, then linear with the Hertz slope at yield (eqs. 7.5, 7.8, 7.9)."""

    @classmethod
    def from_material(cls, R: float, E: float, nu: float, sigma_Y: float) -> Self:
        """Sphere of radius ``R`` on a flat; thesis (7.6) and (7.7) (``LinearPlastic``: ``K_h2 = K_h``)."""
        return cls(hertz_stiffness_thesis(R, E, nu), yield_indentation_yigit(R, E, nu, sigma_Y))

    @property
    def K_Y(self) -> float:
        """Plastic stiffness ``3/2 K_h alpha_Y^0.5`` [N/m] (eq. 7.8)."""
        return yigit_plastic_stiffness(self.K_h, self.alpha_Y)

    def loading_force(self, alpha):
        alpha = _pos(alpha)
        plastic = self.F_Y + self.K_Y * (alpha - self.alpha_Y)
        return np.where(alpha <= self.alpha_Y, self.K_h * alpha**1.5, plastic)

    def params(self):
        """``[K_h, alpha_Y, F_Y, K_Y]`` (subclasses append their unloading constants)."""
        return np.array([self.K_h, self.alpha_Y, self.F_Y, self.K_Y])


@jit
def _yield_then_linear(alpha, K_h, alpha_Y, F_Y, K_Y):
    """``YieldThenLinear.loading_force`` [N] at ``alpha >= 0`` [m]."""
    if alpha <= alpha_Y:
        return K_h * alpha**1.5
    return F_Y + K_Y * (alpha - alpha_Y)


@dataclass(frozen=True)
class YigitChristoforou(YieldThenLinear):
    """Yigit & Christoforou (1997): unloading ``F = F_m - K_h (alpha_m^1.5 - alpha^1.5)`` (thesis eq. 7.10).

    The Hertz curve shifted down, not a Hertzian unloading (thesis eq. 7.11). Its residual
    indentation is ``alpha_r^1.5 = alpha_m^1.5 - alpha_Y^1.5 - (K_Y/K_h)(alpha_m - alpha_Y)``; the
    thesis's (7.12) prints the ratio inverted and ``alpha`` for ``alpha_Y`` (erratum).
    """

    name = "yigit_christoforou"

    def _offset(self, alpha_max):
        """``F_m - K_h alpha_m^1.5`` [N], <= 0 (0 while elastic)."""
        return self.loading_force(alpha_max) - self.K_h * _pos(alpha_max) ** 1.5

    def residual_indentation(self, alpha_max):
        return _result(_pos(-self._offset(alpha_max) / self.K_h) ** (2.0 / 3.0))

    def unloading_force(self, alpha, alpha_max):
        return self._offset(alpha_max) + self.K_h * _pos(alpha) ** 1.5

    def unloading_energy(self, alpha, alpha_max):
        a_r = self.residual_indentation(alpha_max)
        return self._offset(alpha_max) * (alpha - a_r) + 0.4 * self.K_h * (alpha**2.5 - a_r**2.5)


class YigitChristoforouItems(Items):
    """Contacts with a ``YigitChristoforou`` law: f[p0:] = [K_h, alpha_Y, F_Y, K_Y]."""


YigitChristoforou.compiled_items = YigitChristoforouItems


@compiled_piece(normal_force, YigitChristoforouItems)
def _yigit_christoforou(d, k, p0, alpha, alpha_dot, approach_speed, alpha_max, clip):
    if alpha <= 0.0:
        return 0.0
    K_h, alpha_Y, F_Y, K_Y = d.f[k, p0], d.f[k, p0 + 1], d.f[k, p0 + 2], d.f[k, p0 + 3]
    if alpha >= alpha_max:
        return _clipped(_yield_then_linear(alpha, K_h, alpha_Y, F_Y, K_Y), clip)
    # below alpha_m (> alpha > 0): the Hertz curve shifted by F_m - K_h alpha_m^1.5 <= 0 (eq. 7.10)
    offset = _yield_then_linear(alpha_max, K_h, alpha_Y, F_Y, K_Y) - K_h * alpha_max**1.5
    return _clipped(offset + K_h * alpha**1.5, clip)


@dataclass(frozen=True)
class HertzianUnloading(ElastoplasticLaw):
    """Unloading ``F = K_u (alpha - alpha_r)^1.5`` through ``(alpha_m, F_m)``: ``alpha_r = alpha_m - (F_m/K_u)^(2/3)``.

    Subclasses give the unloading constant ``unloading_stiffness(alpha_max)``.
    """

    @abstractmethod
    def unloading_stiffness(self, alpha_max: Scalar) -> Scalar:
        """``K_u`` [N/m^1.5] after loading to ``alpha_max``."""

    def residual_indentation(self, alpha_max):
        alpha_max = np.asarray(alpha_max, dtype=float)
        return _result(_pos(alpha_max - (self.loading_force(alpha_max) / self.unloading_stiffness(alpha_max)) ** (2.0 / 3.0)))

    def unloading_force(self, alpha, alpha_max):
        return self.unloading_stiffness(alpha_max) * _pos(alpha - self.residual_indentation(alpha_max)) ** 1.5

    def unloading_energy(self, alpha, alpha_max):
        return 0.4 * self.unloading_stiffness(alpha_max) * _pos(alpha - self.residual_indentation(alpha_max)) ** 2.5


@jit
def _hertzian_unloading(alpha, alpha_max, F_m, K_u):
    """``K_u (alpha - alpha_r)^1.5`` [N], ``alpha_r = alpha_m - (F_m/K_u)^(2/3)`` [m] (both held >= 0)."""
    alpha_r = max(alpha_max - (F_m / K_u) ** (2.0 / 3.0), 0.0)
    return K_u * max(alpha - alpha_r, 0.0) ** 1.5


@dataclass(frozen=True)
class LinearPlastic(HertzianUnloading, YieldThenLinear):
    """The thesis's "linear plastic" model (7.16): Yigit-Christoforou loading, Hertzian unloading.

    ``alpha_r`` from (7.14), or (7.15) when ``K_h2`` is None (unloading constant = ``K_h``). The
    unloading range printed in (7.16) is ``alpha_Y < alpha < alpha_m``; it is ``alpha_r < alpha < alpha_m``.

    Attributes
    ----------
    K_h2 : float or None
        Unloading Hertz constant after yield [N/m^1.5], ``>= K_h``; None uses ``K_h``.
    """

    name = "linear_plastic"
    K_h2: float | None = None

    def __post_init__(self):
        # alpha_r = alpha_m - (F_m / K_h2)^(2/3) would be negative just above yield (F_m ~ K_h alpha_m^1.5)
        if self.K_h2 is not None and self.K_h2 < self.K_h:
            raise ValueError(f"unloading constant K_h2 = {self.K_h2} below K_h = {self.K_h}: negative crater")

    def unloading_stiffness(self, alpha_max):
        K_h2 = self.K_h if self.K_h2 is None else self.K_h2
        return np.where(np.asarray(alpha_max) > self.alpha_Y, K_h2, self.K_h)

    def params(self):
        """``[K_h, alpha_Y, F_Y, K_Y, K_h2]``, ``K_h2 = K_h`` when None."""
        return np.append(super().params(), self.K_h if self.K_h2 is None else self.K_h2)


class LinearPlasticItems(Items):
    """Contacts with a ``LinearPlastic`` law: f[p0:] = [K_h, alpha_Y, F_Y, K_Y, K_h2]."""


LinearPlastic.compiled_items = LinearPlasticItems


@compiled_piece(normal_force, LinearPlasticItems)
def _linear_plastic(d, k, p0, alpha, alpha_dot, approach_speed, alpha_max, clip):
    if alpha <= 0.0:
        return 0.0
    K_h, alpha_Y, F_Y, K_Y = d.f[k, p0], d.f[k, p0 + 1], d.f[k, p0 + 2], d.f[k, p0 + 3]
    if alpha >= alpha_max:
        return _clipped(_yield_then_linear(alpha, K_h, alpha_Y, F_Y, K_Y), clip)
    K_u = d.f[k, p0 + 4] if alpha_max > alpha_Y else K_h
    F_m = _yield_then_linear(alpha_max, K_h, alpha_Y, F_Y, K_Y)
    return _clipped(_hertzian_unloading(alpha, alpha_max, F_m, K_u), clip)


@dataclass(frozen=True)
class PowerPlastic(HertzianUnloading):
    """The thesis's "power plastic" model (7.41) for a sphere on a flat.

    Loading: Hertz to ``alpha_Y``, then ``F = K_hY (alpha^n - alpha_Y^n) + F_Y`` (7.33) with
    ``(K_hY, n)`` from Yigit's tangent and Johnson's secant criteria (7.34). Unloading:
    ``K_h2 (alpha - alpha_r)^1.5``, ``K_h2 = 4/3 E* sqrt(R*)`` with the crater-corrected radius
    ``R* = 4 E* a_m^3 / (3 F_m)`` (7.35-7.38, written with ``E* = E'/2``), the contact radius from
    the interpolation (7.25) ``a^2 = (1 + (alpha - alpha_Y)/(alpha_fp - alpha_Y)) alpha R``, whose
    factor is held in [1, 2] (elastic ``a^2 = alpha R`` below yield, fully plastic ``a^2 = 2 alpha R``
    beyond ``alpha_fp``, where (7.25) is not defined). ``alpha_r`` from (7.43); (7.39) and (7.42)
    as printed use the linear-plastic ``F_m`` and ``(alpha_m - alpha_Y)``: errata.

    Attributes
    ----------
    alpha_fp : float
        Start of the fully plastic regime [m] (7.26).
    K_hY : float
        Plastic constant [N/m^n].
    n : float
        Plastic exponent.
    E_star : float
        Effective modulus [Pa] (``E'/2`` in the thesis).
    R : float
        Sphere radius [m].
    """

    name = "power_plastic"
    alpha_fp: float
    K_hY: float
    n: float
    E_star: float
    R: float

    @classmethod
    def from_material(cls, R: float, E: float, nu: float, sigma_Y: float) -> PowerPlastic:
        """Sphere of radius ``R`` on a flat of the same material: (7.6), (7.26), (7.34)."""
        K_h = hertz_stiffness_thesis(R, E, nu)
        alpha_Y = yield_indentation_thesis(R, E, nu, sigma_Y)
        alpha_fp = fully_plastic_indentation(R, E, nu, sigma_Y)
        K_hY, n = power_plastic_constants(K_h, alpha_Y, alpha_fp)
        return cls(K_h, alpha_Y, alpha_fp, K_hY, n, plane_strain_modulus(E, nu) / 2.0, R)

    def loading_force(self, alpha):
        alpha = _pos(alpha)
        plastic = self.K_hY * (alpha**self.n - self.alpha_Y**self.n) + self.F_Y
        return np.where(alpha <= self.alpha_Y, self.K_h * alpha**1.5, plastic)

    def contact_radius_squared(self, alpha: Scalar) -> Scalar:
        """``a^2`` [m^2] from (7.22)-(7.25), interpolation factor held in [1, 2]."""
        ratio = np.clip(1.0 + (alpha - self.alpha_Y) / (self.alpha_fp - self.alpha_Y), 1.0, 2.0)
        return ratio * alpha * self.R

    def unloading_stiffness(self, alpha_max):
        # Below yield a^2 = alpha R and F = K_h alpha^1.5 give R* = R, K_h2 = K_h exactly; written
        # out so that alpha_max -> 0 does not divide 0 by 0.
        a_m = np.maximum(np.asarray(alpha_max, dtype=float), self.alpha_Y)
        R_star = 4.0 * self.E_star * self.contact_radius_squared(a_m) ** 1.5 / (3.0 * self.loading_force(a_m))
        return np.where(np.asarray(alpha_max) > self.alpha_Y, hertz_stiffness(self.E_star, R_star), self.K_h)

    def params(self):
        """``[K_h, alpha_Y, F_Y, K_hY, n, alpha_Y^n, alpha_fp, E_star, R]``."""
        return np.array([self.K_h, self.alpha_Y, self.F_Y, self.K_hY, self.n, self.alpha_Y**self.n,
                         self.alpha_fp, self.E_star, self.R])


class PowerPlasticItems(Items):
    """Contacts with a ``PowerPlastic`` law: f[p0:] = [K_h, alpha_Y, F_Y, K_hY, n, alpha_Y^n, alpha_fp, E*, R]."""


PowerPlastic.compiled_items = PowerPlasticItems


@jit
def _yield_then_power(alpha, K_h, alpha_Y, F_Y, K_hY, n, alpha_Y_n):
    """``PowerPlastic.loading_force`` [N] at ``alpha >= 0`` [m] (7.33)."""
    if alpha <= alpha_Y:
        return K_h * alpha**1.5
    return K_hY * (alpha**n - alpha_Y_n) + F_Y


@jit
def _power_plastic_unloading_stiffness(alpha_m, F_m, alpha_Y, alpha_fp, E_star, R):
    """``K_h2 = 4/3 E* sqrt(R*)`` [N/m^1.5] after yield, ``alpha_m > alpha_Y`` [m], ``F_m`` [N] (7.35-7.38)."""
    ratio = min(max(1.0 + (alpha_m - alpha_Y) / (alpha_fp - alpha_Y), 1.0), 2.0)
    a_m2 = ratio * alpha_m * R  # contact radius squared (7.25) [m^2]
    R_star = 4.0 * E_star * a_m2**1.5 / (3.0 * F_m)
    return 4.0 / 3.0 * E_star * math.sqrt(R_star)


@compiled_piece(normal_force, PowerPlasticItems)
def _power_plastic(d, k, p0, alpha, alpha_dot, approach_speed, alpha_max, clip):
    if alpha <= 0.0:
        return 0.0
    K_h, alpha_Y, F_Y, K_hY, n, alpha_Y_n = (d.f[k, p0], d.f[k, p0 + 1], d.f[k, p0 + 2], d.f[k, p0 + 3],
                                             d.f[k, p0 + 4], d.f[k, p0 + 5])
    if alpha >= alpha_max:
        return _clipped(_yield_then_power(alpha, K_h, alpha_Y, F_Y, K_hY, n, alpha_Y_n), clip)
    F_m = _yield_then_power(alpha_max, K_h, alpha_Y, F_Y, K_hY, n, alpha_Y_n)
    if alpha_max > alpha_Y:
        K_u = _power_plastic_unloading_stiffness(alpha_max, F_m, alpha_Y, d.f[k, p0 + 6], d.f[k, p0 + 7], d.f[k, p0 + 8])
    else:
        K_u = K_h  # never yielded: R* = R, Hertz both ways
    return _clipped(_hertzian_unloading(alpha, alpha_max, F_m, K_u), clip)


NORMAL_LAWS: dict[str, type[NormalLaw]] = {
    cls.name: cls
    for cls in (Linear, Hertz, HuntCrossley, LankaraniNikravesh, Flores, YigitChristoforou, LinearPlastic, PowerPlastic)
}
