"""Parameter sweeps: ``viz3d sweep SCENE --grid key=v1,v2 [--sample key=dist(...) --n N] --out DIR``.

Every point of the grid or sample is the scene with those ``--set`` overrides, run once
(``viz3d.studies``: here, on local cores or on a Dask cluster). Its row holds the point's values, the
run's status, every scalar summary of the run (the ``SUMMARY`` metrics and each scalar of the
trajectory's extras, e.g. ``restitution``) and its cost (``COST``). Files in ``--out``: ``runs.jsonl``
(the results store, appended as runs finish), ``table.parquet`` and ``table.csv`` (the requested
metrics), ``table.md`` and ``chart.png`` (the main metric over the first one or two keys).
"""

from __future__ import annotations

import csv
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from viz3d.scene.load import Scene
from viz3d.simulate import simulate
from viz3d.studies.execute import IN_PROCESS, Cluster, Outcome, Store, run_study
from viz3d.studies.plan import Point

#: Summary metrics of every run (besides the scalar extras of its scene kind).
SUMMARY = ("status", "t_final", "energy_drift_rel", "energy_drift", "max_constraint_violation")
#: The run's cost: wall time [s], process time [s], integration steps, right-hand-side evaluations.
COST = ("wall_time_s", "cpu_s", "n_steps", "n_rhs")
#: Metrics of the table when ``--metrics`` is not given.
DEFAULT_METRICS = ("status", "energy_drift_rel", "max_constraint_violation")

@dataclass(frozen=True)
class Summary:
    """Measure of a sweep: one run of the scene; its ``SUMMARY`` metrics, scalar extras and ``COST``."""

    def __call__(self, scene: Scene) -> dict:
        cpu = time.process_time()
        traj = simulate(scene)
        row = scalar_extras(traj.extras)
        row.update(status=traj.status, t_final=float(traj.t[-1]) if len(traj.t) else math.nan,
                   energy_drift_rel=traj.energy_drift_rel, energy_drift=traj.energy_drift,
                   max_constraint_violation=traj.max_constraint_violation)
        row.update(wall_time_s=float(traj.wall_time), cpu_s=time.process_time() - cpu, n_steps=int(traj.n_steps),
                   n_rhs=int(traj.n_rhs))
        return row


def scalar_extras(extras: dict) -> dict:
    """The extras of a run that are one number or one string (arrays of one element included)."""
    out = {}
    for name, value in extras.items():
        a = np.asarray(value)
        if a.size == 1 and a.dtype.kind in "biuf":
            out[name] = a.item() if a.dtype.kind != "f" else float(a.item())
        elif a.size == 1 and a.dtype.kind == "U":
            out[name] = str(a.item())
    return out


@dataclass(frozen=True)
class SweepReport:
    """A finished (or interrupted) sweep.

    Attributes
    ----------
    scene : str
        The scene's file stem.
    keys : tuple of str
        The swept keys (grid keys, then sampled keys).
    metrics : tuple of str
        The requested metrics (table columns after the keys).
    outcomes : tuple of Outcome
        One per point, in the plan's order (``row`` None for a point not run yet).
    """

    scene: str
    keys: tuple[str, ...]
    metrics: tuple[str, ...]
    outcomes: tuple[Outcome, ...]

    @property
    def header(self) -> list[str]:
        return [*self.keys, *self.metrics, *COST, "key"]

    def table(self) -> list[list]:
        """Rows of the table (points run so far): values, metrics (nan where a run has none), cost, key."""
        return [[*o.point.values, *(_metric(o.row, m) for m in self.metrics), *(_metric(o.row, c) for c in COST),
                 o.key or ""] for o in self.outcomes if o.row is not None]

    @property
    def failed(self) -> list[Outcome]:
        return [o for o in self.outcomes if o.row is not None and o.row["status"] != "ok"]

    def missing_metrics(self) -> list[str]:
        """Requested metrics that no successful run has (misspelt, or not a summary of this scene)."""
        ok = [o.row for o in self.outcomes if o.row is not None and o.row["status"] == "ok"]
        return [m for m in self.metrics if ok and all(m not in row for row in ok)]

    def markdown(self, max_rows: int = 50) -> str:
        rows = self.table()
        done = len(rows)
        lines = [f"sweep of {self.scene}: {done} of {len(self.outcomes)} runs, {len(self.failed)} failed, "
                 f"{sum(o.cached for o in self.outcomes)} from the results store", "",
                 "| " + " | ".join(self.header[:-1]) + " |", "|" + "---|" * (len(self.header) - 1)]
        lines += ["| " + " | ".join(_cell(v) for v in r[:-1]) + " |" for r in rows[:max_rows]]
        if done > max_rows:
            lines.append(f"... {done - max_rows} more rows in table.csv")
        return "\n".join(lines)


def _metric(row: dict, name: str):
    value = row.get(name, math.nan)
    return str(value)[:300] if name == "status" else value


def _cell(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)[:80]


def sweep(path, keys: tuple[str, ...], points: list[Point], metrics=DEFAULT_METRICS, cluster: Cluster = IN_PROCESS,
          out: Path | None = None, overrides=(), mesh_dirs=(), progress: bool = False,
          max_runs: int | None = None) -> SweepReport:
    """Run ``points`` of the scene ``path`` (``viz3d.studies.plan``); rows stored in ``out/runs.jsonl``
    as they arrive when ``out`` is given (and read back from it: done points are not run again)."""
    store = Store.in_folder(out)
    outcomes = run_study(path, points, Summary(), cluster, overrides=overrides, mesh_dirs=mesh_dirs, store=store,
                         progress=progress, max_runs=max_runs)
    return SweepReport(Path(path).stem, tuple(keys), tuple(metrics), tuple(outcomes))


def save(report: SweepReport, out: Path) -> list[Path]:
    """``table.parquet``, ``table.csv``, ``table.md`` and ``chart.png`` into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "table.parquet", out / "table.csv", out / "table.md", out / "chart.png"]
    columns = _columns(report.header, report.table())
    _write_parquet(columns, paths[0])
    with paths[1].open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(report.header)
        w.writerows(zip(*columns.values()) if columns else [])
    paths[2].write_text(report.markdown(max_rows=10**9) + "\n")
    chart(report, paths[3])
    return paths


def _columns(header: list[str], rows: list[list]) -> dict[str, list]:
    """Column name -> values, each column of one type: integers, floats (None as nan) or strings."""
    cols = {}
    for j, name in enumerate(header):
        values = [r[j] for r in rows]
        if all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in values):
            cols[name] = [int(v) for v in values]
        elif all(v is None or (isinstance(v, (int, float, np.number)) and not isinstance(v, bool)) for v in values):
            cols[name] = [math.nan if v is None else float(v) for v in values]
        else:
            cols[name] = ["" if v is None else str(v) for v in values]
    return cols


def _write_parquet(columns: dict[str, list], path: Path) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    pq.write_table(pa.table(columns), path)


def main_metric(report: SweepReport) -> str | None:
    """The metric the chart shows: the first requested numeric one."""
    return next((m for m in report.metrics if m != "status"), None)


def chart(report: SweepReport, path: Path) -> None:
    """The main metric over the first key, one line per value of the second key (a scatter for
    sampled keys); failed runs as crosses on the lower edge."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    metric = main_metric(report)
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    done = [o for o in report.outcomes if o.row is not None]
    x_of = _axis_positions(ax, [o.point.values[0] for o in done], report.keys[0])
    groups = dict.fromkeys(o.point.values[1] if len(report.keys) > 1 else None for o in done)
    style = "o-" if _is_grid(report) else "o"
    for g in groups:
        runs = [o for o in done if (o.point.values[1] if len(report.keys) > 1 else None) == g]
        good = sorted((x_of(o.point.values[0]), o.row.get(metric, np.nan)) for o in runs if o.row["status"] == "ok")
        label = None if g is None else f"{report.keys[1]} = {_cell(g)}"
        line, = ax.plot([x for x, _ in good], [_float(y) for _, y in good], style, label=label)
        bad = [x_of(o.point.values[0]) for o in runs if o.row["status"] != "ok"]
        ax.plot(bad, [0.0] * len(bad), "x", color=line.get_color(), ms=9, transform=ax.get_xaxis_transform(),
                clip_on=False)
    _scale_y(ax, done, metric)
    ax.set_ylabel(metric or "")
    ax.set_title(f"sweep of {report.scene} (x: failed run)")
    ax.grid(True, which="both", alpha=0.3)
    if len(groups) > 1:
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _is_grid(report: SweepReport) -> bool:
    firsts = [o.point.values[0] for o in report.outcomes]
    return len(set(map(str, firsts))) < len(firsts) or len(report.keys) == 1


def _axis_positions(ax, values: list, key: str):
    """x position of a key's value: the number itself (log axis when it spans > 100x), or the index
    of a category."""
    ax.set_xlabel(key)
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        v = np.asarray(values, float)
        if len(v) and v.min() > 0 and v.max() > 100 * v.min():
            ax.set_xscale("log")
        return float
    cats = list(dict.fromkeys(str(v) for v in values))
    ax.set_xticks(range(len(cats)), cats)
    return lambda v: float(cats.index(str(v)))


def _scale_y(ax, done: list[Outcome], metric: str | None) -> None:
    y = np.asarray([_float(o.row.get(metric, np.nan)) for o in done if o.row["status"] == "ok"], float)
    y = y[np.isfinite(y)]
    if len(y) and y.min() > 0 and y.max() > 100 * y.min():
        ax.set_yscale("log")


def _float(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan
