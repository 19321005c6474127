"""Cost and accuracy of the main methods on `chain` (N = 2...50 links) and `heavy_top` (a
benchmark, not a test).

    python benchmarks/bench_methods.py [--n 2,5,10,20,50] [--t-end 0.2] [--dt 5e-4] [--out docs/bench_methods.png]
                                       [--methods "ali3p,ali3p (NumPy)"]

Every method runs through ``viz3d.bench.bench`` (the code behind ``viz3d bench``): the same scene,
step and output grid; CPU time of the whole run after an untimed warm-up; error = largest
distance of body points from the dop853 reference at rtol 1e-12. Reported per method and scene:
microseconds per step, CPU seconds per simulated second, and the error reached. "(NumPy)" is the
method with the compiled kernel switched off (``sim.compiled = false``). ``--methods`` runs only the
rows of those labels. Prints a Markdown table, writes it beside the two-panel chart (``.md``). CPU times
of this machine: compare rows of one run, not machines.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from viz3d.bench import bench

ROOT = Path(__file__).resolve().parents[1]
#: (label, method string, extra overrides, setting): fixed steps use --dt, embedded pairs a tolerance.
#: Every method names its formulation (the scenes' default is projection).
METHODS = [
    ("rk4+index1", "rk4+index1", [], "dt"),
    ("rk4+index1 (NumPy)", "rk4+index1", ["sim.compiled=false"], "dt"),
    ("rk4+projection", "rk4+projection", [], "dt"),
    ("dopri5+projection rtol 1e-8", "dopri5+projection", [], 1e-8),
    ("dop853+projection rtol 1e-10", "dop853+projection", [], 1e-10),
    ("trapezoidal+projection", "trapezoidal+projection", [], "dt"),
    ("gen_alpha+projection", "gen_alpha+projection", [], "dt"),
    ("ali3p", "ali3p", [], "dt"),
    ("ali3p (NumPy)", "ali3p", ["sim.compiled=false"], "dt"),
]


def measure(scene: Path, label_scene: str, dt: float, t_end: float, over: list[str], methods: list) -> list[dict]:
    rows = []
    for label, method, extra, setting in methods:
        dts, tols = ([dt], None) if setting == "dt" else ([dt], [setting])
        report = bench(scene, [method], dts, tols, t_end, progress=False, overrides=over + extra)
        r = report.rows[0]
        rows.append(dict(scene=label_scene, method=label, us_per_step=1e6 * r.cpu / r.steps, s_per_s=r.cpu / t_end,
                         steps=r.steps, error=r.error, constraint=r.constraint, status=r.status))
        print(f"  {label_scene:>10} {label:<18} {rows[-1]['us_per_step']:9.1f} us/step  error {r.error:.2e} m", flush=True)
    return rows


def table(rows: list[dict]) -> str:
    lines = ["| scene | method | µs/step | CPU s per simulated s | steps | error [m] | max abs C [m] | status |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['method']} | {r['us_per_step']:.1f} | {r['s_per_s']:.3g} | {r['steps']} | "
                     f"{r['error']:.2e} | {r['constraint']:.1e} | {r['status'][:50]} |")
    return "\n".join(lines)


def chart(rows: list[dict], ns: list[int], path: Path, methods: list) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.5))
    for label, *_ in methods:
        mine = [r for r in rows if r["method"] == label and r["scene"].startswith("chain")]
        a.loglog(ns, [r["us_per_step"] for r in mine], "o-", label=label)
        b.loglog(ns, [max(r["error"], 1e-16) for r in mine], "o-", label=label)
    a.set_ylabel("CPU µs per step (adaptive: per accepted step)")
    b.set_ylabel("error reached [m]")
    for ax in (a, b):
        ax.set_xlabel("links N")
        ax.grid(True, which="both", alpha=0.3)
    a.legend(fontsize=7)
    fig.suptitle("chain: cost and accuracy of the methods at one step")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", default="2,5,10,20,50")
    ap.add_argument("--t-end", type=float, default=0.2)
    ap.add_argument("--dt", type=float, default=5e-4)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_methods.png")
    ap.add_argument("--methods", default=None, help="comma-separated row labels (default: all)")
    args = ap.parse_args()
    ns = [int(x) for x in args.n.split(",")]
    methods = METHODS
    if args.methods:
        wanted = args.methods.split(",")
        unknown = set(wanted) - {m[0] for m in METHODS}
        if unknown:
            ap.error(f"--methods: unknown labels {sorted(unknown)}; expected some of {[m[0] for m in METHODS]}")
        methods = [m for m in METHODS if m[0] in wanted]
    rows = measure(ROOT / "scenes" / "heavy_top.toml", "heavy_top", args.dt, args.t_end, [], methods)
    for n in ns:
        rows += measure(ROOT / "scenes" / "chain.toml", f"chain N={n}", args.dt, args.t_end, [f"chain.n={n}"], methods)
    print()
    print(table(rows))
    chart(rows, ns, args.out, methods)
    md = args.out.with_suffix(".md")
    md.write_text(f"Generated by `python benchmarks/bench_methods.py` (dt = {args.dt:g} s, {args.t_end:g} s simulated; "
                  "adaptive methods: per accepted step).\n\n" + table(rows) + "\n")
    print(f"\nwrote {args.out} and {md}")
    ok = [r for r in rows if np.isfinite(r["error"])]
    print(f"{len(ok)} of {len(rows)} runs reached the end")


if __name__ == "__main__":
    main()
