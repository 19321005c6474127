"""The stowage study (seed 004's design question, issue 11): the haul's verdict and peak hauling force
over a grid of two scene keys, by default the ship's heel and trim.

``stowage_study(scene, {"ship.heel": [...], "ship.trim": [...]})`` runs the scene once per grid point
(``viz3d.studies``: in this process, on local worker processes or on a Dask cluster), and returns a
``StowageReport``: a table (markdown, CSV) and a chart (verdict per cell, coloured; peak force written
in it). With an output folder, finished runs are kept in its results store
(``viz3d.studies.execute.Store``): the same study started again runs only the missing points.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from viz3d.studies.execute import IN_PROCESS, Cluster, Store, run_study, store_note
from viz3d.studies.plan import grid_points

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
    note: str = ""  # what came from the results store (``store_note``)

    def markdown(self) -> str:
        head = [*self.keys, "verdict", "at [s]", "peak force [kN]", "pose error [m]", "[deg]", "wall [s]"]
        rows = [[*(f"{v:g}" for v in r.values), r.outcome, f"{r.time:.2f}", f"{r.peak_force / 1e3:.1f}",
                 f"{r.position_error:.3f}", f"{r.angle_error:.2f}", f"{r.wall_time:.0f}"] for r in self.runs]
        lines = [f"stowage study of {self.scene}", *([self.note] if self.note else []), "",
                 "| " + " | ".join(head) + " |",
                 "|" + "---|" * len(head)]
        lines += ["| " + " | ".join(r) + " |" for r in rows]
        failed = [r for r in self.runs if r.outcome == "failed"]
        lines += [f"\nfailed at {dict(zip(self.keys, r.values))}: {r.status}" for r in failed]
        return "\n".join(lines)


@dataclass(frozen=True)
class StowageMeasure:
    """Measure of the study (``viz3d.studies``): the haul's verdict and numbers of one run."""

    def __call__(self, scene) -> dict:
        from viz3d.simulate import simulate

        traj = simulate(scene)
        x = traj.extras
        if "stowage_verdict" not in x:
            return {"outcome": "failed", "time": float(traj.t[-1]), "status": traj.status, "wall_time": traj.wall_time}
        jam = x["stowage_verdict"] == "jammed"
        return {"outcome": str(x["stowage_verdict"]) if traj.ok or jam else "failed", "time": float(x["stowage_time"]),
                "peak_force": float(x["stowage_peak_force"]), "position_error": float(x["stowage_position_error"]),
                "angle_error": float(x["stowage_angle_error"]), "status": traj.status, "wall_time": traj.wall_time}


def _run_of(values: tuple, row: dict) -> StowageRun:
    """A grid point's ``StowageRun`` from its row; a point the scene refuses, or a run that raised, is a
    ``failed`` row, so the other points' runs are kept."""
    nan = np.nan
    return StowageRun(values, row.get("outcome", "failed"), row.get("time", nan), row.get("peak_force", nan),
                      row.get("position_error", nan), row.get("angle_error", nan),
                      row["status"].removeprefix("refused: "), row.get("wall_time", 0.0))


def stowage_study(scene: str | Path, grid: dict[str, list[float]], overrides=(), cluster: Cluster = IN_PROCESS,
                  out: Path | None = None) -> StowageReport:
    """Run ``scene`` at every point of ``grid`` (key path -> values; the product of all), with the
    extra ``overrides``, on ``cluster`` (``viz3d.studies.execute``); finished runs are kept in (and
    read back from) the results store of the folder ``out``."""
    keys, store = tuple(grid), Store.in_folder(out)
    outcomes = run_study(scene, grid_points(grid), StowageMeasure(), cluster, overrides=list(overrides), store=store)
    return StowageReport(Path(scene).stem, keys, tuple(_run_of(o.point.values, o.row) for o in outcomes),
                         store_note(store, outcomes))


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
