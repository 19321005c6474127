"""Start-up time of ``viz3d`` (a benchmark, not a test; issue 14).

    python benchmarks/bench_startup.py [--repeat 5] [--before DIR] [--out docs/bench_startup.md]

Each case runs in a fresh interpreter; the wall time of the whole process is measured, and its CPU
time (user + system, of the process and its threads), which the load of a shared machine inflates far
less (warm caches: nothing to wait for; on a lightly loaded machine the CPU time exceeds the wall time,
threads such as numpy's BLAS pool starting in parallel). The median of ``--repeat``, the cases
interleaved (one round runs every case once) so that the load falls on all of them alike. Warm caches,
as a user has them after the first run: every tree is run once untimed first (numba's on-disk cache of
the kernel, ``NUMBA_CACHE_DIR`` if set, and the modules' bytecode: ``PYTHONDONTWRITEBYTECODE`` is dropped
for the children).

Cases: Python alone, ``import numpy``, ``import numba``, ``import numba, scipy.linalg`` (what a run
imported while its initial projection called LAPACK; a rigid run the kernel covers now projects in the
kernel and imports numba only), ``import viz3d``, ``import viz3d.cli``, ``viz3d run
scenes/heavy_top.toml --t-end 0.01`` (10 steps) and ``viz3d check scenes/heavy_top.toml`` (load and build
on the NumPy path: no compiled kernel). ``--before DIR`` measures a second source tree too (an earlier
version, e.g. ``git archive <commit> | tar -x -C DIR``), imported through PYTHONPATH, in the same rounds.

A last table splits one run into its phases, timed from within the process: the imports (numpy's,
numba's, viz3d's modules); scene load and build, the initial projection included (in the kernel for a
covered rigid system, through the kernel's one entry for a run, ``advance_frames``, loaded from numba's
cache; before that entry took the sampling and projection too, the initial projection loaded an entry of
its own); the kernel's first call, one step through ``advance_frames`` (loading it, on trees where the
build did not); the rest of the run (the steps and their sampling, whose entry earlier trees loaded
here, the output). Wall and CPU time, median of ``--repeat``. The process is set up as the ``viz3d``
command sets its own up (``viz3d.process``: OpenBLAS on one thread, the garbage collector held through
the start-up), where the tree has that module. The load average (``uptime``'s) is quoted before and after.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The case of a run (the warm-up's).
RUN = "viz3d run heavy_top --t-end 0.01"
#: (label, interpreter arguments); ``{scene}`` and ``{out}`` are filled per tree.
CASES = [
    ("python -c pass", ["-c", "pass"]),
    ("import numpy", ["-c", "import numpy"]),
    ("import numba", ["-c", "import numba"]),
    ("import numba, scipy.linalg", ["-c", "import numba, scipy.linalg"]),
    ("import viz3d", ["-c", "import viz3d"]),
    ("import viz3d.cli", ["-c", "import viz3d.cli"]),
    (RUN, ["-m", "viz3d", "run", "{scene}", "--t-end", "0.01", "--out", "{out}", "--no-progress"]),
    ("viz3d check heavy_top", ["-m", "viz3d", "check", "{scene}"]),
]
#: The two clocks of every measurement.
CLOCKS = ("wall", "CPU")
#: The phases of ``PHASES``.
PHASE_NAMES = ("import numpy", "import numba", "import viz3d's modules", "load and build", "kernel from cache", "run")
#: One run split into phases (printed as JSON: wall and CPU seconds of each).
PHASES = """
try:  # the process settings of the viz3d command (viz3d.__main__), where the tree has them
    from viz3d.process import single_threaded_blas
    single_threaded_blas()
except ImportError:
    pass
try:
    from viz3d.process import hold_collector
    hold_collector()
except ImportError:
    pass
import time
def now():
    return time.perf_counter(), time.process_time()
t0 = now()
import numpy as np
ta = now()
import numba
tb = now()
from viz3d.cli import main
from viz3d.scene.build import build, make_formulation
from viz3d.scene.load import load_scene
t1 = now()
scene = load_scene({scene!r}, ["sim.t_end=0.01"])
system, state = build(scene)
t2 = now()
from viz3d.integrators.tableaus import RK4
from viz3d.kernel import KernelStepper, kernel_for
data = kernel_for(system, make_formulation(scene.data["sim"]))
y, chart = state.y.copy(), state.chart.copy()
KernelStepper(data, RK4).frames(1, 1, 0, 0.0, 1e-3, y, chart, np.zeros(system.n_bodies, np.int64), 1e6)
t3 = now()
main(["run", {scene!r}, "--t-end", "0.01", "--out", {out!r}, "--no-progress"])
t4 = now()
import json
names = {names!r}
ts = (t0, ta, tb, t1, t2, t3, t4)
print(json.dumps({{f"{{k}} {{c}}": ts[i + 1][j] - ts[i][j] for i, k in enumerate(names) for j, c in enumerate(("wall", "CPU"))}}))
"""


def child_env(tree: Path) -> dict:
    """The children's environment: bytecode written (warm, as installed), ``tree`` first on the path
    (this tree too: the children run in a temporary directory, where an installed viz3d would win)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPATH"] = str(tree) + os.pathsep + env.get("PYTHONPATH", "")
    return env


def timed(args: list[str], env: dict) -> tuple[float, float]:
    """Wall and CPU time (user + system) [s] of one interpreter running ``args``."""
    r0, t0 = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
    subprocess.run([sys.executable, *args], env=env, cwd=tempfile.gettempdir(), check=True, stdout=subprocess.DEVNULL)
    t1, r1 = time.perf_counter(), resource.getrusage(resource.RUSAGE_CHILDREN)
    return t1 - t0, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def case_args(args: list[str], tree: Path, out: Path) -> list[str]:
    return [a.format(scene=str(tree / "scenes" / "heavy_top.toml"), out=str(out)) for a in args]


def measure(trees: dict[str, Path], repeat: int, out: Path) -> dict[tuple[str, str, str], float]:
    """Median wall and CPU time [s] per (tree label, case label, "wall" or "CPU"), cases and trees
    interleaved."""
    envs = {name: child_env(tree) for name, tree in trees.items()}
    run = dict(CASES)[RUN]
    for name, tree in trees.items():  # warm-up: numba cache, bytecode
        timed(case_args(run, tree, out), envs[name])
    times: dict[tuple[str, str, str], list[float]] = {}
    for _ in range(repeat):
        for label, args in CASES:
            for name, tree in trees.items():
                for clock, t in zip(CLOCKS, timed(case_args(args, tree, out), envs[name])):
                    times.setdefault((name, label, clock), []).append(t)
    return {k: statistics.median(v) for k, v in times.items()}


def phases(trees: dict[str, Path], repeat: int, out: Path) -> dict[str, dict[str, float]]:
    """Per tree, the median wall and CPU time [s] of each phase of one run (``PHASES``), keyed
    ``"<phase> <clock>"``; the trees interleaved, as in ``measure``."""
    codes = {n: PHASES.format(scene=str(t / "scenes" / "heavy_top.toml"), out=str(out), names=PHASE_NAMES)
             for n, t in trees.items()}
    times: dict[str, dict[str, list[float]]] = {n: {} for n in trees}
    for _ in range(repeat):
        for name, tree in trees.items():
            res = subprocess.run([sys.executable, "-c", codes[name]], env=child_env(tree), cwd=tempfile.gettempdir(),
                                 check=True, capture_output=True, text=True)
            for k, v in json.loads(res.stdout.strip().splitlines()[-1]).items():
                times[name].setdefault(k, []).append(v)
    return {n: {k: statistics.median(v) for k, v in ts.items()} for n, ts in times.items()}


def table(median: dict, names: list[str]) -> str:
    """Per case and tree: wall and CPU time, each also beyond Python's own start."""
    cols = [(n, c) for n in names for c in CLOCKS]
    base = {(n, c): median[n, CASES[0][0], c] for n, c in cols}
    head = " | ".join(f"{n} {c} [s] | {n} {c}, beyond Python [s]" for n, c in cols)
    lines = [f"| case | {head} |", "|---|" + "---|---|" * len(cols)]
    for label, _ in CASES:
        cells = " | ".join(f"{median[n, label, c]:.3f} | {median[n, label, c] - base[n, c]:.3f}" for n, c in cols)
        lines.append(f"| `{label}` | {cells} |")
    return "\n".join(lines)


def phase_table(split: dict[str, dict[str, float]]) -> str:
    cols = [(n, c) for n in split for c in CLOCKS]
    lines = ["| phase of one run | " + " | ".join(f"{n} {c} [s]" for n, c in cols) + " |", "|---|" + "---|" * len(cols)]
    for k in PHASE_NAMES:
        lines.append(f"| {k} | " + " | ".join(f"{split[n][f'{k} {c}']:.3f}" for n, c in cols) + " |")
    return "\n".join(lines)


def _load(avg: tuple[float, float, float]) -> str:
    """The 1, 5 and 15 min load averages, as ``uptime`` prints them."""
    return " / ".join(f"{x:.2f}" for x in avg)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--before", type=Path, help="an earlier source tree to measure in the same rounds")
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_startup.md")
    args = p.parse_args(argv)
    trees = {"now": ROOT} if args.before is None else {"before": args.before.resolve(), "now": ROOT}
    load0 = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        npz = Path(tmp) / "top.npz"
        median = measure(trees, args.repeat, npz)
        split = phases(trees, args.repeat, npz)
    text = (f"Generated by `python benchmarks/bench_startup.py{' --before DIR' if args.before else ''}` "
            f"({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.cpu_count()} cores, "
            f"Python {sys.version.split()[0]}, "
            f"median of {args.repeat} fresh processes, warm numba cache and bytecode; load average {_load(load0)} at the "
            f"start, {_load(os.getloadavg())} at the end).\n\n"
            f"{table(median, list(trees))}\n\n{phase_table(split)}\n")
    print(text)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
