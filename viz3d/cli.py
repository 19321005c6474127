"""Command line: turns flags into library calls (no physics here).

Usage::

    viz3d run SCENE [--t-end T] [--dt DT] [--set key.path=value ...] [--out FILE.npz] [--record FILE.rrd] [--view]
    viz3d view SCENE [--host H] [--port P] [--speed S] [--paused] [--record FILE.rrd] [--set ...]
    viz3d replay FILE.rrd
    viz3d bench SCENE --methods LIST (--dt LIST | --tol LIST) [--t-end T] [--out DIR]
    viz3d stability SCENE --methods LIST [--sweep key.path=V1,V2,...] [--t-end T] [--out DIR]
    viz3d stowage SCENE [--heel LIST] [--trim LIST] [--ensemble N --perturb KEY=SIZE,... [--seed S]] [--out DIR]
    viz3d sweep SCENE --grid key.path=V1,V2,... [--grid key.path=A:B:N] [--sample key.path=DIST(ARGS) --n N]
                [--metrics LIST] [--out DIR] [--workers N | --scheduler tcp://HOST:8786 [--worker-timeout S]]
    viz3d check SCENE [SCENE ...]
    viz3d list [--format] [--scenes DIR]

Every flag value goes through the same checkers as the scene keys (``viz3d.scene.schema``); bad
input ends with exit code 2 and one message naming the flag or key. SIGTERM is treated like
Ctrl-C: a run stops, keeps and writes what it computed; a study (bench, stability, stowage, sweep)
keeps its finished runs in ``DIR/runs.jsonl`` and the same command started again runs only the rest.

``python -m viz3d`` is the same command.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import tempfile
import threading
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from viz3d.scene.schema import SceneError

#: Where ``viz3d list`` looks for scenes: the current folder's, then the repository's.
SCENES_DIR = Path("scenes")
REPOSITORY_SCENES = Path(__file__).resolve().parents[1] / "scenes"
#: Exit code of a command stopped by Ctrl-C or SIGTERM outside a run (128 + SIGINT, as shells do).
EXIT_INTERRUPTED = 130


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the process exit code (0 ok, 1 failed run, 2 bad input, 130 interrupted)."""
    parser = _parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse printed the usage and "argument --flag: ..." (or the help)
        return int(exc.code or 0)
    if not hasattr(args, "func"):
        parser.print_help()
        return 2
    previous = _terminate_like_interrupt()
    try:
        return args.func(args)
    except SceneError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


#: Signals that interrupted a command of this process (SIGTERM made an interrupt by ``main``).
RECEIVED: list[int] = []


def _terminate_like_interrupt():
    """Make SIGTERM (the default of ``kill`` and ``timeout``) raise ``KeyboardInterrupt`` in the main
    thread, so a run stops the way Ctrl-C stops it: frames kept, files written; noted in
    ``RECEIVED``. Returns the previous handler (None when not on the main thread, where signals
    cannot be set)."""
    if threading.current_thread() is not threading.main_thread():
        return None

    def interrupt(signum, frame):
        RECEIVED.append(signum)
        raise KeyboardInterrupt(f"signal {signum}")

    return signal.signal(signal.SIGTERM, interrupt)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="viz3d", description="Spatial multibody simulation you can watch.")
    sub = p.add_subparsers()
    run = sub.add_parser("run", help="run a scene headless and write its trajectory")
    run.add_argument("scene", type=Path)
    run.add_argument("--t-end", type=_number_flag, help="simulated duration [s] (sim.t_end)")
    run.add_argument("--dt", type=_number_flag,
                     help="integration step [s] (sim.dt; adaptive runs: the interval between frames)")
    _set_arg(run)
    _mesh_dir_arg(run)
    run.add_argument("--out", type=Path, help="trajectory file (.npz); default out/<scene>.npz")
    run.add_argument("--no-progress", action="store_true", help="never draw the progress bar")
    run.add_argument("--record", type=Path, metavar="FILE.rrd", help="also write a rerun recording of the run")
    run.add_argument("--view", action="store_true", help="run in the live viewer instead of headless (as `viz3d view`)")
    _viewer_args(run)
    run.set_defaults(func=cmd_run)
    view = sub.add_parser("view", help="animate a scene live in the browser (viser)")
    view.add_argument("scene", type=Path)
    _set_arg(view)
    _mesh_dir_arg(view)
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
    bench.add_argument("--dt", type=_positive_list("--dt"), help="comma-separated steps [s] for fixed-step methods")
    bench.add_argument("--tol", type=_positive_list("--tol"), help="comma-separated relative tolerances for dopri5/dop853")
    _report_args(bench, "bench")
    _cluster_args(bench, 1, "(default 1: CPU times are measured on an otherwise idle core)")
    bench.set_defaults(func=cmd_bench)
    stab = sub.add_parser("stability", help="map where methods fail (largest stable step, failure reasons)")
    stab.add_argument("scene", type=Path)
    stab.add_argument("--methods", default="", help="comma-separated method strings (multibody scenes)")
    stab.add_argument("--sweep", help="key.path=V1,V2,...: find the largest stable step at each value")
    stab.add_argument("--dt", type=_positive_flag, help="step of the runs without --sweep (default: the scene's)")
    _report_args(stab, "stability")
    _cluster_args(stab)
    stab.set_defaults(func=cmd_stability)
    stow = sub.add_parser("stowage", help="verdict and peak hauling force of a haul over a grid of heel and trim")
    stow.add_argument("scene", type=Path)
    stow.add_argument("--heel", type=_number_list("--heel"), default=[-5.0, 0.0, 5.0], help="ship.heel values [deg]")
    stow.add_argument("--trim", type=_number_list("--trim"), default=[-2.0, 0.0, 2.0], help="ship.trim values [deg]")
    _cluster_args(stow)
    _set_arg(stow)
    _ensemble_args(stow)
    stow.add_argument("--out", type=Path, help="report folder (default out/stowage/<scene>); its runs.jsonl keeps every "
                      "finished run, so the same command started again runs only what is missing")
    stow.set_defaults(func=cmd_stowage)
    _sweep_parser(sub)
    check = sub.add_parser("check", help="validate scene files (and build them)")
    check.add_argument("scenes", type=Path, nargs="+")
    _set_arg(check)
    _mesh_dir_arg(check)
    check.set_defaults(func=cmd_check)
    lst = sub.add_parser("list", help="list scenes, integrators, formulations, rotations, joints, forces")
    lst.add_argument("--format", action="store_true", help="print the scene file reference instead")
    lst.add_argument("--scenes", type=Path, help="folder of scene files to list (default: ./scenes, else the repository's)")
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


def _number_flag(text: str) -> float:
    """A flag's number, any sign: its own range is checked with the scene key it sets (one validation)."""
    from viz3d.scene.schema import number

    return flag_type(number)(text)


def _positive_flag(text: str) -> float:
    from viz3d.scene.schema import positive

    return flag_type(positive)(text)


def _positive_list(flag: str):
    """``type=`` of a comma-separated list of positive numbers (``--dt 1e-3,5e-4``)."""
    from viz3d.scene.schema import positive

    return _list_of(flag_type(positive))


def _number_list(flag: str):
    """``type=`` of a comma-separated list of numbers (``--heel -5,0,5``)."""
    from viz3d.scene.schema import number

    return _list_of(flag_type(number))


def _list_of(check):
    """``type=`` of a comma-separated list of values each passing ``check``."""

    def convert(text: str) -> list[float]:
        return [check(x.strip()) for x in text.split(",") if x.strip()] or check("")

    return convert


def _mesh_dir_arg(p) -> None:
    p.add_argument("--mesh-dir", dest="mesh_dirs", action="append", default=[], type=Path, metavar="DIR",
                   help="also allow mesh files from this folder (scenes may only read files below their own folder)")


def _set_arg(p, help="override a scene value, e.g. --set chain.n=20 --set sim.integrator=heun") -> None:
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY.PATH=VALUE", help=help)


def _report_args(p, kind: str) -> None:
    """Options shared by ``bench`` and ``stability``."""
    from viz3d.scene.schema import positive

    p.add_argument("--t-end", type=flag_type(positive), help="simulated duration [s] (default: the scene's)")
    p.add_argument("--out", type=Path, help=f"output directory (default out/{kind}/<scene>); its runs.jsonl keeps "
                   "every finished run, so the same command started again runs only what is missing")
    _set_arg(p, "scene overrides applied to every run")


def cmd_bench(args) -> int:
    from viz3d.bench import bench, save

    methods = [m.strip() for m in args.methods.split(",")]
    out = _writable_dir(args.out or Path("out") / "bench" / args.scene.stem, "bench")
    return _report(lambda: bench(args.scene, methods, args.dt, args.tol, args.t_end, overrides=args.overrides,
                                 cluster=_cluster(args), out=out), save, out)


def cmd_stability(args) -> int:
    from viz3d.stability import save, stability

    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    out = _writable_dir(args.out or Path("out") / "stability" / args.scene.stem, "stability")
    return _report(lambda: stability(args.scene, methods, args.sweep, args.dt, args.t_end, overrides=args.overrides,
                                     cluster=_cluster(args), out=out), save, out)


def _cluster_args(p, default: int | None = None, why: str = "(default: one per core)") -> None:
    """``--workers``, ``--scheduler`` and ``--worker-timeout`` of the studies (``viz3d.studies.execute.Cluster``)."""
    from viz3d.scene.schema import positive, positive_int
    from viz3d.studies import WORKER_TIMEOUT

    p.add_argument("--workers", type=flag_type(positive_int), default=default,
                   help=f"local worker processes {why}; 1 runs in this process")
    p.add_argument("--scheduler", metavar="tcp://HOST:8786", help="run on this existing Dask scheduler's workers instead")
    p.add_argument("--worker-timeout", type=flag_type(positive), default=WORKER_TIMEOUT, metavar="SECONDS",
                   help=f"with --scheduler: stop with an error once the scheduler has had no worker for this long "
                        f"(default {WORKER_TIMEOUT:g} s); finished runs stay in the results store")


def _cluster(args):
    from viz3d.studies.execute import Cluster, local_cores

    return Cluster(args.workers or local_cores(), args.scheduler, args.worker_timeout)


def _report(make, save, out: Path) -> int:
    """Run ``make()`` (a bench, stability or stowage report), print its table and save it into ``out``
    (into a temporary folder if ``out`` cannot be written: a computed report is never lost). Ctrl-C
    keeps the finished runs in ``out``'s results store."""
    from viz3d.methods import MethodError
    from viz3d.studies.execute import STORE_NAME

    try:
        report = make()
    except (ValueError, MethodError, ConnectionError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"interrupted: finished runs are kept in {out / STORE_NAME}; the same command runs only the missing ones",
              file=sys.stderr)
        return EXIT_INTERRUPTED
    print(report.markdown())
    try:
        paths = save(report, out)
    except OSError as exc:
        fallback = Path(tempfile.mkdtemp(prefix="viz3d-report-"))
        print(f"error: cannot write the report into {out} ({exc}); writing it into {fallback} instead", file=sys.stderr)
        paths = save(report, fallback)
    for path in paths:
        print(f"wrote {path}")
    return 0


def _writable_dir(out: Path, kind: str) -> Path:
    """``out`` if a file can be created in it, else a new temporary folder (said at once, before
    any computing, so nothing computed is lost to an unwritable path)."""
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out):
            pass
        return out
    except OSError as exc:
        fallback = Path(tempfile.mkdtemp(prefix=f"viz3d-{kind}-"))
        print(f"error: cannot write into {out} ({exc}); the {kind} report will be written into {fallback}",
              file=sys.stderr)
        return fallback


def _writable_file(path: Path, suffix: str) -> Path:
    """``path`` if it can be created, else a new temporary file with ``suffix`` (said at once)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        existed = path.exists()
        with open(path, "ab"):
            pass
        if not existed:
            path.unlink()
        return path
    except OSError as exc:
        fd, name = tempfile.mkstemp(prefix=f"{path.stem}-", suffix=suffix)
        os.close(fd)
        print(f"error: cannot write {path} ({exc}); writing {name} instead", file=sys.stderr)
        return Path(name)


def _viewer_args(p) -> None:
    from viz3d.scene.schema import positive

    p.add_argument("--host", default="127.0.0.1", help="interface to serve on (default: loopback only)")
    p.add_argument("--port", type=flag_type(port_number), default=8080,
                   help="port (0 picks a free one; a busy one is replaced by the next free one; the real URL is printed)")
    p.add_argument("--speed", type=flag_type(positive),
                   help="simulated seconds per wall-clock second (default: the scene's [display] speed, else 1)")
    p.add_argument("--paused", action="store_true", help="stay paused when the browser connects")
    p.add_argument("--duration", type=flag_type(positive), help="quit after this many wall-clock seconds (scripted use)")


def port_number(x):
    """Scene-checker style (``viz3d.scene.schema``) check of a TCP port: an integer 0..65535."""
    from viz3d.scene.schema import Invalid

    if isinstance(x, bool) or not isinstance(x, int) or not 0 <= x <= 65535:
        raise Invalid("an integer 0..65535")
    return x


def _ensemble_args(p) -> None:
    """``--ensemble``, ``--perturb`` and ``--seed`` of ``viz3d stowage`` (``viz3d.studies.ensemble``)."""
    from viz3d.scene.schema import nonnegative_int
    from viz3d.studies import STOWAGE_PERTURBATIONS as PERTURBATIONS

    p.add_argument("--ensemble", type=int, metavar="N", help="N perturbed runs (members) per grid point: the "
                   "report gives per point the verdict counts, the fraction seated with its 95 %% Wilson interval "
                   "and the peak force's min/median/max (default: one unperturbed run)")
    p.add_argument("--perturb", action="append", default=[], metavar="KEY=SIZE,...",
                   help="what the members perturb, each uniformly within +-SIZE: relative (0 < SIZE < 1) for "
                   + ", ".join(k for k, (kind, _) in PERTURBATIONS.items() if kind == "relative")
                   + "; absolute for " + ", ".join(f"{k} [{u}]" for k, (kind, u) in PERTURBATIONS.items()
                                                   if kind == "absolute"))
    p.add_argument("--seed", type=flag_type(nonnegative_int), default=0, help="seed of the members' draws (default 0); "
                   "member m draws the same perturbations at every grid point and in an ensemble of any size")


def cmd_stowage(args) -> int:
    from viz3d.stowagestudy import save, stowage_study
    from viz3d.studies import STOWAGE_PERTURBATIONS
    from viz3d.studies.ensemble import parse_ensemble
    from viz3d.studies.plan import PlanError

    try:
        n = 1 if args.ensemble is None else args.ensemble
        ensemble = (parse_ensemble(n, args.perturb, STOWAGE_PERTURBATIONS, args.seed)
                    if args.ensemble is not None or args.perturb else None)
    except PlanError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    out = _writable_dir(args.out or Path("out") / "stowage" / args.scene.stem, "stowage")
    grid = {"ship.heel": args.heel, "ship.trim": args.trim}
    return _report(lambda: stowage_study(args.scene, grid, args.overrides, cluster=_cluster(args), out=out,
                                         ensemble=ensemble), save, out)


def _sweep_parser(sub) -> None:
    from viz3d.scene.schema import nonnegative_int, positive_int

    sw = sub.add_parser("sweep", help="run a scene over a grid or a random sample of --set values (Dask: local cores "
                                      "or a cluster)")
    sw.add_argument("scene", type=Path)
    sw.add_argument("--grid", action="append", default=[], metavar="KEY.PATH=V1,V2,...",
                    help="a grid axis: listed values, or A:B:N (A:B:N:log) for N values from A to B; axes multiply")
    sw.add_argument("--sample", action="append", default=[], metavar="KEY.PATH=DIST(ARGS)",
                    help="a sampled key: uniform(a,b), loguniform(a,b), normal(mean,std), int(a,b), choice(v1,v2,...)")
    sw.add_argument("--n", type=flag_type(positive_int), help="number of draws of --sample (default 20)")
    sw.add_argument("--seed", type=flag_type(nonnegative_int), default=0, help="seed of the draws (default 0)")
    sw.add_argument("--metrics", help="comma-separated table columns after the keys (default status,energy_drift_rel,"
                    "max_constraint_violation): "
                    "status, t_final, energy_drift_rel, energy_drift, max_constraint_violation or a scalar extra of the "
                    "scene (e.g. restitution); the first numeric one is charted")
    sw.add_argument("--out", type=Path, help="study folder (default out/sweep/<scene>); its runs.jsonl keeps every "
                    "finished run, so the same command started again runs only what is missing")
    sw.add_argument("--max-runs", type=flag_type(positive_int), help="run at most this many new points, then stop")
    sw.add_argument("--no-progress", action="store_true", help="never draw the progress line")
    _cluster_args(sw)
    _set_arg(sw, "scene overrides applied to every run")
    _mesh_dir_arg(sw)
    sw.set_defaults(func=cmd_sweep)


def cmd_sweep(args) -> int:
    from viz3d.scene.load import kind_of_file
    from viz3d.studies.plan import PlanError
    from viz3d.studies.execute import STORE_NAME
    from viz3d.sweep import save, sweep

    try:
        keys, points, metrics = _sweep_plan(args)
    except PlanError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if kind_of_file(args.scene) != "multibody":
        raise SceneError(str(args.scene), "", "a multibody scene (viz3d sweep runs viz3d.simulate on each point)")
    out = _writable_dir(args.out or Path("out") / "sweep" / args.scene.stem, "sweep")
    try:
        report = sweep(args.scene, keys, points, metrics, _cluster(args), out, args.overrides, args.mesh_dirs,
                       progress=not args.no_progress, max_runs=args.max_runs)
    except KeyboardInterrupt:
        print(f"interrupted: finished runs are kept in {out / STORE_NAME}; the same command runs only the missing ones",
              file=sys.stderr)
        return EXIT_INTERRUPTED
    except ConnectionError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    refused = [o for o in report.outcomes if o.key is None]
    if len(refused) == len(report.outcomes):
        print(f"error: every point was refused; the first: {refused[0].row['status']}", file=sys.stderr)
        return 2
    print(report.markdown())
    for name in report.missing_metrics():
        print(f"warning: --metrics {name}: no run has it (a typo, or not a scalar summary of this scene)", file=sys.stderr)
    for path in save(report, out) + [out / STORE_NAME]:
        print(f"wrote {path}")
    return 0


def _sweep_plan(args):
    """(keys, points, metrics) of ``viz3d sweep``'s flags; ``PlanError`` naming a bad flag."""
    from viz3d.studies.plan import PlanError, parse_grid, parse_sample, plan_points
    from viz3d.sweep import DEFAULT_METRICS

    axes = [parse_grid(g) for g in args.grid]
    samples = [parse_sample(s) for s in args.sample]
    if not axes and not samples:
        raise PlanError("--grid", "at least one --grid or --sample", "")
    if args.n is not None and not samples:
        raise PlanError("--n", "a --sample to draw from", str(args.n))
    text = args.metrics if args.metrics is not None else ",".join(DEFAULT_METRICS)
    metrics = tuple(m.strip() for m in text.split(",") if m.strip())
    if not metrics or any(not m.isidentifier() for m in metrics):
        raise PlanError("--metrics", "comma-separated metric names (e.g. status,energy_drift_rel)", text)
    keys, points = plan_points(axes, samples, args.n or 20, args.seed)
    return keys, points, metrics


def cmd_run(args) -> int:
    from viz3d.scene.load import load_scene

    scene = load_scene(args.scene, args.overrides, mesh_dirs=args.mesh_dirs)
    return SCENE_KINDS[scene.kind].run(scene, args)


def _run_multibody(scene, args) -> int:
    from viz3d.interrupts import InterruptGuard
    from viz3d.scene.load import with_sim
    from viz3d.simulate import check_methods, simulate

    scene = with_sim(scene, t_end=args.t_end, dt=args.dt)
    if args.view:
        return _view(scene, args)
    record = _writable_file(args.record, ".rrd") if args.record else None
    check_methods(scene)  # refused before the run is announced
    print(run_header(scene), flush=True)
    sinks = [_recorder(record)] if record else []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        traj = simulate(scene, progress=not args.no_progress, sinks=sinks)
    if record:
        print(f"recorded    {record}  (replay: viz3d replay {record})")
    for w in caught:
        print(f"warning: {w.message}", file=sys.stderr)
    with InterruptGuard() as guard, guard.held():  # the computed run is written whole, then interrupted
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

    scene = load_scene(args.scene, args.overrides, mesh_dirs=args.mesh_dirs)
    return SCENE_KINDS[scene.kind].view(scene, args)


def _address_refused(args) -> bool:
    """True (the error printed, naming the flag) if the viewer cannot serve on ``--host``/``--port``:
    refused before anything starts."""
    from viz3d.viz.viewer_viser import ServeError, check_address

    try:
        check_address(args.host, args.port)
    except ServeError as exc:
        print(f"error: argument {exc.flag}: {exc}", file=sys.stderr)
        return True
    return False


def _view(scene, args) -> int:
    """Serve ``scene`` live; the run starts when the first browser connects. An address that
    cannot be served is refused before anything starts (exit code 2, nothing left running)."""
    from viz3d.realtime import SimRunner
    from viz3d.viz.viewer_viser import ServeError, Viewer

    if _address_refused(args):
        return 2
    record = _writable_file(args.record, ".rrd") if args.record else None
    runner = SimRunner(scene, speed=args.speed, playing=not args.paused, sinks=[_recorder(record)] if record else [])
    try:
        viewer = Viewer(runner, host=args.host, port=args.port)
    except ServeError as exc:  # lost a race for the address since the check
        runner.stop()
        print(f"error: argument {exc.flag}: {exc}", file=sys.stderr)
        return 2
    url = viewer.start()
    busy = f"; port {args.port} is busy" if args.port and viewer.port != args.port else ""
    start = "it stays paused until Play" if args.paused else "the run starts when a browser connects"
    print(f"viz3d viewer: open {url} in a browser{busy}  (scene {scene.name}, speed {runner.speed:g}x; {start}; "
          f"Ctrl-C to stop)", flush=True)
    try:
        viewer.wait(args.duration)
    finally:
        viewer.stop()
        if record:
            print(f"recorded {record}  (replay: viz3d replay {record})")
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


def run_header(scene) -> str:
    """The line ``viz3d run`` prints before it builds and runs (so a long run says what it does)."""
    sim = scene.data["sim"]
    if "rtol" in sim:
        events = " with contact events" if scene.data["contacts"] else ""
        how = (f"adaptive {sim['integrator']}{events}, rtol = {sim['rtol']:g}, "
               f"output every {sim.get('output_dt', sim['dt']):g} s")
    else:
        import math

        how = f"{math.ceil(sim['t_end'] / sim['dt'] - 1e-9)} steps of {sim['integrator']}, dt = {sim['dt']:g} s"
    return f"running     {scene.name} to t = {sim['t_end']:g} s: {how}"


def summary(traj, out: Path) -> str:
    """The run summary printed by ``viz3d run`` (with contact, restitution and ledger lines when
    the scene has contacts)."""
    meta = traj.scene["run"]
    sim_time = float(traj.t[-1] - traj.t[0]) if traj.t.size else 0.0
    rtf = sim_time / traj.wall_time if traj.wall_time > 0 else float("inf")
    sim = traj.scene["scene"]["sim"]
    step = f"rtol = {sim['rtol']:g}" if "rtol" in sim else f"dt = {meta['dt']:g} s"
    x = traj.extras
    lines = [
        f"scene       {traj.scene['scene']['scene'].get('name', Path(meta['source']).stem)} ({meta['source']})",
        f"method      {meta['integrator']}, {step}, {meta['formulation']}, {meta['rotation']}",
        f"bodies      {len(traj.body_names)}, joints {len(traj.joint_names)}"
        + (f"; {x['model_choice']}" if str(x.get("model_choice", "rigid bodies")) != "rigid bodies" else "")
        + _departure_text(traj),
        f"steps       {traj.n_steps} ({traj.n_rhs} RHS evaluations), simulated {sim_time:.6g} s",
        f"wall time   {traj.wall_time:.3f} s, real-time factor {rtf:.3g}, "
        f"{1e6 * traj.wall_time / max(traj.n_steps, 1):.1f} us/step",
        *(contact_lines(traj) if "approach_velocity" in x else [_energy_line(traj, meta)]),
        f"constraints max |C| = {traj.max_constraint_violation:.3e} m",
        f"charts      {int(traj.chart_switches.sum())} Euler-chart switches",
        f"kernel      {meta.get('kernel', 'n/a')}",
        *_stowage_lines(x),
        f"status      {traj.status}",
        f"wrote       {out}",
    ]
    return "\n".join(lines)


def _departure_text(traj) -> str:
    """How many bodies left the run (``viz3d.departures``: NaN poses from then on), and when."""
    import numpy as np

    if not traj.t.size:
        return ""
    gone = np.isnan(traj.position[:, :, 0])
    left = np.flatnonzero(gone[-1])
    if not left.size:
        return ""
    when = traj.t[np.argmax(gone[:, left], axis=0)]
    return (f"; {left.size} left the run (t = {when.min():.4g}-{when.max():.4g} s), "
            f"{len(traj.body_names) - left.size} at the end")


def _stowage_lines(x: dict) -> list[str]:
    """The haul's verdict and the generator's chain choice (``[stowage]`` scenes), else nothing."""
    if "stowage_verdict" not in x:
        return []
    lines = [f"verdict     {x['stowage_verdict']} at t = {float(x['stowage_time']):.3f} s ({x['stowage_reason']}); peak "
             f"hauling force {float(x['stowage_peak_force']) / 1e3:.1f} kN; at the end "
             f"{float(x['stowage_position_error']):.3f} m, {float(x['stowage_angle_error']):.2f} deg from stowed"]
    if "stowage_simulated_links" in x:
        lines.append(f"chain       {int(x['stowage_simulated_links'])} simulated links of "
                     f"{int(x['stowage_real_links_each'])} real link(s) each (pitch {float(x['stowage_pitch']):.3f} m, "
                     f"{float(x['stowage_real_link_mass']):.1f} kg), haul {float(x['stowage_haul']):.2f} m")
    return lines


def contact_lines(traj) -> list[str]:
    """Contacts as the physics defines them (with what the model cannot resolve), the bodies'
    approach velocity and restitution, peak force, and the energy ledger."""
    import numpy as np

    x = traj.extras
    e_req = float(x["restitution_requested"])
    req = f"; requested {e_req:g}" if np.isfinite(e_req) else ""
    per = x["contact_restitution"]
    per_txt = ", ".join(f"{e if abs(e) >= 5e-5 else 0.0:.4f}" for e in per[:6]) + (", ..." if len(per) > 6 else "")
    scale = float(max(np.max(np.abs(traj.energy_total), initial=0.0), np.max(traj.energy_kinetic, initial=0.0)))
    balance = float(np.max(np.abs(x["energy_balance_error"]))) if traj.t.size else 0.0
    tau = float(x.get("contact_resolution", 0.0))
    breaks, touches = int(np.sum(x.get("contact_breaks_unresolved", 0))), len(x.get("contact_touches_unresolved", ()))
    unresolved = (f" ({breaks} breaks and {touches} touches shorter than {tau * 1e6:.3g} us, the period of the model's "
                  f"highest mode, which it cannot resolve: Gibbs ringing of the truncated modes, merged or left out)"
                  if breaks or touches else "")
    dv, de = float(x.get("relative_velocity_uncertainty", 0.0)), float(x.get("restitution_uncertainty", np.nan))
    v = np.asarray(x["approach_velocity"], float)
    name = str(x["contact_names"][0])
    v_txt = ""
    speeds = np.asarray(x.get("impact_speeds", np.zeros((0, 2))), float).reshape(-1, 2)
    if v.size:
        v_end = -float(v[-1, 0])
        v_start = float(speeds[0, 0]) if len(speeds) else float(v[0, 0])  # approaching the first contact
        v_txt = f"{v_start:.4g} -> {v_end:.4g}" + (f" +- {dv:.2g}" if dv > 0 else "") + " m/s apart"
        if dv > 0:
            v_txt += (" (+-: velocity jumps of instantaneous impulses on the modal body, shorter than it can resolve"
                      + ("; the sign of the final motion is not resolved)" if abs(v_end) < dv else ")"))
    e_txt = f"{float(x['restitution']):.4f}" + (f" +- {de:.2g}" if np.isfinite(de) and de > 0 else "")
    if len(speeds) and not speeds[0, 0] > 0.0:  # a body resting on its contacts from the start: no impact
        v_txt = f"started in contact at rest, {v_end:.4g} m/s apart at the end" if v.size else "started in contact at rest"
        e_txt = "none (the first contact started at rest: not an impact)"
    elif len(speeds):
        e_txt += (f" of the bodies' rigid motion (impact 1 of {len(speeds)}: approaching at {speeds[0, 0]:.4g} m/s "
                  f"before its first contact, {-speeds[0, 1]:.4g} m/s apart after its last)")
    else:
        e_txt += " (no contact)"
    return [
        f"contacts    {int(x['contact_count'])}{unresolved}; peak force "
        f"{float(np.max(x['contact_force'], initial=0.0)):.4g} N, "
        f"peak indentation {float(np.max(x['penetration'], initial=0.0)):.4g} m",
        f"approach    {name}: {v_txt} along the normal (centres of mass)",
        f"restitution {e_txt}; per contact {per_txt}{req}",
        f"energy      dissipated {float(x['energy_dissipated'][-1]):.4g} J; balance error {balance:.3g} J "
        f"({balance / scale if scale else 0.0:.2g} of the largest energy, {scale:.4g} J)",
    ]


def _energy_line(traj, meta) -> str:
    import numpy as np

    x = traj.extras
    if "energy_balance_error" in x and traj.t.size:  # the ledger of a driven scene
        work, lost = float(x["energy_work_in"][-1]), float(x["energy_dissipated"][-1])
        balance = float(np.max(np.abs(x["energy_balance_error"])))
        scale = max(abs(work), lost, float(np.max(np.abs(traj.energy_total - traj.energy_total[0]))))
        return (f"energy      work in {work:.4g} J, dissipated {lost:.4g} J; balance error {balance:.3g} J "
                f"({balance / scale if scale else 0.0:.2g} of the work in or the change)")
    if meta.get("conservative", True):
        return f"energy      drift max |E - E0| = {traj.energy_drift:.3e} J ({traj.energy_drift_rel:.3e} of max kinetic)"
    return (f"energy      change max |E - E0| = {traj.energy_drift:.3e} J (not conserved: the scene has dampers, "
            f"applied loads, motors, drives or dissipative contacts)")


def cmd_check(args) -> int:
    from viz3d.scene.load import load_scene

    bad = 0
    for path in args.scenes:
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                scene = load_scene(path, args.overrides, mesh_dirs=args.mesh_dirs)
                what = SCENE_KINDS[scene.kind].check(scene)
            extra = "".join(f"\n  warning: {w.message}" for w in caught)
            print(f"ok     {path}: {what}{extra}")
        except SceneError as exc:
            bad += 1
            print(f"error: {exc}", file=sys.stderr)
    return 2 if bad else 0


def _check_built(scene) -> str:
    """What ``scene`` builds, built on the NumPy path (``sim.compiled = false``): its initial projection
    then raises the diagnoses a run's kernel projection hands on to it, and no compiled kernel is
    loaded, nor compiled on a cold numba cache (minutes) only to be checked."""
    from dataclasses import replace

    from viz3d.scene.build import build

    numpy_path = {**scene.data, "sim": {**scene.data["sim"], "compiled": False}}
    system = build(replace(scene, data=numpy_path))[0]
    what = f"{system.n_bodies} bodies, {len(system.joint_names)} joints"
    if scene.data["contacts"]:
        what += f", {len(scene.data['contacts'])} contacts ({', '.join(c['law'] for c in scene.data['contacts'])})"
    for fb in system.bodies.flexible:
        what += f"; {system.bodies.names[fb.index]}: {fb.model_choice}"
    return what


def cmd_list(args) -> int:
    from viz3d.contact.collision import GEOMETRIES
    from viz3d.contact.friction import FRICTION_LAWS
    from viz3d.contact.laws import NORMAL_LAWS
    from viz3d.coordinates import ROTATIONS
    from viz3d.forces import FORCES
    from viz3d.formulation import FORMULATIONS
    from viz3d.integrators import INTEGRATORS
    from viz3d.joints import DRIVES, JOINTS
    from viz3d.scene import format_reference
    from viz3d.timefunctions import TIME_FUNCTIONS

    if args.format:
        print(format_reference())
        return 0
    folder = scenes_folder(args.scenes)
    if folder is None:
        print(f"scenes: none in {SCENES_DIR.resolve()} (run from the repository root, or pass --scenes DIR: the "
              f"repository's scenes/ folder)")
    else:
        print(f"scenes ({folder}):")
        for path in sorted(folder.glob("*.toml")):
            print(f"  {path.stem:<28} {_description(path)}")
    for title, names in (("integrators", INTEGRATORS), ("formulations", FORMULATIONS), ("rotations", ROTATIONS),
                         ("joints", JOINTS), ("drives", DRIVES), ("forces", FORCES), ("contact laws", NORMAL_LAWS),
                         ("friction laws", FRICTION_LAWS), ("collision shapes", GEOMETRIES),
                         ("time functions", TIME_FUNCTIONS)):
        print(f"{title}: {', '.join(names)}")
    return 0


def scenes_folder(given: Path | None) -> Path | None:
    """The folder ``viz3d list`` shows: ``given``, else ./scenes, else the repository's (an
    editable install), else None."""
    for folder in ([given] if given is not None else [SCENES_DIR, REPOSITORY_SCENES]):
        if folder.is_dir() and any(folder.glob("*.toml")):
            return folder
    return None


def _description(path: Path) -> str:
    import tomllib

    try:
        return tomllib.loads(path.read_text()).get("scene", {}).get("description", "")
    except (tomllib.TOMLDecodeError, OSError) as exc:
        return f"(unreadable: {exc})"


# ---------------------------------------------------------------- hydrodynamics scenes ([reservoir])


def _run_hydro(scene, args) -> int:
    """``viz3d run`` of a dam-reservoir study: arrays (.npz), charts, summary, optional recording."""
    from viz3d import hydrostudy
    from viz3d.interrupts import InterruptGuard

    _refuse_flags(scene, args, {"t_end": "--t-end", "dt": "--dt"})
    if args.view:
        return _view_hydro(scene, args)
    record = _writable_file(args.record, ".rrd") if args.record else None
    print(f"running     {scene.name}: dam-reservoir hydrodynamics (viz3d.hydro)", flush=True)
    result = hydrostudy.run(scene)
    with InterruptGuard() as guard, guard.held():  # the computed study is written whole, then interrupted
        paths = _save_hydro(result, args.out or Path("out") / f"{scene.name}.npz")
        if record:
            paths.append(_record_hydro(result, record))
        print(hydrostudy.summary(result, paths))
    return 0 if result.status == "ok" else 1


def _refuse_flags(scene, args, flags: dict) -> None:
    """A multibody flag given to a scene that has no use for it: ``SceneError`` naming the flag."""
    for key, flag in flags.items():
        if getattr(args, key, None) is not None:
            raise SceneError(scene.source(), flag, f"no {flag} for a {scene.kind} scene (it has no time steps; "
                             "see docs/hydro.md for its keys)", getattr(args, key))


def _save_hydro(result, out: Path) -> list[Path]:
    """Save the study; if ``out`` cannot be written, into a temporary folder (never lose a computed study)."""
    from viz3d import hydrostudy

    try:
        return hydrostudy.save(result, out)
    except OSError as exc:
        fallback = Path(tempfile.mkdtemp(prefix=f"viz3d-{result.model.name}-")) / out.name
        print(f"error: cannot write {out} ({exc}); writing into {fallback.parent} instead", file=sys.stderr)
        return hydrostudy.save(result, fallback)


def _record_hydro(result, path: Path) -> Path:
    """The recording of a study: the earthquake with a dam and a record, else the harmonic cycle at view.omega."""
    from viz3d import hydrostudy
    from viz3d.viz.hydro_recorder import write_recording

    model = result.model
    frames = (hydrostudy.earthquake_frames(model) if model.dam is not None and model.record is not None
              else hydrostudy.harmonic_frames(model, model.view.omega))
    return write_recording(path, result, frames)


def _view_hydro(scene, args) -> int:
    """``viz3d view`` of a dam-reservoir study (the reservoir section animated live)."""
    from viz3d import hydrostudy
    from viz3d.viz.hydro_viewer import HydroViewer
    from viz3d.viz.viewer_viser import ServeError

    if _address_refused(args):
        return 2
    record = _writable_file(args.record, ".rrd") if args.record else None
    result = hydrostudy.run(scene)
    if record:
        print(f"recorded {_record_hydro(result, record)}  (replay: viz3d replay {record})")
    try:
        viewer = HydroViewer(result, host=args.host, port=args.port, speed=args.speed or 1.0, playing=not args.paused)
    except ServeError as exc:
        print(f"error: argument {exc.flag}: {exc}", file=sys.stderr)
        return 2
    url = viewer.start()
    print(f"viz3d viewer: open {url} in a browser  (scene {scene.name}, dam-reservoir hydrodynamics; Ctrl-C to stop)",
          flush=True)
    try:
        viewer.wait(args.duration)
    finally:
        viewer.stop()
    return 0


def _check_hydro(scene) -> str:
    """What ``viz3d check`` reports of a dam-reservoir study (its models built, nothing computed)."""
    from viz3d.scene.hydro import hydro_model

    model = hydro_model(scene)
    water = model.reservoir
    what = (f"reservoir h = {water.depth:g} m, "
            + (f"c = {water.sound_speed:g} m/s" if water.compressible else "incompressible")
            + ("" if water.rigid_bottom else f", alpha = {water.reflection:g}"))
    if model.dam is not None:
        what += f"; dam {model.dam.height:g} m, {model.dam.n_modes} modes (omega_1 empty {model.dam.omega.min():.4g} rad/s)"
    if model.record is not None:
        what += f"; record {Path(model.record.name).name} ({model.record.acceleration.size} samples)"
    return what


@dataclass(frozen=True)
class SceneKind:
    """What ``run``, ``view`` and ``check`` do with a scene of one kind (``Scene.kind``)."""

    run: Callable
    view: Callable
    check: Callable


SCENE_KINDS = {
    "multibody": SceneKind(_run_multibody, _view, _check_built),
    "hydro": SceneKind(_run_hydro, _view_hydro, _check_hydro),
}
