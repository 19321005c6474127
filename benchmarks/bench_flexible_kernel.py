"""Wall time of the flexible mechanisms before and after the kernel took framed joints and drives on
flexible sections and geometric stiffening (a benchmark, not a test; issue 14, "a run costs what
its steps cost"): the flexible four-bar and slider-crank, and the spin-up beam.

    python benchmarks/bench_flexible_kernel.py --before COMMIT [--after COMMIT] [--repeat 2] [--out docs/bench_flexible_kernel.md]

``--before`` and ``--after`` (default HEAD) are the commits compared, each extracted with ``git
archive`` into a temporary directory and imported through PYTHONPATH (edits of the working tree
during the run do not enter it). Each case is one
``viz3d run SCENE`` of the whole scene (its own ``t_end``) in a fresh interpreter; the cases are
interleaved (a round runs every case once) so the load of this shared machine falls on all alike;
best of ``--repeat``. Every tree first runs each scene once with ``--t-end 0.02`` into an empty
numba cache of its own: that warm-up run's time (compiling the kernel, or loading the NumPy path)
is reported apart, the timed runs find the kernel in the cache, as a user's second run does.

Columns: the run's own wall time (``viz3d run`` prints it: stepping and output frames), the
process's (imports and start-up too), steps, right-hand-side evaluations, microseconds per step,
the real-time factor (simulated / wall), the path (``kernel`` line of the output), and after/before
ratios of the run's wall time. ``uptime``'s load averages are quoted before and after.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from datetime import date
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENES = ("scenes/flexible_four_bar.toml", "scenes/flexible_slider_crank.toml", "scenes/spin_up_beam.toml")
#: What the benchmark reads from ``viz3d run``'s summary.
FIELDS = {
    "steps": re.compile(r"^steps\s+(\d+) \((\d+) RHS evaluations\), simulated ([0-9.eE+-]+) s", re.M),
    "wall": re.compile(r"^wall time\s+([0-9.]+) s", re.M),
    "kernel": re.compile(r"^kernel\s+(.*)$", re.M),
    "status": re.compile(r"^status\s+(.*)$", re.M),
}


def load() -> str:
    """``uptime``'s load averages."""
    out = subprocess.run(["uptime"], capture_output=True, text=True).stdout
    return out.split("load average:")[-1].strip()


def extract(commit: str, where: Path) -> Path:
    """The source tree of ``commit`` in ``where`` (``git archive``)."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", commit], capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(where)], input=archive, check=True)
    return where


def run(tree: Path, cache: Path, scene: str, out: Path, t_end: float | None = None) -> dict:
    """One ``viz3d run`` of ``scene`` with ``tree`` on PYTHONPATH: the summary's fields and the
    process's wall time [s]; raises if the run fails."""
    env = dict(os.environ, PYTHONPATH=str(tree), NUMBA_CACHE_DIR=str(cache))
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    cmd = [sys.executable, "-m", "viz3d", "run", str(tree / scene), "--out", str(out), "--no-progress"]
    cmd += ["--t-end", str(t_end)] if t_end is not None else []
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=tree)
    process = time.perf_counter() - t0
    text = proc.stdout + proc.stderr
    if proc.returncode != 0:
        raise RuntimeError(f"{scene} with {tree}: exit {proc.returncode}\n{text[-2000:]}")
    steps = FIELDS["steps"].search(text)
    return {"process": process, "wall": float(FIELDS["wall"].search(text).group(1)), "steps": int(steps.group(1)),
            "rhs": int(steps.group(2)), "simulated": float(steps.group(3)),
            "kernel": FIELDS["kernel"].search(text).group(1).strip(), "status": FIELDS["status"].search(text).group(1)}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", required=True, help="commit before the change")
    ap.add_argument("--after", default="HEAD", help="commit after the change")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_flexible_kernel.md")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="bench_flexible_kernel_") as tmp:
        tmp = Path(tmp)
        trees = {}
        for name in ("before", "after"):
            (tmp / name).mkdir()
            trees[name] = extract(getattr(args, name), tmp / name)
        caches = {name: tmp / f"numba_{name}" for name in trees}
        load0 = load()
        warm = {}
        for name, tree in trees.items():
            for scene in SCENES:
                t0 = time.perf_counter()
                run(tree, caches[name], scene, tmp / "warm.npz", t_end=0.02)
                warm[name, scene] = time.perf_counter() - t0
        best: dict = {}
        for _ in range(args.repeat):
            for scene in SCENES:
                for name, tree in trees.items():
                    r = run(tree, caches[name], scene, tmp / "out.npz")
                    if (name, scene) not in best or r["wall"] < best[name, scene]["wall"]:
                        best[name, scene] = r
        load1 = load()
    write(args, best, warm, load0, load1)


def write(args, best: dict, warm: dict, load0: str, load1: str) -> None:
    rows = ["| scene | tree | path | run wall [s] | process wall [s] | warm-up run [s] | steps | RHS | us/step | "
            "real-time factor | after / before |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for scene in SCENES:
        for name in ("before", "after"):
            r = best[name, scene]
            ratio = f"{r['wall'] / best['before', scene]['wall']:.3f}" if name == "after" else ""
            rows.append(f"| {Path(scene).stem} | {name} | {r['kernel']} | {r['wall']:.2f} | {r['process']:.2f} | "
                        f"{warm[name, scene]:.1f} | {r['steps']} | {r['rhs']} | {1e6 * r['wall'] / r['steps']:.0f} | "
                        f"{r['simulated'] / r['wall']:.3g} | {ratio} |")
    table = "\n".join(rows)
    print(table)
    commit = {name: subprocess.run(["git", "rev-parse", "--short", rev], cwd=ROOT, capture_output=True, text=True,
                                   check=True).stdout.strip() for name, rev in (("before", args.before), ("after", args.after))}
    text = f"""# Flexible mechanisms on the compiled kernel

Written by `benchmarks/bench_flexible_kernel.py --before {args.before} --after {args.after} --repeat {args.repeat}`
on {date.today()}. "before" is commit `{commit["before"]}`, where framed joints with a side on a section of a
flexible body (and drives on them, and geometric stiffening) sent a run to the NumPy path; "after"
is commit `{commit["after"]}`, whose kernel covers them. One `viz3d run` of each
whole scene per case in a fresh interpreter, cases interleaved, best of {args.repeat}; warm numba
caches (the warm-up run, `--t-end 0.02` into an empty cache, compiles the kernel: its time is the
column "warm-up run"). "run wall" is what `viz3d run` reports (stepping and output frames);
"process wall" adds start-up and imports.

Load average (1, 5, 15 min) before: {load0}; after: {load1} (a shared 2-core machine).

{table}
"""
    args.out.write_text(text)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
