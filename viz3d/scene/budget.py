"""Size and cost of a scene, estimated from its tables before anything is built.

A scene that would build or run far beyond what a workstation can do (a million chain links, a
hundred thousand modes, 1e300 steps) is refused at load time with a ``SceneError`` that names the
key driving the cost and the limit to raise (``--set limits.max_steps=...``), instead of going
silent for minutes and running out of memory. The limits are the ``[limits]`` table of every
scene (``LIMITS``, documented in docs/scene_format.md); the estimates are cheap functions of the
resolved tables, so checking costs nothing. A raised limit still has to fit the machine: the
sizes it governs are also checked against the memory available now (``available_memory``), so
that a build or run the machine cannot hold is refused with the key, not killed by the system.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

from viz3d.scene.schema import Field, SceneError, Table, positive_int

LIMITS = Table({
    "max_bodies": Field(positive_int, 10_000, "rigid bodies after generators are expanded (chain.n counts)"),
    "max_modes": Field(positive_int, 400, "analytic modes of a flexible bar (400 modes: about 10 s and 0.6 GB to build; "
                       "the cost grows like n^2.5)"),
    "max_flexible_coordinates": Field(positive_int, 4_000,
                                      "finite-element dofs of a flexible bar (4000: about 10 s to build and reduce)"),
    "max_steps": Field(positive_int, 100_000_000, "integration steps of a fixed-step run, t_end / dt"),
    "max_frames": Field(positive_int, 2_000_000, "stored output frames, t_end / output_dt"),
    "max_memory_mb": Field(positive_int, 4_000, "estimated memory of the stored frames [MB]"),
}, "size limits checked before a scene is built (raise one with --set limits.<key>=<integer>)")

#: Stored bytes per frame (Python objects and small arrays), per rigid body (position, rotation,
#: Euler angles, velocities: 21 doubles, twice over for the frame and the trajectory) and per joint.
BYTES_PER_FRAME = 2048
BYTES_PER_BODY_FRAME = 400
BYTES_PER_JOINT_FRAME = 100
#: Memory a build takes per unit of size [B], measured 2026-11-28 as the peak resident size of
#: ``viz3d check`` above its 0.13 GB start: analytic bar modes 2.8 kB n^2 (n = 200, 400, 800: 0.12,
#: 0.45, 1.8 GB), finite-element dofs 0.11 kB n^2 (rod, 400 to 1900 elements), rigid bodies 7.5 kB
#: each (chains of 2000 and 8000 links); rounded up.
BUILD_BYTES_PER_MODE_SQUARED = 3000.0
BUILD_BYTES_PER_DOF_SQUARED = 128.0
BUILD_BYTES_PER_BODY = 10_000.0
#: Default output interval of multibody scenes [s] (viz3d.simulate.DEFAULT_OUTPUT_DT).
DEFAULT_OUTPUT_DT = 0.01


@dataclass(frozen=True)
class Estimate:
    """What a scene will cost, from its tables.

    Attributes
    ----------
    steps : float
        Fixed integration steps (0 for adaptive runs, whose count the tables do not fix).
    frames : float
        Stored output frames.
    bytes : float
        Memory of the stored frames [B].
    """

    steps: float
    frames: float
    bytes: float


def check_chain_size(raw_chain: dict, limits: dict, source: str) -> None:
    """Refuse a chain generator longer than ``limits.max_bodies`` before it is expanded."""
    n = raw_chain.get("n")
    if isinstance(n, int) and not isinstance(n, bool):
        if n > limits["max_bodies"]:
            raise _over(source, "chain.n", f"at most {limits['max_bodies']} links", n, "max_bodies")
        _check_fits(n * BUILD_BYTES_PER_BODY, source, "chain.n", "links", n)


def check_generated_bodies(n: int, limits: dict, source: str, key: str, what: str) -> None:
    """Refuse a generator (``key``, e.g. ``ship``) whose parameters would make ``n`` bodies, more than
    ``limits.max_bodies``, before it makes them; ``what`` says which parameters set ``n``."""
    if n > limits["max_bodies"]:
        raise _over(source, key, f"parameters giving at most {limits['max_bodies']} bodies ({what})", n, "max_bodies")
    _check_fits(n * BUILD_BYTES_PER_BODY, source, key, f"parameters giving bodies ({what})", n)


def check_budget(data: dict, source: str) -> Estimate:
    """Estimate a validated scene's cost; raise ``SceneError`` on the key that breaks a limit."""
    limits = data["limits"]
    sim = data["sim"]
    t_end = sim["t_end"]
    for i, b in enumerate(data["bodies"]):
        if b["type"] == "flexible":
            check_bar_size(b, limits, source, f"bodies[{i}]")
    n_bodies, n_joints = len(data["bodies"]), len(data["joints"])
    if n_bodies > limits["max_bodies"]:
        raise _over(source, "bodies", f"at most {limits['max_bodies']} bodies", n_bodies, "max_bodies")
    _check_fits(n_bodies * BUILD_BYTES_PER_BODY, source, "bodies", "bodies", n_bodies)
    dt = sim["dt"]
    ratio = 0.0 if "rtol" in sim else t_end / dt  # inf for a tiny dt and a long run: refused, not rounded
    if not ratio <= limits["max_steps"]:
        raise _over(source, "sim.dt", f"a step giving at most {limits['max_steps']} steps over sim.t_end = {t_end:g} s "
                    f"(t_end / dt = {t_end / dt:.3g})", dt, "max_steps")
    steps = float(math.ceil(ratio - 1e-9)) if ratio else 0.0
    output_dt = sim.get("output_dt", max(DEFAULT_OUTPUT_DT, dt))
    frames = t_end / max(output_dt, dt) + 1
    per_frame = BYTES_PER_FRAME + BYTES_PER_BODY_FRAME * n_bodies + BYTES_PER_JOINT_FRAME * n_joints
    return _memory_checked(Estimate(steps, frames, frames * per_frame), limits, source,
                           "sim.output_dt" if "output_dt" in sim else "sim.t_end")


def check_bar_size(bar: dict, limits: dict, source: str, where: str) -> None:
    """Refuse a flexible bar with more modes or finite-element dofs than ``limits`` allow."""
    key, n = _bar_coordinates(bar)
    limit = "max_modes" if key == "modes" else "max_flexible_coordinates"
    what = "analytic modes" if key == "modes" else "finite-element dofs"
    if n > limits[limit]:
        raise _over(source, f"{where}.{key}", f"at most {limits[limit]} {what}", n, limit)
    per = BUILD_BYTES_PER_MODE_SQUARED if key == "modes" else BUILD_BYTES_PER_DOF_SQUARED
    _check_fits(per * float(n) ** 2, source, f"{where}.{key}", what, n)


def _bar_coordinates(bar: dict) -> tuple[str, int]:
    """The key that sets a bar's size and its number of coordinates (an upper bound)."""
    if bar.get("model", "modal") == "fe" and "elements" in bar:
        dofs_per_node = 1 if bar["theory"] == "rod" else 3 if bar.get("element") == "quintic" else 2
        return "elements", (bar["elements"] + 1) * dofs_per_node
    if "modes" in bar and bar.get("model", "modal") == "modal":
        return "modes", bar["modes"]
    return "tolerance", 0  # chosen from the physics, bounded by the selection itself


def _memory_checked(est: Estimate, limits: dict, source: str, key: str) -> Estimate:
    if est.frames > limits["max_frames"]:
        raise _over(source, key, f"at most {limits['max_frames']} stored frames (got t_end / output_dt = "
                    f"{est.frames - 1:.3g})", None, "max_frames")
    megabytes = est.bytes / 1e6
    if megabytes > limits["max_memory_mb"]:
        raise _over(source, key, f"stored frames within {limits['max_memory_mb']} MB (estimated {megabytes:.3g} MB)",
                    None, "max_memory_mb")
    _check_fits(est.bytes, source, key, "stored frames", None)
    return est


def available_memory() -> float | None:
    """Memory available to a new allocation now [B]: Linux's MemAvailable (free plus reclaimable
    caches), else the free physical pages; None where neither can be read (then nothing is checked)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_AVPHYS_PAGES")) * float(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def _check_fits(nbytes: float, source: str, key: str, what: str, got) -> None:
    """Refuse a size (``key``) whose estimated memory ``nbytes`` exceeds what the machine has
    available, whatever the limits allow."""
    available = available_memory()
    if available is not None and nbytes > available:
        expected = (f"{what} that fit in this machine's available memory (estimated {nbytes / 1e9:.3g} GB, "
                    f"{available / 1e9:.3g} GB available)")
        raise SceneError(source, key, expected) if got is None else SceneError(source, key, expected, got)


def _over(source: str, key: str, expected: str, got, limit: str) -> SceneError:
    hint = f"{expected}; raise the limit with --set limits.{limit}=<integer> if this machine can afford it"
    return SceneError(source, key, hint) if got is None else SceneError(source, key, hint, got)
