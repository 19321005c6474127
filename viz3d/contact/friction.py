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

Each law packs its parameters as ``FRICTION_PARAMS`` numbers, ``[code, mu, mu_s, v_s, v_st, c_v]``,
read by the compiled ``friction_force`` (code 0: no friction).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from viz3d.compiled import jit

#: Packed parameters per contact: [code, mu, mu_s, v_s, v_st, c_v].
FRICTION_PARAMS = 6


class FrictionLaw(ABC):
    """Base class: ``name``, ``code`` (the compiled switch), ``force`` and ``params``."""

    name: ClassVar[str]
    code: ClassVar[int]

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
        return [self.code, self.mu, self.mu, self.slip_speed, 1.0, 0.0]


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
        return [self.code, self.mu, self.mu_static, self.slip_speed, self.stribeck_speed, self.viscous]


FRICTION_LAWS: dict[str, type[FrictionLaw]] = {cls.name: cls for cls in (RegularizedCoulomb, Stribeck)}


@jit
def friction_force(p, s, F_n):
    """Compiled ``FrictionLaw.force`` from packed parameters ``p`` (``FRICTION_PARAMS``): the friction
    force magnitude [N] at slip speed ``s`` under ``F_n``; 0 without friction (code 0)."""
    if p[0] == 0.0:
        return 0.0
    mu = p[1] + (p[2] - p[1]) * math.exp(-((s / p[4]) ** 2))
    return mu * F_n * math.tanh(s / p[3]) + p[5] * s
