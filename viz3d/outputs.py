"""Output elements: quantities a run reports without acting on the bodies (strain and deflection
gauges, the chain's tension at a hawse).

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
class SectionGauges(Output):
    """Gauges at sections ``x`` of a flexible bar whose readings are linear in its elastic
    coordinates, ``rows @ eta``; subclasses give ``section_rows`` and their ``plot`` (its path prefix
    names the keys, ``<prefix>/<name>``).

    Attributes
    ----------
    names : tuple of str, length k
    flex : int
        The bar among ``Bodies.flexible``.
    x : ndarray, shape (k,)
        Sections [m].
    rows : ndarray, shape (k, n)
        Reading per unit elastic coordinate (``section_rows()``, from ``bar``).
    """

    names: tuple[str, ...]
    flex: int
    x: FloatArray
    bar: object = field(repr=False)
    rows: FloatArray = field(init=False, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "rows", self.section_rows())

    def section_rows(self) -> FloatArray:
        raise NotImplementedError

    def readings(self, cfg: Configuration) -> FloatArray:
        """Reading of each gauge at ``cfg``, shape (k,)."""
        return self.rows @ cfg.eta[self.flex]

    @property
    def keys(self):
        return tuple(f"{self.plot[1]}/{n}" for n in self.names)

    def values(self, cfg, reactions=None):
        return dict(zip(self.keys, map(float, self.readings(cfg))))


@dataclass(frozen=True)
class StrainGauges(SectionGauges):
    """Strain gauges: the axial strain plus the bending surface strain on the fibre at ``+depth/2``
    of every field (``BarModel.strain``) [-]."""

    type_name = "strain_gauge"
    plot = ("Gauge strain [-]", "strain")

    def section_rows(self) -> FloatArray:
        rows = np.zeros((len(self.x), self.bar.n))
        for model, sl in zip(self.bar.fields, self.bar.field_slices):
            rows[:, sl] = model.strain(self.x)
        return rows


@dataclass(frozen=True)
class DeflectionGauges(SectionGauges):
    """Deflection gauges: the transverse displacement of the axis [m], measured from the bar's
    reference frame, along its bending direction d (the first bending field's: the direction of
    positive w).

    The frame is what the bar's shapes make it (``viz3d.flexible.floating``): for pinned-pinned
    shapes the chord through the pins, so a gauge at midspan reads the sag relative to the chord;
    clamped-free, the tangent at x = 0; free-free, the mean axes. Linear in eta:
    ``w(x) = d . U(x) eta`` (an axial field contributes nothing along d).
    """

    type_name = "deflection_gauge"
    plot = ("Deflection [m]", "deflection")

    def section_rows(self) -> FloatArray:
        from viz3d.flexible.floating_points import material_points

        bending = [d for d, m in zip(self.bar.directions, self.bar.fields) if m.kind == "bending"]
        if not bending:
            raise ValueError("a deflection gauge needs a bar with a bending field")
        return np.einsum("i,kin->kn", bending[0], material_points(self.bar, self.x).N)


#: Gauge classes by the scene's ``gauges[i].quantity``.
GAUGES: dict[str, type[Output]] = {"strain": StrainGauges, "deflection": DeflectionGauges}


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


OUTPUTS: dict[str, type[Output]] = {cls.type_name: cls for cls in (StrainGauges, DeflectionGauges, HawseTension)}
