"""The stowage study (seed 004's design question, issue 11): the haul's verdict and peak hauling force
over a grid of two scene keys, by default the ship's heel and trim.

``stowage_study(scene, {"ship.heel": [...], "ship.trim": [...]})`` runs the scene once per grid point
(``viz3d.studies``: in this process, on local worker processes or on a Dask cluster), and returns a
``StowageReport``: a table (markdown, CSV) and a chart (verdict per cell, coloured; peak force written
in it). With an output folder, finished runs are kept in its results store
(``viz3d.studies.execute.Store``): the same study started again runs only the missing points.

With an ``Ensemble`` (``viz3d.studies.ensemble``; ``--ensemble N --perturb KEY=SIZE,...``) each grid
point runs ``N`` members with seeded perturbations of keys of ``viz3d.studies.STOWAGE_PERTURBATIONS``,
and the report gives per cell (``EnsembleCell``) the verdict counts, the fraction seated with its 95 % Wilson
interval and the peak hauling force's min/median/max; the chart shows the fraction seated. Each
member is a run of its own in the results store (resumed member by member) and its overrides are
in ``runs.csv``, so ``viz3d run SCENE --set ...`` reproduces it alone.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from viz3d.scene.load import load_scene
from viz3d.scene.schema import SceneError
from viz3d.stowage import OUTCOMES
from viz3d.studies.ensemble import Ensemble, Member, members, nominal_values, wilson_interval
from viz3d.studies.execute import IN_PROCESS, Cluster, Store, run_study, store_note
from viz3d.studies.plan import Point, grid_points

#: Cell colours of the chart per outcome (RGB 0-1).
COLORS = {"seated": (0.55, 0.80, 0.55), "jammed": (0.90, 0.45, 0.40), "not reached": (0.95, 0.80, 0.40),
          "failed": (0.70, 0.70, 0.70)}


@dataclass(frozen=True)
class StowageRun:
    """One run: the grid values, the verdict (``failed`` when the run stopped otherwise) and its
    numbers; in an ensemble, the member's index and every override of the run (``--set`` text: the
    study's, the grid point's, the member's perturbations), which ``viz3d run SCENE --set ...`` reruns."""

    values: tuple
    outcome: str
    time: float
    peak_force: float
    position_error: float
    angle_error: float
    status: str
    wall_time: float
    member: int = 0
    overrides: tuple[str, ...] = ()


@dataclass(frozen=True)
class EnsembleCell:
    """The members of one grid point.

    Attributes
    ----------
    values : tuple
        The grid values.
    runs : tuple of StowageRun
        Its members, in member order.
    """

    values: tuple
    runs: tuple[StowageRun, ...]

    def count(self, outcome: str) -> int:
        return sum(r.outcome == outcome for r in self.runs)

    @property
    def n_verdicts(self) -> int:
        """Members that ended with a verdict (not ``failed``): the fraction's denominator."""
        return len(self.runs) - self.count("failed")

    @property
    def fraction_seated(self) -> float:
        return self.count("seated") / self.n_verdicts if self.n_verdicts else np.nan

    @property
    def interval(self) -> tuple[float, float]:
        """95 % Wilson score interval of the fraction seated (``wilson_interval``)."""
        return wilson_interval(self.count("seated"), self.n_verdicts)

    @property
    def peak_forces(self) -> tuple[float, float, float]:
        """Min, median and max of the members' peak hauling forces [N] (nan without any)."""
        f = np.array([r.peak_force for r in self.runs], float)
        f = f[np.isfinite(f)]
        return (float(f.min()), float(np.median(f)), float(f.max())) if f.size else (np.nan,) * 3


def cells_of(runs: tuple[StowageRun, ...]) -> tuple[EnsembleCell, ...]:
    """The runs grouped by grid values (in the order the values first appear)."""
    groups: dict[tuple, list[StowageRun]] = {}
    for r in runs:
        groups.setdefault(r.values, []).append(r)
    return tuple(EnsembleCell(v, tuple(sorted(rs, key=lambda r: r.member))) for v, rs in groups.items())


@dataclass(frozen=True)
class StowageReport:
    scene: str
    keys: tuple[str, ...]
    runs: tuple[StowageRun, ...]
    note: str = ""  # what came from the results store (``store_note``)
    ensemble: Ensemble | None = None

    @property
    def cells(self) -> tuple[EnsembleCell, ...]:
        return cells_of(self.runs)

    def markdown(self) -> str:
        return self._ensemble_markdown() if self.ensemble is not None else self._runs_markdown()

    def _ensemble_markdown(self) -> str:
        head = [*self.keys, "members", *OUTCOMES, "failed", "seated fraction [95 % Wilson]",
                "peak force min / median / max [kN]"]
        rows = [[*(f"{v:g}" for v in c.values), str(len(c.runs)), *(str(c.count(o)) for o in (*OUTCOMES, "failed")),
                 _fraction_text(c), " / ".join(f"{f / 1e3:.1f}" for f in c.peak_forces)] for c in self.cells]
        lines = [f"stowage study of {self.scene}: {self.ensemble.describe()}", *([self.note] if self.note else []), "",
                 "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        lines += ["| " + " | ".join(r) + " |" for r in rows]
        lines.append("\nthe fraction is of the members with a verdict (not failed); every member's verdict and "
                     "overrides are in runs.csv (`viz3d run SCENE --set ...` reruns one alone)")
        for c in self.cells:
            failed = [r for r in c.runs if r.outcome == "failed"]
            if failed:
                lines.append(f"{len(failed)} failed at {dict(zip(self.keys, c.values))}, member {failed[0].member}: "
                             f"{failed[0].status}")
        return "\n".join(lines)

    def _runs_markdown(self) -> str:
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


def _fraction_text(c: EnsembleCell) -> str:
    lo, hi = c.interval
    if not c.n_verdicts:
        return "- (no verdict)"
    return f"{c.count('seated')}/{c.n_verdicts} = {c.fraction_seated:.2f} [{lo:.2f}, {hi:.2f}]"


def _run_of(member: Member, row: dict, overrides: list[str]) -> StowageRun:
    """A member's ``StowageRun`` from its row; a point the scene refuses, or a run that raised, is a
    ``failed`` row, so the other points' runs are kept."""
    nan = np.nan
    return StowageRun(member.point.values, row.get("outcome", "failed"), row.get("time", nan),
                      row.get("peak_force", nan), row.get("position_error", nan), row.get("angle_error", nan),
                      row["status"].removeprefix("refused: "), row.get("wall_time", 0.0), member.index,
                      (*overrides, *member.study_point.overrides))


def stowage_study(scene: str | Path, grid: dict[str, list[float]], overrides=(), cluster: Cluster = IN_PROCESS,
                  out: Path | None = None, ensemble: Ensemble | None = None) -> StowageReport:
    """Run ``scene`` at every point of ``grid`` (key path -> values; the product of all), with the
    extra ``overrides``, on ``cluster`` (``viz3d.studies.execute``); with an ``ensemble``, its members
    at every point (``parse_ensemble(n, texts, STOWAGE_PERTURBATIONS)`` makes one of the keys meant
    here). Finished runs are kept in (and read back from) the results store of the folder ``out``."""
    keys, store = tuple(grid), Store.in_folder(out)
    runs = [m for point in grid_points(grid) for m in _members(scene, point, list(overrides), ensemble)]
    outcomes = run_study(scene, [m.study_point for m in runs], StowageMeasure(), cluster, overrides=list(overrides),
                         store=store)
    rows = tuple(_run_of(m, o.row, list(overrides)) for m, o in zip(runs, outcomes))
    return StowageReport(Path(scene).stem, keys, rows, store_note(store, outcomes), ensemble)


def _members(scene, point: Point, overrides: list[str], ensemble: Ensemble | None) -> list[Member]:
    """The runs of one grid point: the point itself without an ensemble; else the ensemble's members,
    perturbed about the values the point's scene has (unperturbed where the scene refuses the point:
    each member is then that refusal's failed row)."""
    if ensemble is None:
        return [Member(point, 0, ())]
    try:
        data = load_scene(scene, overrides + list(point.overrides)).data
    except SceneError:
        return [Member(point, m, ()) for m in range(ensemble.n)]
    return members(ensemble, point, nominal_values(data, [p.key for p in ensemble.perturbations]))


def save(report: StowageReport, out: Path) -> list[Path]:
    """``table.md``, ``runs.csv``, ``runs.json`` and ``chart.png`` into ``out``; with an ensemble also
    ``cells.csv`` (one row per grid point), and ``runs.csv`` gives each member's index and overrides."""
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "table.md", out / "runs.csv", out / "runs.json", out / "chart.png"]
    paths[0].write_text(report.markdown() + "\n")
    member = ["member", "overrides"] if report.ensemble is not None else []
    with paths[1].open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow([*report.keys, "verdict", "time_s", "peak_force_N", "position_error_m", "angle_error_deg",
                    "wall_time_s", "status", *member])
        for r in report.runs:
            w.writerow([*r.values, r.outcome, r.time, r.peak_force, r.position_error, r.angle_error, r.wall_time,
                        r.status, *([r.member, " ".join(r.overrides)] if member else [])])
    summary = {"scene": report.scene, "keys": report.keys, "runs": [r.__dict__ for r in report.runs]}
    if report.ensemble is not None:
        paths.append(out / "cells.csv")
        _write_cells(report, paths[-1])
        summary |= {"ensemble": report.ensemble.describe(), "cells": [_cell_dict(c) for c in report.cells]}
    paths[2].write_text(json.dumps(summary, indent=1, default=float))
    (_fraction_chart if report.ensemble is not None else _chart)(report, paths[3])
    return paths


def _cell_dict(c: EnsembleCell) -> dict:
    """One grid point's ensemble numbers (``cells.csv`` columns after the keys)."""
    lo, hi = c.interval
    f_min, f_med, f_max = c.peak_forces
    return {"values": c.values, "members": len(c.runs), **{o: c.count(o) for o in (*OUTCOMES, "failed")},
            "fraction_seated": c.fraction_seated, "wilson95_low": lo, "wilson95_high": hi,
            "peak_force_min_N": f_min, "peak_force_median_N": f_med, "peak_force_max_N": f_max}


def _write_cells(report: StowageReport, path: Path) -> None:
    rows = [_cell_dict(c) for c in report.cells]
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow([*report.keys, *list(rows[0])[1:]] if rows else report.keys)
        w.writerows([*r["values"], *list(r.values())[1:]] for r in rows)


def _chart(report: StowageReport, path: Path) -> None:
    """Verdict (colour) and peak hauling force per run of the grid."""

    def cell(r):
        force = "" if np.isnan(r.peak_force) else f"\n{r.peak_force / 1e3:.0f} kN"
        return COLORS[r.outcome], f"{r.outcome}{force}"

    _grid_chart(report, report.runs, cell, f"{report.scene}: verdict and peak hauling force", path, (1.6, 1.3, 1.2, 1.0))


def _fraction_chart(report: StowageReport, path: Path) -> None:
    """Fraction seated per cell (colour, red 0 to green 1; grey: no verdict), with its counts and
    95 % Wilson interval written in it."""
    import matplotlib

    cmap = matplotlib.colormaps["RdYlGn"]

    def cell(c):
        if not c.n_verdicts:
            return COLORS["failed"], f"{len(c.runs)} failed"
        lo, hi = c.interval
        return cmap(0.15 + 0.7 * c.fraction_seated), f"{c.count('seated')}/{c.n_verdicts} seated\n[{lo:.2f}, {hi:.2f}]"

    _grid_chart(report, report.cells, cell, f"{report.scene}: fraction seated of {report.ensemble.n} members [95 % Wilson]",
                path, (2.4, 1.6, 1.4, 1.1), title_size=9)


def _grid_chart(report: StowageReport, items, cell, title: str, path: Path, size: tuple, title_size=None) -> None:
    """One coloured square per grid point of ``items`` (each with ``values``: one or two study keys),
    ``cell(item) -> (colour, text)``; ``size``: figure width and height as (base, per column, base,
    per row) [in]."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    two = len(report.keys) == 2
    keys = report.keys if two else (*report.keys, "")
    xs = sorted({r.values[0] for r in items})
    ys = sorted({r.values[1] for r in items}) if two else [0.0]
    fig, ax = plt.subplots(figsize=(size[0] + size[1] * len(xs), size[2] + size[3] * len(ys)))
    for r in items:
        i, j = xs.index(r.values[0]), ys.index(r.values[1] if two else 0.0)
        color, text = cell(r)
        ax.add_patch(plt.Rectangle((i - 0.5, j - 0.5), 1, 1, color=color))
        ax.text(i, j, text, ha="center", va="center", fontsize=8)
    ax.set_xlim(-0.5, len(xs) - 0.5)
    ax.set_ylim(-0.5, len(ys) - 0.5)
    ax.set_xticks(range(len(xs)), [f"{x:g}" for x in xs])
    ax.set_yticks(range(len(ys)), [f"{y:g}" for y in ys])
    ax.set_xlabel(keys[0])
    ax.set_ylabel(keys[1])
    ax.set_title(title, fontsize=title_size)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
