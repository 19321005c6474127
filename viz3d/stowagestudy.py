"""The stowage study (seed 004's design question, issue 11): the haul's verdict and peak hauling force
over a grid of two scene keys, by default the ship's heel and trim.

``stowage_study(scene, {"ship.heel": [...], "ship.trim": [...]})`` runs the scene once per grid point
(``workers`` processes at a time), and returns a ``StowageReport``: a table (markdown, CSV) and a
chart (verdict per cell, coloured; peak force written in it).
"""

from __future__ import annotations

import csv
import itertools
import json
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: Cell colours of the chart per outcome (RGB 0-1).
COLORS = {"seated": (0.55, 0.80, 0.55), "jammed": (0.90, 0.45, 0.40), "not reached": (0.95, 0.80, 0.40),
          "failed": (0.70, 0.70, 0.70)}


@dataclass(frozen=True)
class StowageRun:
    """One grid point: the overrides, the verdict (``failed`` when the run stopped otherwise) and its numbers."""

    values: tuple
    outcome: str
    time: float
    peak_force: float
    position_error: float
    angle_error: float
    status: str
    wall_time: float


@dataclass(frozen=True)
class StowageReport:
    scene: str
    keys: tuple[str, ...]
    runs: tuple[StowageRun, ...]

    def markdown(self) -> str:
        head = [*self.keys, "verdict", "at [s]", "peak force [kN]", "pose error [m]", "[deg]", "wall [s]"]
        rows = [[*(f"{v:g}" for v in r.values), r.outcome, f"{r.time:.2f}", f"{r.peak_force / 1e3:.1f}",
                 f"{r.position_error:.3f}", f"{r.angle_error:.2f}", f"{r.wall_time:.0f}"] for r in self.runs]
        lines = [f"stowage study of {self.scene}", "", "| " + " | ".join(head) + " |",
                 "|" + "---|" * len(head)]
        lines += ["| " + " | ".join(r) + " |" for r in rows]
        failed = [r for r in self.runs if r.outcome == "failed"]
        lines += [f"\nfailed at {dict(zip(self.keys, r.values))}: {r.status}" for r in failed]
        return "\n".join(lines)


def _one(args) -> StowageRun:
    """One grid point's run; a scene error (a value the scene refuses) is a ``failed`` row, so the
    other points' runs are kept."""
    path, overrides, values = args
    import viz3d
    from viz3d.scene.schema import SceneError

    try:
        traj = viz3d.simulate(viz3d.load_scene(path, overrides))
    except SceneError as exc:
        return StowageRun(values, "failed", np.nan, np.nan, np.nan, np.nan, str(exc), 0.0)
    x = traj.extras
    if "stowage_verdict" not in x:
        return StowageRun(values, "failed", float(traj.t[-1]), np.nan, np.nan, np.nan, traj.status, traj.wall_time)
    jam = x["stowage_verdict"] == "jammed"
    outcome = str(x["stowage_verdict"]) if traj.ok or jam else "failed"
    return StowageRun(values, outcome, float(x["stowage_time"]), float(x["stowage_peak_force"]),
                      float(x["stowage_position_error"]), float(x["stowage_angle_error"]), traj.status, traj.wall_time)


def stowage_study(scene: str | Path, grid: dict[str, list[float]], overrides=(), workers: int = 1) -> StowageReport:
    """Run ``scene`` at every point of ``grid`` (key path -> values; the product of all), with the
    extra ``overrides``; ``workers`` processes at a time."""
    keys = tuple(grid)
    points = list(itertools.product(*(grid[k] for k in keys)))
    jobs = [(str(scene), [*overrides, *(f"{k}={v!r}" for k, v in zip(keys, p))], p) for p in points]
    if workers > 1:
        with ProcessPoolExecutor(workers) as pool:
            runs = list(pool.map(_one, jobs))
    else:
        runs = [_one(j) for j in jobs]
    return StowageReport(Path(scene).stem, keys, tuple(runs))


def save(report: StowageReport, out: Path) -> list[Path]:
    """``table.md``, ``runs.csv``, ``runs.json`` and ``chart.png`` into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "table.md", out / "runs.csv", out / "runs.json", out / "chart.png"]
    paths[0].write_text(report.markdown() + "\n")
    with paths[1].open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow([*report.keys, "verdict", "time_s", "peak_force_N", "position_error_m", "angle_error_deg",
                    "wall_time_s", "status"])
        for r in report.runs:
            w.writerow([*r.values, r.outcome, r.time, r.peak_force, r.position_error, r.angle_error, r.wall_time,
                        r.status])
    paths[2].write_text(json.dumps({"scene": report.scene, "keys": report.keys,
                                    "runs": [r.__dict__ for r in report.runs]}, indent=1, default=float))
    _chart(report, paths[3])
    return paths


def _chart(report: StowageReport, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = report.keys if len(report.keys) == 2 else (*report.keys, "")
    xs = sorted({r.values[0] for r in report.runs})
    ys = sorted({r.values[1] for r in report.runs}) if len(report.keys) == 2 else [0.0]
    fig, ax = plt.subplots(figsize=(1.6 + 1.3 * len(xs), 1.2 + 1.0 * len(ys)))
    for r in report.runs:
        i, j = xs.index(r.values[0]), ys.index(r.values[1] if len(report.keys) == 2 else 0.0)
        ax.add_patch(plt.Rectangle((i - 0.5, j - 0.5), 1, 1, color=COLORS[r.outcome]))
        force = "" if np.isnan(r.peak_force) else f"\n{r.peak_force / 1e3:.0f} kN"
        ax.text(i, j, f"{r.outcome}{force}", ha="center", va="center", fontsize=8)
    ax.set_xlim(-0.5, len(xs) - 0.5)
    ax.set_ylim(-0.5, len(ys) - 0.5)
    ax.set_xticks(range(len(xs)), [f"{x:g}" for x in xs])
    ax.set_yticks(range(len(ys)), [f"{y:g}" for y in ys])
    ax.set_xlabel(keys[0])
    ax.set_ylabel(keys[1])
    ax.set_title(f"{report.scene}: verdict and peak hauling force")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
