"""The diverging colour map of flexible bodies' surface bending stress, shared by the viewer and the
recorder so both draw a stress in the same colour.

The map is symmetric about zero: -scale (compression) blue, 0 light grey, +scale (tension) red,
clipped beyond. Its colours are Moreland's cool-warm map (K. Moreland, "Diverging Color Maps for
Scientific Visualization", ISVC 2009) as matplotlib 3.11's ``coolwarm`` gives it at five points,
interpolated linearly in RGB between them (no matplotlib at run time).

The scale is the scene's ``[display] stress_scale`` [Pa] when it gives one: a fixed scale lets a
colour mean the same stress in every frame and in every run of the scene. Without it (the material
carries no yield stress to offer), the scale is the largest |stress| the sink has drawn so far, a
running maximum that never decreases: any scene gets a usable map, at the price that a colour
means a larger stress later in the run than at its start.
"""

from __future__ import annotations

import numpy as np

from viz3d._typing import FloatArray

#: (value in [-1, 1], RGB): Moreland's cool-warm map at 0, 1/4, 1/2, 3/4 and 1 of its range.
ANCHORS = np.array([-1.0, -0.5, 0.0, 0.5, 1.0])
ANCHOR_RGB = np.array([[59, 76, 192], [141, 176, 254], [221, 220, 220], [244, 152, 122], [180, 4, 38]], float)


def diverging_colors(u: FloatArray) -> np.ndarray:
    """RGB (k, 3) uint8 of values ``u`` (k,) on the map, -1 and below blue, +1 and above red."""
    u = np.clip(np.asarray(u, float), -1.0, 1.0)
    rgb = np.column_stack([np.interp(u, ANCHORS, ANCHOR_RGB[:, c]) for c in range(3)])
    return np.rint(rgb).astype(np.uint8)


class StressColors:
    """Colours of surface stresses [Pa] on the map with a fixed ``scale`` [Pa], or (scale 0) the
    running maximum of the stresses passed to ``observe``."""

    def __init__(self, scale: float = 0.0):
        if not (np.isfinite(scale) and scale >= 0.0):
            raise ValueError(f"stress scale must be a finite non-negative stress [Pa], got {scale}")
        self.fixed = scale > 0.0
        self.scale = float(scale)

    def observe(self, stresses) -> float:
        """Take in a frame's stresses (an iterable of arrays) [Pa]; returns the scale now in use [Pa]."""
        if not self.fixed:
            self.scale = max([self.scale] + [float(np.max(np.abs(s), initial=0.0)) for s in stresses])
        return self.scale

    def __call__(self, stress: FloatArray) -> np.ndarray:
        """RGB (k, 3) uint8 of stresses (k,) [Pa]; all mid-map grey while the scale is still 0."""
        stress = np.asarray(stress, float)
        return diverging_colors(stress / self.scale if self.scale > 0.0 else np.zeros_like(stress))
