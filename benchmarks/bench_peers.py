"""viz3d, MuJoCo, Exudyn and Pinocchio at equal accuracy on the problems of issue 14 (a benchmark, not a test).

    pip install -e '.[peers]'   # MuJoCo, Exudyn, Pinocchio; a peer that is not installed is skipped with a message
    python benchmarks/bench_peers.py [--problems heavy_top,torque_free,top_through_vertical,chain]
        [--chains 2,10,50,100,200] [--simulators viz3d,MuJoCo,Exudyn,Pinocchio] [--tol 1e-6]
        [--max-run 20] [--out docs/bench_peers.png]

Problems (the shipped scenes, one model for all simulators, ``peers.rigid_tree``): the heavy top on
a ball joint over 10 s, the torque-free asymmetric T-handle (Dzhanibekov flips, no gravity) over
20 s, the top whose axis passes through theta = 0 over its scene's 3 s, and ball-joint chains of N
links over their first second (``--chains``). viz3d runs in each of its configurations ``VIZ3D``
(RK4 with the index-1 formulation, with coordinate projection, with projection and quaternion
coordinates; adaptive DOPRI5 and DOP853 with projection), all compiled; its column takes the
cheapest and names it, as the peers' cells name their methods. The default run takes about 25
minutes on 2 cores.

Each fixed-step method runs each problem at steps dt = 10 ms / k (k = 2, 3, 4, 6, 8, 11, 16, ...:
about sqrt(2) apart, each dividing the frame interval), each adaptive one at rtol = 1e-3, 10^-3.5,
..., 1e-12 (atol = 1e-3 rtol, as the reference's), coarse to fine, until a run reaches ``--tol`` or
the next run would take longer than ``--max-run`` seconds. Error: the largest distance,
over the 100 Hz output frames, of any marker point (each body's centre of mass and three points
0.1 m along its axes) from the reference: viz3d's own equations (maximal coordinates, Euler-angle
charts) integrated by its adaptive DOP853 at rtol 1e-12 (``viz3d.bench.reference_run``). MuJoCo
(minimal coordinates, quaternions, RK4) and Exudyn (Euler parameters, index-3 generalized-alpha;
RK44 on rotation vectors for the free body) and Pinocchio (minimal coordinates, its articulated-body
algorithm ``aba``, or its mass matrix ``crba`` and a Cholesky solve, stepped by RK4 written in Python,
as a user steps it: Pinocchio has no integrator; see ``peers.pinocchio_run`` for why both)
are independent formulations of the same model: the
error they reach at small steps also bounds how well the models agree. Wall time: the whole run
with its frames at 100 Hz, each simulator's clock started once its model is built: for viz3d
``viz3d.simulate.simulate_built`` after ``viz3d.scene.build.build`` (the scene's ``System`` and
projected initial ``State``; the simulation, packing for the kernel, stepping, frames and the
``Trajectory`` are timed), for MuJoCo stepping and reading the poses at every frame after its
``MjModel``, for Exudyn ``SolveDynamic`` with its sensors after ``Assemble``, for Pinocchio its RK4
loop after its model and data (``peers``); best of ``--repeat`` for runs under a second, the
simulators interleaved at each step. Tables generated before 2026-11-27 10:35 UTC timed viz3d's
``simulate(scene)``, its build included.

Writes the table to ``docs/bench_peers.md`` and a work-precision chart beside it (``--out``). A run
on part of the default problems, chains or simulators, without ``--out``, merges its rows into that
table: they replace the rows of the same problem and simulator, the others are kept, the chart is
redrawn from all of them and the header names the rows re-run, when and at what load.
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from peers import PINOCCHIO_DYNAMICS, exudyn_run, exudyn_solver, markers, mujoco_run, pinocchio_run, rigid_tree

from viz3d.bench import ATOL_FACTOR, reference_run
from viz3d.scene.build import build
from viz3d.scene.load import load_scene, with_sim
from viz3d.simulate import simulate_built

ROOT = Path(__file__).resolve().parents[1]
#: Where the table (``.md``) and the chart go unless ``--out`` says otherwise.
DOC = ROOT / "docs" / "bench_peers.png"
OUTPUT_DT = 0.01
#: name -> (scene file, overrides, simulated time [s])
PROBLEMS = {
    "heavy_top": ("heavy_top.toml", [], 10.0),
    "torque_free": ("torque_free.toml", [], 20.0),
    "top_through_vertical": ("top_through_vertical.toml", [], 3.0),
}
#: Steps tried: the output interval over these (every step divides it), about sqrt(2) apart.
DIVISIONS = (2, 3, 4, 6, 8, 11, 16, 23, 32, 45, 64, 91, 128, 181, 256, 362, 512, 724, 1024)


@dataclass(frozen=True)
class Run:
    """One run: problem, simulator, its method and setting (``setting``: "dt 0.000625" or
    "rtol 1e-08"), error [m], wall time [s], steps."""

    problem: str
    simulator: str
    setting: str
    error: float
    wall: float
    steps: int


@dataclass(frozen=True)
class Problem:
    """A problem ready to run: its scene, reference markers (n, nb, 4, 3) [m] and peer model."""

    name: str
    path: Path
    overrides: list
    t_end: float
    reference: np.ndarray
    tree: object


def problems(names: list[str], chains: list[int], rtol: float) -> list[Problem]:
    """The selected problems with their references (computed here, printed with their cost)."""
    specs = [(n, *PROBLEMS[n]) for n in names if n != "chain"]
    if "chain" in names:
        specs += [(f"chain N={n}", "chain.toml", [f"chain.n={n}"], 1.0) for n in chains]
    out = []
    for name, scene, over, t_end in specs:
        path = ROOT / "scenes" / scene
        t0 = time.perf_counter()
        ref = reference_run(path, over, OUTPUT_DT, t_end, rtol)
        print(f"{name}: reference (viz3d dop853, rtol {rtol:g}) in {time.perf_counter() - t0:.1f} s", flush=True)
        out.append(Problem(name, path, over, t_end, markers(ref.position, ref.rotation),
                           rigid_tree(load_scene(path, over), ref)))
    return out


#: viz3d's configurations tried: name -> (scene overrides, adaptive). Fixed-step ones run at the steps
#: ``OUTPUT_DT / DIVISIONS``, adaptive ones at the tolerances ``RTOLS`` (atol = rtol * ATOL_FACTOR, as the
#: reference's); all on the compiled kernel.
VIZ3D = {
    "rk4+index1": (["sim.integrator=rk4", "sim.formulation=index1"], False),
    "rk4+projection": (["sim.integrator=rk4", "sim.formulation=projection"], False),
    "rk4+projection+quaternion": (["sim.integrator=rk4", "sim.formulation=projection", "sim.rotation=quaternion"],
                                  False),
    "dopri5+projection": (["sim.integrator=dopri5", "sim.formulation=projection"], True),
    "dop853+projection": (["sim.integrator=dop853", "sim.formulation=projection"], True),
}
#: Tolerances tried by the adaptive configurations, coarse to fine (half a decade apart).
RTOLS = tuple(10.0 ** (-3 - k / 2) for k in range(len(DIVISIONS)))


def viz3d_run(p: Problem, level: int, config: str) -> tuple[np.ndarray | None, float, int, str]:
    """viz3d in ``config`` (``VIZ3D``) at the ``level``-th step or tolerance, Euler-angle charts unless
    the configuration says otherwise, compiled kernel."""
    over, adaptive = VIZ3D[config]
    if adaptive:
        rtol = RTOLS[level]
        over = over + [f"sim.dt={OUTPUT_DT!r}", f"sim.rtol={rtol!r}", f"sim.atol={rtol * ATOL_FACTOR!r}"]
        setting = f"rtol {rtol:.2g}"
    else:
        dt = OUTPUT_DT / DIVISIONS[level]
        over = over + [f"sim.dt={dt!r}"]
        setting = f"dt {dt:.3g}"
    scene = with_sim(load_scene(p.path, p.overrides + over + [f"sim.output_dt={OUTPUT_DT!r}"]), t_end=p.t_end)
    system, state = build(scene)  # the model, as the peers' are built before their clocks start
    t0 = time.perf_counter()
    traj = simulate_built(scene, system, state)
    wall = time.perf_counter() - t0
    return (markers(traj.position, traj.rotation) if traj.ok else None), wall, traj.n_steps, f"{config} {setting}"


def mujoco(p: Problem, level: int):
    dt = OUTPUT_DT / DIVISIONS[level]
    r = mujoco_run(p.tree, dt, p.t_end, OUTPUT_DT)
    return r.position, r.wall, r.steps, f"RK4 dt {dt:.3g}"


def exudyn(p: Problem, level: int):
    dt = OUTPUT_DT / DIVISIONS[level]
    r = exudyn_run(p.tree, dt, p.t_end, OUTPUT_DT)
    return r.position, r.wall, r.steps, f"{exudyn_solver(p.tree)} dt {dt:.3g}"


def pinocchio(p: Problem, level: int, dynamics: str):
    dt = OUTPUT_DT / DIVISIONS[level]
    r = pinocchio_run(p.tree, dt, p.t_end, OUTPUT_DT, dynamics)
    return r.position, r.wall, r.steps, f"{dynamics}+RK4 dt {dt:.3g}"


def group(name: str) -> str:
    """The simulator a runner belongs to: "viz3d" for its configurations, "Pinocchio" for both of
    its dynamics, else the runner's name."""
    return "viz3d" if name in VIZ3D else name.split()[0]


def simulators(wanted: list[str]) -> dict:
    """The runners of the installed simulators among ``wanted`` ("viz3d": every configuration of
    ``VIZ3D``, or one of them by name), a message for each one missing."""
    runners = {"MuJoCo": {"MuJoCo": mujoco}, "Exudyn": {"Exudyn": exudyn},
               "Pinocchio": {f"Pinocchio {d}": functools.partial(pinocchio, dynamics=d) for d in PINOCCHIO_DYNAMICS}}
    out = {}
    for name in wanted:
        if name == "viz3d" or name in VIZ3D:
            for config in (VIZ3D if name == "viz3d" else [name]):
                out[config] = functools.partial(viz3d_run, config=config)
            continue
        module = {"MuJoCo": "mujoco", "Exudyn": "exudyn", "Pinocchio": "pinocchio"}[name]
        try:
            print(f"{name} {__import__(module).__version__}")
        except ImportError:
            print(f"{name}: not installed, skipped (pip install -e '.[peers]')")
            continue
        out.update(runners[name])
    return out


def measure(p: Problem, runners: dict, tol: float, max_run: float, repeat: int) -> list[Run]:
    """Every runner on ``p`` at its levels (steps ``OUTPUT_DT / DIVISIONS``, tolerances ``RTOLS``),
    coarse to fine, until it reaches ``tol`` or its next run would exceed ``max_run`` seconds; the
    runners alternate at each level."""
    active, rows = dict(runners), []
    for level in range(len(DIVISIONS)):
        if not active:
            break
        for name, run in list(active.items()):
            row = one(p, name, run, level, repeat)
            rows.append(row)
            print(f"  {p.name:>12} {name:<26} {row.setting:<46} error {row.error:9.2e} m  wall {row.wall:8.3f} s",
                  flush=True)
            if row.error <= tol or 1.5 * row.wall > max_run:
                del active[name]
    return rows


def one(p: Problem, name: str, run, level: int, repeat: int) -> Run:
    """Best of ``repeat`` runs (one when a run takes over a second); a failed run has error inf."""
    best, error, steps, setting = np.inf, np.inf, 0, f"level {level}"
    for _ in range(repeat):
        try:
            pos, wall, steps, setting = run(p, level)
        except Exception as exc:  # a peer's solver may give up (Exudyn's Newton iteration)
            print(f"  {name} at level {level}: {type(exc).__name__}: {str(exc)[:100]}")
            return Run(p.name, name, setting, np.inf, np.nan, 0)
        if pos is None or pos.shape != p.reference.shape or not np.all(np.isfinite(pos)):
            return Run(p.name, name, setting, np.inf, wall, steps)
        error = float(np.linalg.norm(pos - p.reference, axis=-1).max())
        best = min(best, wall)
        if wall > 1.0:
            break
    return Run(p.name, name, setting, error, best, steps)


def cheapest(rows: list[Run], tol: float) -> dict[tuple[str, str], Run]:
    """Per (problem, simulator): the fastest run that reaches ``tol``."""
    out: dict = {}
    for r in rows:
        if r.error <= tol and ((r.problem, r.simulator) not in out or r.wall < out[r.problem, r.simulator].wall):
            out[r.problem, r.simulator] = r
    return out


def summary(rows: list[Run], tol: float, sims: list[str]) -> str:
    """Per problem and simulator (``group``), the cheapest run of any of its methods that reaches
    ``tol``, and viz3d's time over the fastest peer's."""
    best = cheapest(rows, tol)
    groups = {}
    for s in sims:
        groups.setdefault(group(s), []).append(s)
    names = [g if g != "viz3d" else "viz3d (cheapest configuration)" for g in groups]
    lines = [f"| problem | {' | '.join(names)} | viz3d / fastest peer |", "|---|" + "---|" * (len(groups) + 1)]
    for prob in dict.fromkeys(r.problem for r in rows):
        cells = []
        for members in groups.values():
            mine = [best[prob, s] for s in members if (prob, s) in best]
            cells.append(_cell(rows, prob, members, min(mine, key=lambda r: r.wall) if mine else None))
        lines.append(f"| {prob} | {' | '.join(cells)} | {_ratio(best, prob, sims)} |")
    return "\n".join(lines)


def configurations(rows: list[Run], tol: float, sims: list[str]) -> str:
    """Per problem and viz3d configuration, its cheapest run that reaches ``tol``."""
    best = cheapest(rows, tol)
    ours = [s for s in sims if s in VIZ3D]
    lines = [f"| problem | {' | '.join(ours)} |", "|---|" + "---|" * len(ours)]
    for prob in dict.fromkeys(r.problem for r in rows):
        lines.append(f"| {prob} | {' | '.join(_cell(rows, prob, [s], best.get((prob, s)), named=False) for s in ours)} |")
    return "\n".join(lines)


def _cell(rows: list[Run], prob: str, sims: list[str], r: Run | None, named: bool = True) -> str:
    """``r`` as a table cell (wall time, setting, error), or the closest any of ``sims`` came."""
    if r is None:
        tried = [x for x in rows if x.problem == prob and x.simulator in sims and np.isfinite(x.error)]
        low = min(tried, key=lambda x: x.error) if tried else None
        return "not reached" + (f" (best {low.error:.1e} m, {low.wall:.3g} s)" if low else "")
    setting = r.setting if named else r.setting.split(" ", 1)[1]
    return f"{r.wall:.3g} s ({setting}, {r.error:.1e} m)"


def _ratio(best: dict, prob: str, sims: list[str]) -> str:
    """viz3d's cheapest wall time (any configuration) over the fastest peer's, on ``prob``."""
    ours = [best[prob, s].wall for s in sims if s in VIZ3D and (prob, s) in best]
    peers = [best[prob, s].wall for s in sims if s not in VIZ3D and (prob, s) in best]
    if not ours:
        return "-"
    return f"{min(ours) / min(peers):.2f}" if peers else "no peer reached it"


def all_runs(rows: list[Run]) -> str:
    lines = ["| problem | simulator | setting | steps | error [m] | wall [s] |", "|---|---|---|---|---|---|"]
    lines += [f"| {r.problem} | {r.simulator} | {r.setting} | {r.steps} | {r.error:.2e} | {r.wall:.4g} |" for r in rows]
    return "\n".join(lines)


def read_runs(md: Path) -> tuple[str, list[Run]]:
    """The header (the text before the first table) and the "All runs" rows of a table this script wrote."""
    text = md.read_text()
    head = text[: text.index("| problem |")]
    rows = []
    for line in text[text.index("All runs:"):].splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 6 and cells[0] not in ("problem", "---"):
            prob, sim, setting, steps, error, wall = cells
            rows.append(Run(prob, sim, setting, float(error), float(wall), int(steps)))
    return head, rows


def merged(old: list[Run], new: list[Run]) -> list[Run]:
    """``old`` with the rows of each (problem, simulator) in ``new`` replaced by ``new``'s, problems
    in their first order (``old``'s, then new ones); each problem's rows keep their order."""
    fresh = {(r.problem, r.simulator) for r in new}
    rows = [r for r in old if (r.problem, r.simulator) not in fresh] + new
    order = list(dict.fromkeys(r.problem for r in old + new))
    return sorted(rows, key=lambda r: order.index(r.problem))


def load() -> str:
    """``uptime``'s load averages over 1, 5 and 15 minutes, as text."""
    return "/".join(f"{x:.1f}" for x in os.getloadavg())


def chart(rows: list[Run], tol: float, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    probs = list(dict.fromkeys(r.problem for r in rows))
    cols = min(4, len(probs))
    nrows = -(-len(probs) // cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4 * cols, 3.4 * nrows), squeeze=False)
    for ax, prob in zip(axes.flat, probs):
        for sim, marker in zip(dict.fromkeys(r.simulator for r in rows), "osx^vD<>ph"):
            mine = [r for r in rows if r.problem == prob and r.simulator == sim and np.isfinite(r.error)]
            ax.loglog([r.wall for r in mine], [r.error for r in mine], marker + "-", label=sim)
        ax.axhline(tol, color="grey", lw=0.8, ls="--")
        ax.set_title(prob, fontsize=9)
        ax.set_xlabel("wall time of the run [s]")
        ax.set_ylabel("largest marker error [m]")
        ax.grid(True, which="both", alpha=0.3)
        ax.xaxis.set_minor_formatter(NullFormatter())  # a narrow decade labels its minor ticks over each other
        ax.legend(fontsize=7)
    for ax in list(axes.flat)[len(probs):]:
        ax.set_visible(False)
    fig.suptitle(f"work-precision, whole runs with 100 Hz frames (dashed: {tol:g} m)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", default="heavy_top,torque_free,top_through_vertical,chain")
    ap.add_argument("--chains", default="2,10,50,100,200", help="chain lengths (links)")
    ap.add_argument("--simulators", default="viz3d,MuJoCo,Exudyn,Pinocchio",
                    help="viz3d (all its configurations) or configuration names, and peers")
    ap.add_argument("--tol", type=float, default=1e-6, help="accuracy to reach [m]")
    ap.add_argument("--max-run", type=float, default=20.0, help="longest run tried [s]")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--ref-rtol", type=float, default=1e-12)
    ap.add_argument("--out", type=Path, default=None,
                    help=f"chart path, the table beside it (.md); default {DOC.relative_to(ROOT)}, into whose table a run "
                         "on part of the problems, chains or simulators merges its rows")
    args = ap.parse_args(argv)
    defaults = {a.dest: a.default for a in ap._actions}
    subset = any(getattr(args, k) != defaults[k] for k in ("problems", "chains", "simulators"))
    merge = args.out is None and subset and DOC.with_suffix(".md").exists()
    if merge and any(getattr(args, k) != defaults[k] for k in ("tol", "ref_rtol")):
        ap.error("a run at another --tol or --ref-rtol cannot merge into the default table: give --out")
    out = args.out or DOC
    runners = simulators(args.simulators.split(","))
    probs = problems(args.problems.split(","), [int(n) for n in args.chains.split(",")], args.ref_rtol)
    for p in probs:  # untimed warm-up: the kernel from numba's cache, first calls of each library
        for run in runners.values():
            one(Problem(p.name, p.path, p.overrides, 2 * OUTPUT_DT, p.reference[:3], p.tree), "", run, 4, 1)
    start, load0 = time.strftime("%Y-%m-%d %H:%M", time.gmtime()), load()
    rows = [r for p in probs for r in measure(p, runners, args.tol, args.max_run, args.repeat)]
    when = (f"{start}-{time.strftime('%H:%M', time.gmtime())} UTC, {os.cpu_count()} cores, load average "
            f"(1/5/15 min) {load0} at the start and {load()} at the end")
    print("\n" + summary(rows, args.tol, list(runners)))
    if merge:
        head, old = read_runs(DOC.with_suffix(".md"))
        rows = merged(old, rows)
        command = " ".join(sys.argv[1:] if argv is None else argv)
        head = (head.rstrip("\n") + f"\n\nRows of {', '.join(p.name for p in probs)} ({args.simulators}) re-run on "
                f"{when} (`python benchmarks/bench_peers.py {command}`); the other rows are from the runs above.\n\n")
    else:
        head = (f"Generated by `python benchmarks/bench_peers.py` ({when}; cheapest whole run, frames at 100 Hz, whose "
                f"largest marker error is at most {args.tol:g} m; reference: viz3d dop853 at rtol {args.ref_rtol:g}; "
                "each clock starts once its model is built: viz3d's after `viz3d.scene.build.build` (scene to System "
                "and initial State), MuJoCo's after its `MjModel`, Exudyn's after `Assemble`).\n\n")
    sims = list(dict.fromkeys(r.simulator for r in rows))
    text = (head + summary(rows, args.tol, sims) + "\n\nviz3d's configurations (cheapest run of each):\n\n"
            + configurations(rows, args.tol, sims) + "\n\nAll runs:\n\n" + all_runs(rows) + "\n")
    chart(rows, args.tol, out)
    out.with_suffix(".md").write_text(text)
    print(f"\nwrote {out} and {out.with_suffix('.md')}" + (" (rows merged into the earlier table)" if merge else ""))


if __name__ == "__main__":
    main()
