"""Regenerate ramp.stl, the faceted ramp of scenes/shapes_on_a_ramp.toml.

    python scenes/meshes/make_ramp.py

A wedge 1.0 m long (x from -0.5 to 0.5), 0.6 m wide, rising from 0 at x = 0.5 to 0.25 m at
x = -0.5 (a 14.0 degree slope), subdivided twice so that shapes rolling down it cross many
facets and their edges: the ground's triangle mesh the collision library sees as a triangle soup.
"""

from pathlib import Path

import numpy as np
import trimesh

x0, x1, width, height = -0.5, 0.5, 0.6, 0.25
points = np.array([[x, y, 0.0] for x in (x0, x1) for y in (-width / 2, width / 2)]
                  + [[x0, y, height] for y in (-width / 2, width / 2)])
mesh = trimesh.convex.convex_hull(points).subdivide().subdivide()
assert mesh.is_watertight and mesh.is_volume
mesh.export(Path(__file__).with_name("ramp.stl"))
