"""Convergence of the cubic (6-DOF planar / "hermite") and quintic (seed 003's 8-DOF planar /
"quintic") Euler-Bernoulli elements against exact beam solutions (a benchmark, not a test).

    .venv/bin/python benchmarks/bench_beam_elements.py [--out docs/charts/beam_elements]

* Natural frequencies of cantilever, pinned-pinned and free-free beams, modes 1-3, against the roots
  of the characteristic equations (tests/flexible/beam_exact.py): relative error against the
  number of free dofs.
* Bending stress at the clamp of a cantilever, read at the node (quintic: the curvature dof; cubic:
  w'' of the first element) under a tip load (exact -P L c / I), its own weight (exact
  -q L^2 c / 2 I) and a cosine load q0 cos(pi x / 2L) (exact from int q x dx).

Every error is drawn with the round-off floor n eps kappa_J(K) of its model. Observed orders are
least-squares slopes of log error against log n_elements over the meshes the tests use for them:
error above 100 x the floor and, for frequencies, k h <= pi / 2. Writes beam_elements.png,
beam_elements.md and beam_elements.csv into the output directory and prints the table.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "flexible"))  # the exact references the tests use
import beam_exact as exact  # noqa: E402
from test_beam_elements import FLOOR_MARGIN, KH_MAX  # noqa: E402  (the tests' rule for fitting orders)

from viz3d.flexible import Material, Section, fe_model, node_bending_stress  # noqa: E402
from viz3d.flexible.bar import rigid_mode_count  # noqa: E402

STEEL = Material(210e9, 7900.0, 0.3)
SECTION = Section.rectangle(0.03, 0.03)
L = 0.3
EI = STEEL.E * SECTION.second_moment
C_FIBRE = SECTION.depth / 2
Q0, P, G = 1.0e4, 1000.0, 9.81  # cosine load amplitude [N/m], tip load [N], gravity [m/s^2]
ELEMENTS = ("hermite", "quintic")
LABEL = {"hermite": "cubic (6-DOF planar)", "quintic": "quintic (8-DOF planar)"}
MESHES = {"hermite": (1, 2, 3, 4, 5, 6, 8, 10, 12, 16, 24, 32, 48, 64), "quintic": (*range(1, 13), 16, 24, 32)}
SUPPORTS = {"cantilever": ("clamped", "free"), "pinned-pinned": ("pinned", "pinned"), "free-free": ("free", "free")}
N_MODES = 3


def beam(element: str, n: int, supports=("clamped", "free")):
    return fe_model("euler_bernoulli", L, STEEL, SECTION, n, supports, element=element)


def frequency_rows() -> list[dict]:
    rows = []
    for case, supports in SUPPORTS.items():
        omega = exact.eb_frequencies(supports, N_MODES, L, STEEL.E, SECTION.second_moment, STEEL.rho, SECTION.area)
        n_rigid = rigid_mode_count("bending", supports)
        for element in ELEMENTS:
            for n in MESHES[element]:
                model = beam(element, n, supports)
                got = model.frequencies()[n_rigid:n_rigid + N_MODES]
                if len(got) < N_MODES:
                    continue
                floor = exact.roundoff_floor(model.K, n_rigid)
                for mode in range(N_MODES):
                    rows.append(dict(case=case, element=element, n=n, dofs=model.n, quantity=f"mode {mode + 1}",
                                     error=got[mode] / omega[mode] - 1, floor=floor,
                                     kh=exact.eb_roots(supports, N_MODES)[mode] / n))
    return rows


def clamp_stress_rows() -> list[dict]:
    M_cos = Q0 * (2 * L**2 / np.pi - 4 * L**2 / np.pi**2)  # Q0 int_0^L cos(pi s / 2L) s ds, by parts
    exact_sigma = {"tip load": -P * L, "weight": -STEEL.rho * SECTION.area * G * L**2 / 2, "cosine load": -M_cos}
    rows = []
    for element in ELEMENTS:
        for n in MESHES[element]:
            model = beam(element, n)
            loads = {"tip load": model.point_force(L, P), "weight": G * model.S1,
                     "cosine load": model.integrate(lambda x: Q0 * np.cos(np.pi * x / (2 * L))[:, None] * model.displacement(x))}
            floor = exact.roundoff_floor(model.K)
            for name, F in loads.items():
                sigma = node_bending_stress(model, np.linalg.solve(model.K, F))[0]
                rows.append(dict(case="clamp stress", element=element, n=n, dofs=model.n, quantity=name,
                                 error=sigma / (exact_sigma[name] * C_FIBRE / SECTION.second_moment) - 1, floor=floor, kh=0.0))
    return rows


def is_exact(rows: list[dict]) -> bool:
    """Every error within FLOOR_MARGIN x the round-off floor: the element reproduces the solution."""
    return all(abs(r["error"]) <= FLOOR_MARGIN * r["floor"] for r in rows)


def observed_order(rows: list[dict]) -> float | None:
    usable = [(r["n"], abs(r["error"])) for r in rows
              if abs(r["error"]) > FLOOR_MARGIN * r["floor"] and r["kh"] <= KH_MAX]
    if len(usable) < 2:
        return None
    n, e = np.array(usable).T
    return float(-np.polyfit(np.log(n), np.log(e), 1)[0])


def groups(rows):
    keys = sorted({(r["case"], r["quantity"], r["element"]) for r in rows}, key=lambda k: (k[0], k[1], k[2]))
    return {k: [r for r in rows if (r["case"], r["quantity"], r["element"]) == k] for k in keys}


def summary(rows: list[dict]) -> list[tuple]:
    out = []
    for (case, quantity, element), rs in groups(rows).items():
        resolved = [r for r in rs if abs(r["error"]) > FLOOR_MARGIN * r["floor"]]
        finest = resolved[-1] if resolved else rs[-1]
        out.append((case, quantity, element, observed_order(rs), finest["n"], finest["dofs"], finest["error"], finest["floor"],
                    is_exact(rs)))
    return out


def chart(rows: list[dict], path: Path) -> None:
    fig, axes = plt.subplots(2, 2, figsize=(12, 9), sharex=False)
    panels = list(SUPPORTS) + ["clamp stress"]
    style = {"hermite": dict(color="tab:blue"), "quintic": dict(color="tab:red")}
    marks = {"mode 1": "o", "mode 2": "s", "mode 3": "^", "tip load": "o", "weight": "s", "cosine load": "^"}
    for ax, case in zip(axes.ravel(), panels):
        for (c, quantity, element), rs in groups(rows).items():
            if c != case:
                continue
            d = np.array([r["dofs"] for r in rs])
            e = np.array([max(abs(r["error"]), 1e-17) for r in rs])
            p = observed_order(rs)
            tag = f"{LABEL[element]}, {quantity}" + (" (exact)" if is_exact(rs) else f" (order {p:.1f})")
            ax.loglog(d, e, marker=marks[quantity], label=tag, **style[element])
            if quantity in ("mode 1", "tip load"):
                ax.loglog(d, [r["floor"] for r in rs], ":", color=style[element]["color"], lw=1,
                          label=f"{LABEL[element]}: round-off floor n eps kappa_J(K)")
        ax.set_title(case if case == "clamp stress" else f"{case}: natural frequencies")
        ax.set_xlabel("free dofs")
        ax.set_ylabel("|relative error|")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6.5)
    fig.suptitle("Euler-Bernoulli elements against exact beam solutions (steel, L = 0.3 m, 30 mm square)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def table(rows: list[dict]) -> str:
    lines = ["| case | quantity | element | observed order | elements | free dofs | relative error | round-off floor |",
             "|---|---|---|---|---|---|---|---|"]
    for case, quantity, element, p, n, dofs, e, floor, exact_ in summary(rows):
        order = "exact (round-off)" if exact_ else f"{p:.2f}"
        lines.append(f"| {case} | {quantity} | {element} | {order} | {n} | {dofs} | {e:.2e} | {floor:.1e} |")
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "charts" / "beam_elements")
    out = parser.parse_args(argv).out
    out.mkdir(parents=True, exist_ok=True)
    rows = frequency_rows() + clamp_stress_rows()
    chart(rows, out / "beam_elements.png")
    md = table(rows)
    (out / "beam_elements.md").write_text(
        "Generated by `.venv/bin/python benchmarks/bench_beam_elements.py`. Error at the finest mesh whose error is "
        f"above {FLOOR_MARGIN:g} x the round-off floor n eps kappa_J(K) (the finest mesh of the series if none is); "
        "observed orders are least-squares slopes over those meshes (frequencies: k h <= pi/2 too). "
        "Full series: beam_elements.csv.\n\n" + md + "\n")
    with open(out / "beam_elements.csv", "w") as f:
        f.write("case,quantity,element,n_elements,free_dofs,relative_error,roundoff_floor\n")
        for r in rows:
            f.write(f"{r['case']},{r['quantity']},{r['element']},{r['n']},{r['dofs']},{r['error']:.6e},{r['floor']:.3e}\n")
    print(md)
    print(f"\nwrote {out / 'beam_elements.png'}")


if __name__ == "__main__":
    main()
