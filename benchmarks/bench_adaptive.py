"""Adaptive runs (dopri5, dop853), and fixed steps with contact events, through the compiled adaptive
driver against the Python loop (issue 14): whole-run wall time and cost per accepted step, on
shipped scenes (a benchmark, not a test).

    python benchmarks/bench_adaptive.py [--repeat 3] [--out docs/bench_adaptive.md] [--before /work/main]

Every scene runs headless (``viz3d.simulate.run``: output frames and their checks included, the build
of the system not) both ways, the two interleaved in each repeat so that both see the same load: with
the compiled driver (``viz3d.kernel.adaptive``: the default), and with the Python adaptive loop it
replaced (``Simulation._adaptive_samples`` / ``_event_steps``, still the path of the step after
each contact event, with stateful friction and for systems the kernel does not cover), its
right-hand side compiled as before. With ``--before`` (a checkout of an earlier viz3d), the compiled driver of that checkout
too, and this checkout's, each in a fresh subprocess importing it (``PYTHONPATH``), interleaved likewise. Wall time is the least of the repeats (the load of a shared machine only adds); an untimed
warm-up run of each first (numba's cache loads). Both runs must take the same steps (the table
says so). Prints a Markdown table and writes it to ``--out``. Wall times of this machine under its
load at the time (quoted): compare the ratios of one run, not machines.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import viz3d
from viz3d.scene.build import make_controller, make_formulation, make_integrator_from
from viz3d.scene.load import with_sim
from viz3d.simulate import Simulation, run

ROOT = Path(__file__).resolve().parents[1]
#: label -> (scene file stem, overrides, simulated time [s]).
SCENES = {
    "flexible_pendulum": ("flexible_pendulum", [], 2.0),
    "flexible_pendulum dop853": ("flexible_pendulum", ["sim.integrator=dop853"], 2.0),
    "ball_on_flexible_beam": ("ball_on_flexible_beam", [], 0.12),
    "pendulum_strikes_bar": ("pendulum_strikes_bar", [], 1e-3),
    "impact_free_bar": ("impact_free_bar", [], 1.6e-4),
    "impact_bronze_ball": ("impact_bronze_ball", [], 1e-3),
    "bouncing_sphere": ("bouncing_sphere", [], 0.1),
    "bouncing_sphere restitution": ("bouncing_sphere", ["contact.law=restitution", "sim.max_step=2e-3"], 0.4),
    # fixed RK4 steps with contact events (``FixedSteps`` in the driver): law contacts with regularised
    # Coulomb friction throughout, and the coin's 48 rim contacts with bristle friction
    "box_on_incline (rk4)": ("box_on_incline", [], 1.0),
    "rolling_ball (rk4)": ("rolling_ball", [], 0.5),
    "coin_drop (rk4)": ("coin_drop", [], 0.4),
}


@contextlib.contextmanager
def python_loop(on: bool, kernel_steps: list, event_steps: list, python_walls: list):
    """Adaptive steps in the Python loop (``on``) instead of the compiled driver; the steps the
    compiled driver takes (those its calls kept: ``Simulation._kernel_samples`` counts the last call
    only, not a call it redid for fewer frames) are appended to ``kernel_steps``, a 1 for each step the Python loop takes
    with contacts (``Simulation._event_step``) to ``event_steps``, the wall time [s] of each sample
    the Python loop takes (``Simulation._python_step``: its steps, event location and handlers)
    to ``python_walls``."""
    covers, samples = Simulation._adaptive_kernel_covers, Simulation._kernel_samples
    event_step, python_step = Simulation._event_step, Simulation._python_step

    def counted_step(self, *args):
        event_steps.append(1)
        return event_step(self, *args)

    def timed(self, *args):
        t0 = time.perf_counter()
        try:
            return python_step(self, *args)
        finally:
            python_walls.append(time.perf_counter() - t0)

    def counted(self, *args):
        before = self.n_steps
        try:
            return samples(self, *args)
        finally:
            kernel_steps.append(self.n_steps - before)

    Simulation._kernel_samples, Simulation._event_step, Simulation._python_step = counted, counted_step, timed
    if on:
        Simulation._adaptive_kernel_covers = lambda self: False
    try:
        yield
    finally:
        Simulation._adaptive_kernel_covers, Simulation._kernel_samples = covers, samples
        Simulation._event_step, Simulation._python_step = event_step, python_step


def one_run(label: str, python: bool) -> dict:
    """One headless run of ``label``: wall time [s], accepted and rejected steps, evaluations, status."""
    stem, overrides, t_end = SCENES[label]
    scene = with_sim(viz3d.load_scene(ROOT / "scenes" / f"{stem}.toml", overrides), t_end=t_end)
    system, state = viz3d.build(scene)
    cfg = scene.data["sim"]
    sim = Simulation(system, state, make_integrator_from(cfg), make_formulation(cfg), cfg["dt"], cfg["blowup_speed"],
                     make_controller(cfg))
    kernel_steps: list[int] = []
    event_steps: list[int] = []
    python_walls: list[float] = []
    with python_loop(python, kernel_steps, event_steps, python_walls):
        t0 = time.perf_counter()
        traj = run(sim, scene)
        wall = time.perf_counter() - t0
    return dict(wall=wall, steps=sim.n_steps, rejected=sim.n_rejected, rhs=sim.n_rhs, status=traj.status,
                kernel_steps=sum(kernel_steps), python_steps=len(event_steps), python_wall=sum(python_walls))


def checkout_run(label: str, checkout: Path) -> dict:
    """``one_run(label, python=False)`` with the viz3d of ``checkout``, in a fresh subprocess (after an
    untimed warm-up run there): a run in this process, which holds every scene's runs so far, is a
    little slower on the scenes whose frames dominate (bouncing_sphere: 0.097 s against 0.063 s)."""
    cache = os.environ.get("NUMBA_CACHE_DIR", "/tmp/nbc") + ("" if checkout == ROOT else "_before")
    env = {**os.environ, "PYTHONPATH": str(checkout), "NUMBA_CACHE_DIR": cache}
    out = subprocess.run([sys.executable, __file__, "--worker", label], env=env, check=True, capture_output=True,
                         text=True, cwd=checkout)
    return json.loads(out.stdout.splitlines()[-1])


def measure(repeat: int, before: Path | None) -> dict:
    """label -> {"kernel": best run, "python": best run[, "before": best run]}, interleaved repeats
    after a warm-up."""
    best: dict = {}
    ways = [("kernel", False), ("python", True)] + ([("after", ROOT), ("before", before)] if before else [])
    for label in SCENES:
        for python in (False, True):
            one_run(label, python)  # warm-up: numba's cache, scipy imports
    for r in range(repeat):
        for label in SCENES:
            for way, python in ways:
                res = one_run(label, python) if isinstance(python, bool) else checkout_run(label, python)
                if way not in best.setdefault(label, {}) or res["wall"] < best[label][way]["wall"]:
                    best[label][way] = res
                print(f"  repeat {r + 1}: {label:<26} {way:<6} {res['wall']:.3f} s  {res['steps']} steps", flush=True)
    return best


def table(best: dict) -> str:
    has_before = any("before" in ways for ways in best.values())
    extra = ((" subprocess: compiled driver [s] | subprocess: before [s] | steps in the driver before "
              "| speed-up over before | steps in Python: now / before | Python's samples [ms]: now / before |",
              "---|---|---|---|---|---|") if has_before else ("", ""))
    lines = ["| scene | steps (rejected) | evaluations | same steps | steps in the compiled driver | Python loop [s] "
             "| compiled driver [s] | per step: Python [us] | per step: compiled [us] | speed-up |" + extra[0],
             "|---|---|---|---|---|---|---|---|---|---|" + extra[1]]
    for label, ways in best.items():
        k, p = ways["kernel"], ways["python"]
        same = all((k["steps"], k["rejected"], k["rhs"], k["status"]) == (x["steps"], x["rejected"], x["rhs"], x["status"])
                   for x in ways.values())
        row = (f"| {label} | {k['steps']} ({k['rejected']}) | {k['rhs']} | {'yes' if same else 'NO'} "
               f"| {100 * k['kernel_steps'] / k['steps']:.0f} % | {p['wall']:.3f} | {k['wall']:.3f} | {1e6 * p['wall'] / p['steps']:.0f} "
               f"| {1e6 * k['wall'] / k['steps']:.0f} | {p['wall'] / k['wall']:.2f}x |")
        if "before" in ways:
            a, b = ways["after"], ways["before"]
            row += (f" {a['wall']:.3f} | {b['wall']:.3f} | {100 * b['kernel_steps'] / b['steps']:.0f} % "
                    f"| {b['wall'] / a['wall']:.2f}x | {a['python_steps']} / {b['python_steps']} "
                    f"| {1e3 * a['python_wall']:.1f} / {1e3 * b['python_wall']:.1f} |")
        lines.append(row)
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_adaptive.md")
    ap.add_argument("--before", type=Path, help="a checkout of an earlier viz3d: its compiled driver too")
    ap.add_argument("--scenes", help="comma-separated labels of SCENES to run (default: all)")
    ap.add_argument("--worker", help=argparse.SUPPRESS)  # (before_run's subprocess: one timed run as JSON)
    args = ap.parse_args()
    if args.worker:
        one_run(args.worker, False)
        print(json.dumps(one_run(args.worker, False)))
        return
    if args.scenes:
        chosen = args.scenes.split(",")
        unknown = sorted(set(chosen) - set(SCENES))
        if unknown:
            ap.error(f"--scenes: unknown label(s) {unknown}; expected some of {sorted(SCENES)}")
        for label in set(SCENES) - set(chosen):
            del SCENES[label]
    load0 = os.getloadavg()
    best = measure(args.repeat, args.before)
    load1 = os.getloadavg()
    text = table(best)
    print(text)
    header = (f"Generated by `python benchmarks/bench_adaptive.py` on {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}: "
              f"whole headless runs (output frames and checks included, build excluded), least wall time of "
              f"{args.repeat} interleaved repeats; {platform.machine()} with {os.cpu_count()} cores, load average "
              f"before {load0[0]:.1f} / {load0[1]:.1f} / {load0[2]:.1f}, after {load1[0]:.1f} / {load1[1]:.1f} / "
              f"{load1[2]:.1f} (1 / 5 / 15 min). Simulated: "
              + ", ".join(f"{label} {t_end:g} s" for label, (_, _, t_end) in SCENES.items())
              + ". Per step: wall time over accepted steps. The step after each contact event is the Python "
              "loop's in every column; the steps of law contacts the compiled driver's since 18cf73e, the steps "
              "cut at contact events (located in the kernel) since 2a61818, fixed steps with contacts and the steps "
              "of bristle friction since 61e4d83 (the share of the steps in the driver is given)"
              + (f"; subprocess columns: the compiled driver of this checkout (git {_commit(ROOT)}) and of "
                 f"{args.before} (git {_commit(args.before)}), each run in a fresh process, with the steps the "
                 "Python loop took at contacts (``Simulation._event_step``) and the wall time of the samples it "
                 "took (``Simulation._python_step``: those steps, locating and handling the events; of the "
                 "fastest run)" if args.before else "")
              + ".\n")
    args.out.write_text(header + "\n" + text + "\n")
    print(f"wrote {args.out}")


def _commit(path: Path) -> str:
    """The short commit of the checkout at ``path``."""
    out = subprocess.run(["git", "-C", str(path), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    return out.stdout.strip() or "unknown"


if __name__ == "__main__":
    main()
