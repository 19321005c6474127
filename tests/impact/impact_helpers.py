"""Reading impact runs of the one engine: the impactor's motion along the contact normal, the
contact's force, the bodies of a shorthand scene (``viz3d/scene/shorthand.py``: flexible body
``bar``, rigid body ``impactor``, contact ``impact`` whose normal ``n`` is the struck surface's
outward normal; the impactor arrives moving along ``-n``)."""

from __future__ import annotations

import numpy as np

from viz3d.scene.build import build


def contact_normal(traj) -> np.ndarray:
    """World normal ``n`` (3,) of the scene's first contact (the struck surface's, outward)."""
    return np.asarray(traj.scene["scene"]["contacts"][0]["normal"], float)


def impactor_velocity(traj) -> np.ndarray:
    """The impactor's velocity towards the target, ``-v . n``, per frame (n,) [m/s] (+1 at the start
    of the 1 m/s scenes, negative after a rebound)."""
    return -(traj.velocity[:, traj.body("impactor")] @ contact_normal(traj))


def contact_force(traj) -> np.ndarray:
    """Normal force of the scene's first contact per frame (n,) [N]."""
    return traj.extras["contact_force"][:, 0]


def contact_law(scene):
    """The normal law of a loaded scene's first contact (``ContactSet.laws``)."""
    return build(scene)[0].contacts[0].laws[0]
