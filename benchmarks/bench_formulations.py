"""Work-precision of the formulations with RK4 on shipped scenes: which one is cheapest at 1e-6 m and
at 1e-3 m (a benchmark, not a test; it informs the choice of ``sim.formulation``'s default).

    python benchmarks/bench_formulations.py [--scenes heavy_top,chain_10,...] [--dt 8e-3,6e-3,...]
                                            [--out docs/bench_formulations.png]

Every scene runs ``rk4`` with each formulation (``index1``, ``baumgarte`` at the scene's alpha and
beta, ``projection`` at ``sim.projection_tol``) at every step of ``--dt``, through ``viz3d.bench.bench``
(the code behind ``viz3d bench``): whole runs, output frames included, CPU time of the process after
an untimed warm-up; error = largest distance of body points from the dop853 reference at rtol 1e-12
over the output grid (``viz3d.bench.body_point_error``). For each scene and accuracy target, the
cost of each formulation at the target, interpolated log-log between the two runs around it
(``cost_at``; "<=" when its longest step already reaches it), the cheapest of all, and the cheapest
measured run of each. Prints
Markdown tables and writes them beside a chart of one work-precision panel per scene (``.md``).
CPU times of this machine, under its load at the time: compare rows of one run, not machines.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np

from viz3d.bench import bench, common_grid
from viz3d.scene.load import load_scene

ROOT = Path(__file__).resolve().parents[1]
#: (label, method string): RK4 with each formulation the kernel covers at fixed steps.
FORMULATIONS = [("index1", "rk4"), ("baumgarte", "rk4+baumgarte"), ("projection", "rk4+projection")]
#: Accuracy targets [m] of the summary.
TARGETS = (1e-6, 1e-3)
#: label -> (scene file stem, overrides, simulated time [s]): the problems of issue 14 (the heavy top and
#: the top through theta = 0 over 10 s, the torque-free body over 20 s, chains over their first second) and
#: two mechanisms.
SCENES = {
    "heavy_top": ("heavy_top", [], 10.0),
    "top_through_vertical": ("top_through_vertical", [], 10.0),
    "torque_free": ("torque_free", [], 20.0),
    "chain_10": ("chain", ["chain.n=10"], 1.0),
    "chain_50": ("chain", ["chain.n=50"], 1.0),
    "double_pendulum": ("double_pendulum", [], 10.0),
    "slider_crank": ("slider_crank", [], 10.0),
}
#: Steps [s]: each divides 24 ms, so that every run has output frames at the same times (``viz3d.bench.common_grid``).
DTS = "2.4e-2,1.2e-2,8e-3,6e-3,4e-3,3e-3,2e-3,1.5e-3,1e-3,7.5e-4,5e-4,3.75e-4,2.5e-4,1.25e-4"


def measure(scene: str, dts: list[float], repeat: int) -> tuple[list[dict], float]:
    """Every formulation at every step on ``scene`` (a label of ``SCENES``), ``repeat`` times: rows (scene,
    formulation, dt, error, cpu (the least of the repeats: the load of a shared machine only adds), steps,
    max |C|, status) and the reference's self-convergence [m]."""
    labels = {m: f for f, m in FORMULATIONS}
    stem, overrides, t_end = SCENES[scene]
    reports = [bench(ROOT / "scenes" / f"{stem}.toml", [m for _, m in FORMULATIONS], dts, None, t_end, progress=False,
                     overrides=overrides) for _ in range(repeat)]
    rows = [dict(scene=scene, formulation=labels[r.method], dt=float(r.setting.split("=")[1]), error=r.error,
                 cpu=min(rep.rows[k].cpu for rep in reports), steps=r.steps, constraint=r.constraint, status=r.status)
            for k, r in enumerate(reports[0].rows)]
    report = reports[0]
    for r in rows:
        print(f"  {scene:>20} {r['formulation']:<10} dt {r['dt']:<8g} error {r['error']:.2e} m  cpu {r['cpu']:.3f} s"
              f"  |C| {r['constraint']:.1e}  {r['status'][:40]}", flush=True)
    return rows, report.reference_self


def output_interval(scene: str, dts: list[float]) -> float:
    """The output interval [s] of ``scene``'s runs: its own, made a multiple of every step (``common_grid``)."""
    stem, overrides, t_end = SCENES[scene]
    own = load_scene(ROOT / "scenes" / f"{stem}.toml", overrides).data["sim"].get("output_dt", 0.01)
    return common_grid(dts, own, t_end)[0]


def cheapest(rows: list[dict], target: float) -> dict | None:
    """The run of least CPU time among ``rows`` that finished with error <= ``target``, or None."""
    ok = [r for r in rows if r["status"] == "ok" and r["error"] <= target]
    return min(ok, key=lambda r: r["cpu"]) if ok else None


def cost_at(rows: list[dict], target: float) -> tuple[float, bool] | None:
    """CPU time [s] at which one formulation's runs ``rows`` reach error ``target``: log-log interpolation
    between the longest step that reaches it and the next longer one, which does not; ``(cost, True)``
    when the longest step measured already reaches it (the cost is then at most that); None if no run does."""
    runs = sorted((r for r in rows if r["status"] == "ok"), key=lambda r: -r["dt"])
    for k, r in enumerate(runs):
        if r["error"] <= target:
            if k == 0:
                return r["cpu"], True
            a = runs[k - 1]
            x = np.log(target / a["error"]) / np.log(r["error"] / a["error"])
            return float(np.exp((1 - x) * np.log(a["cpu"]) + x * np.log(r["cpu"]))), False
    return None


def summary(rows: list[dict], scenes: list[str]) -> str:
    """Per scene and target: each formulation's interpolated cost (and its cheapest measured run), the winner."""
    head = " | ".join(f for f, _ in FORMULATIONS)
    lines = [f"| scene | target [m] | {head} | cheapest | next (ratio) |",
             "|---|---|" + "---|" * len(FORMULATIONS) + "---|---|"]
    for scene in scenes:
        for target in TARGETS:
            cells, found = [], []
            for f, _ in FORMULATIONS:
                mine = [r for r in rows if r["scene"] == scene and r["formulation"] == f]
                c, run = cost_at(mine, target), cheapest(mine, target)
                if c is None:
                    cells.append("not reached")
                    continue
                found.append((c[0], f))
                cells.append(f"{'<= ' if c[1] else ''}{c[0]:.3f} s (run: {run['cpu']:.3f} s at dt {run['dt']:g})")
            found.sort()
            win = found[0][1] if found else "none"
            nxt = f"{found[1][1]} ({found[1][0] / found[0][0]:.2f}x)" if len(found) > 1 else ""
            lines.append(f"| {scene} | {target:g} | " + " | ".join(cells) + f" | {win} | {nxt} |")
    return "\n".join(lines)


def table(rows: list[dict]) -> str:
    lines = ["| scene | formulation | dt [s] | error [m] | CPU [s] | steps | max abs C [m] | status |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['formulation']} | {r['dt']:g} | {r['error']:.2e} | {r['cpu']:.3f} | "
                     f"{r['steps']} | {r['constraint']:.1e} | {r['status'][:50]} |")
    return "\n".join(lines)


def chart(rows: list[dict], scenes: list[str], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    cols = 3
    nrows = -(-len(scenes) // cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4.2 * cols, 3.6 * nrows), squeeze=False)
    for ax, scene in zip(axes.flat, scenes):
        for f, _ in FORMULATIONS:
            mine = [r for r in rows if r["scene"] == scene and r["formulation"] == f and r["status"] == "ok"
                    and np.isfinite(r["error"])]
            ax.loglog([r["cpu"] for r in mine], [max(r["error"], 1e-16) for r in mine], "o-", label=f, ms=4)
        for target in TARGETS:
            ax.axhline(target, color="gray", ls=":", lw=1)
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_title(scene, fontsize=10)
        ax.set_xlabel("CPU time of the run [s]")
        ax.set_ylabel("error [m]")
        ax.grid(True, which="both", alpha=0.3)
    for ax in list(axes.flat)[len(scenes):]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=8)
    fig.suptitle("RK4 work-precision by formulation (dotted: 1e-6 m and 1e-3 m)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--dt", default=DTS)
    ap.add_argument("--repeat", type=int, default=3, help="runs of each point; the least CPU time is kept")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_formulations.png")
    args = ap.parse_args()
    scenes, dts = args.scenes.split(","), [float(x) for x in args.dt.split(",")]
    rows, selfconv = [], {}
    for scene in scenes:
        scene_rows, selfconv[scene] = measure(scene, dts, args.repeat)
        rows += scene_rows
    load = os.getloadavg()
    when = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    spans = ", ".join(f"{s} {SCENES[s][2]:g} s" for s in scenes)
    grid = ", ".join(f"{s} {1e3 * output_interval(s, dts):g} ms" for s in scenes)
    head = (f"Generated by `python benchmarks/bench_formulations.py` on {when}: RK4, whole runs with output frames "
            f"(every {grid}), simulated {spans}; least CPU time of {args.repeat} repeats; {platform.machine()} with "
            f"{os.cpu_count()} cores, load average after the runs {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} "
            "(1 / 5 / 15 min). Reference: dop853 at rtol "
            "1e-12; its self-convergence (distance to rtol 1e-11) per scene: "
            + ", ".join(f"{s} {v:.1e} m" for s, v in selfconv.items()) + ".")
    text = (head + "\n\n## Cost of reaching each target (interpolated; in brackets the cheapest run that does)\n\n"
            + summary(rows, scenes) + "\n\n## All runs\n\n" + table(rows) + "\n")
    print()
    print(summary(rows, scenes))
    chart(rows, scenes, args.out)
    md = args.out.with_suffix(".md")
    md.write_text(text)
    print(f"\nwrote {args.out} and {md}")


if __name__ == "__main__":
    main()
