"""What an output frame costs, with and without sinks, before and after a change (a benchmark, not a
test).

    python benchmarks/bench_frames.py [--t-end 0.5,1.5] [--repeat 3] [--before /work/main] [--out docs/bench_frames.md]

Scenes: ``heavy_top`` (dt 1e-3) and ``chain`` at 10 and 50 links (dt 5e-4, ``--set chain.n=N``
as bench_methods builds them). Runs:

* ``steps``: the steps alone (``Simulation.steps`` through the compiled kernel, no frame);
* ``headless``: ``viz3d.simulate`` without sinks, ``sim.output_dt = sim.dt`` (the trajectory's
  frames, one per step: enough of them to measure);
* ``NullSink``: the same with a ``NullSink`` (it gets the frame of each output instant, unread);
* ``recorder``: with a ``RerunRecorder`` at its defaults (plot samples every step, poses every
  ``display_dt``), to a temporary ``.rrd``.

Each is timed as process CPU time (the rerun SDK's writer thread included), the best of
``--repeat`` after a warm-up run, at two lengths ``--t-end T1,T2``: the difference is what the
extra ``T2 - T1`` of simulated time costs, free of every fixed cost (loading, building, the
sinks' geometry, opening and closing the file). Cost per frame = (that difference - the steps'
difference) / the frames' difference, where frames are the trajectory's output instants
(headless, NullSink) or the frames handed to the recorder (one per step); it includes the sink's
own work. It is also expressed in kernel steps (the ``steps`` row's cost per step, of the same
code). With ``--before DIR`` the same
measurements run in a subprocess on the code in DIR (``PYTHONPATH=DIR``), so old and new are
measured in one run under the same load. Prints a Markdown table and writes it to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: (label, scene file, overrides)
SCENES = [("heavy top", "heavy_top.toml", []), ("chain N=10", "chain.toml", ["chain.n=10"]),
          ("chain N=50", "chain.toml", ["chain.n=50"])]
RUNS = ("steps", "headless", "NullSink", "recorder")


def _cpu(fn) -> float:
    t0 = time.process_time()
    fn()
    return time.process_time() - t0


def _steps(path: Path, overrides: list[str], t_end: float) -> tuple[float, int]:
    """CPU seconds of the run's steps alone and their number."""
    import viz3d
    from viz3d.scene.build import make_controller, make_formulation, make_integrator_from
    from viz3d.simulate import Simulation

    scene = viz3d.load_scene(path, overrides)
    system, state = viz3d.build(scene)
    cfg = scene.data["sim"]
    n = round(t_end / cfg["dt"])
    sim = Simulation(system, state, make_integrator_from(cfg), make_formulation(cfg), cfg["dt"], cfg["blowup_speed"],
                     make_controller(cfg))
    return _cpu(lambda: sim.steps(n)), n


class _Counting:
    """Counts the frames the recorder is handed (wraps its ``log``)."""

    def __init__(self, sink):
        self.sink, self.n = sink, 0

    def __getattr__(self, name):
        return getattr(self.sink, name)

    def log(self, frame):
        self.n += 1
        self.sink.log(frame)


def _run(path: Path, overrides: list[str], t_end: float, kind: str, tmp: Path) -> tuple[float, int]:
    """CPU seconds of a whole run of ``kind`` and the frames it delivered."""
    import viz3d
    from viz3d.sink import NullSink
    from viz3d.viz.recorder_rerun import RerunRecorder

    sinks = {"headless": [], "NullSink": [NullSink()], "recorder": [_Counting(RerunRecorder(tmp / "b.rrd"))]}[kind]
    if kind != "recorder":  # an output frame every step, as the recorder's (a measurable number of frames)
        overrides = overrides + [f"sim.output_dt={viz3d.load_scene(path, overrides).data['sim']['dt']!r}"]
    out = {}
    cpu = _cpu(lambda: out.setdefault("traj", viz3d.simulate(path, overrides, t_end=t_end, sinks=sinks)))
    assert out["traj"].status == "ok", out["traj"].status
    return cpu, sinks[0].n if kind == "recorder" else len(out["traj"].t)


def measure(t_ends: list[float], repeat: int) -> dict:
    """{scene: {run: [(cpu seconds, frames or steps) at each of t_ends]}} of the code on ``sys.path``."""
    res = {}
    with tempfile.TemporaryDirectory() as tmp:
        for label, name, over in SCENES:
            path = ROOT / "scenes" / name
            row = {}
            for kind in RUNS:
                row[kind] = []
                for t_end in t_ends:
                    go = (lambda: _steps(path, over, t_end)) if kind == "steps" else (
                        lambda: _run(path, over, t_end, kind, Path(tmp)))
                    go()  # warm-up (compiled kernels, caches)
                    row[kind].append(min((go() for _ in range(repeat)), key=lambda x: x[0]))
                    print(f"  {label:>10} {kind:<9} t_end {t_end:g}: {row[kind][-1][0]:.3f} s CPU, "
                          f"{row[kind][-1][1]} frames/steps", file=sys.stderr, flush=True)
            res[label] = row
    return res


def _measure_in(code: Path, t_ends: str, repeat: int) -> dict:
    env = {**os.environ, "PYTHONPATH": str(code)}
    proc = subprocess.run([sys.executable, __file__, "--measure-only", "--t-end", t_ends, "--repeat", str(repeat)],
                          env=env, capture_output=True, text=True, cwd=code)
    if proc.returncode:
        raise SystemExit(f"measuring {code} failed:\n{proc.stderr}")
    return json.loads(proc.stdout)


def table(results: dict[str, dict]) -> str:
    lines = ["| scene | code | step [µs] | run | frames | CPU of the extra time [s] | µs per frame | kernel steps per frame |",
             "|---|---|---|---|---|---|---|---|"]
    for label, *_ in SCENES:
        for code, res in results.items():
            row = res[label]
            (s1, n1), (s2, n2) = row["steps"]
            step = (s2 - s1) / (n2 - n1)
            for kind in RUNS[1:]:
                (c1, f1), (c2, f2) = row[kind]
                per = ((c2 - c1) - step * (n2 - n1)) / (f2 - f1)
                lines.append(f"| {label} | {code} | {1e6 * step:.1f} | {kind} | {f2 - f1} | {c2 - c1:.3f} | {1e6 * per:.1f} | "
                             f"{per / step:.2f} |")
    return "\n".join(lines)


def _commit(code: Path) -> str:
    """The commit of the code in ``code`` (and whether its tree has changes)."""
    def git(*a):
        return subprocess.run(["git", "-C", str(code), *a], capture_output=True, text=True).stdout.strip()

    return f"{code} at {git('rev-parse', '--short', 'HEAD')}{' (modified)' if git('status', '--porcelain', '--', 'viz3d') else ''}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--t-end", default="0.5,1.5", help="two run lengths T1,T2 [s]")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--before", type=Path, help="measure the code in this directory too (as 'before')")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_frames.md")
    ap.add_argument("--measure-only", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.measure_only:
        print(json.dumps(measure([float(x) for x in args.t_end.split(",")], args.repeat)))
        return
    results = {}
    if args.before is not None:
        results["before"] = _measure_in(args.before, args.t_end, args.repeat)
    results["after" if args.before is not None else "this"] = _measure_in(ROOT, args.t_end, args.repeat)
    load = os.getloadavg()
    when = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    head = (f"Generated by `python benchmarks/bench_frames.py --t-end {args.t_end}"
            f"{' --before ' + str(args.before) if args.before else ''}` on {when}, load average "
            f"{load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} (1 / 5 / 15 min; 2 cores). CPU time per run, best of "
            f"{args.repeat}, at two lengths; per frame = (CPU difference - steps' difference) / frames' difference "
            "(no fixed cost); 'kernel steps per frame' divides by the step cost measured in the same run of the "
            "same code.\n\n")
    commits = {code: _commit(d) for code, d in (("before", args.before), ("after", ROOT)) if d is not None}
    head += "Code: " + ", ".join(f"{k} = {v}" for k, v in commits.items()) + ".\n\n"
    text = table(results)
    print(text)
    args.out.write_text(head + text + "\n")
    print(f"\nwrote {args.out}")


if __name__ == "__main__":
    main()
