"""Perturbation ensembles (``viz3d.studies.ensemble``) without running a scene: the Wilson interval
against scipy's and its closed forms, reproducible seeded members that differ, stay within their
stated bounds and do not depend on the ensemble's size, the flags' errors, and the stowage report's
per-cell counts, fraction and peak forces on hand-made runs (``viz3d.stowagestudy``)."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest
from scipy.stats import binomtest

from viz3d.scene.load import parse_value
from viz3d.stowagestudy import StowageReport, StowageRun, save
from viz3d.studies import STOWAGE_PERTURBATIONS
from viz3d.studies.ensemble import Z_95, Ensemble, Perturbation, members, parse_ensemble, wilson_interval
from viz3d.studies.plan import PlanError, Point

#: Wilson's interval is a closed form: it agrees with scipy's to round-off (a few ulps of O(1) terms).
INTERVAL_TOL = 1e-12
POINT = Point((5.0, 0.0), ("ship.heel=5.0", "ship.trim=0.0"))
NOMINAL = {"ship.mu": 0.25, "ship.hauling_speed": 0.15, "ship.payout": 0.0}


@pytest.mark.parametrize("k, n", [(0, 1), (1, 1), (0, 10), (3, 10), (7, 10), (10, 10), (1, 40), (17, 29)])
def test_the_wilson_interval_is_scipys(k, n):
    ref = binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    lo, hi = wilson_interval(k, n)
    assert lo == pytest.approx(ref.low, abs=INTERVAL_TOL) and hi == pytest.approx(ref.high, abs=INTERVAL_TOL)


@pytest.mark.parametrize("n", [1, 5, 20])
def test_the_wilson_interval_at_none_and_all_seated_has_its_closed_form(n):
    # k = 0: [0, z^2 / (n + z^2)]; k = n: [n / (n + z^2), 1]
    z2 = Z_95**2
    assert wilson_interval(0, n) == pytest.approx((0.0, z2 / (n + z2)), abs=INTERVAL_TOL)
    assert wilson_interval(n, n) == pytest.approx((n / (n + z2), 1.0), abs=INTERVAL_TOL)
    assert all(math.isnan(x) for x in wilson_interval(0, 0))


def _ensemble(n: int, seed: int = 0) -> Ensemble:
    return parse_ensemble(n, ["ship.mu=0.1,ship.hauling_speed=0.05", "ship.payout=1e-6"], STOWAGE_PERTURBATIONS, seed)


def _values(m) -> dict[str, float]:
    return {o.split("=")[0]: parse_value(o.split("=")[1]) for o in m.perturbed}


def test_members_are_reproducible_differ_and_do_not_depend_on_the_ensemble_size():
    five = members(_ensemble(5), POINT, NOMINAL)
    assert five == members(_ensemble(5), POINT, NOMINAL)
    assert [m.perturbed for m in members(_ensemble(3), POINT, NOMINAL)] == [m.perturbed for m in five[:3]]
    assert len({m.perturbed for m in five}) == 5
    assert {m.perturbed for m in members(_ensemble(5, seed=1), POINT, NOMINAL)}.isdisjoint({m.perturbed for m in five})
    other = Point((0.0, 3.0), ("ship.heel=0.0", "ship.trim=3.0"))  # common random numbers across grid points
    assert [m.perturbed for m in members(_ensemble(5), other, NOMINAL)] == [m.perturbed for m in five]
    run = five[2].study_point
    assert run.values == (5.0, 0.0, 2) and run.overrides[:2] == POINT.overrides


def test_members_stay_within_their_stated_bounds_and_their_text_reads_back_exactly():
    ens = _ensemble(200)
    vals = [_values(m) for m in members(ens, POINT, NOMINAL)]
    mu = np.array([v["ship.mu"] for v in vals])
    speed = np.array([v["ship.hauling_speed"] for v in vals])
    payout = np.array([v["ship.payout"] for v in vals])
    assert np.all(np.abs(mu / 0.25 - 1) <= 0.1) and np.all(np.abs(speed / 0.15 - 1) <= 0.05)
    assert np.all(np.abs(payout) <= 1e-6)
    # uniform on [-1, 1]: 200 draws fill it (the chance that all miss the outer tenth of one side is 0.95^200)
    assert np.abs(payout).max() > 0.9e-6 and payout.min() < 0 < payout.max()
    for m, v in zip(members(ens, POINT, NOMINAL)[:5], vals):
        u = ens.draws(m.index)
        assert v["ship.mu"] == 0.25 * (1 + 0.1 * u[0]) and v["ship.payout"] == 1e-6 * u[2]


@pytest.mark.parametrize("n, texts, flag, words", [
    (0, ["ship.mu=0.1"], "--ensemble", "positive integer"),
    (-2, ["ship.mu=0.1"], "--ensemble", "positive integer"),
    (3, [], "--perturb", "at least one KEY=SIZE"),
    (3, ["ship.friction=0.1"], "--perturb", "a key among ship.mu"),
    (3, ["ship.mu=-0.1"], "--perturb", "0 < SIZE < 1"),
    (3, ["ship.mu=1.5"], "--perturb", "0 < SIZE < 1"),
    (3, ["ship.payout=-1e-6"], "--perturb", "SIZE > 0"),
    (3, ["ship.mu=abc"], "--perturb", "0 < SIZE < 1"),
    (3, ["ship.mu"], "--perturb", "KEY=SIZE"),
    (3, ["ship.mu=0.1", "ship.mu=0.2"], "--perturb", "each key once"),
])
def test_bad_ensemble_flags_are_refused_naming_the_flag_and_what_was_expected(n, texts, flag, words):
    with pytest.raises(PlanError) as err:
        parse_ensemble(n, texts, STOWAGE_PERTURBATIONS)
    assert str(err.value).startswith(f"{flag}: expected") and words in str(err.value)


def _run(values, member, outcome, force):
    return StowageRun(values, outcome, 1.0, force, 0.0, 0.0, "ok" if outcome != "failed" else "diverged", 1.0, member)


def _report() -> StowageReport:
    a, b = (0.0, 0.0), (5.0, 0.0)
    outcomes_a = ["seated", "seated", "jammed", "not reached", "failed"]
    outcomes_b = ["jammed", "jammed", "jammed", "seated", "jammed"]
    runs = [_run(a, m, o, f) for m, (o, f) in enumerate(zip(outcomes_a, [200e3, 300e3, 500e3, 100e3, np.nan]))]
    runs += [_run(b, m, o, 400e3 + 1e3 * m) for m, o in enumerate(outcomes_b)]
    ens = Ensemble(5, (Perturbation("ship.mu", "relative", 0.1),))
    return StowageReport("anchor_hoist", ("ship.heel", "ship.trim"), tuple(runs), "", ens)


def test_the_cells_count_every_member_and_the_fraction_is_of_the_verdicts():
    a, b = _report().cells
    assert [a.count(o) for o in ("seated", "jammed", "not reached", "failed")] == [2, 1, 1, 1]
    assert a.n_verdicts == 4 and a.fraction_seated == 0.5 and a.interval == wilson_interval(2, 4)
    assert a.peak_forces == (100e3, 250e3, 500e3)  # the failed member's nan left out
    assert b.fraction_seated == 0.2 and b.peak_forces == (400e3, 402e3, 404e3)


def test_the_ensemble_report_writes_its_cells_and_every_member(tmp_path):
    report = _report()
    text = report.markdown()
    assert "| 0 | 0 | 5 | 2 | 1 | 1 | 1 | 2/4 = 0.50 [0.15, 0.85] | 100.0 / 250.0 / 500.0 |" in text
    assert "1 failed at {'ship.heel': 0.0, 'ship.trim': 0.0}, member 4: diverged" in text
    save(report, tmp_path)
    with (tmp_path / "cells.csv").open() as f:
        cells = list(csv.DictReader(f))
    for c in cells:
        assert sum(int(c[o]) for o in ("seated", "jammed", "not reached", "failed")) == int(c["members"]) == 5
    assert [float(c["fraction_seated"]) for c in cells] == [0.5, 0.2]
    with (tmp_path / "runs.csv").open() as f:
        assert [int(r["member"]) for r in csv.DictReader(f)] == [0, 1, 2, 3, 4] * 2
    assert (tmp_path / "chart.png").stat().st_size > 1000
