"""Where seed 003's kineto-elastodynamic (KED) assumption breaks down: the flexible four-bar
(scenes/flexible_four_bar.toml) with its coupler and rocker coupled (floating frame, both ways) or
KED (``coupling = "ked"``: the elastic equations loaded by the rigid motion only), over the ratio of
crank speed to the links' first pinned-pinned frequency (a benchmark, not a test).

    .venv/bin/python benchmarks/bench_four_bar_ked.py [--ratios 0.05 0.1 0.2 0.4] [--damping 0.05] [--no-gravity]
        [--out docs]

For each ratio the crank speed is ``ratio * omega_1`` (omega_1 = pi^2 / L^2 sqrt(EI / rho A), 297
rad/s), reached by a cycloidal ramp (``kind = "smooth_ramp"``) over two crank periods, then held
until the links' free vibration (the ramp's and gravity's, the models' frequencies differ) has
decayed by ``exp(-DECAY_EXPONENTS)`` under the modal damping ``--damping`` (the scene has none: an
undamped run never reaches the periodic state), then for one period, measured. The error is
``max |w_KED - w_coupled| / max |w_coupled|`` of the coupler's midspan deflection (from its chord)
over that period, both runs sampled at the same instants (the crank's angle is prescribed: the same
in both). Both runs: two modes per link, dopri5 at rtol 1e-7.

Expected (docs/bench_four_bar_ked.md): the links' joints sit on the chords, where their
pinned-pinned shapes vanish, and the crank's rate is prescribed, so the rigid motion is the same in
both models; what KED leaves out is the motion-dependent stiffness of the elastic equations, for a
link turning at Omega in its bending plane the centrifugal softening ``Omega^2 M_ee eta``. Its
relative effect on the deflection is ``(Omega / omega_1)^2 ~ ratio^2`` (slope 2 on the chart) at low
speed, larger near the resonances ``k ratio = 1`` of the crank harmonics.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import viz3d
from viz3d.diagnosis import SimulationFailure
from viz3d.scene.build import make_controller, make_formulation, make_integrator_from

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "flexible_four_bar.toml"
L, E, RHO, WIDTH, DEPTH = 0.2794, 70e9, 2700.0, 0.0254, 0.0016
OMEGA_1 = np.pi**2 / L**2 * np.sqrt(E * DEPTH**2 / (12 * RHO))
SAMPLES_PER_PERIOD = 200
#: Free vibration left when the measured period starts: exp(-8) = 3e-4 of its amplitude.
DECAY_EXPONENTS = 8.0
RATIOS = (0.025, 0.05, 0.07, 0.1, 0.14, 0.2, 0.28, 0.4, 0.56, 0.7, 0.8)
#: Tolerances [relative] the statement is made for.
TOLERANCES = (0.01, 0.05)


def overrides(ratio: float, coupling: str, damping: float, gravity: bool = True) -> tuple[list[str], float, float]:
    """Scene overrides for crank speed ``ratio * OMEGA_1``, ``coupling`` and ``damping`` of both links
    and the scene's gravity or none; the start of the measured period and the end of the run [s]."""
    speed = ratio * OMEGA_1
    period = 2 * np.pi / speed
    ramp = 2 * period
    held = np.ceil(DECAY_EXPONENTS / (damping * OMEGA_1) / period) * period
    start, t_end = ramp + held, ramp + held + period
    dt = period / SAMPLES_PER_PERIOD
    out = [f"sim.t_end={t_end}", f"sim.dt={dt}", "sim.rtol=1e-7", f"drives.motor.amplitude={-speed}",
           "drives.motor.kind=smooth_ramp", f"drives.motor.duration={ramp}"]
    for link in ("coupler", "rocker"):
        out += [f"bodies.{link}.modes=2", f"bodies.{link}.coupling={coupling}", f"bodies.{link}.damping={damping}"]
    if not gravity:
        out.append("sim.gravity=[0.0, 0.0, 0.0]")
    return out, start, t_end


def midspan_history(ratio: float, coupling: str, damping: float,
                    gravity: bool = True) -> tuple[np.ndarray, np.ndarray, float]:
    """Times [s] and coupler midspan deflections [m] over the measured period, wall time [s]."""
    sets, start, t_end = overrides(ratio, coupling, damping, gravity)
    scene = viz3d.load_scene(SCENE, sets)
    system, state = viz3d.build(scene)
    assert all(fb.ked == (coupling == "ked") for fb in system.bodies.flexible), "the coupling override did not apply"
    sim_cfg = scene.data["sim"]
    dt = sim_cfg["dt"]
    sim = viz3d.Simulation(system, state, make_integrator_from(sim_cfg), make_formulation(sim_cfg), dt,
                           controller=make_controller(sim_cfg))
    k = system.bodies.names.index("coupler")
    i = [fb.index for fb in system.bodies.flexible].index(k)
    phi = system.bodies.flexible[i].bar.fields[0].displacement(np.array([L / 2]))[0]
    wall = time.perf_counter()
    t, w = [], []
    for _ in range(round(t_end / dt)):
        s = sim.step()
        if s.t >= start - 1e-9 * t_end:
            t.append(s.t)
            w.append(phi @ system.elastic_q(s.q)[i])
    return np.array(t), np.array(w), time.perf_counter() - wall


def ked_error(ratio: float, damping: float, gravity: bool = True) -> tuple[float, float, float, float]:
    """KED's relative midspan deflection error, the coupled model's largest deflection [m] and both
    wall times [s] at crank speed ``ratio * OMEGA_1``."""
    t_c, w_c, wall_c = midspan_history(ratio, "coupled", damping, gravity)
    t_k, w_k, wall_k = midspan_history(ratio, "ked", damping, gravity)
    assert np.array_equal(t_c, t_k)
    return float(np.abs(w_k - w_c).max() / np.abs(w_c).max()), float(np.abs(w_c).max()), wall_c, wall_k


def log_slope(x: np.ndarray, y: np.ndarray) -> float:
    """Least-squares slope of log y against log x."""
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


def crossing(ratios: np.ndarray, errors: np.ndarray, tol: float) -> float | None:
    """The lowest ratio at which the error reaches ``tol`` (log-log interpolation); None if never."""
    above = np.nonzero(errors >= tol)[0]
    if not above.size:
        return None
    j = above[0]
    if j == 0:
        return float(ratios[0])
    a = np.log(tol / errors[j - 1]) / np.log(errors[j] / errors[j - 1])
    return float(np.exp(np.log(ratios[j - 1]) + a * np.log(ratios[j] / ratios[j - 1])))


def report(rows: list[tuple], failed: list[tuple], damping: float, load: str) -> str:
    r = np.array(rows)
    low = r[:, 0] <= 0.1 + 1e-12
    slope = log_slope(r[low, 0], r[low, 2]) if low.sum() >= 2 else float("nan")
    local = [float("nan")] + [log_slope(r[j - 1:j + 1, 0], r[j - 1:j + 1, 2]) for j in range(1, len(r))]
    lines = [
        "# Flexible four-bar: where kineto-elastodynamics (KED) breaks down",
        "",
        "Written by `benchmarks/bench_four_bar_ked.py`. The mechanism is `scenes/flexible_four_bar.toml`",
        f"(coupler and rocker: quintic FE strips, 2 modes each, modal damping {damping:g}; omega_1 = "
        f"{OMEGA_1:.1f} rad/s, their first pinned-pinned frequency), crank speed `ratio * omega_1` "
        "after a two-period cycloidal ramp, measured over one period once the free vibration has "
        f"decayed by exp(-{DECAY_EXPONENTS:g}). Error: `max |w_KED - w_coupled| / max |w_coupled|` of "
        "the coupler's midspan deflection from its chord, both runs sampled at the same instants "
        "(same crank angle). dopri5, rtol 1e-7. Local slope: of log error against log ratio from the "
        "row above.",
        "",
        "| omega / omega_1 | max coupler midspan deflection [m] | KED error (relative) | local slope "
        "| wall coupled [s] | wall KED [s] |",
        "|---|---|---|---|---|---|",
    ]
    lines += [f"| {a:.3f} | {b:.3e} | {c:.3e} | {'' if np.isnan(s) else f'{s:.2f}'} | {d:.0f} | {e:.0f} |"
              for (a, b, c, d, e), s in zip(rows, local)]
    lines += [f"| {a:.3f} | run failed: {msg} | | | | |" for a, msg in failed]
    cost = float(np.median(r[:, 4] / r[:, 3]))
    lines += ["", f"Wall times on a shared 2-core machine (load average {load}); KED / coupled: {cost:.2f} "
              "(median). KED is not the cheaper model in this engine: it evaluates the forces twice per "
              "step, on the NumPy path (docs/notation.md), and solves the same system. The cheapest model "
              "that meets a tolerance is therefore the coupled one at every speed; KED is seed 003's model, "
              "offered for comparison and to show what its assumption costs in accuracy.", "",
              f"**Observed slope** of the error against the ratio up to 0.1 (least squares): **{slope:.2f}**; "
              "theory: 2 as the ratio goes to 0, with a correction of relative order ratio^2 (below).", ""]
    for tol in TOLERANCES:
        y = crossing(r[:, 0], r[:, 2], tol)
        if y is None:
            lines.append(f"**KED meets a tolerance of {100 * tol:g} % over the whole range charted "
                         f"(omega / omega_1 <= {r[-1, 0]:g}).**")
        else:
            lines.append(f"**KED meets a tolerance of {100 * tol:g} % below omega / omega_1 = {y:.2f}.**")
        lines.append("")
    lines += [
        "## Why the error grows as ratio^2",
        "",
        "Both links are pinned-pinned on floating frames that are their chords: the joints sit where the",
        "shapes vanish (w(0) = w(L) = 0) and the universal joint's axis is the axis the sections turn about,",
        "so no joint row has an elastic column, and with the crank's rate prescribed the four-bar has no",
        "degree of freedom left: the frames' motion is the rigid kinematics in *both* models. The",
        "feedback KED drops (the elastic columns of the frames' mass blocks and forces) only changes the",
        "joint reactions here. What it also drops are the motion-dependent terms of the elastic",
        "equations: for a bending field in the link's plane turning at Omega(t) (coupler, rocker) the",
        "centrifugal softening `+Omega^2 M_ee eta` (Coriolis and Euler terms act along the axis only).",
        "The difference e of the two models obeys exactly `M_ee e'' + C e' + K e = Omega^2 M_ee w_coupled`:",
        "the inertia loads of the rigid motion drive a deflection w ~ omega^2, and below the resonances",
        "e ~ (Omega / omega_1)^2 w, a relative error ~ ratio^2 (absolute ~ ratio^4); the links turn at up to",
        "0.69 of the crank's rate in this four-bar, so the quasi-static bound is (0.69 ratio)^2. The",
        "correction factor `1 + d ratio^2` comes from the dynamic response of the crank harmonics",
        "(1 / (1 - (k ratio)^2)) of w and of e, and the error rises and falls about the resonances",
        "k ratio = 1 (k = 3, 2 at 0.33, 0.5) where the shifted frequency matters most. Past ratio ~0.3",
        "the linear model itself is out of its range: deflections of a third of the strip's length and",
        "more, bending stresses far above aluminium's yield.",
        "",
        "`tests/flexible/test_ked.py` checks KED and the coupled model of one turning link against their",
        "modal equations integrated by scipy, and (slow) the slope of this error at low speed.",
        "",
        "## The earlier run (errors 6e-8 to 1.8e-10, falling with speed)",
        "",
        "The comparison itself was sound (same instants, the override applied); the engine's KED then",
        "kept every term of the elastic equations in eta (`M_ef(eta)` and the velocity forces of the",
        "deformed body) and dropped only the feedback on the frames, which, as above, changes nothing",
        "in this mechanism: the two runs solved the same equations, their difference was the",
        "integrator's (1.4e-11 m absolute at ratio 0.2 against 1.2e-2 m of deflection). The engine's KED",
        "is now seed 003's (Erdman & Sandor; Midha, Erdman & Frohrib 1978): the elastic equations loaded",
        "by the rigid motion only, `M_ee eta_ddot + C eta_dot + K eta = Q_e(undeformed, at elastic rest)",
        "- M_ef(0) a_frame` (viz3d/dynamics.py, docs/notation.md).",
        "",
    ]
    return "\n".join(lines)


def chart(rows: list[tuple], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    r = np.array(rows)
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    ax.loglog(r[:, 0], r[:, 2], "o-", label="KED vs coupled")
    ref = r[0, 2] * (r[:, 0] / r[0, 0]) ** 2
    ax.loglog(r[:, 0], ref, "k--", lw=0.8, label="slope 2 (theory, low speed)")
    for tol in TOLERANCES:
        ax.axhline(tol, color="grey", lw=0.6, ls=":")
        ax.text(r[0, 0], tol * 1.1, f"{100 * tol:g} %", fontsize=8, color="grey")
    ax.set_xticks(r[:, 0], [f"{x:g}" for x in r[:, 0]], fontsize=8)
    ax.minorticks_off()
    ax.set_xlabel("crank speed / first link frequency  omega / omega_1")
    ax.set_ylabel("coupler midspan deflection error (relative)")
    ax.set_title("Flexible four-bar: kineto-elastodynamics vs coupled")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ratios", type=float, nargs="+", default=list(RATIOS))
    parser.add_argument("--damping", type=float, default=0.05, help="modal damping ratio of the links")
    parser.add_argument("--no-gravity", dest="gravity", action="store_false", help="switch the scene's gravity off")
    parser.add_argument("--out", type=Path, default=ROOT / "docs")
    args = parser.parse_args()
    rows, failed = [], []
    for ratio in sorted(args.ratios):
        try:
            error, w_max, wall_c, wall_k = ked_error(ratio, args.damping, args.gravity)
        except SimulationFailure as exc:   # e.g. the step collapsing at deflections beyond the linear range
            failed.append((ratio, str(exc)))
            print(f"ratio {ratio:5.3f}: failed: {exc}", flush=True)
            continue
        rows.append((ratio, w_max, error, wall_c, wall_k))
        print(f"ratio {ratio:5.3f}: max |w| {w_max:.3e} m, KED error {error:.3e} ({wall_c:.0f} s / {wall_k:.0f} s)",
              flush=True)
    load = ", ".join(f"{x:.1f}" for x in __import__("os").getloadavg())
    args.out.mkdir(parents=True, exist_ok=True)
    chart(rows, args.out / "bench_four_bar_ked.png")
    text = report(rows, failed, args.damping, load)
    (args.out / "bench_four_bar_ked.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
