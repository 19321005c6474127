"""Convergence of impact results with the number of modes or elements (a benchmark, not a test).

    python benchmarks/bench_impact_convergence.py [--out docs/impact_convergence.png]

Two cases with exact solutions (seed 002): the rigid mass on a free bar (Saint-Venant, beta = 1:
contact time T, rebound velocity e^-2) and on a clamped bar (beta = 1: first separation 1.5338 T,
final velocity -0.6989 m/s, by the exact characteristic recursion). Both run with analytic modes
and a kinematic contact; the clamped bar also with n 2-node finite elements and the thesis's
linear contact spring K_c = EA / l_e (ch. 8; a kinematic contact on a finite-element mesh rings:
the upper half of its spectrum is dispersive). Errors are printed as a table and drawn log-log
against the model size, with the wall time of each run.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import viz3d
from viz3d.contact.exact import clamped_bar_rigid_mass, saint_venant_free_bar

ROOT = Path(__file__).resolve().parents[1]
E, RHO, L, A = 210e9, 7900.0, 0.3, 9e-4
C = np.sqrt(E / RHO)
T = 2 * L / C
Z = A * np.sqrt(E * RHO)
SIZES = (10, 20, 40, 80, 160)
MERGE = 0.1 * T  # gaps shorter than this are chatter within one contact period (the exact gap is 0.59 T)


def first_separation(contacts: np.ndarray) -> float:
    end = contacts[0, 2]
    for t0, _, t1, _ in contacts[1:]:
        if t0 - end < MERGE:
            end = t1
        else:
            break
    return end


def run(scene: str, model: str, n: int) -> tuple[float, float, float]:
    key = {"bar.modes": n} if model == "modal" else {
        "bar.model": "fe", "bar.elements": n, "bar.modes": n, "contact.law": "linear", "contact.stiffness": E * A / (L / n)}
    t0 = time.perf_counter()
    traj = viz3d.simulate(ROOT / "scenes" / scene, key)
    wall = time.perf_counter() - t0
    x = traj.extras
    return first_separation(x["contacts"]), float(x["impactor_velocity"][-1]), wall


def measure() -> list[dict]:
    sv = saint_venant_free_bar(1.0, 1.0, C, L, Z)
    cb = clamped_bar_rigid_mass(1.0, 1.0, C, L, np.linspace(0, 4 * T, 10), Z)
    refs = {"free bar": ("impact_free_bar.toml", sv.separation_time, sv.v1_plus),
            "clamped bar": ("impact_clamped_bar.toml", cb.contact_intervals[0][1], cb.final_velocity)}
    rows = []
    for case, (scene, t_ref, v_ref) in refs.items():
        for model in ("modal", "fe") if case == "clamped bar" else ("modal",):
            for n in SIZES:
                t_sep, v, wall = run(scene, model, n)
                rows.append({"case": case, "model": model, "n": n, "t_err": abs(t_sep - t_ref) / t_ref,
                             "v_err": abs(v - v_ref), "wall": wall})
    return rows


def table(rows: list[dict]) -> str:
    lines = ["| case | model | modes / elements | separation time rel. error | rebound velocity error [m/s] | wall [s] |",
             "|---|---|---|---|---|---|"]
    lines += [f"| {r['case']} | {r['model']} | {r['n']} | {r['t_err']:.2e} | {r['v_err']:.2e} | {r['wall']:.2f} |"
              for r in rows]
    return "\n".join(lines)


def chart(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for case, marker in (("free bar", "o"), ("clamped bar", "s")):
        for model, style in (("modal", "-"), ("fe", "--")):
            sel = [r for r in rows if r["case"] == case and r["model"] == model]
            n = [r["n"] for r in sel]
            if not sel:
                continue
            label = f"{case}, {'analytic modes, kinematic contact' if model == 'modal' else 'FE, spring EA/l_e'}"
            axes[0].loglog(n, [max(r["t_err"], 1e-6) for r in sel], marker + style, label=label)
            axes[1].loglog(n, [max(r["v_err"], 1e-6) for r in sel], marker + style, label=label)
    axes[0].set_title("first separation time, relative error")
    axes[1].set_title("impactor rebound velocity, error [m/s]")
    for ax in axes:
        ax.set_xlabel("modes or elements")
        ax.grid(True, which="both", alpha=0.3)
    axes[1].legend(fontsize=8)
    fig.suptitle("Rigid mass on a steel bar (beta = 1) against the exact wave solutions")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "impact_convergence.png")
    args = p.parse_args(argv)
    rows = measure()
    print(table(rows))
    chart(rows, args.out)
    print(f"\nchart: {args.out}")


if __name__ == "__main__":
    main()
