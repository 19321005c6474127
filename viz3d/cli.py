"""Command line: turns flags into library calls (no physics here).

Usage::

    viz3d run SCENE [--t-end T] [--dt DT] [--set key.path=value ...] [--out FILE.npz]
    viz3d check SCENE [SCENE ...]
    viz3d list [--format]

``python -m viz3d`` is the same command.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from viz3d.scene.schema import SceneError

#: Where ``viz3d list`` looks for scenes.
SCENES_DIR = Path("scenes")


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the process exit code (0 ok, 1 failed run, 2 bad input)."""
    parser = _parser()
    args = parser.parse_args(argv)
    if not hasattr(args, "func"):
        parser.print_help()
        return 2
    try:
        return args.func(args)
    except SceneError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="viz3d", description="Spatial multibody simulation you can watch.")
    sub = p.add_subparsers()
    run = sub.add_parser("run", help="run a scene headless and write its trajectory")
    run.add_argument("scene", type=Path)
    run.add_argument("--t-end", type=float, help="simulated duration [s] (sim.t_end)")
    run.add_argument("--dt", type=float, help="integration step [s] (sim.dt)")
    run.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY.PATH=VALUE",
                     help="override a scene value, e.g. --set chain.n=20 --set sim.integrator=heun")
    run.add_argument("--out", type=Path, help="trajectory file (.npz); default out/<scene>.npz")
    run.add_argument("--no-progress", action="store_true", help="never draw the progress bar")
    run.set_defaults(func=cmd_run)
    check = sub.add_parser("check", help="validate scene files (and build them)")
    check.add_argument("scenes", type=Path, nargs="+")
    check.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY.PATH=VALUE")
    check.set_defaults(func=cmd_check)
    lst = sub.add_parser("list", help="list scenes, integrators, formulations, rotations, joints, forces")
    lst.add_argument("--format", action="store_true", help="print the scene file reference instead")
    lst.set_defaults(func=cmd_list)
    return p


def cmd_run(args) -> int:
    from viz3d.scene.load import load_scene
    from viz3d.simulate import simulate

    scene = load_scene(args.scene, args.overrides)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        traj = simulate(scene, t_end=args.t_end, dt=args.dt, progress=not args.no_progress)
    for w in caught:
        print(f"warning: {w.message}", file=sys.stderr)
    out = save_or_fallback(traj, args.out or Path("out") / f"{scene.name}.npz", scene.name)
    print(summary(traj, out))
    return 0 if traj.ok else 1


def save_or_fallback(traj, out: Path, name: str) -> Path:
    """Save ``traj`` to ``out``; if that fails, to a temporary file (never lose a computed run)."""
    try:
        return traj.save(out)
    except OSError as exc:
        import tempfile

        fallback = Path(tempfile.mkstemp(prefix=f"{name}-", suffix=".npz")[1])
        print(f"error: cannot write {out} ({exc}); the trajectory was saved to {fallback} instead", file=sys.stderr)
        return traj.save(fallback)


def summary(traj, out: Path) -> str:
    """The run summary printed by ``viz3d run``."""
    meta = traj.scene["run"]
    sim_time = float(traj.t[-1] - traj.t[0]) if traj.t.size else 0.0
    rtf = sim_time / traj.wall_time if traj.wall_time > 0 else float("inf")
    lines = [
        f"scene       {traj.scene['scene']['scene'].get('name', Path(meta['source']).stem)} ({meta['source']})",
        f"method      {meta['integrator']}, dt = {meta['dt']:g} s, {meta['formulation']}, {meta['rotation']}",
        f"bodies      {len(traj.body_names)}, joints {len(traj.joint_names)}",
        f"steps       {traj.n_steps} ({traj.n_rhs} RHS evaluations), simulated {sim_time:.6g} s",
        f"wall time   {traj.wall_time:.3f} s, real-time factor {rtf:.3g}, "
        f"{1e6 * traj.wall_time / max(traj.n_steps, 1):.1f} us/step",
        _energy_line(traj, meta),
        f"constraints max |C| = {traj.max_constraint_violation:.3e} m",
        f"charts      {int(traj.chart_switches.sum())} Euler-chart switches",
        f"status      {traj.status}",
        f"wrote       {out}",
    ]
    return "\n".join(lines)


def _energy_line(traj, meta) -> str:
    if meta.get("conservative", True):
        return f"energy      drift max |E - E0| = {traj.energy_drift:.3e} J ({traj.energy_drift_rel:.3e} of max kinetic)"
    return (f"energy      change max |E - E0| = {traj.energy_drift:.3e} J (not conserved: the scene has dampers "
            f"or applied loads)")


def cmd_check(args) -> int:
    from viz3d.scene.build import build
    from viz3d.scene.load import load_scene

    bad = 0
    for path in args.scenes:
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                system, _ = build(load_scene(path, args.overrides))
            extra = "".join(f"\n  warning: {w.message}" for w in caught)
            print(f"ok     {path}: {system.n_bodies} bodies, {len(system.joint_names)} joints{extra}")
        except SceneError as exc:
            bad += 1
            print(f"error  {exc}", file=sys.stderr)
    return 2 if bad else 0


def cmd_list(args) -> int:
    from viz3d.coordinates import ROTATIONS
    from viz3d.forces import FORCES
    from viz3d.formulation import FORMULATIONS
    from viz3d.integrators import INTEGRATORS
    from viz3d.joints import JOINTS
    from viz3d.scene import spec
    from viz3d.scene.schema import describe
    from viz3d.timefunctions import TIME_FUNCTIONS

    if args.format:
        print(describe(spec.SCENE_FILE))
        return 0
    print("scenes:")
    for path in sorted(SCENES_DIR.glob("*.toml")):
        print(f"  {path}  {_description(path)}")
    for title, names in (("integrators", INTEGRATORS), ("formulations", FORMULATIONS), ("rotations", ROTATIONS),
                         ("joints", JOINTS), ("forces", FORCES), ("time functions", TIME_FUNCTIONS)):
        print(f"{title}: {', '.join(names)}")
    return 0


def _description(path: Path) -> str:
    import tomllib

    try:
        return tomllib.loads(path.read_text()).get("scene", {}).get("description", "")
    except (tomllib.TOMLDecodeError, OSError) as exc:
        return f"(unreadable: {exc})"
