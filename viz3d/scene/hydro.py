"""Hydrodynamics scenes: a file with a ``[reservoir]`` table is a dam-reservoir study (``viz3d.hydro``).

Tables (``HYDRO_FILE``, documented in docs/scene_format.md and docs/hydro.md):

* ``[reservoir]``: water density, depth, sound speed (``inf``: incompressible) and the bottom's
  reflection coefficient alpha (1: rigid, the seed's model);
* ``[sweep]``: the frequency sweep of S(omega) and the responses, the frequencies of the pressure
  profiles on the face, the series tolerance;
* ``[dam]`` (optional): a cantilever dam of ``viz3d.flexible`` (its modes are the wall shapes);
  without it the wall is rigid and moves as a whole (the seed's example);
* ``[ground_motion]`` (optional, with ``[dam]``): the record the dam's time response is computed
  for, the shipped synthetic one or a CSV file below the scene's folder;
* ``[view]``: the reservoir section drawn by ``viz3d view`` and recorded by ``--record``.

``hydro_model`` turns a loaded scene into a frozen ``HydroModel`` of ``viz3d.hydro`` values; every
error names the file, the key and what was expected (``SceneError``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from viz3d._typing import FloatArray
from viz3d.flexible import Material
from viz3d.hydro.dam import CONCRETE, DEFAULT_DAMPING_RATIO, Dam, cantilever_dam
from viz3d.hydro.records import GroundMotion, read_csv, shipped_record
from viz3d.hydro.reservoir import DEFAULT_RTOL, Reservoir
from viz3d.scene.schema import (
    OPTIONAL,
    Field,
    Invalid,
    SceneError,
    Table,
    allowed_path,
    nonnegative,
    number,
    one_of,
    poisson_ratio,
    positive,
    string,
)
from viz3d.scene.spec import SCENE

#: Largest sizes a scene may ask for (a sweep of 20 000 frequencies takes seconds; grids of 200 x 200
#: points are more than a browser draws smoothly).
MAX_FREQUENCIES, MAX_POINTS, MAX_GRID, MAX_DAM_MODES = 20_000, 10_001, 200, 60
#: Records of the ``[ground_motion]`` table.
RECORDS = ("shipped", "file")


def sound_speed(x):
    """c [m/s]: a positive number, or ``inf`` (TOML's infinity) for incompressible water."""
    expected = "a positive number [m/s], or inf (incompressible water)"
    if isinstance(x, bool) or not isinstance(x, (int, float)) or math.isnan(x) or not x > 0:
        raise Invalid(expected)
    return float(x)


def reflection(x):
    """alpha: the bottom's wave reflection coefficient, -1 < alpha <= 1."""
    expected = "a reflection coefficient in (-1, 1] (1: rigid bottom)"
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not -1.0 < x <= 1.0:
        raise Invalid(expected)
    return float(x)


def int_in(low: int, high: int):
    """An integer low..high (counts of frequencies, modes, grid points)."""

    def check(x):
        if isinstance(x, bool) or not isinstance(x, int) or not low <= x <= high:
            raise Invalid(f"an integer {low}..{high}")
        return x

    return check


def frequencies(x):
    """A non-empty list of frequencies >= 0 [rad/s]."""
    expected = "a non-empty list of frequencies >= 0 [rad/s]"
    if not (isinstance(x, list) and x and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in x)):
        raise Invalid(expected)
    if not all(math.isfinite(v) and v >= 0 for v in x):
        raise Invalid(expected)
    return [float(v) for v in x]


def tolerance(x):
    """A relative tolerance in [1e-14, 0.1]."""
    expected = "a relative tolerance in [1e-14, 0.1]"
    try:
        x = number(x)
    except Invalid:
        raise Invalid(expected) from None
    if not 1e-14 <= x <= 0.1:
        raise Invalid(expected)
    return x


RESERVOIR = Table({
    "density": Field(positive, 1000.0, "rho [kg/m^3]"),
    "depth": Field(positive, doc="h [m] (at most dam.height)"),
    "sound_speed": Field(sound_speed, 1493.0, "c [m/s]; inf: incompressible water (Westergaard's case)"),
    "reflection": Field(reflection, 1.0, "alpha, the bottom's wave reflection coefficient in (-1, 1]: 1 rigid "
                        "(the seed), 0 absorbs vertically incident waves; needs a finite sound_speed"),
}, "the water: a semi-infinite reservoir of constant depth in front of a vertical dam face")

SWEEP = Table({
    "omega_max": Field(positive, 80.0, "highest frequency of the sweep [rad/s]"),
    "n_omega": Field(int_in(1, MAX_FREQUENCIES), 400, "frequencies from 0 to omega_max"),
    "profile_omegas": Field(frequencies, [0.0, 20.0, 80.0], "frequencies of the pressure profiles on the face [rad/s]"),
    "n_y": Field(int_in(2, MAX_POINTS), 101, "heights of the profiles, from 0 to depth"),
    "rtol": Field(tolerance, DEFAULT_RTOL, "truncation of every series, relative to rho h max|phi| (pressure) or "
                  "rho h^2 max|phi|^2 (S); the terms it takes are reported"),
}, "the frequency sweep: S(omega), pressure profiles, crest responses")

DAM_MATERIAL = Table({
    "E": Field(positive, CONCRETE.E, "Young's modulus [Pa] (Pine Flat's mass concrete)"),
    "rho": Field(positive, CONCRETE.rho, "density [kg/m^3]"),
    "nu": Field(poisson_ratio, CONCRETE.nu, "Poisson's ratio"),
}, "the dam's concrete")

DAM = Table({
    "height": Field(positive, doc="H [m], the cantilever's length (at least reservoir.depth)"),
    "thickness": Field(positive, doc="constant thickness of the wall [m] (1 m wide section)"),
    "modes": Field(int_in(1, MAX_DAM_MODES), 5, "clamped-free bending modes: the wall shapes"),
    "theory": Field(one_of("euler_bernoulli", "timoshenko"), "timoshenko", "bending theory of the modes"),
    "material": Field(DAM_MATERIAL, dict, "E, rho, nu"),
    "damping": Field(nonnegative, DEFAULT_DAMPING_RATIO, "modal viscous damping ratio of every mode"),
}, "a flexible cantilever dam (viz3d.flexible), 1 m wide; its modes are the wall shapes")

GROUND_MOTION = Table({
    "record": Field(one_of(*RECORDS), "shipped", "shipped: the synthetic Kanai-Tajimi record of viz3d.hydro "
                    "(20 s, 0.3 g); file: a CSV file"),
    "file": Field(string, OPTIONAL, "record = 'file': CSV path relative to the scene file (below its folder, or a "
                  "folder allowed with --mesh-dir)"),
    "column": Field(string, "acceleration", "header of the acceleration column"),
    "time_column": Field(string, "time", "header of the time column [s] (uniform steps), if the file has one"),
    "dt": Field(positive, OPTIONAL, "sampling step [s] when the file has no time column"),
    "scale": Field(positive, 1.0, "factor to m/s^2 (9.80665 for a record in g)"),
}, "the horizontal ground acceleration of the dam's time response (positive towards the reservoir)")

VIEW = Table({
    "length": Field(positive, 3.0, "length of the drawn reservoir section, in depths h"),
    "n_x": Field(int_in(2, MAX_GRID), 41, "grid points of the section along x"),
    "n_y": Field(int_in(2, MAX_GRID), 21, "grid points of the section along y"),
    "rtol": Field(tolerance, 1e-4, "series tolerance of the drawn pressures (coarser than sweep.rtol: it sets the "
                  "terms drawn)"),
    "omega": Field(nonnegative, 20.0, "frequency of the harmonic animation [rad/s]"),
    "frames_per_cycle": Field(int_in(1, 360), 36, "frames of one harmonic cycle"),
    "frame_dt": Field(positive, 0.04, "simulated time between earthquake frames [s]; the drawn pressure is low-passed "
                      "at pi / frame_dt"),
    "amplification": Field(positive, 200.0, "dam deflection drawn this many times larger"),
}, "what viz3d view draws and --record records")

HYDRO_FILE = Table({
    "scene": Field(SCENE, dict, "about the scene"),
    "reservoir": Field(RESERVOIR, doc="the water (this table makes the file a hydrodynamics scene)"),
    "sweep": Field(SWEEP, dict, "frequency sweep"),
    "dam": Field(DAM, OPTIONAL, "a flexible dam (without it: a rigid wall moving as a whole)"),
    "ground_motion": Field(GROUND_MOTION, OPTIONAL, "ground acceleration record (with [dam])"),
    "view": Field(VIEW, dict, "viewer and recording"),
})


def check_consistency(data: dict, source: str) -> None:
    """Checks across keys of a validated hydrodynamics scene."""
    water, dam = data["reservoir"], data.get("dam")
    if water["reflection"] < 1.0 and not math.isfinite(water["sound_speed"]):
        raise SceneError(source, "reservoir.reflection", "1 (a rigid bottom) for incompressible water "
                         "(an absorbing bottom needs a finite reservoir.sound_speed)", water["reflection"])
    if dam is not None and water["depth"] > dam["height"]:
        raise SceneError(source, "reservoir.depth", f"at most dam.height = {dam['height']:g} m", water["depth"])
    if "ground_motion" in data and dam is None:
        raise SceneError(source, "ground_motion", "a [dam] table too (a ground motion shakes a dam)")
    motion = data.get("ground_motion", {})
    if motion and (motion["record"] == "file") != ("file" in motion):
        raise SceneError(source, "ground_motion.file", "a file with record = 'file', and none otherwise",
                         motion.get("file", motion["record"]))


@dataclass(frozen=True)
class ViewSpec:
    """The drawn reservoir section and its animation.

    Attributes
    ----------
    x, y : ndarray, shapes (n_x,), (n_y,)
        Grid of the section [m]: x upstream from the dam face, y up from the bottom.
    rtol : float
        Series tolerance of the drawn pressures.
    omega : float
        Frequency of the harmonic animation [rad/s].
    frames_per_cycle : int
    frame_dt : float
        Simulated time between earthquake frames [s].
    amplification : float
        Drawn deflection / true deflection.
    """

    x: FloatArray
    y: FloatArray
    rtol: float
    omega: float
    frames_per_cycle: int
    frame_dt: float
    amplification: float


@dataclass(frozen=True)
class HydroModel:
    """A hydrodynamics scene as ``viz3d.hydro`` values.

    Attributes
    ----------
    name : str
    reservoir : Reservoir
        The scene's water.
    omega : ndarray, shape (w,)
        The sweep, 0 to sweep.omega_max [rad/s].
    profile_omegas : ndarray, shape (k,)
        [rad/s].
    y : ndarray, shape (p,)
        Heights of the profiles, 0 to h [m].
    rtol : float
    dam : Dam or None
        None: a rigid wall moving as a whole (phi = 1).
    record : GroundMotion or None
    view : ViewSpec
    """

    name: str
    reservoir: Reservoir
    omega: FloatArray
    profile_omegas: FloatArray
    y: FloatArray
    rtol: float
    dam: Dam | None
    record: GroundMotion | None
    view: ViewSpec

    def cases(self) -> dict[str, Reservoir | None]:
        """The reservoirs a dam is compared with: empty (None), incompressible, and the scene's water
        when it is compressible (its c and alpha)."""
        water = self.reservoir
        out = {"empty": None, "incompressible": Reservoir(water.density, water.depth)}
        if water.compressible:
            out["compressible"] = water
        return out


def hydro_model(scene) -> HydroModel:
    """The ``HydroModel`` of a loaded hydrodynamics scene (``viz3d.scene.load.Scene``).

    Raises
    ------
    SceneError
        Naming the key whose value the models refuse, or the record file that cannot be read.
    """
    data, source = scene.data, scene.source()
    w, s, v = data["reservoir"], data["sweep"], data["view"]
    reservoir = Reservoir(w["density"], w["depth"], w["sound_speed"], w["reflection"])
    view = ViewSpec(np.linspace(0.0, v["length"] * w["depth"], v["n_x"]), np.linspace(0.0, w["depth"], v["n_y"]),
                    v["rtol"], v["omega"], v["frames_per_cycle"], v["frame_dt"], v["amplification"])
    dam = _dam(data["dam"], source) if "dam" in data else None
    record = _record(scene, data["ground_motion"]) if "ground_motion" in data else None
    return HydroModel(scene.name, reservoir, np.linspace(0.0, s["omega_max"], s["n_omega"]),
                      np.asarray(s["profile_omegas"]), np.linspace(0.0, w["depth"], s["n_y"]), s["rtol"], dam,
                      record, view)


def _dam(table: dict, source: str) -> Dam:
    m = table["material"]
    try:
        return cantilever_dam(table["height"], table["thickness"], table["modes"],
                              material=Material(E=m["E"], rho=m["rho"], nu=m["nu"]), theory=table["theory"],
                              damping_ratio=table["damping"])
    except ValueError as exc:
        raise SceneError(source, "dam", f"a dam the bar models accept ({exc})") from None


def _record(scene, table: dict) -> GroundMotion:
    if table["record"] == "shipped":
        return shipped_record()
    source = scene.source()
    path = allowed_path(scene.base_dir, table["file"], scene.mesh_dirs, source, "ground_motion.file")
    try:
        return read_csv(path, table["column"], time_column=table["time_column"], dt=table.get("dt"),
                        scale=table["scale"])
    except (OSError, ValueError) as exc:
        raise SceneError(source, "ground_motion.file", f"a readable ground-acceleration CSV ({exc})",
                         table["file"]) from None
