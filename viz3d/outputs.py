"""Output elements: quantities a run reports without acting on the bodies (strain gauges, the
chain's tension at a hawse).

An output element has one hook, ``values(cfg, reactions) -> {name: value}`` (SI units; ``reactions``
(nj, 3) the joints' reaction forces on body 1 [N], in ``System.joint_names`` order), lists its
``keys`` and names its ``plot`` panel; frames carry the values under ``Frame.scalars`` (live plots
and recordings) and the trajectory stores them as arrays. Register a new kind in ``OUTPUTS``; see
docs/extending.md.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from viz3d._typing import FloatArray
from viz3d.kinematics import Configuration


class Output(ABC):
    """Base class; subclasses set ``type_name`` and ``plot`` and implement ``keys`` and ``values``."""

    type_name: ClassVar[str]
    #: The panel of the live viewer and of recordings: (title, plot path prefix of the keys).
    plot: ClassVar[tuple[str, str]]

    @property
    @abstractmethod
    def keys(self) -> tuple[str, ...]:
        """The plot paths ``values`` returns (``strain/g1``)."""

    @abstractmethod
    def values(self, cfg: Configuration, reactions: FloatArray) -> dict[str, float]:
        """Named values at ``cfg`` with the joints' reaction forces ``reactions`` (nj, 3) [N]."""


@dataclass(frozen=True)
class StrainGauges(Output):
    """Strain gauges on a flexible bar: the axial strain plus the bending surface strain on the fibre
    at ``+depth/2`` of every field (``BarModel.strain``) at sections ``x``.

    Attributes
    ----------
    names : tuple of str, length k
    flex : int
        The bar among ``Bodies.flexible``.
    x : ndarray, shape (k,)
        Sections [m].
    rows : ndarray, shape (k, n)
        Strain per unit elastic coordinate (derived from ``bar``).
    """

    type_name = "strain_gauge"
    plot = ("Gauge strain [-]", "strain")
    names: tuple[str, ...]
    flex: int
    x: FloatArray
    bar: object = field(repr=False)
    rows: FloatArray = field(init=False, repr=False)

    def __post_init__(self):
        rows = np.zeros((len(self.x), self.bar.n))
        for model, sl in zip(self.bar.fields, self.bar.field_slices):
            rows[:, sl] = model.strain(self.x)
        object.__setattr__(self, "rows", rows)

    def strains(self, cfg: Configuration) -> FloatArray:
        """Strain at each gauge, shape (k,) [-]."""
        return self.rows @ cfg.eta[self.flex]

    @property
    def keys(self):
        return tuple(f"strain/{n}" for n in self.names)

    def values(self, cfg, reactions=None):
        return dict(zip(self.keys, map(float, self.strains(cfg))))


@dataclass(frozen=True)
class HawseTension(Output):
    """A chain's tension where it enters the hull: the reaction force of the chain's joint nearest to
    the hawse point (a link's joint is its upper end, ``half`` from its centre along its body z).

    Attributes
    ----------
    links : ndarray of int, shape (k,)
        The chain's link bodies, from the windlass down.
    joints : ndarray of int, shape (k,)
        Each link's upper joint, index in ``System.joint_names``.
    half : float
        Half a link's pitch [m].
    hawse : ndarray, shape (3,)
        Where the chain enters the hull, world [m].
    """

    type_name = "hawse_tension"
    plot = ("Chain tension at the hawse [N]", "stowage")
    links: FloatArray
    joints: FloatArray
    half: float
    hawse: FloatArray

    @property
    def keys(self):
        return ("stowage/hawse_tension",)

    def values(self, cfg, reactions):
        ends = cfg.pose.W_r[self.links] - self.half * cfg.pose.R_WB[self.links][:, :, 2]
        nearest = int(np.argmin(np.linalg.norm(ends - self.hawse, axis=1)))
        return {self.keys[0]: float(np.linalg.norm(reactions[self.joints[nearest]]))}


OUTPUTS: dict[str, type[Output]] = {cls.type_name: cls for cls in (StrainGauges, HawseTension)}
