"""`viz3d stowage`: one run per grid point, a table, CSV, JSON and chart; a point the scene refuses is
a failed row and the other points' runs are kept."""

from __future__ import annotations

import csv
import json
from pathlib import Path

from viz3d.cli import main
from viz3d.stowagestudy import stowage_study

SCENE = Path(__file__).resolve().parents[2] / "scenes" / "anchor_hoist.toml"


def test_a_refused_point_is_a_failed_row_and_the_others_are_kept():
    report = stowage_study(SCENE, {"ship.heel": [0.0, 4.0], "ship.pipe_angle": [25.0, 35.0]}, ["sim.t_end=0.1"])
    rows = {r.values: r for r in report.runs}
    assert len(rows) == 4
    for heel in (0.0, 4.0):
        assert rows[(heel, 35.0)].outcome == "failed" and "ship.pipe_angle" in rows[(heel, 35.0)].status
        assert rows[(heel, 25.0)].outcome == "not reached" and rows[(heel, 25.0)].status == "ok"
        assert rows[(heel, 25.0)].peak_force > 0.0
    assert "| ship.heel | ship.pipe_angle | verdict |" in report.markdown()


def test_the_command_writes_table_csv_json_and_chart(tmp_path, capsys):
    out = tmp_path / "study"
    code = main(["stowage", str(SCENE), "--heel=-3,3", "--trim=0", "--set", "sim.t_end=0.1", "--out", str(out)])
    assert code == 0
    assert "stowage study of anchor_hoist" in capsys.readouterr().out
    with (out / "runs.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [float(r["ship.heel"]) for r in rows] == [-3.0, 3.0] and {r["verdict"] for r in rows} == {"not reached"}
    assert len(json.loads((out / "runs.json").read_text())["runs"]) == 2
    assert (out / "chart.png").stat().st_size > 1000 and (out / "table.md").read_text().count("\n| ") == 3
