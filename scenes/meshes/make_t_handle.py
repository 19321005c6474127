"""Regenerate t_handle.stl, the wing-nut-like body of scenes/torque_free.toml.

    python scenes/meshes/make_t_handle.py

Two face-touching boxes (a handle along x and a shaft along y, metres), then rotated by a fixed
rotation so that the mesh axes are NOT principal axes: the body's inertia tensor in body axes has
products of inertia, which exercises the general Euler equations.
"""

from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

handle = trimesh.creation.box(extents=(0.08, 0.016, 0.016))
shaft = trimesh.creation.box(extents=(0.012, 0.05, 0.012))
shaft.apply_translation((0.0, 0.008 + 0.025, 0.0))
mesh = trimesh.util.concatenate([handle, shaft])
T = np.eye(4)
T[:3, :3] = Rotation.from_euler("ZXZ", [0.3, 0.5, -0.2]).as_matrix()
mesh.apply_transform(T)
assert mesh.is_watertight and mesh.is_volume
mesh.export(Path(__file__).with_name("t_handle.stl"))
