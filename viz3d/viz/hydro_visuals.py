"""Geometry and colours of a hydrodynamics scene, shared by the viser viewer and the rerun recorder.

World axes (z up, as every viz3d view): X = x, upstream from the dam face; Z = y, up from the
reservoir bottom; Y across the valley. The reservoir section lies in the plane Y = 0; the dam (or
the rigid wall) is a block behind it, x in [-thickness, 0], Y in [-width, 0], its upstream face
displaced by the frames' face motion times the view's amplification.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viz3d._typing import FloatArray
from viz3d.hydrostudy import SectionFrames
from viz3d.scene.hydro import HydroModel

#: Drawn thickness of a rigid wall and width of the dam block, in water depths.
WALL_THICKNESS, BLOCK_WIDTH = 0.1, 0.6
#: Colours: concrete, water surface (RGBA), and the pressure scale's ends and middle (RGB).
CONCRETE_COLOR = np.array([170, 170, 165], dtype=np.uint8)
WATER_COLOR = np.array([80, 140, 220, 90], dtype=np.uint8)
SUCTION, ZERO, COMPRESSION = np.array([40, 80, 220.0]), np.array([245, 245, 245.0]), np.array([210, 40, 40.0])


@dataclass(frozen=True)
class HydroGeometry:
    """Meshes of a hydrodynamics scene (world coordinates [m]).

    Attributes
    ----------
    section_vertices : ndarray, shape (n_x n_y, 3)
        Grid points of the section, x-major (the order of ``SectionFrames.pressure[k].ravel()``).
    section_faces : ndarray, shape (2 (n_x - 1)(n_y - 1), 3)
    dam_vertices : ndarray, shape (4 m, 3)
        Undeformed block, four corners per face height (face at x = 0 first).
    dam_faces : ndarray, shape (8 (m - 1) + 4, 3)
    surface_vertices, surface_faces : ndarray
        The water surface (a rectangle over the section and the block's width).
    amplification : float
    """

    section_vertices: FloatArray
    section_faces: np.ndarray
    dam_vertices: FloatArray
    dam_faces: np.ndarray
    surface_vertices: FloatArray
    surface_faces: np.ndarray
    amplification: float

    def dam_at(self, face: FloatArray) -> FloatArray:
        """Block vertices with the face displacement ``face`` (m,) [m] drawn amplified, shape (4 m, 3)."""
        out = self.dam_vertices.copy()
        out[:, 0] += self.amplification * np.repeat(np.asarray(face, float), 4)
        return out


def grid_faces(n_u: int, n_v: int) -> np.ndarray:
    """Triangles of an n_u x n_v grid of points numbered u-major, shape (2 (n_u - 1)(n_v - 1), 3)."""
    i = (np.arange(n_u - 1)[:, None] * n_v + np.arange(n_v - 1)[None, :]).ravel()
    return np.concatenate([np.stack([i, i + n_v, i + n_v + 1], 1), np.stack([i, i + n_v + 1, i + 1], 1)]).astype(np.uint32)


def geometry(model: HydroModel, frames: SectionFrames) -> HydroGeometry:
    """The meshes of ``model`` for ``frames`` (their grid and face heights)."""
    h = model.reservoir.depth
    X, Z = np.meshgrid(frames.x, frames.y, indexing="ij")
    section = np.stack([X.ravel(), np.zeros(X.size), Z.ravel()], axis=1)
    thickness = model.dam.bar.section.depth if model.dam is not None else WALL_THICKNESS * h
    width = BLOCK_WIDTH * h
    corners = np.array([[0.0, 0.0], [0.0, -width], [-thickness, -width], [-thickness, 0.0]])
    m = frames.face_y.size
    dam = np.concatenate([np.column_stack([corners, np.full(4, z)]) for z in frames.face_y])
    sides = [[4 * k + a, 4 * k + b, 4 * (k + 1) + b] for k in range(m - 1) for a, b in zip(range(4), (1, 2, 3, 0))]
    sides += [[4 * k + a, 4 * (k + 1) + b, 4 * (k + 1) + a] for k in range(m - 1) for a, b in zip(range(4), (1, 2, 3, 0))]
    top = 4 * (m - 1)
    caps = [[0, 2, 1], [0, 3, 2], [top, top + 1, top + 2], [top, top + 2, top + 3]]
    length = float(frames.x.max())
    surface = np.array([[0.0, 0.0, h], [length, 0.0, h], [length, -width, h], [0.0, -width, h]])
    return HydroGeometry(section, grid_faces(frames.x.size, frames.y.size), dam, np.array(sides + caps, dtype=np.uint32),
                         surface, np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32), model.view.amplification)


def pressure_colors(p: FloatArray, p_max: float) -> np.ndarray:
    """RGB (n, 3) uint8 of pressures p (n,) [Pa] on a diverging scale: blue suction -p_max, white 0,
    red compression +p_max (clipped beyond)."""
    s = np.clip(np.asarray(p, float) / (p_max if p_max > 0 else 1.0), -1.0, 1.0)[:, None]
    rgb = np.where(s >= 0, ZERO + s * (COMPRESSION - ZERO), ZERO - s * (SUCTION - ZERO))
    return rgb.round().astype(np.uint8)


def pressure_scale(frames: SectionFrames) -> float:
    """max |p| over all frames [Pa]: the colour scale's end."""
    return float(np.abs(frames.pressure).max(initial=0.0))
