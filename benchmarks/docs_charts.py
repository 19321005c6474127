"""Generate the speed-against-accuracy charts and tables of the shipped scenes into docs/charts/.

    .venv/bin/python benchmarks/docs_charts.py            # all of them (a few minutes)
    .venv/bin/python benchmarks/docs_charts.py heavy_top  # the ones whose name contains this

Each entry is one ``viz3d bench`` or ``viz3d stability`` run (the same functions the CLI calls);
it writes ``docs/charts/<name>/`` (chart, Markdown table, CSV) and ``docs/charts/README.md``
collects the tables with the command that reproduces each one. Numbers are CPU times of this
machine: compare ratios within one chart, not absolute times across machines.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from viz3d import bench as B
from viz3d import stability as S

ROOT = Path(__file__).resolve().parents[1]
SCENES, OUT = ROOT / "scenes", ROOT / "docs" / "charts"

#: name -> (kind, scene, arguments of viz3d.bench.bench / viz3d.stability.stability, what it shows)
CHARTS = {
    "heavy_top_work_precision": ("bench", "heavy_top", dict(
        methods=["rk4", "heun", "dopri5", "dop853", "trapezoidal", "gen_alpha", "ali3p"],
        dts=[4e-3, 2e-3, 1e-3, 5e-4], tols=[1e-5, 1e-7, 1e-9, 1e-11], t_end=1.0),
        "symmetric top on a ball joint, 1 s: error of the body points against CPU time"),
    "double_pendulum_work_precision": ("bench", "double_pendulum", dict(
        methods=["rk4", "rk4+baumgarte", "rk4+projection", "dop853", "trapezoidal", "ali3p", "penalty"],
        dts=[4e-3, 2e-3, 1e-3, 5e-4], tols=[1e-6, 1e-8, 1e-10], t_end=1.0),
        "two bodies on ball joints, 1 s: formulations of the constraints"),
    "torque_free_work_precision": ("bench", "torque_free", dict(
        methods=["rk4", "rk4+quaternion", "dopri5", "dop853", "gen_alpha"],
        dts=[2e-3, 1e-3, 5e-4, 2.5e-4], tols=[1e-6, 1e-8, 1e-10], t_end=3.0),
        "Dzhanibekov flip, 3 s: rotation parametrizations and integrators"),
    "stiff_contact_stable_step": ("stability", "stiff_contact", dict(
        methods=["rk4", "trapezoidal", "gen_alpha"], sweep="contacts.floor.stiffness=1e6,1e7,1e8,1e9,1e10,2.2e10",
        t_end=0.1),
        "largest stable step against Hertz contact stiffness (ball dropped 5 mm)"),
    "stiff_contact_stable_step_whole_run": ("stability", "stiff_contact", dict(
        methods=["rk4", "trapezoidal", "gen_alpha"], sweep="contacts.floor.stiffness=1e6,1e8,1e10"),
        "the same over the scene's whole 0.2 s (several bounces): what a step spanning each onset adds accumulates"),
    "stiff_spring_stable_step": ("stability", "stiff_spring", dict(
        methods=["rk4", "trapezoidal", "gen_alpha", "ali3p"], sweep="forces.spring.stiffness=1e4,1e5,1e6,1e7,1e8",
        t_end=0.5),
        "largest stable step against spring stiffness (1 kg block swinging on the spring)"),
    "top_through_vertical_rotations": ("stability", "top_through_vertical", dict(
        methods=["rk4+euler_zxz", "dopri5+euler_zxz", "rk4+euler_switching", "rk4+quaternion", "gen_alpha+quaternion"],
        dt=5e-4, t_end=1.0),
        "through theta = 0: plain Euler angles against chart switching and quaternions"),
    "chain_constraint_drift": ("stability", "chain", dict(
        methods=["rk4", "rk4+baumgarte", "rk4+projection", "penalty", "ali3p"], dt=2e-3, t_end=3.0,
        overrides=["chain.n=5"]),
        "5-link chain, 3 s: constraint drift with and without stabilization"),
    "clamped_bar_modes": ("stability", "impact_clamped_bar", dict(
        methods=[], sweep="bar.modes=1,2,4,8,16,32,60"),
        "rigid mass on a clamped bar (thesis 4.5): too few modes miss the second contact"),
    "free_bar_modes": ("stability", "impact_free_bar", dict(
        methods=[], sweep="bar.modes=1,2,4,8,16,32,80"),
        "rigid mass on a free bar: restitution against the number of modes (exact 0.7293)"),
}


def command(kind: str, scene: str, args: dict) -> str:
    """The CLI command equivalent to one entry."""
    parts = [f"viz3d {kind} scenes/{scene}.toml"]
    if args.get("methods"):
        parts.append("--methods " + ",".join(args["methods"]))
    for key, flag in (("dts", "--dt"), ("tols", "--tol")):
        if args.get(key):
            parts.append(f"{flag} " + ",".join(f"{v:g}" for v in args[key]))
    for key, flag in (("sweep", "--sweep"), ("dt", "--dt"), ("t_end", "--t-end")):
        if args.get(key) is not None:
            parts.append(f"{flag} {args[key]:g}" if isinstance(args[key], float) else f"{flag} {args[key]}")
    parts += [f"--set {o}" for o in args.get("overrides", [])]
    return " ".join(parts)


def run(name: str) -> str:
    kind, scene, args, what = CHARTS[name]
    path, out = SCENES / f"{scene}.toml", OUT / name
    t0 = time.perf_counter()
    if kind == "bench":
        report = B.bench(path, progress=False, **args)
        B.save(report, out)
    else:
        a = dict(args)
        report = S.stability(path, a.pop("methods"), a.pop("sweep", None), a.pop("dt", None), a.pop("t_end", None), **a)
        S.save(report, out)
    print(f"{name}: {time.perf_counter() - t0:.1f} s", flush=True)
    chart = "work_precision.png" if kind == "bench" else "stability.png"
    return (f"## {name}\n\n{what}.\n\n    {command(kind, scene, args)}\n\n![{name}]({name}/{chart})\n\n"
            f"{report.markdown()}\n")


def main(argv: list[str]) -> int:
    names = [n for n in CHARTS if not argv or any(a in n for a in argv)]
    sections = {n: run(n) for n in names}
    index = OUT / "README.md"
    if argv and index.exists():  # keep the sections not regenerated
        old = index.read_text().split("\n## ")[1:]
        kept = {s.split("\n", 1)[0]: "## " + s for s in old}
        sections = {n: sections.get(n, kept.get(n, "")) for n in CHARTS if n in sections or n in kept}
    header = ("# Speed against accuracy: charts of the shipped scenes\n\n"
              "Generated by `.venv/bin/python benchmarks/docs_charts.py` (CPU times of the machine that ran it; "
              "compare ratios within a chart). Error = largest distance of body points from the reference "
              "(`viz3d.bench`); reasons of failure as in `viz3d.stability`.\n\n")
    index.write_text(header + "\n".join(s.rstrip() + "\n" for s in sections.values()))
    print(f"wrote {index}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
