"""``Trajectory``: the stored result of a run and its ``.npz`` file format (a stable contract).

Fields (n frames, nb bodies, nj joints), documented in docs/trajectory.md:

=====================  ==============  ==========================================================
t                      (n,)            time [s]
body_names             (nb,)           str
mass                   (nb,)           [kg]
inertia_body           (nb, 3, 3)      about the centre of mass, body axes [kg m^2]
position               (n, nb, 3)      world centre of mass [m]
rotation               (n, nb, 3, 3)   world-from-body
euler                  (n, nb, 3)      ZXZ (psi, theta, phi) of ``rotation`` w.r.t. world [rad]
velocity               (n, nb, 3)      world centre-of-mass velocity [m/s]
omega                  (n, nb, 3)      world angular velocity [rad/s]
energy_kinetic         (n,)            [J]
energy_potential       (n,)            gravity + springs [J]
energy_total           (n,)            [J]
constraint_violation   (n,)            max |C| [m]
joint_names            (nj,)           str
reaction_force         (n, nj, 3)      world force on the first body of each joint [N]
chart_switches         (nb,)           Euler-chart switches per body during the run
status                 ()              "ok" or the diagnosis
scene_json             ()              resolved scene + viz3d version, integrator, dt, ...
=====================  ==============  ==========================================================
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

ARRAY_FIELDS = (
    "t", "body_names", "mass", "inertia_body", "position", "rotation", "euler", "velocity", "omega",
    "energy_kinetic", "energy_potential", "energy_total", "constraint_violation", "joint_names",
    "reaction_force", "chart_switches",
)


@dataclass(frozen=True)
class Trajectory:
    """A run's frames and metadata (see the module docstring for shapes and units).

    ``wall_time`` [s], ``n_steps`` and ``n_rhs`` describe the run's cost; they are saved too.
    ``extras`` holds further named arrays a kind of scene adds (impact runs: ``contact_force``,
    ``gauge_strain``, ``energy_*``, ...; docs/trajectory.md); each is saved under its own name.
    """

    t: np.ndarray
    body_names: np.ndarray
    mass: np.ndarray
    inertia_body: np.ndarray
    position: np.ndarray
    rotation: np.ndarray
    euler: np.ndarray
    velocity: np.ndarray
    omega: np.ndarray
    energy_kinetic: np.ndarray
    energy_potential: np.ndarray
    energy_total: np.ndarray
    constraint_violation: np.ndarray
    joint_names: np.ndarray
    reaction_force: np.ndarray
    chart_switches: np.ndarray
    status: str
    scene_json: str
    wall_time: float = 0.0
    n_steps: int = 0
    n_rhs: int = 0
    extras: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    @property
    def scene(self) -> dict:
        """The resolved scene and run metadata (parsed ``scene_json``)."""
        return json.loads(self.scene_json)

    @property
    def energy_drift(self) -> float:
        """``max |E(t) - E(0)|`` [J]."""
        e = self.energy_total
        return float(np.max(np.abs(e - e[0]))) if e.size else 0.0

    @property
    def energy_drift_rel(self) -> float:
        """Energy drift over the largest kinetic energy of the run (the reference level of the
        potential is arbitrary, so ``E(0)`` is not a meaningful scale)."""
        scale = float(np.max(self.energy_kinetic)) if self.energy_kinetic.size else 0.0
        return self.energy_drift / scale if scale > 0 else 0.0

    @property
    def max_constraint_violation(self) -> float:
        return float(np.max(self.constraint_violation)) if self.constraint_violation.size else 0.0

    def body(self, name: str) -> int:
        """Index of body ``name`` in the per-body arrays."""
        return list(self.body_names).index(name)

    def save(self, path: str | Path) -> Path:
        """Write the ``.npz`` file (compressed); returns its path. The file appears whole or not at
        all: it is written beside ``path`` under a temporary name and renamed (an interrupt or a
        full disk never leaves a truncated archive, nor destroys a previous one)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        data = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "extras"}
        clash = set(self.extras) & set(data)
        if clash:
            raise ValueError(f"extras may not reuse field names: {sorted(clash)}")
        partial = path.with_name(f".{path.name}.partial")
        try:
            with open(partial, "wb") as f:
                np.savez_compressed(f, **data, **self.extras)
            os.replace(partial, path)
        finally:
            partial.unlink(missing_ok=True)
        return path

    @classmethod
    def load(cls, path: str | Path) -> "Trajectory":
        """Read a file written by ``save``."""
        names = {f.name for f in fields(cls)}
        with np.load(path, allow_pickle=False) as z:
            kw = {k: z[k] for k in z.files if k in names}
            kw["extras"] = {k: z[k] for k in z.files if k not in names}
        kw["status"], kw["scene_json"] = str(kw["status"]), str(kw["scene_json"])
        for key, typ in (("wall_time", float), ("n_steps", int), ("n_rhs", int)):
            if key in kw:
                kw[key] = typ(kw[key])
        return cls(**kw)
