"""Command line: turns flags into library calls (no physics here).

Usage::

    viz3d run SCENE [--t-end T] [--dt DT] [--set key.path=value ...] [--out FILE.npz] [--record FILE.rrd] [--view]
    viz3d view SCENE [--host H] [--port P] [--speed S] [--paused] [--record FILE.rrd] [--set ...]
    viz3d replay FILE.rrd
    viz3d bench SCENE --methods LIST (--dt LIST | --tol LIST) [--t-end T] [--out DIR]
    viz3d stability SCENE --methods LIST [--sweep key.path=V1,V2,...] [--t-end T] [--out DIR]
    viz3d check SCENE [SCENE ...]
    viz3d list [--format]

``python -m viz3d`` is the same command.
"""

from __future__ import annotations

import argparse
import os
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
    _set_arg(run)
    run.add_argument("--out", type=Path, help="trajectory file (.npz); default out/<scene>.npz")
    run.add_argument("--no-progress", action="store_true", help="never draw the progress bar")
    run.add_argument("--record", type=Path, metavar="FILE.rrd", help="also write a rerun recording of the run")
    run.add_argument("--view", action="store_true", help="run in the live viewer instead of headless (as `viz3d view`)")
    _viewer_args(run)
    run.set_defaults(func=cmd_run)
    view = sub.add_parser("view", help="animate a scene live in the browser (viser)")
    view.add_argument("scene", type=Path)
    _set_arg(view)
    view.add_argument("--record", type=Path, metavar="FILE.rrd", help="write a rerun recording of the viewed run")
    _viewer_args(view)
    view.set_defaults(func=cmd_view)
    replay = sub.add_parser("replay", help="open a .rrd recording in the rerun viewer")
    replay.add_argument("recording", type=Path)
    replay.add_argument("--web", action="store_true", help="serve the rerun web viewer instead of a native window")
    replay.set_defaults(func=cmd_replay)
    bench = sub.add_parser("bench", help="work-precision benchmark of methods on a scene")
    bench.add_argument("scene", type=Path)
    bench.add_argument("--methods", required=True, help="comma-separated method strings, e.g. rk4,dopri5,ali3p+quaternion")
    bench.add_argument("--dt", help="comma-separated steps [s] for fixed-step methods")
    bench.add_argument("--tol", help="comma-separated relative tolerances for dopri5/dop853")
    _report_args(bench, "bench")
    bench.set_defaults(func=cmd_bench)
    stab = sub.add_parser("stability", help="map where methods fail (largest stable step, failure reasons)")
    stab.add_argument("scene", type=Path)
    stab.add_argument("--methods", default="", help="comma-separated method strings (multibody scenes)")
    stab.add_argument("--sweep", help="key.path=V1,V2,...: find the largest stable step at each value")
    stab.add_argument("--dt", type=float, help="step of the runs without --sweep (default: the scene's)")
    _report_args(stab, "stability")
    stab.set_defaults(func=cmd_stability)
    check = sub.add_parser("check", help="validate scene files (and build them)")
    check.add_argument("scenes", type=Path, nargs="+")
    _set_arg(check)
    check.set_defaults(func=cmd_check)
    lst = sub.add_parser("list", help="list scenes, integrators, formulations, rotations, joints, forces")
    lst.add_argument("--format", action="store_true", help="print the scene file reference instead")
    lst.set_defaults(func=cmd_list)
    return p


def flag_type(check, expected: str | None = None):
    """An argparse ``type=`` that parses a flag's text as a TOML value and checks it with a scene
    checker (``viz3d.scene.schema``), so flags and scene keys share one validation. A bad value
    ends the command with exit code 2 and "argument --flag: expected ..., got ...".
    """
    from viz3d.scene.load import parse_value
    from viz3d.scene.schema import Invalid

    def convert(text: str):
        try:
            return check(parse_value(text))
        except Invalid as exc:
            raise argparse.ArgumentTypeError(f"expected {expected or exc.expected}, got {text!r}") from None

    convert.__name__ = getattr(check, "__name__", "value")
    return convert


def _set_arg(p, help="override a scene value, e.g. --set chain.n=20 --set sim.integrator=heun") -> None:
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY.PATH=VALUE", help=help)


def _report_args(p, kind: str) -> None:
    """Options shared by ``bench`` and ``stability``."""
    p.add_argument("--t-end", type=float, help="simulated duration [s] (default: the scene's)")
    p.add_argument("--out", type=Path, help=f"output directory (default out/{kind}/<scene>)")
    _set_arg(p, "scene overrides applied to every run")


def _floats(text: str | None) -> list[float] | None:
    return None if not text else [float(x) for x in text.split(",")]


def cmd_bench(args) -> int:
    from viz3d.bench import bench, save

    methods = [m.strip() for m in args.methods.split(",")]
    return _report(lambda: bench(args.scene, methods, _floats(args.dt), _floats(args.tol), args.t_end,
                                 overrides=args.overrides),
                   save, args.out or Path("out") / "bench" / args.scene.stem)


def cmd_stability(args) -> int:
    from viz3d.stability import save, stability

    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    return _report(lambda: stability(args.scene, methods, args.sweep, args.dt, args.t_end, overrides=args.overrides),
                   save, args.out or Path("out") / "stability" / args.scene.stem)


def _report(make, save, out: Path) -> int:
    """Run ``make()`` (a bench or stability report), print its table and save it into ``out``."""
    from viz3d.methods import MethodError

    try:
        report = make()
    except (ValueError, MethodError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(report.markdown())
    for path in save(report, out):
        print(f"wrote {path}")
    return 0


def _viewer_args(p) -> None:
    p.add_argument("--host", default="127.0.0.1", help="interface to serve on (default: loopback only)")
    p.add_argument("--port", type=int, default=8080, help="port (0 picks a free one; the real URL is printed)")
    p.add_argument("--speed", type=float, default=1.0, help="simulated seconds per wall-clock second")
    p.add_argument("--paused", action="store_true", help="start paused")
    p.add_argument("--duration", type=float, help="quit after this many wall-clock seconds (scripted use)")


def cmd_run(args) -> int:
    from viz3d.scene.load import load_scene
    from viz3d.simulate import simulate, with_sim

    scene = load_scene(args.scene, args.overrides)
    if args.view:
        return _view(with_sim(scene, t_end=args.t_end, dt=args.dt), args)
    sinks = [_recorder(args.record)] if args.record else []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        traj = simulate(scene, t_end=args.t_end, dt=args.dt, progress=not args.no_progress, sinks=sinks)
    if args.record:
        print(f"recorded    {args.record}  (replay: viz3d replay {args.record})")
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

        fd, name_tmp = tempfile.mkstemp(prefix=f"{name}-", suffix=".npz")
        os.close(fd)
        fallback = Path(name_tmp)
        print(f"error: cannot write {out} ({exc}); the trajectory was saved to {fallback} instead", file=sys.stderr)
        return traj.save(fallback)


def _recorder(path: Path):
    from viz3d.viz.recorder_rerun import RerunRecorder

    return RerunRecorder(path)


def cmd_view(args) -> int:
    from viz3d.scene.load import load_scene

    return _view(load_scene(args.scene, args.overrides), args)


def _view(scene, args) -> int:
    import time

    from viz3d.realtime import SimRunner
    from viz3d.viz.viewer_viser import Viewer

    sinks = [_recorder(args.record)] if args.record else []
    runner = SimRunner(scene, speed=args.speed, playing=not args.paused, sinks=sinks)
    viewer = Viewer(runner, host=args.host, port=args.port)
    url = viewer.start()
    print(f"viz3d viewer: open {url} in a browser  (scene {scene.name}; Ctrl-C to stop)", flush=True)
    try:
        if args.duration is not None:
            time.sleep(args.duration)
        else:
            viewer.wait()
    finally:
        viewer.stop()
        if args.record:
            print(f"recorded {args.record}  (replay: viz3d replay {args.record})")
    return 0


def cmd_replay(args) -> int:
    """Open a recording with the rerun viewer of the pinned rerun-sdk (or print the command)."""
    import os
    import shutil
    import subprocess

    if not args.recording.is_file():
        print(f"error: {args.recording}: no such recording", file=sys.stderr)
        return 2
    rerun = shutil.which("rerun", path=os.pathsep.join([str(Path(sys.executable).parent), os.environ.get("PATH", "")]))
    cmd = [rerun or "rerun", str(args.recording)]
    if args.web:
        cmd += ["--web-viewer", "--bind", "127.0.0.1"]
    has_display = bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")) or sys.platform in ("darwin", "win32")
    if rerun is None or not (has_display or args.web):
        why = "no rerun binary found" if rerun is None else "no display here"
        print(f"{why}; open the recording with the rerun viewer of rerun-sdk {_rerun_version()}:\n  {' '.join(cmd)}\n"
              f"or in a browser:\n  {' '.join(cmd[:2])} --web-viewer --bind 127.0.0.1")
        return 0
    return subprocess.call(cmd)


def _rerun_version() -> str:
    from importlib.metadata import version

    return version("rerun-sdk")


def summary(traj, out: Path) -> str:
    """The run summary printed by ``viz3d run``."""
    meta = traj.scene["run"]
    if meta.get("kind") == "impact":
        return impact_summary(traj, out)
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


def impact_summary(traj, out: Path) -> str:
    """Summary of an impact run: model, events, restitution, peak force, energy ledger."""
    import numpy as np

    meta, x = traj.scene["run"], traj.extras
    e_req = float(x["restitution_requested"])
    req = f"; requested {e_req:g}" if np.isfinite(e_req) else ""
    per = x["contact_restitution"]
    per_txt = ", ".join(f"{e:.4f}" for e in per[:6]) + (", ..." if len(per) > 6 else "")
    scale = float(max(np.max(np.abs(traj.energy_total), initial=0.0), np.max(traj.energy_kinetic, initial=0.0)))
    balance = float(np.max(np.abs(x["energy_balance_error"]))) if traj.t.size else 0.0
    sim_time = float(traj.t[-1]) if traj.t.size else 0.0
    lines = [
        f"scene       {traj.scene['scene']['scene'].get('name', Path(meta['source']).stem)} ({meta['source']})",
        f"method      {meta['integrator']}, rtol = {meta['rtol']:g}; bar: {x['model_choice']}",
        f"steps       {traj.n_steps} ({traj.n_rhs} RHS evaluations), simulated {sim_time:.6g} s",
        f"wall time   {traj.wall_time:.3f} s",
        f"contacts    {int(x['contact_count'])}; peak force {float(np.max(x['contact_force'], initial=0.0)):.4g} N, "
        f"peak indentation {float(np.max(x['penetration'], initial=0.0)):.4g} m",
        f"impactor    {float(x['impactor_velocity'][0]):.4g} -> {float(x['impactor_velocity'][-1]):.4g} m/s along the normal",
        f"restitution {float(x['restitution']):.4f} of the bodies' rigid motion; per contact {per_txt}{req}",
        f"energy      dissipated {float(x['energy_dissipated'][-1]):.4g} J; balance error {balance:.3g} J "
        f"({balance / scale if scale else 0.0:.2g} of the largest energy, {scale:.4g} J)",
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
                scene = load_scene(path, args.overrides)
                what = _check_impact(scene) if scene.kind == "impact" else _check_rigid(build(scene)[0])
            extra = "".join(f"\n  warning: {w.message}" for w in caught)
            print(f"ok     {path}: {what}{extra}")
        except SceneError as exc:
            bad += 1
            print(f"error  {exc}", file=sys.stderr)
    return 2 if bad else 0


def _check_rigid(system) -> str:
    return f"{system.n_bodies} bodies, {len(system.joint_names)} joints"


def _check_impact(scene) -> str:
    from viz3d.impact.build import build_impact

    setup = build_impact(scene)
    target = "rigid wall" if setup.bar is None else f"bar: {setup.model_choice}"
    return f"impact, {scene.data['contact']['law']} contact, {target}"


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
