"""Where methods fail: ``viz3d stability SCENE --methods LIST [--sweep key.path=V1,V2,...]``.

Three maps, each run ending with a reason:

* **largest stable step** (multibody scene with ``--sweep``): for each swept value (e.g. a
  contact stiffness) and method, the largest step (searched down from ``top_step``, then bisected
  in log steps) at which a run ends ok (in conservative scenes that includes energy not
  growing by more than ``sim.blowup_energy`` of the largest kinetic energy);
* **one step per method** (multibody scene, no sweep): status and failure reason, time of
  failure, error against the bench reference (viz3d.bench), constraint drift and energy drift,
  with their histories charted (e.g. plain Euler angles against charts and quaternions through
  theta = 0; constraint drift without stabilization);
* **model size on contacts** (a scene with contacts, ``--sweep`` and no ``--methods``, e.g.
  ``--sweep bar.modes=...``): each run against the
  finest one: a contact of the finest model that the run does not have is missed (one the finest
  model does not have is spurious); then the restitution. Contacts are the runs' own, as the
  physics defines them at each model's time resolution (``viz3d.contact.intervals``: breaks and
  touches shorter than the period of the highest mode are not contacts), so ``viz3d run`` and
  this map count the same.

Reasons: ``ok``, ``diverged`` (non-finite, runaway speed or energy growth), ``singular``
(gimbal lock, singular matrix), ``no convergence`` (an implicit method's iteration), ``constraint
drift above tolerance``, ``unresolved rotation`` (orientation coordinates turning more than
a radian per step), ``missed contact``, ``spurious contact``, ``restitution error above
tolerance``, ``failed`` (any other diagnosis); the diagnosis's full text is kept as the detail.

With an output folder, every finished run (a whole step search, in the first map) is kept in its
results store (``viz3d.studies.execute.Store``): the same command started again runs only the
missing ones.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from viz3d.bench import body_point_error, common_grid, reference_digest, reference_run, write_report
from viz3d.contact.intervals import physical_contacts
from viz3d.methods import method_overrides
from viz3d.scene.load import load_scene, with_sim
from viz3d.simulate import simulate
from viz3d.studies.execute import IN_PROCESS, Cluster, Store, run_study, store_note
from viz3d.studies.plan import Point
from viz3d.trajectory import Trajectory

#: Searched range of steps [s], descent factor from the top, halvings of the log interval after it
#: (the result is within DESCENT ** (1 / 2 ** BISECTIONS) = 0.5 % of the true limit).
DT_MIN, DT_MAX, DESCENT, BISECTIONS = 1e-7, 1e-1, 4.0, 8
#: The searched steps leave at least this many steps in a run.
STEPS_MIN = 10
#: Constraint drift above this [m] makes a run unstable.
CONSTRAINT_TOL = 1e-2
#: Contacts of two runs closer than this fraction of the finest model's contact span are the same
#: contact (matching tolerance between models; each run's contacts are already merged at its own
#: time resolution).
GAP_FRACTION = 0.01
#: A restitution differing from the finest model's by more than this counts as an error.
RESTITUTION_TOL = 0.02


@dataclass
class StabilityRow:
    method: str
    value: str              # swept value, or ""
    dt: float               # largest stable step (sweep) or the step used [s]
    reason: str
    detail: str = ""
    t_fail: float = float("nan")
    error: float = float("nan")
    energy_drift: float = float("nan")
    constraint: float = float("nan")
    extra: dict = field(default_factory=dict)


@dataclass
class StabilityReport:
    scene: str
    mode: str               # "sweep", "methods" or "contacts"
    key: str
    rows: list[StabilityRow]
    histories: dict = field(default_factory=dict)  # method -> (t, |C|, energy drift) for "methods"
    note: str = ""          # what came from the results store (``store_note``)

    def markdown(self) -> str:
        if self.mode == "sweep":
            head = (f"| method | {self.key} | largest stable step [s] | reason just above it |\n|---|---|---|---|")
            body = [f"| {r.method} | {r.value} | {_dt_text(r)} | {r.reason}: {r.detail[:80]} |" for r in self.rows]
        elif self.mode == "methods":
            head = ("| method | step [s] | reason | failed at [s] | error [m] | max abs C [m] | energy drift | detail |\n"
                    "|---|---|---|---|---|---|---|---|")
            body = [f"| {r.method} | {r.dt:g} | {r.reason} | {r.t_fail:.4g} | {r.error:.2e} | {r.constraint:.1e} | "
                    f"{r.energy_drift:.1e} | {r.detail[:80]} |" for r in self.rows]
        else:
            head = (f"| {self.key} | reason | contacts | restitution | peak force [N] | detail |\n|---|---|---|---|---|---|")
            body = [f"| {r.value} | {r.reason} | {r.extra['contacts']} | {r.extra['restitution']:.4f} | "
                    f"{r.extra['peak_force']:.4g} | {r.detail[:80]} |" for r in self.rows]
        return "\n".join([*([self.note, ""] if self.note else []), head, *body])


def _dt_text(row: StabilityRow) -> str:
    if row.reason == "ok":
        return f">= {row.dt:g} (stable over the whole range)"
    if row.dt < DT_MIN:
        return f"< {DT_MIN:g}"
    return f"{row.dt:.3g}"


def reason_of(traj) -> tuple[str, str]:
    """(reason, detail) of a finished run (energy growth in conservative scenes and an energy ledger
    that does not balance stop the run itself: ``sim.blowup_energy``, viz3d.diagnosis.EnergyWatch)."""
    status = traj.status
    if not traj.ok:
        low = status.lower()
        if "singular" in low or "gimbal" in low:
            return "singular", status
        if "newton" in low or "did not converge" in low:
            return "no convergence", status
        if "energy ledger" in low:
            return "energy ledger off", status
        if "diverged" in low or "non-finite" in low or "speed" in low:
            return "diverged", status
        if "constraint violation" in low:
            return "constraint drift above tolerance", status
        if "cannot resolve" in low:
            return "unresolved rotation", status
        return "failed", status
    if traj.max_constraint_violation > CONSTRAINT_TOL:
        return "constraint drift above tolerance", f"max |C| {traj.max_constraint_violation:.3g} m > {CONSTRAINT_TOL:g} m"
    return "ok", ""


def stability(path, methods: list[str], sweep: str | None, dt: float | None, t_end: float | None,
              overrides: list[str] = (), cluster: Cluster = IN_PROCESS, out: Path | None = None) -> StabilityReport:
    """The map for ``path`` (see the module docstring); ``overrides`` apply to every run; the runs (a
    whole step search per point of the sweep map) run on ``cluster`` (``viz3d.studies.execute``), and
    are kept in (and read back from) the results store of the folder ``out``."""
    over, store = list(overrides), Store.in_folder(out)
    scene = load_scene(path, over)
    key, values = _parse_sweep(sweep)
    if not methods:
        if not (sweep and scene.data["contacts"]):
            raise ValueError(f"{path}: give --methods (e.g. rk4,trapezoidal), or --sweep for a scene with contacts "
                             f"(e.g. bar.modes=1,2,4,8,16)")
        return _contact_map(path, key, values, t_end, over, cluster, store)
    if sweep:
        return _sweep_map(path, methods, key, values, t_end, over, cluster, store)
    return _methods_map(path, methods, dt, t_end, over, cluster, store)


def _parse_sweep(sweep: str | None) -> tuple[str, list[str]]:
    if not sweep:
        return "", []
    key, sep, vals = sweep.partition("=")
    if not sep or not vals:
        raise ValueError(f"--sweep expects key.path=V1,V2,..., got {sweep!r}")
    return key.strip(), [v.strip() for v in vals.split(",")]


@dataclass(frozen=True)
class StableStep:
    """Measure of the sweep map (``viz3d.studies``): the largest stable step of one scene."""

    t_end: float | None

    def __call__(self, scene) -> dict:
        dt, reason, detail = stable_step_of(scene, self.t_end)
        return {"dt": dt, "reason": reason, "detail": detail}


def _sweep_map(path, methods, key, values, t_end, base_over, cluster, store) -> StabilityReport:
    points = [Point((value, method), (*method_overrides(method), f"{key}={value}")) for value in values
              for method in methods]
    outcomes = run_study(path, points, StableStep(t_end), cluster, overrides=base_over, store=store)
    rows = [StabilityRow(o.point.values[1], o.point.values[0], o.row.get("dt", float("nan")),
                         o.row.get("reason", "failed"), o.row.get("detail", o.row["status"])) for o in outcomes]
    return StabilityReport(Path(path).stem, "sweep", key, rows, note=store_note(store, outcomes))


def largest_stable_step(path, overrides: list[str], t_end) -> tuple[float, str, str]:
    """Largest stable step [s] of the scene ``path`` with ``overrides`` (``stable_step_of``)."""
    return stable_step_of(load_scene(path, overrides), t_end)


def stable_step_of(scene, t_end) -> tuple[float, str, str]:
    """Largest stable step [s] of ``scene``, with the reason of the failure just above it.

    Steps descend from ``top_step`` by factors of ``DESCENT`` until a run is stable (so the cost is
    set by the stable step, never by ``DT_MIN``), then ``BISECTIONS`` halvings of the log interval
    between that step and the failing one above it."""

    def run(dt):
        return reason_of(simulate(with_sim(scene, dt=dt, output_dt=dt), t_end=t_end))

    top = top_step(scene, t_end)
    hi, above = top, run(top)
    if above[0] == "ok":
        return top, "ok", "stable over the whole range"
    while True:
        lo = hi / DESCENT
        if lo < DT_MIN:
            return lo, *above
        res = run(lo)
        if res[0] == "ok":
            break
        hi, above = lo, res
    for _ in range(BISECTIONS):
        mid = float(np.sqrt(lo * hi))
        res = run(mid)
        if res[0] == "ok":
            lo = mid
        else:
            hi, above = mid, res
    return lo, *above


def top_step(scene, t_end: float | None) -> float:
    """Top of the searched range [s]: ``DT_MAX``, or a tenth of the run if that is shorter (a
    run of fewer steps says nothing about stability)."""
    return min(DT_MAX, (t_end or scene.data["sim"]["t_end"]) / STEPS_MIN)


def failure_time(traj) -> float:
    """Time named by a diagnosis ("t = 0.1085 s: ...") [s]; nan for a run that did not fail."""
    import re

    if traj.ok:
        return float("nan")
    m = re.search(r"t = ([0-9.eE+-]+) s", traj.status)
    return float(m.group(1)) if m else float(traj.t[-1]) if len(traj.t) else float("nan")


@dataclass(frozen=True)
class MethodRun:
    """Measure of the methods map (``viz3d.studies``): one run, its reason, error against
    ``reference`` (identified by ``reference_key``, its ``viz3d.bench.reference_digest``) and drift
    histories (t, max |C|, energy drift; each shape (n,))."""

    reference: Trajectory = field(compare=False)
    reference_key: str
    t_end: float

    def __call__(self, scene) -> dict:
        traj = simulate(scene, t_end=self.t_end)
        reason, detail = reason_of(traj)
        n = len(traj.t)
        scale = float(np.max(traj.energy_kinetic)) if n and np.max(traj.energy_kinetic) > 0 else 1.0
        return {"reason": reason, "detail": detail, "t_fail": failure_time(traj),
                "error": body_point_error(traj, self.reference) if traj.ok else float("nan"),
                "energy_drift": traj.energy_drift_rel, "constraint": traj.max_constraint_violation,
                "history": (traj.t, traj.constraint_violation,
                            np.abs(traj.energy_total - traj.energy_total[0]) / scale)}


def _methods_map(path, methods, dt, t_end, base_over, cluster, store) -> StabilityReport:
    base = load_scene(path, base_over)
    dt = dt or base.data["sim"]["dt"]
    output_dt, t_end = common_grid([dt], base.data["sim"].get("output_dt", 0.01), t_end or base.data["sim"]["t_end"])
    grid = base_over + [f"sim.output_dt={output_dt!r}"]
    ref = reference_run(path, base_over + ["sim.rotation=quaternion"], output_dt, t_end)
    points = [Point((method,), (*method_overrides(method), f"sim.dt={dt!r}")) for method in methods]
    outcomes = run_study(path, points, MethodRun(ref, reference_digest(ref), t_end), cluster, overrides=grid,
                         store=store)
    nan = float("nan")
    rows = [StabilityRow(o.point.values[0], "", dt, o.row.get("reason", "failed"), o.row.get("detail", o.row["status"]),
                         o.row.get("t_fail", nan), o.row.get("error", nan), o.row.get("energy_drift", nan),
                         o.row.get("constraint", nan)) for o in outcomes]
    hist = {o.point.values[0]: o.row["history"] for o in outcomes if "history" in o.row}
    return StabilityReport(Path(path).stem, "methods", "", rows, hist, store_note(store, outcomes))


@dataclass(frozen=True)
class ContactRun:
    """Measure of the model-size map (``viz3d.studies``): one run's contacts (rows of start, approach
    speed, end, separation speed; shape (n, 4)), unresolved touches (same columns), restitution and
    peak contact force [N]."""

    t_end: float | None

    def __call__(self, scene) -> dict:
        traj = simulate(scene, t_end=self.t_end)
        x = traj.extras
        touches = np.asarray(x.get("contact_touches_unresolved", np.zeros((0, 4))), float).reshape(-1, 4)
        return {"status": traj.status, "contacts": np.asarray(x["contacts"]), "touches": touches,
                "restitution": float(x["restitution"]), "contact_count": int(x["contact_count"]),
                "peak_force": float(np.max(x["contact_force"]))}


def _contact_map(path, key, values, t_end, base_over, cluster, store) -> StabilityReport:
    outcomes = run_study(path, [Point((v,), (f"{key}={v}",)) for v in values], ContactRun(t_end), cluster,
                         overrides=base_over, store=store)
    runs = [{**o.row, "contacts": _contact_rows(o.row["contacts"])} if "contacts" in o.row else o.row
            for o in outcomes]
    finest = runs[-1]
    if "contacts" not in finest:
        raise RuntimeError(f"the finest model ({key} = {values[-1]}) did not run: {finest['status']}")
    ref = finest["contacts"]
    gap = GAP_FRACTION * (np.nanmax(ref[:, [0, 2]]) - ref[0, 0]) if len(ref) else 0.0
    ref_windows, e_ref = contact_windows(ref, 0.0), finest["restitution"]
    ref_any = ref_windows + _touch_windows(finest)
    rows = []
    for v, run in zip(values, runs):
        if "contacts" not in run:
            rows.append(StabilityRow("", v, float("nan"), "failed", run["status"],
                                     extra={"contacts": 0, "restitution": float("nan"), "peak_force": float("nan")}))
            continue
        windows, e = contact_windows(run["contacts"], 0.0), run["restitution"]
        # an unresolved touch (shorter than the model resolves) neither misses nor adds a contact
        missed = [w for w in ref_windows if not _overlaps(w, windows + _touch_windows(run), gap)]
        spurious = [w for w in windows if not _overlaps(w, ref_any, gap)]
        if run["status"] != "ok":
            reason, detail = "failed", run["status"]
        elif missed:
            reason, detail = "missed contact", f"no contact near {_window_text(missed[0])} ({key} = {values[-1]} has one)"
        elif spurious:
            reason, detail = "spurious contact", f"contact at {_window_text(spurious[0])} ({key} = {values[-1]} has none)"
        elif abs(e - e_ref) > RESTITUTION_TOL:
            reason, detail = "restitution error above tolerance", f"{e:.4f} vs {e_ref:.4f}"
        else:
            reason, detail = "ok", f"contacts match and restitution within {RESTITUTION_TOL} of the finest model"
        rows.append(StabilityRow("", v, float("nan"), reason, detail, extra={
            "contacts": run["contact_count"], "restitution": e, "peak_force": run["peak_force"]}))
    return StabilityReport(Path(path).stem, "contacts", key, rows, note=store_note(store, outcomes))


def _contact_rows(contacts) -> np.ndarray:
    """A ``ContactRun`` row's contacts (lists, as rows come back) as an array, shape (n, 4)."""
    return np.asarray(contacts, float).reshape(-1, 4)


def contact_windows(contacts, gap: float) -> list[tuple[float, float]]:
    """Contact intervals ``(start, end)`` [s] from a run's ``contacts`` rows (start, approach
    speed, end, separation speed), merged at the resolution ``gap`` [s] by the one definition of a
    contact, ``viz3d.contact.intervals.physical_contacts`` (0: the rows as they are; a run's
    ``contacts`` are already merged at its model's time resolution). Unfinished contacts end at
    their start."""
    rows = physical_contacts(contacts, gap).rows
    return [(float(s), float(s if np.isnan(e) else e)) for s, _, e, _ in rows]


def _touch_windows(run: dict) -> list[tuple[float, float]]:
    """Unresolved touches of a run (recontacts shorter than its model resolves; ``ContactRun``'s row)."""
    return [(float(a), float(b)) for a, _, b, _ in run["touches"]]


def _overlaps(w, windows, gap) -> bool:
    return any(a - gap <= w[1] and w[0] <= b + gap for a, b in windows)


def _window_text(w) -> str:
    return f"{w[0] * 1e6:.1f}-{w[1] * 1e6:.1f} us"


def save(report: StabilityReport, out: Path) -> list[Path]:
    """Write ``stability.md``, ``stability.csv`` and ``stability.png`` into ``out``."""
    header = ["method", "value", "dt", "reason", "detail", "t_fail", "error", "energy_drift", "constraint"]
    rows = [[r.method, r.value, r.dt, r.reason, r.detail, r.t_fail, r.error, r.energy_drift, r.constraint]
            for r in report.rows]
    return write_report(out, "stability", report.markdown(), header, rows, lambda path: _chart(report, path),
                        "stability.png")


def _chart(report: StabilityReport, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if report.mode == "methods":
        fig, axes = plt.subplots(1, 2, figsize=(10, 4))
        for method, (t, C, E) in report.histories.items():
            axes[0].semilogy(t, np.maximum(C, 1e-17), label=method)
            axes[1].semilogy(t, np.maximum(E, 1e-17), label=method)
        axes[0].set_title("constraint violation max |C| [m]")
        axes[1].set_title("energy drift |E - E0| / max T")
        for ax in axes:
            ax.set_xlabel("t [s]")
            ax.grid(True, which="both", alpha=0.3)
        axes[1].legend(fontsize=8)
    elif report.mode == "sweep":
        fig, ax = plt.subplots(figsize=(6.5, 4.5))
        for method in dict.fromkeys(r.method for r in report.rows):
            rows = [r for r in report.rows if r.method == method]
            line, = ax.loglog([float(r.value) for r in rows], [r.dt for r in rows], "o-", label=method)
            ok = [r for r in rows if r.reason == "ok"]
            ax.loglog([float(r.value) for r in ok], [r.dt for r in ok], "^", ms=11, mfc="none", color=line.get_color())
        ax.plot([], [], "^", ms=11, mfc="none", color="gray", label="stable up to the top of the range")
        ax.set_xlabel(report.key)
        ax.set_ylabel("largest stable step [s]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    else:
        fig, axes = plt.subplots(1, 2, figsize=(10, 4))
        v = [float(r.value) for r in report.rows]
        axes[0].plot(v, [r.extra["contacts"] for r in report.rows], "o-")
        axes[0].set_title("number of contacts")
        axes[1].plot(v, [r.extra["restitution"] for r in report.rows], "o-")
        axes[1].set_title("restitution")
        for ax in axes:
            ax.set_xscale("log")
            ax.set_xlabel(report.key)
            ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"stability: {report.scene}")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
