"""Speed-up of a sweep on this machine's cores against the sequential run (a benchmark, not a test).

    python benchmarks/bench_sweep.py [--points 16] [--t-end 0.4] [--out docs/charts/sweep_speedup.png]

The study: the bouncing sphere (``scenes/bouncing_sphere.toml``: event-located contacts, adaptive
DOPRI5) over contact laws x target restitution, ``--points`` runs. It runs once in this process, one
after the other (the sequential reference), then on a local Dask cluster of 1, 2, ... worker processes
up to the core count (``viz3d.studies.execute``). Reported per setting: the study's wall time with
the cluster's start and stop (what ``viz3d sweep`` costs), the sum of the runs' own wall times (a
run slowed by the other processes on the machine, or compiling the kernel afresh after an edit of
viz3d's compiled sources, shows here), the speed-up against the sequential run, and a check that
every table equals the sequential one. Prints a Markdown table and writes a chart.
Times are wall-clock on a machine shared with other work; compare rows of one run.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from viz3d.studies.execute import Cluster, local_cores
from viz3d.studies.plan import grid_points
from viz3d.sweep import sweep

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "bouncing_sphere.toml"
LAWS = ["hunt_crossley", "lankarani_nikravesh", "flores", "restitution"]
METRICS = ("status", "restitution", "contact_count")


def study(n_points: int) -> dict[str, list]:
    """The grid: laws x restitution values, ``n_points`` runs in all."""
    n_e = max(1, n_points // len(LAWS))
    return {"contact.law": LAWS, "contact.restitution": [float(e) for e in np.linspace(0.5, 0.9, n_e)]}


def timed(grid: dict, cluster: Cluster, t_end: float):
    """(report, wall time of the whole study [s], sum of the runs' own wall times [s])."""
    t0 = time.perf_counter()
    report = sweep(SCENE, tuple(grid), grid_points(grid), METRICS, cluster, None, [f"sim.t_end={t_end!r}"])
    wall = time.perf_counter() - t0
    return report, wall, sum(o.row.get("wall_time_s", 0.0) for o in report.outcomes)


def metrics(report) -> list:
    return [row[: len(report.keys) + len(METRICS)] for row in report.table()]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--points", type=int, default=16)
    p.add_argument("--t-end", type=float, default=0.4)
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "charts" / "sweep_speedup.png")
    args = p.parse_args()
    grid = study(args.points)
    timed(grid, Cluster(1), 0.01)  # warm-up: imports and compiled caches of this process
    seq, t_seq, busy = timed(grid, Cluster(1), args.t_end)
    rows = [("sequential (this process)", 1, t_seq, busy, True)]
    for n in range(1, local_cores() + 1):
        report, wall, busy = timed(grid, Cluster(workers=n), args.t_end)
        rows.append((f"local Dask cluster, {n} worker(s)", n, wall, busy, metrics(report) == metrics(seq)))
    n_runs = len(seq.table())
    print(f"{n_runs} runs of {SCENE.name} (t_end {args.t_end:g} s), {local_cores()} cores\n")
    print("| setting | workers | study wall [s] | sum of run wall times [s] | speed-up | tables equal |\n"
          "|---|---|---|---|---|---|")
    for name, n, wall, busy, same in rows:
        print(f"| {name} | {n} | {wall:.1f} | {busy:.1f} | {t_seq / wall:.2f} | {'yes' if same else 'NO'} |")
    chart(rows, t_seq, n_runs, args.out)
    print(f"\nwrote {args.out}")


def chart(rows, t_seq: float, n_runs: int, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    workers = [n for name, n, *_ in rows[1:]]
    fig, ax = plt.subplots(figsize=(5.5, 4))
    ax.plot(workers, [t_seq / wall for _, _, wall, *_ in rows[1:]], "o-", label="Dask, study wall time")
    ax.plot(workers, workers, ":", color="gray", label="ideal")
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_xlabel("local worker processes")
    ax.set_ylabel("speed-up against the sequential run")
    ax.set_xticks(workers)
    ax.set_title(f"sweep of {n_runs} runs (bouncing_sphere)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
