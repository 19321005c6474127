"""Dam-reservoir hydrodynamics (viz3d.hydro): timings, reference checks, and the seed's charts.

    .venv/bin/python benchmarks/bench_hydro.py            # tables on stdout, charts + bench.md in docs/charts/hydro/
    .venv/bin/python benchmarks/bench_hydro.py --no-fe    # skip the finite-element cross-check (a few seconds)

Charts (seed 000, figures 10-13, and the issue's coupled dam):
pressure_profiles.png (p(0, y) per unit wall acceleration at omega = 0, 20, 80 rad/s), dynamic_stiffness.png
(Re and Im S(omega) of a uniform wall motion over [0, 80] rad/s), crest_response.png (crest acceleration of
the example dam: empty, incompressible, compressible, absorbing bottom), time_response.png (the shipped
synthetic record). CPU times are this machine's; compare ratios, not absolute values across machines.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.integrate import quad
from scipy.linalg import eigh

from viz3d.hydro import dam as D
from viz3d.hydro.records import shipped_record
from viz3d.hydro.reservoir import (
    SEED_EXAMPLE,
    WESTERGAARD_COEFFICIENT,
    Reservoir,
    added_mass,
    dynamic_stiffness,
    pressure,
    westergaard_pressure,
)
from viz3d.hydro.shapes import SmoothShapes, uniform

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "charts" / "hydro"
RHO, H = SEED_EXAMPLE.density, SEED_EXAMPLE.depth
INCOMPRESSIBLE = Reservoir(RHO, H)
ABSORBING = Reservoir(RHO, H, SEED_EXAMPLE.sound_speed, reflection=0.5)
SWEEP = np.linspace(0.0, 80.0, 400)
PROFILE_OMEGAS = (0.0, 20.0, 80.0)
CATALAN = 0.915965594177219015054603514932  # OEIS A006752
REPEATS = 5


def best_time(function, repeats: int = REPEATS) -> tuple[float, object]:
    """Shortest wall time of ``repeats`` calls [s], and the last result."""
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - start)
    return min(times), result


def table(header: list[str], rows: list[list]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return "\n".join(lines + ["| " + " | ".join(str(c) for c in row) + " |" for row in rows])


def timing_rows() -> list[list]:
    bar = D.cantilever_dam().bar
    modes = SmoothShapes.from_function(lambda y: bar.displacement(y), H)
    rows = []
    for name, reservoir in (("incompressible", INCOMPRESSIBLE), ("seed (c = 1493 m/s)", SEED_EXAMPLE),
                            ("absorbing bottom, alpha = 0.5", ABSORBING)):
        seconds, S = best_time(lambda r=reservoir: dynamic_stiffness(r, modes, SWEEP))
        rows.append([f"S(omega): 400 frequencies x 5 dam modes, {name}", f"{seconds:.3f}", S.n_terms,
                     f"{S.bound / np.abs(S.value).max():.1e}"])
    dam = D.cantilever_dam()
    seconds, r = best_time(lambda: D.frequency_response(dam, SEED_EXAMPLE, SWEEP))
    rows.append(["crest frequency response, 400 frequencies, seed", f"{seconds:.3f}", r.n_terms, ""])
    record = shipped_record()
    seconds, r = best_time(lambda: D.time_response(dam, SEED_EXAMPLE, record), repeats=2)
    rows.append([f"time response to the shipped record ({r.n_fft // 2 + 1} FFT frequencies), seed",
                 f"{seconds:.3f}", r.n_terms, ""])
    return rows


def westergaard_frequency(dam: D.Dam) -> float:
    """Fundamental frequency with Westergaard's added mass m(y) = (7/8) rho sqrt(h (h - y)) lumped on the face."""
    phi = dam.bar.displacement
    n = dam.n_modes
    M = np.zeros((n, n))
    for i in range(n):
        for j in range(i, n):
            def integrand(y, i=i, j=j):
                return WESTERGAARD_COEFFICIENT * RHO * np.sqrt(H * (H - y)) * phi([y])[0, i] * phi([y])[0, j]
            M[i, j] = M[j, i] = quad(integrand, 0.0, H, limit=200)[0] * dam.width
    return float(np.sqrt(eigh(dam.bar.K, np.eye(n) + M, eigvals_only=True)[0]))


def check_rows(with_fe: bool) -> list[list]:
    """[quantity, viz3d, reference, |difference|, tolerance, where the tolerance comes from]."""
    rows = []
    A = added_mass(INCOMPRESSIBLE, uniform(H), 0.0)
    force = A.value[0, 0, 0].real / (RHO * H**2)
    rows.append(["rigid-wall force / (rho a h^2), incompressible", f"{force:.10f}", "0.5428 (Chopra, issue 13)",
                 f"{abs(force - 0.5428):.1e}", "5e-05", "rounding of the printed 0.5428"])
    p = pressure(INCOMPRESSIBLE, uniform(H), 0.0, [0.0])
    base = p.value[0, 0].real / (RHO * H)
    rows.append(["base pressure / (rho a h), incompressible", f"{base:.12f}", "8 G / pi^2 = 0.742453745422",
                 f"{abs(base - 8 * CATALAN / np.pi**2):.1e}", f"{p.bound / (RHO * H) + 2.2e-12:.1e}",
                 "series truncation bound + 1e4 eps"])
    rows.append(["Westergaard / exact, base pressure", f"{WESTERGAARD_COEFFICIENT / base:.4f}", "(7/8) / 0.7425",
                 "", "", "Westergaard is 17.9 % high at the base"])
    rows.append(["Westergaard / exact, total force", f"{(7 / 12) / force:.4f}", "(7/12) / 0.5428", "", "",
                 "Westergaard is 7.5 % high on the force"])
    cutoff = SEED_EXAMPLE.cutoff_frequencies(1)[0]
    rows.append(["first cut-off pi c / 2h [rad/s]", f"{cutoff:.6f}", "23.45 (seed)", f"{abs(cutoff - 23.45):.1e}",
                 "5e-03", "rounding of the printed 23.45"])
    dam = D.cantilever_dam()
    empty, water, compressible = (D.fundamental_frequency(dam, r) for r in (None, INCOMPRESSIBLE, SEED_EXAMPLE))
    rows.append(["dam omega_1 [rad/s]: empty / incompressible / compressible",
                 f"{empty:.4f} / {water:.4f} / {compressible:.4f}", "decreasing (Chopra)", "", "", ""])
    rows.append(["dam omega_1 with Westergaard's lumped added mass [rad/s]", f"{westergaard_frequency(dam):.4f}",
                 f"{water:.4f} (exact, incompressible)", "", "", "classical approximation"])
    if with_fe:
        sys.path.insert(0, str(ROOT / "tests" / "hydro"))
        import helmholtz_fe as fe  # the tests' independent finite-element reservoir

        for omega in (20.0, 80.0):
            fine = [fe.solve(RHO, H, SEED_EXAMPLE.sound_speed, omega, np.ones_like, n_y=n)[1][0] for n in (20, 40)]
            series = pressure(SEED_EXAMPLE, uniform(H), omega, [0.0]).value[0, 0]
            rows.append([f"base pressure / (rho a h) at {omega:g} rad/s vs FE (n_y = 40)",
                         f"{series / (RHO * H):.6f}".replace("j", " j"), f"{fine[1] / (RHO * H):.6f}".replace("j", " j"),
                         f"{abs(series - fine[1]) / (RHO * H):.1e}", f"{abs(fine[0] - fine[1]) / (RHO * H):.1e}",
                         "FE(n_y=20) - FE(n_y=40): 3x Richardson's error estimate"])
    return rows


def response_rows() -> list[list]:
    dam, record = D.cantilever_dam(), shipped_record()
    rows = []
    for name, reservoir in (("empty", None), ("incompressible", INCOMPRESSIBLE), ("compressible", SEED_EXAMPLE),
                            ("absorbing bottom alpha = 0.5", ABSORBING)):
        r = D.frequency_response(dam, reservoir, SWEEP)
        peak = int(np.argmax(np.abs(r.crest_acceleration)))
        t = D.time_response(dam, reservoir, record)
        rows.append([name, f"{SWEEP[peak]:.2f}", f"{abs(r.crest_acceleration[peak]):.2f}",
                     f"{np.abs(t.crest_acceleration).max():.3f}", f"{1e3 * np.abs(t.crest_displacement).max():.2f}"])
    return rows


# ----------------------------------------------------------------------------------------------
# charts
# ----------------------------------------------------------------------------------------------
def charts() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    y = np.linspace(0.0, H, 201)
    fig, axes = plt.subplots(1, 3, figsize=(12, 4.5), sharey=True)
    for ax, omega in zip(axes, PROFILE_OMEGAS):
        p = pressure(SEED_EXAMPLE, uniform(H), omega, y).value[0] / (RHO * H)
        ax.plot(p.real, y / H, label="Re p")
        ax.plot(p.imag, y / H, label="Im p")
        if omega == 0.0:
            ax.plot(westergaard_pressure(SEED_EXAMPLE, y) / (RHO * H), y / H, "k--", lw=1, label="Westergaard")
        ax.axvline(0.0, color="0.7", lw=0.5)
        ax.set_title(f"omega = {omega:g} rad/s")
        ax.set_xlabel("p(0, y) / (rho h a)")
        ax.legend(loc="upper right")
    axes[0].set_ylabel("y / h")
    fig.suptitle("Pressure on the dam face, uniform wall acceleration a (seed figs. 10-12; rho 1000, h 100 m, c 1493 m/s)")
    fig.tight_layout()
    fig.savefig(OUT / "pressure_profiles.png", dpi=120)
    plt.close(fig)

    omega = np.linspace(0.0, 80.0, 801)
    S = dynamic_stiffness(SEED_EXAMPLE, uniform(H), omega).value[:, 0, 0]
    S_inc = dynamic_stiffness(INCOMPRESSIBLE, uniform(H), omega).value[:, 0, 0]
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(omega, S.real / 1e9, label="Re S (compressible)")
    ax.plot(omega, S.imag / 1e9, label="Im S (compressible)")
    ax.plot(omega, S_inc.real / 1e9, "k--", lw=1, label="Re S (incompressible) = -0.5428 rho h^2 omega^2")
    for w in SEED_EXAMPLE.cutoff_frequencies(2):
        ax.axvline(w, color="0.6", lw=0.6, ls=":")
    ax.set_ylim(-60, 40)
    ax.set_xlabel("omega [rad/s]")
    ax.set_ylabel("S [GN/m per m of dam]")
    ax.set_title("Dynamic stiffness of a uniform wall motion (seed fig. 13); cut-offs dotted")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / "dynamic_stiffness.png", dpi=120)
    plt.close(fig)

    dam = D.cantilever_dam()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for name, reservoir, style in (("empty", None, "k-"), ("incompressible", INCOMPRESSIBLE, "C0-"),
                                   ("compressible", SEED_EXAMPLE, "C1-"), ("compressible, alpha = 0.5", ABSORBING, "C2--")):
        r = D.frequency_response(dam, reservoir, omega)
        ax.plot(omega, np.abs(r.crest_acceleration), style, lw=1.2, label=name)
    for w in SEED_EXAMPLE.cutoff_frequencies(2):
        ax.axvline(w, color="0.6", lw=0.6, ls=":")
    ax.set_xlabel("omega [rad/s]")
    ax.set_ylabel("|total crest acceleration / ground acceleration|")
    ax.set_title(f"Example dam (H {dam.height:g} m, t {D.EXAMPLE_THICKNESS:g} m, zeta {dam.damping_ratio:g}), h = 100 m")
    ax.legend()
    fig.tight_layout()
    fig.savefig(OUT / "crest_response.png", dpi=120)
    plt.close(fig)

    record = shipped_record()
    fig, axes = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    axes[0].plot(record.t, record.acceleration, "k", lw=0.6)
    axes[0].set_ylabel("a_g [m/s^2]")
    axes[0].set_title("Shipped synthetic record (Kanai-Tajimi, 0.3 g) and crest acceleration")
    for name, reservoir in (("empty", None), ("incompressible", INCOMPRESSIBLE), ("compressible", SEED_EXAMPLE)):
        t = D.time_response(dam, reservoir, record)
        axes[1].plot(t.t, t.crest_acceleration, lw=0.7, label=name)
    axes[1].set_xlabel("t [s]")
    axes[1].set_ylabel("crest acceleration [m/s^2]")
    axes[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / "time_response.png", dpi=120)
    plt.close(fig)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-fe", action="store_true", help="skip the finite-element cross-check")
    args = parser.parse_args(argv)
    OUT.mkdir(parents=True, exist_ok=True)
    sections = [
        ("Timings (best of repeated runs)", ["computation", "CPU time [s]", "series terms", "truncation bound / max abs S"],
         timing_rows()),
        ("Reference checks", ["quantity", "viz3d", "reference", "difference", "tolerance", "tolerance from"],
         check_rows(not args.no_fe)),
        ("Example dam: crest response", ["reservoir", "FRF peak [rad/s]", "peak abs(a_crest / a_g)",
                                         "shipped record: max abs a_crest [m/s^2]", "max abs u_crest [mm]"],
         response_rows()),
    ]
    charts()
    text = ["# viz3d.hydro: timings, reference checks, charts", "",
            "Generated by `.venv/bin/python benchmarks/bench_hydro.py` (CPU times of the machine that ran it).", ""]
    for title, header, rows in sections:
        block = table(header, rows)
        print(f"\n## {title}\n\n{block}")
        text += [f"## {title}", "", block, ""]
    text += ["![pressure profiles](pressure_profiles.png)", "", "![dynamic stiffness](dynamic_stiffness.png)", "",
             "![crest response](crest_response.png)", "", "![time response](time_response.png)", ""]
    (OUT / "bench.md").write_text("\n".join(text))
    print(f"\nwrote {OUT.relative_to(ROOT)}/: bench.md and four charts")


if __name__ == "__main__":
    main()
