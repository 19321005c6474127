"""Output elements: quantities a run reports without acting on the bodies (strain gauges).

An output element has one hook, ``values(cfg) -> {name: value}`` (SI units); frames carry the values
under ``Frame.scalars`` (plots and recordings) and the trajectory stores them as arrays. Register a
new kind in ``OUTPUTS``; see docs/extending.md.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from viz3d._typing import FloatArray
from viz3d.kinematics import Configuration


class Output(ABC):
    """Base class; subclasses set ``type_name`` and implement ``values``."""

    type_name: ClassVar[str]

    @abstractmethod
    def values(self, cfg: Configuration) -> dict[str, float]:
        """Named values at ``cfg``; keys are plot paths (``strain/g1``)."""


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

    def values(self, cfg):
        return {f"strain/{n}": float(e) for n, e in zip(self.names, self.strains(cfg))}


OUTPUTS: dict[str, type[Output]] = {cls.type_name: cls for cls in (StrainGauges,)}
