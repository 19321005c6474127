"""Work-precision benchmarks: ``viz3d bench SCENE --methods LIST --dt LIST | --tol LIST``.

Every method (a method string, viz3d.methods) runs at every step (fixed-step methods) or every
tolerance (integrators with an embedded error estimate: dopri5, dop853) on the same scene and output grid. The reference is
computed automatically: the most accurate method in the registry (dop853, adaptive) at
rtol = 1e-12, whose self-convergence (its distance to the same method at rtol = 1e-11) is reported
beside it. The error of a run is the largest distance, over output frames and bodies, between
its body points and the reference's: ``|dW_r| + r_g |dR|`` with ``r_g`` the body's radius of
gyration [m]. Results: a table (printed, and saved as Markdown and CSV) and a log-log chart of
error against CPU time, one line per method. With an output folder, finished runs are kept in its
results store (``viz3d.studies.execute.Store``): the same command started again runs only the
missing ones (the references are computed again: they identify the runs).
"""

from __future__ import annotations

import csv
import hashlib
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from viz3d.integrators import INTEGRATORS, make_integrator
from viz3d.methods import method_overrides, parse_method
from viz3d.scene.load import load_scene
from viz3d.simulate import simulate
from viz3d.studies.execute import IN_PROCESS, Cluster, Store, run_study, store_note
from viz3d.studies.plan import Point
from viz3d.trajectory import Trajectory

#: Reference: the most accurate method, much tighter than any run.
REFERENCE_METHOD = "dop853"
REFERENCE_RTOL = 1e-12
CHECK_RTOL = 1e-11
#: Absolute tolerance as a fraction of the relative one.
ATOL_FACTOR = 1e-3


@dataclass
class BenchRow:
    """One run of a work-precision benchmark."""

    method: str
    setting: str           # "dt=..." or "rtol=..."
    error: float           # [m], see the module docstring
    cpu: float             # process time of the run [s]
    steps: int
    rhs: int
    energy_drift: float    # relative to the largest kinetic energy
    constraint: float      # max |C| [m]
    status: str


@dataclass
class BenchReport:
    scene: str
    rows: list[BenchRow]
    reference: str
    reference_self: float  # [m]
    note: str = ""         # what came from the results store (``store_note``)

    def markdown(self) -> str:
        lines = [f"Reference: {self.reference}; its self-convergence {self.reference_self:.2e} m.",
                 *([self.note] if self.note else []), "",
                 "| method | setting | error [m] | CPU time [s] | steps | RHS evaluations | energy drift | max abs C [m] "
                 "| status |",
                 "|---|---|---|---|---|---|---|---|---|"]
        for r in self.rows:
            lines.append(f"| {r.method} | {r.setting} | {r.error:.2e} | {r.cpu:.3f} | {r.steps} | {r.rhs} | "
                         f"{r.energy_drift:.1e} | {r.constraint:.1e} | {r.status[:70]} |")
        return "\n".join(lines)


def run_overrides(method: str, setting: tuple[str, float], output_dt: float) -> list[str]:
    """Scene overrides of one run: the method, and its step or its tolerances."""
    kind, value = setting
    out = method_overrides(method)
    if kind == "dt":
        return out + [f"sim.dt={value!r}"]
    return out + [f"sim.dt={output_dt!r}", f"sim.rtol={value!r}", f"sim.atol={value * ATOL_FACTOR!r}"]


def settings_for(method: str, dts, tols) -> list[tuple[str, float]]:
    """The steps or tolerances a method runs at (embedded pairs prefer tolerances)."""
    integrator = parse_method(method).get("sim.integrator")
    if integrator and make_integrator(integrator).embedded and tols:  # embedded pairs run adaptively
        return [("rtol", t) for t in tols]
    if dts:
        return [("dt", d) for d in dts]
    embedded = ", ".join(n for n in INTEGRATORS if make_integrator(n).embedded)
    raise ValueError(f"method {method!r} runs at fixed steps: give --dt (only {embedded} use --tol)")


def body_point_error(traj, ref) -> float:
    """Largest ``|dW_r| + r_g |dR|`` over common frames and bodies [m] (inf if the run stopped)."""
    n = min(len(traj.t), len(ref.t))
    if n == 0 or not np.allclose(traj.t[:n], ref.t[:n], atol=1e-9):
        raise ValueError("runs do not share their output times")
    r_g = np.sqrt(np.trace(ref.inertia_body, axis1=1, axis2=2) / (2 * ref.mass))
    dr = np.linalg.norm(traj.position[:n] - ref.position[:n], axis=2)
    dR = np.abs(traj.rotation[:n] - ref.rotation[:n]).max(axis=(2, 3))
    err = float((dr + r_g[None] * dR).max())
    return err if n == len(ref.t) else np.inf


def common_grid(dts: list[float] | None, output_dt: float, t_end: float) -> tuple[float, float]:
    """An output interval that every step divides (a common multiple near the scene's own) and
    a duration that it divides: every run then has frames at the same times."""
    from fractions import Fraction
    from math import lcm

    if dts:
        fr = [Fraction(d).limit_denominator(10**9) for d in dts]
        den = lcm(*(f.denominator for f in fr))
        base = Fraction(lcm(*(int(f * den) for f in fr)), den)
        output_dt = float(base * max(1, round(output_dt / float(base))))
    return output_dt, output_dt * max(1, round(t_end / output_dt))


def reference_run(path, overrides: list[str], output_dt: float, t_end: float, rtol: float = REFERENCE_RTOL):
    """The reference trajectory: ``REFERENCE_METHOD`` adaptive at ``rtol`` (atol = rtol *
    ATOL_FACTOR) on the output grid ``output_dt``; raises if it fails."""
    over = list(overrides) + [f"sim.output_dt={output_dt!r}", f"sim.integrator={REFERENCE_METHOD}",
                              f"sim.dt={output_dt!r}", f"sim.rtol={rtol!r}", f"sim.atol={rtol * ATOL_FACTOR!r}"]
    traj = simulate(load_scene(path, over), t_end=t_end)
    if not traj.ok:
        raise RuntimeError(f"the reference run ({REFERENCE_METHOD}, rtol {rtol:g}) failed: {traj.status}")
    return traj


def reference_digest(reference: Trajectory) -> str:
    """SHA-256 (hex) of what ``body_point_error`` reads of a reference (times, body positions and
    rotations, masses and inertias): the identity of a measure that carries it (its wall time differs
    from run to run)."""
    h = hashlib.sha256()
    for a in (reference.t, reference.position, reference.rotation, reference.mass, reference.inertia_body):
        a = np.ascontiguousarray(a, dtype=float)
        h.update(repr(a.shape).encode() + a.tobytes())
    return h.hexdigest()


@dataclass(frozen=True)
class BenchRun:
    """Measure of one benchmark run (``viz3d.studies``): an untimed warm-up over ``warm_up`` [s]
    (compilation, caches of the worker), then the run to ``t_end`` [s], timed (process time), and its
    error against ``reference`` (identified by ``reference_key``, its ``reference_digest``)."""

    reference: Trajectory = field(compare=False)
    reference_key: str
    t_end: float
    warm_up: float

    def __call__(self, scene) -> dict:
        simulate(scene, t_end=self.warm_up)
        t0 = time.process_time()
        traj = simulate(scene, t_end=self.t_end)
        cpu = time.process_time() - t0
        return {"error": body_point_error(traj, self.reference), "cpu": cpu, "steps": traj.n_steps, "rhs": traj.n_rhs,
                "energy_drift": traj.energy_drift_rel, "constraint": traj.max_constraint_violation,
                "status": traj.status}


def _bench_row(point: Point, row: dict) -> BenchRow:
    method, (kind, value) = point.values
    nan = float("nan")
    return BenchRow(method, f"{kind}={value:g}", row.get("error", np.inf), row.get("cpu", nan), row.get("steps", 0),
                    row.get("rhs", 0), row.get("energy_drift", nan), row.get("constraint", nan), row["status"])


def bench(path: str | Path, methods: list[str], dts: list[float] | None = None, tols: list[float] | None = None,
          t_end: float | None = None, progress: bool = True, overrides: list[str] = (), cluster: Cluster = IN_PROCESS,
          out: Path | None = None) -> BenchReport:
    """Run the benchmark (see the module docstring); ``overrides`` apply to every run, which run on
    ``cluster`` (``viz3d.studies.execute``; the references run here first); finished runs are kept
    in (and read back from) the results store of the folder ``out``."""
    base = load_scene(path, list(overrides))
    if "rtol" in base.data["sim"] and base.data["contacts"]:
        raise ValueError(f"{path}: bench compares methods on fixed steps and tolerances; runs with contact events are "
                         f"adaptive (model size: viz3d stability --sweep; see benchmarks/bench_impact_convergence.py)")
    output_dt, t_end = common_grid(dts, base.data["sim"].get("output_dt", 0.01), t_end or base.data["sim"]["t_end"])
    plan = [(m, s) for m in methods for s in settings_for(m, dts, tols)]
    grid = list(overrides) + [f"sim.output_dt={output_dt!r}"]
    ref = reference_run(path, grid, output_dt, t_end, REFERENCE_RTOL)
    chk = reference_run(path, grid, output_dt, t_end, CHECK_RTOL)
    points = [Point((m, s), tuple(run_overrides(m, s, output_dt))) for m, s in plan]
    store = Store.in_folder(out)
    measure = BenchRun(ref, reference_digest(ref), t_end, 3 * output_dt)
    outcomes = run_study(path, points, measure, cluster, overrides=grid, progress=progress, store=store)
    desc = f"{REFERENCE_METHOD} adaptive, rtol {REFERENCE_RTOL:g}, {ref.n_steps} steps"
    return BenchReport(Path(path).stem, [_bench_row(o.point, o.row) for o in outcomes], desc, body_point_error(chk, ref),
                       store_note(store, outcomes))


def save(report: BenchReport, out: Path) -> list[Path]:
    """Write ``bench.md``, ``bench.csv`` and ``work_precision.png`` into ``out``."""
    header = ["method", "setting", "error_m", "cpu_s", "steps", "rhs", "energy_drift", "max_abs_C_m", "status"]
    rows = [[r.method, r.setting, r.error, r.cpu, r.steps, r.rhs, r.energy_drift, r.constraint, r.status]
            for r in report.rows]
    return write_report(out, "bench", report.markdown(), header, rows,
                        lambda path: work_precision_chart(report, path), "work_precision.png")


def write_report(out: Path, stem: str, markdown: str, header: list[str], rows: list[list], chart, chart_name: str
                 ) -> list[Path]:
    """``out/<stem>.md``, ``out/<stem>.csv`` (``header`` + ``rows``) and the chart drawn by
    ``chart(path)`` into ``out/<chart_name>``; returns the three paths."""
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / f"{stem}.md", out / f"{stem}.csv", out / chart_name]
    paths[0].write_text(markdown + "\n")
    with open(paths[1], "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)
    chart(paths[2])
    return paths


def work_precision_chart(report: BenchReport, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for method in dict.fromkeys(r.method for r in report.rows):
        rows = [r for r in report.rows if r.method == method and np.isfinite(r.error) and r.status == "ok"]
        if rows:
            ax.loglog([r.cpu for r in rows], [max(r.error, 1e-16) for r in rows], "o-", label=method)
    ax.axhline(max(report.reference_self, 1e-16), color="gray", ls=":", lw=1, label="reference self-convergence")
    ax.set_xlabel("CPU time [s]")
    ax.set_ylabel("error [m] (body points vs reference)")
    ax.set_title(f"work-precision: {report.scene}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
