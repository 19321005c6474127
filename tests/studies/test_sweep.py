"""``viz3d sweep`` in this process: the table (Parquet, CSV), chart and results store; a refused point
and a run that raises are rows with their diagnosis; an interrupted study started again runs only the
missing points; bad flags are refused naming the flag."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from dataclasses import dataclass

import pyarrow.parquet as pq
import pytest

import viz3d.sweep
from viz3d.cli import main
from viz3d.studies.execute import run_study
from viz3d.studies.plan import grid_points

from conftest import SCENES

SCENE = SCENES / "spherical_pendulum.toml"
#: Short NumPy-path runs (about 0.1 s each): the points of these tests.
SHORT = ["--set", "sim.t_end=0.2", "--set", "sim.compiled=false"]
GRID = ["--grid", "sim.dt=1e-3,2e-3,0.5", "--grid", "sim.integrator=rk4,heun"]


def _sweep(out, *extra):
    return main(["sweep", str(SCENE), *GRID, *SHORT, "--workers", "1", "--out", str(out), *extra])


def _store_keys(out) -> list[str]:
    return [json.loads(line)["key"] for line in (out / "runs.jsonl").read_text().splitlines()]


def test_the_table_has_every_point_with_its_status_metrics_and_cost(tmp_path, capsys):
    out = tmp_path / "study"
    assert _sweep(out, "--metrics", "status,energy_drift_rel,n_steps") == 0
    table = pq.read_table(out / "table.parquet").to_pylist()
    assert len(table) == 6 and [r["sim.integrator"] for r in table[:2]] == ["rk4", "heun"]
    ok = [r for r in table if r["sim.dt"] < 0.5]
    assert all(r["status"] == "ok" and r["n_rhs"] == {"rk4": 4, "heun": 2}[r["sim.integrator"]] * r["n_steps"]
               for r in ok)
    assert ok[0]["energy_drift_rel"] < ok[1]["energy_drift_rel"]  # rk4 keeps energy better than heun
    refused = [r for r in table if r["sim.dt"] == 0.5]  # dt above t_end: the scene refuses the point
    assert len(refused) == 2 and all(r["status"].startswith("refused") and "sim.dt" in r["status"] for r in refused)
    with (out / "table.csv").open() as fh:
        assert [r["status"] for r in csv.DictReader(fh)] == [r["status"] for r in table]
    assert (out / "chart.png").stat().st_size > 10_000
    assert len(_store_keys(out)) == 4  # refused points are not runs
    assert "6 of 6 runs, 2 failed" in capsys.readouterr().out


def test_an_interrupted_study_started_again_runs_only_the_missing_points(tmp_path, capsys, monkeypatch):
    out = tmp_path / "study"
    calls = []
    simulate = viz3d.sweep.simulate

    def interrupted_at_the_third_run(scene):
        calls.append(scene)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return simulate(scene)

    monkeypatch.setattr(viz3d.sweep, "simulate", interrupted_at_the_third_run)
    assert _sweep(out) == 130
    assert "the same command runs only the missing ones" in capsys.readouterr().err
    assert len(_store_keys(out)) == 2
    monkeypatch.setattr(viz3d.sweep, "simulate", simulate)
    assert _sweep(out, "--max-runs", "1") == 0
    assert len(_store_keys(out)) == 3
    assert _sweep(out) == 0
    keys = _store_keys(out)
    assert len(keys) == len(set(keys)) == 4  # each run once: none ran again
    assert "6 of 6 runs, 2 failed, 3 from the results store" in capsys.readouterr().out


@dataclass(frozen=True)
class Raises:
    """A measure whose run raises (a bug in a measure, or in the code it calls)."""

    def __call__(self, scene):
        raise ZeroDivisionError("in the measure")


def test_a_run_that_raises_is_a_row_with_its_diagnosis():
    outcomes = run_study(SCENE, grid_points({"sim.t_end": [0.1, 0.2]}), Raises())
    assert [o.row["status"] for o in outcomes] == ["raised ZeroDivisionError: in the measure"] * 2


@pytest.mark.parametrize("args, words", [
    (["--grid", "sim.dt"], ["--grid", "key.path=V1,V2"]),
    (["--sample", "sim.dt=beta(1, 2)"], ["--sample", "uniform(low, high)"]),
    ([], ["--grid", "at least one --grid or --sample"]),
    (["--grid", "sim.dt=1e-3", "--n", "5"], ["--n", "a --sample"]),
    (["--grid", "sim.dt=1e-3", "--metrics", "status,energy drift"], ["--metrics", "metric names"]),
    (["--grid", "sim.dt=1e-3", "--workers", "0"], ["--workers", "expected"]),
    (["--grid", "sim.nope=1,2"], ["every point was refused", "sim.nope"]),
])
def test_bad_flags_are_refused_naming_the_flag(args, words, tmp_path, capsys):
    assert main(["sweep", str(SCENE), *args, *SHORT, "--workers", "1", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert all(w in err for w in words), err


def test_run_and_sweep_in_this_process_never_import_dask(tmp_path):
    """Startup time: Dask is imported only when a study goes to a cluster."""
    code = ("import sys\nfrom viz3d.cli import main\n"
            f"assert main(['run', {str(SCENE)!r}, '--t-end', '0.01', '--set', 'sim.compiled=false', '--out', "
            f"{str(tmp_path / 'r.npz')!r}]) == 0\n"
            f"assert main(['sweep', {str(SCENE)!r}, '--grid', 'sim.t_end=0.01,0.02', '--set', 'sim.compiled=false', "
            f"'--workers', '1', "
            f"'--out', {str(tmp_path)!r}]) == 0\n"
            "assert not {'dask', 'distributed'} & set(sys.modules), sorted(m for m in sys.modules if 'dask' in m)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
