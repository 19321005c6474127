"""Friction laws: the tangential force of a contact from its slip speed and its normal force.

A law gives the magnitude of the friction force ``F_t(s, F_n) >= 0`` [N] at slip speed ``s = |v_t|``
[m/s] under the normal force ``F_n`` [N]; it acts against the slip, ``-F_t v_t / s``, at the contact
point (``viz3d.contact.contacts``). The laws here are memoryless and regularised: the force is a
smooth function of the slip velocity, zero at zero slip, so a body held by friction creeps at a
speed set by ``slip_speed`` (the regularisation) instead of sticking; ``creep_speed`` says how fast.

==============  ====================================================================================
``coulomb``     ``mu F_n tanh(s / v_s)``
``stribeck``    ``(mu + (mu_s - mu) exp(-(s / v_st)^2)) F_n tanh(s / v_s) + c_v s`` (static peak,
                Stribeck decay to the dynamic coefficient, viscous term)
==============  ====================================================================================

``bristle`` (seed 004, eqs. 3.40-3.49, after Dopico et al. 2011 and Gonthier et al. 2004) has a
state: each contact's stick anchor, a point of B where the bristles were planted, kept in the
contact's phase for sphere contacts (``viz3d.contact.contacts.ContactPhase.anchor``) and in the
element's memory for shape contacts (``viz3d.contact.collision.StickAnchors``). With ``s`` the bristles'
tangential deflection (contact point minus anchor, without its normal part) and ``v_t`` the slip,

    F_t = beta F_stick + (1 - beta) F_slide - c_v v_t,   beta = exp(-|v_t|^2 / v_stick^2),
    F_stick = -(k s + c v_t), its magnitude capped at mu_s F_n,   F_slide = -mu F_n v_t / |v_t|,

and after each step an anchor whose bristles carry more than ``mu_s F_n`` is moved so that they
carry ``alpha_stick mu_s F_n`` (eq. 3.49). At rest ``beta = 1``: the bristle spring holds a load
below ``mu_s F_n`` with a constant deflection, without creep.

Each law packs its parameters as ``FRICTION_PARAMS`` numbers, ``[code, mu, mu_s, v_s, v_st, c_v,
k, c, alpha]``, read by the compiled ``friction_vector`` (code 0: no friction).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from viz3d.compiled import jit

#: Packed parameters per contact: [code, mu, mu_s, v_s, v_st, c_v, k_stick, c_stick, alpha_stick].
FRICTION_PARAMS = 9


class FrictionLaw(ABC):
    """Base class: ``name``, ``code`` (the compiled switch), ``force`` and ``params``; a law with a stick
    anchor (``stateful``) also ``vector`` and ``anchor_update``."""

    name: ClassVar[str]
    code: ClassVar[int]
    stateful: ClassVar[bool] = False

    def vector(self, v_t, s, F_n):
        """Friction force on A (3,) [N] from the slip ``v_t`` (3,) [m/s], the bristles' deflection ``s``
        (3,) [m] (stateful laws) and ``F_n`` [N]."""
        speed = float(np.linalg.norm(v_t))
        return -self.force(speed, F_n) * v_t / speed if speed > 0.0 else np.zeros(3)

    @abstractmethod
    def force(self, s, F_n):
        """Friction force magnitude [N] at slip speed ``s`` [m/s] under normal force ``F_n`` [N]."""

    @abstractmethod
    def params(self) -> list[float]:
        """``FRICTION_PARAMS`` numbers for the compiled ``friction_force``."""

    def creep_speed(self, ratio: float) -> float:
        """Slip speed [m/s] at which the law carries ``ratio`` times the normal force (a tangential
        load ``ratio F_n`` it should hold: how fast a held body creeps); inf if it never does."""
        from scipy.optimize import brentq

        top = 1.0
        while self.force(top, 1.0) < ratio:
            top *= 10.0
            if top > 1e6:
                return math.inf
        return float(brentq(lambda s: self.force(s, 1.0) - ratio, 0.0, top, xtol=1e-15, rtol=1e-12))


@dataclass(frozen=True)
class RegularizedCoulomb(FrictionLaw):
    """``F_t = mu F_n tanh(s / v_s)``: Coulomb's law smoothed over slip speeds of order ``v_s``."""

    name: ClassVar[str] = "coulomb"
    code: ClassVar[int] = 1
    mu: float
    slip_speed: float = 1e-4

    def force(self, s, F_n):
        return self.mu * F_n * np.tanh(s / self.slip_speed)

    def params(self):
        return [self.code, self.mu, self.mu, self.slip_speed, 1.0, 0.0, 0.0, 0.0, 0.0]


@dataclass(frozen=True)
class Stribeck(FrictionLaw):
    """``F_t = (mu + (mu_s - mu) exp(-(s / v_st)^2)) F_n tanh(s / v_s) + c_v s``."""

    name: ClassVar[str] = "stribeck"
    code: ClassVar[int] = 2
    mu: float
    mu_static: float
    stribeck_speed: float
    viscous: float = 0.0
    slip_speed: float = 1e-4

    def force(self, s, F_n):
        mu = self.mu + (self.mu_static - self.mu) * np.exp(-((s / self.stribeck_speed) ** 2))
        return mu * F_n * np.tanh(s / self.slip_speed) + self.viscous * s

    def params(self):
        return [self.code, self.mu, self.mu_static, self.slip_speed, self.stribeck_speed, self.viscous, 0.0, 0.0, 0.0]


@dataclass(frozen=True)
class Bristle(FrictionLaw):
    """Stick-slip friction with bristles and a stick anchor (seed 004, eqs. 3.40-3.49; module docstring)."""

    name: ClassVar[str] = "bristle"
    code: ClassVar[int] = 3
    stateful: ClassVar[bool] = True
    mu: float
    mu_static: float
    stick_speed: float
    stiffness: float
    damping: float = 0.0
    viscous: float = 0.0
    alpha: float = 1.0

    def force(self, s, F_n):
        """Sliding force magnitude (no deflection): ``(1 - beta) mu F_n + c_v s``."""
        return (1.0 - np.exp(-((s / self.stick_speed) ** 2))) * self.mu * F_n + self.viscous * s

    def vector(self, v_t, s, F_n):
        return _bristle(v_t, s, F_n, self.mu, self.mu_static, self.stick_speed, self.stiffness, self.damping,
                        self.viscous, np.zeros(3))

    def anchor_update(self, s, F_n):
        """The deflection (3,) the bristles keep after a step that left them at ``s`` under ``F_n``:
        ``s`` itself while ``k |s| <= mu_s F_n``, else ``s`` scaled to ``alpha mu_s F_n / k`` (eq. 3.49)."""
        limit = self.mu_static * F_n
        size = float(np.linalg.norm(s))
        if self.stiffness * size <= limit or size == 0.0:
            return s
        return s * (self.alpha * limit / (self.stiffness * size))

    def energy(self, s):
        """Elastic energy of the bristles ``k |s|^2 / 2`` [J] at deflections ``s`` (..., 3): shape (...)."""
        s = np.asarray(s, dtype=float)
        return 0.5 * self.stiffness * (s[..., None, :] @ s[..., :, None])[..., 0, 0]

    def params(self):
        return [self.code, self.mu, self.mu_static, 1.0, self.stick_speed, self.viscous, self.stiffness, self.damping,
                self.alpha]


FRICTION_LAWS: dict[str, type[FrictionLaw]] = {cls.name: cls for cls in (RegularizedCoulomb, Stribeck, Bristle)}


def _bristle(v_t, s, F_n, mu, mu_s, v_stick, k, c, c_v, out):
    """Bristle friction force on A into ``out`` (3,) (``Bristle``; used compiled and in Python)."""
    speed = math.sqrt(v_t[0] * v_t[0] + v_t[1] * v_t[1] + v_t[2] * v_t[2])
    beta = math.exp(-((speed / v_stick) ** 2))
    stick = 0.0
    for i in range(3):
        out[i] = k * s[i] + c * v_t[i]
        stick += out[i] * out[i]
    stick = math.sqrt(stick)
    scale = beta * (mu_s * F_n / stick if stick > mu_s * F_n else 1.0)
    slide = (1.0 - beta) * mu * F_n / speed if speed > 0.0 else 0.0
    for i in range(3):
        out[i] = -scale * out[i] - slide * v_t[i] - c_v * v_t[i]
    return out


_bristle_compiled = jit(_bristle)


@jit
def friction_vector(p, v_t, s, F_n, out):
    """Compiled ``FrictionLaw.vector`` from packed parameters ``p`` (``FRICTION_PARAMS``): the friction
    force on A into ``out`` (3,) from the slip ``v_t``, the bristles' deflection ``s`` and ``F_n``;
    zero without friction (code 0)."""
    if p[0] == 3.0:
        _bristle_compiled(v_t, s, F_n, p[1], p[2], p[4], p[6], p[7], p[5], out)
        return
    speed = math.sqrt(v_t[0] * v_t[0] + v_t[1] * v_t[1] + v_t[2] * v_t[2])
    mag = 0.0
    if p[0] != 0.0 and speed > 0.0:
        mu = p[1] + (p[2] - p[1]) * math.exp(-((speed / p[4]) ** 2))
        mag = (mu * F_n * math.tanh(speed / p[3]) + p[5] * speed) / speed
    for i in range(3):
        out[i] = -mag * v_t[i]
