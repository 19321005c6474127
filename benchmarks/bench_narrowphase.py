"""Our narrow phase against Coal's on the anchor hoist (a benchmark, not a test).

    python benchmarks/bench_narrowphase.py [--t 0.5] [--repeats 30] [--runs 3] [--before /work/main]
                                           [--out docs/bench_narrowphase.md]

Simulates the first ``--t`` seconds of ``scenes/anchor_hoist.toml`` and, at its output frames, times
(best of ``--repeats``) ``Collisions._detect`` (broad phase, narrow phase, reduction) with the pairs
``viz3d.contact.narrowphase`` covers handed to it (as the code does) and with every pair handed to
Coal (as before), and the narrow phase of those pairs alone. With ``--before`` (a checkout of an
earlier viz3d) also the wall time of ``viz3d run scenes/anchor_hoist.toml --t-end 0.2`` there and
here (each in a fresh process, best of ``--runs``, after one untimed run that fills the numba
cache). Prints a Markdown table and writes it with the load average. Wall-clock times on this
machine: compare the rows of one run with each other.
"""

from __future__ import annotations

import argparse
import functools
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from bench_collision import best_of  # (benchmarks/ is the script's folder: on sys.path)

import viz3d

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "anchor_hoist.toml"


def states(t: float):
    """The hoist's ``Collisions`` and configurations at its output frames up to ``t``."""
    from viz3d.contact.collision import Collisions
    from viz3d.kinematics import resting_configurations
    from viz3d.scene.build import build

    scene = viz3d.load_scene(SCENE, [f"sim.t_end={t}", "sim.output_dt=0.05"])
    traj = viz3d.simulate(scene)
    system, _ = build(scene)
    col = next(f for f in system.forces if isinstance(f, Collisions))
    return col, resting_configurations(traj.t, traj.position, traj.rotation)


def detect_times(col, cfgs, repeats: int) -> dict:
    """Best wall times [ms] per configuration of detect and of the covered pairs' narrow phase,
    ours and Coal's."""
    w = col._world()
    ours = w["ours"].copy()
    rows = {"ours": [], "coal": [], "narrow_ours": [], "narrow_coal": [], "pairs": [], "contacts": []}
    try:
        for cfg in cfgs:
            r, R = col.shape_poses(cfg)
            pairs = [p for p in col.candidates(r, R) if ours[p]]
            rows["pairs"].append(len(pairs))
            detect = functools.partial(col._detect, cfg)
            narrow = functools.partial(col._narrow, w, pairs, r, R, {})
            for label, mask in (("ours", ours), ("coal", np.zeros_like(ours))):
                w["ours"][:] = mask
                rows[label].append(1e3 * best_of(detect, repeats))
                rows["narrow_" + label].append(1e3 * best_of(narrow, repeats))
            rows["contacts"].append(col._detect(cfg).m)
    finally:
        w["ours"][:] = ours
    return rows


def run_time(checkout: Path, runs: int) -> float:
    """Best wall time [s] of ``viz3d run scenes/anchor_hoist.toml --t-end 0.2`` with ``checkout``'s viz3d."""
    cache = os.environ.get("NUMBA_CACHE_DIR", "/tmp/nbc") + ("" if checkout == ROOT else "_before")
    env = {**os.environ, "PYTHONPATH": str(checkout), "NUMBA_CACHE_DIR": cache}
    cmd = [sys.executable, "-m", "viz3d", "run", str(SCENE), "--t-end", "0.2", "--out", "/tmp/bench_narrowphase.npz",
           "--no-progress"]
    subprocess.run(cmd, env=env, check=True, capture_output=True, cwd=checkout)  # fills the numba cache
    best = np.inf
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run(cmd, env=env, check=True, capture_output=True, cwd=checkout)
        best = min(best, time.perf_counter() - t0)
    return best


def _commit(path: Path) -> str:
    out = subprocess.run(["git", "-C", str(path), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    return out.stdout.strip() or "unknown"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--t", type=float, default=0.5)
    p.add_argument("--repeats", type=int, default=30)
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--before", type=Path)
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_narrowphase.md")
    args = p.parse_args(argv)
    load0 = os.getloadavg()
    col, cfgs = states(args.t)
    rows = detect_times(col, cfgs, args.repeats)
    lines = ["| t [s] | covered pairs | contacts | detect, ours [ms] | detect, Coal [ms] | narrow phase of the "
             "covered pairs, ours [ms] | ..., Coal [ms] |", "|---:|---:|---:|---:|---:|---:|---:|"]
    for k, cfg in enumerate(cfgs):
        lines.append(f"| {cfg.t:.2f} | {rows['pairs'][k]} | {rows['contacts'][k]} | {rows['ours'][k]:.3f} | "
                     f"{rows['coal'][k]:.3f} | {rows['narrow_ours'][k]:.3f} | {rows['narrow_coal'][k]:.3f} |")
    mean = {k: float(np.mean(v)) for k, v in rows.items()}
    lines.append(f"| mean | {mean['pairs']:.1f} | {mean['contacts']:.1f} | {mean['ours']:.3f} | {mean['coal']:.3f} | "
                 f"{mean['narrow_ours']:.3f} | {mean['narrow_coal']:.3f} |")
    summary = (f"\ndetect: Coal / ours = {mean['coal'] / mean['ours']:.2f}; narrow phase of the covered pairs: "
               f"Coal / ours = {mean['narrow_coal'] / mean['narrow_ours']:.2f}")
    if args.before:
        after, before = run_time(ROOT, args.runs), run_time(args.before, args.runs)
        summary += (f"\n\n`viz3d run scenes/anchor_hoist.toml --t-end 0.2` (best of {args.runs}, fresh processes): "
                    f"before ({args.before}, git {_commit(args.before)}) {before:.2f} s, after (git {_commit(ROOT)}) "
                    f"{after:.2f} s, before / after = {before / after:.2f}")
    load1 = os.getloadavg()
    text = "\n".join(lines) + summary
    print(text)
    header = (f"Generated by `python benchmarks/bench_narrowphase.py --t {args.t:g} --repeats {args.repeats}"
              + (f" --before {args.before}" if args.before else "")
              + f"` on {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}: the anchor hoist's output frames up to "
              f"{args.t:g} s, best of {args.repeats} per cell; {os.cpu_count()} cores, load average before "
              f"{load0[0]:.1f} / {load0[1]:.1f} / {load0[2]:.1f}, after {load1[0]:.1f} / {load1[1]:.1f} / "
              f"{load1[2]:.1f} (1 / 5 / 15 min).\n")
    args.out.write_text(header + "\n" + text + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
