"""Start-up time of ``viz3d`` (a benchmark, not a test; issue 14).

    python benchmarks/bench_startup.py [--repeat 5] [--before DIR] [--out docs/bench_startup.md]

Each case runs in a fresh interpreter; the wall time of the whole process is measured, best of
``--repeat``, the cases interleaved (one round runs every case once) so that the load of this shared
machine falls on all of them alike. Warm caches, as a user has them after the first run: every tree
is run once untimed first (numba's on-disk cache of the kernel, ``NUMBA_CACHE_DIR`` if set, and the
modules' bytecode: ``PYTHONDONTWRITEBYTECODE`` is dropped for the children).

Cases: Python alone, ``import numpy``, ``import numba``, ``import numba, scipy.linalg`` (what any run
imports: the kernel, and LAPACK for the initial projection), ``import viz3d``, ``import viz3d.cli``,
and ``viz3d run scenes/heavy_top.toml --t-end 0.01`` (10 steps). ``--before DIR`` measures a second source
tree too (an earlier version, e.g. ``git archive <commit> | tar -x -C DIR``), imported through
PYTHONPATH, in the same rounds. A last table splits one run into its phases (imports, scene load and
build, the kernel's first call = loading the run's stepping entry, ``advance_frames``, from numba's
cache, the rest of the run: its sampling entry loaded, the steps, the output), best of ``--repeat``.
The load average is quoted before and after.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: (label, interpreter arguments); ``{scene}`` and ``{out}`` are filled per tree.
CASES = [
    ("python -c pass", ["-c", "pass"]),
    ("import numpy", ["-c", "import numpy"]),
    ("import numba", ["-c", "import numba"]),
    ("import numba, scipy.linalg", ["-c", "import numba, scipy.linalg"]),
    ("import viz3d", ["-c", "import viz3d"]),
    ("import viz3d.cli", ["-c", "import viz3d.cli"]),
    ("viz3d run heavy_top --t-end 0.01", ["-m", "viz3d", "run", "{scene}", "--t-end", "0.01", "--out", "{out}",
                                         "--no-progress"]),
]
#: One run split into phases (printed as JSON, seconds).
PHASES = """
import time
t0 = time.perf_counter()
import numpy as np
from viz3d.cli import main
from viz3d.scene.build import build, make_formulation
from viz3d.scene.load import load_scene
t1 = time.perf_counter()
scene = load_scene({scene!r}, ["sim.t_end=0.01"])
system, state = build(scene)
t2 = time.perf_counter()
from viz3d.integrators.tableaus import RK4
from viz3d.kernel import KernelStepper, kernel_for
data = kernel_for(system, make_formulation(scene.data["sim"]))
y, chart = state.y.copy(), state.chart.copy()
KernelStepper(data, RK4).frames(1, 1, 0, 0.0, 1e-3, y, chart, np.zeros(system.n_bodies, np.int64), 1e6)
t3 = time.perf_counter()
main(["run", {scene!r}, "--t-end", "0.01", "--out", {out!r}, "--no-progress"])
t4 = time.perf_counter()
import json
print(json.dumps({{"imports": t1 - t0, "load and build": t2 - t1, "kernel from cache": t3 - t2, "run": t4 - t3}}))
"""


def child_env(tree: Path | None) -> dict:
    """The children's environment: bytecode written (warm, as installed), ``tree`` first on the path."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    if tree is not None:
        env["PYTHONPATH"] = str(tree) + os.pathsep + env.get("PYTHONPATH", "")
    return env


def wall(args: list[str], env: dict, quiet: bool = True) -> float:
    """Wall time [s] of one interpreter running ``args``."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, *args], env=env, cwd=tempfile.gettempdir(), check=True,
                   stdout=subprocess.DEVNULL if quiet else None)
    return time.perf_counter() - t0


def case_args(args: list[str], tree: Path, out: Path) -> list[str]:
    return [a.format(scene=str(tree / "scenes" / "heavy_top.toml"), out=str(out)) for a in args]


def measure(trees: dict[str, Path], repeat: int, out: Path) -> dict[tuple[str, str], float]:
    """Best wall time [s] per (tree label, case label), cases and trees interleaved."""
    envs = {name: child_env(None if name == "now" else tree) for name, tree in trees.items()}
    for name, tree in trees.items():  # warm-up: numba cache, bytecode
        wall(case_args(CASES[-1][1], tree, out), envs[name])
    best: dict[tuple[str, str], float] = {}
    for _ in range(repeat):
        for label, args in CASES:
            for name, tree in trees.items():
                t = wall(case_args(args, tree, out), envs[name])
                best[name, label] = min(best.get((name, label), float("inf")), t)
    return best


def phases(tree: Path, env: dict, repeat: int, out: Path) -> dict[str, float]:
    """Best time [s] of each phase of one run (``PHASES``)."""
    code = PHASES.format(scene=str(tree / "scenes" / "heavy_top.toml"), out=str(out))
    best: dict[str, float] = {}
    for _ in range(repeat):
        res = subprocess.run([sys.executable, "-c", code], env=env, cwd=tempfile.gettempdir(), check=True,
                             capture_output=True, text=True)
        for k, v in json.loads(res.stdout.strip().splitlines()[-1]).items():
            best[k] = min(best.get(k, float("inf")), v)
    return best


def table(best: dict, names: list[str]) -> str:
    base = {n: best[n, CASES[0][0]] for n in names}
    head = " | ".join(f"{n} [s] | {n}, beyond Python [s]" for n in names)
    lines = [f"| case | {head} |", "|---|" + "---|---|" * len(names)]
    for label, _ in CASES:
        cells = " | ".join(f"{best[n, label]:.3f} | {best[n, label] - base[n]:.3f}" for n in names)
        lines.append(f"| `{label}` | {cells} |")
    return "\n".join(lines)


def phase_table(split: dict[str, dict[str, float]]) -> str:
    names = list(split)
    lines = ["| phase of one run | " + " | ".join(f"{n} [s]" for n in names) + " |", "|---|" + "---|" * len(names)]
    for k in split[names[0]]:
        lines.append(f"| {k} | " + " | ".join(f"{split[n][k]:.3f}" for n in names) + " |")
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
        best = measure(trees, args.repeat, npz)
        split = {n: phases(t, child_env(None if n == "now" else t), args.repeat, npz) for n, t in trees.items()}
    text = (f"Generated by `python benchmarks/bench_startup.py{' --before DIR' if args.before else ''}` "
            f"({time.strftime('%Y-%m-%d')}, {os.cpu_count()} cores, Python {sys.version.split()[0]}, best of "
            f"{args.repeat} fresh processes, warm numba cache and bytecode; load average {_load(load0)} at the "
            f"start, {_load(os.getloadavg())} at the end).\n\n"
            f"{table(best, list(trees))}\n\n{phase_table(split)}\n")
    print(text)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
