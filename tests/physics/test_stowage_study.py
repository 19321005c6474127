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


#: Ensemble runs: 0.05 s of the haul each (about 10 s of wall time on this machine).
SHORT_HAUL = "sim.t_end=0.05"
PERTURB = "ship.hauling_speed=0.05,ship.payout=1e-6"


def _ensemble_study(out, n: int):
    from viz3d.studies import STOWAGE_PERTURBATIONS
    from viz3d.studies.ensemble import parse_ensemble

    return stowage_study(SCENE, {"ship.heel": [5.0], "ship.trim": [0.0]}, [SHORT_HAUL], out=out,
                         ensemble=parse_ensemble(n, [PERTURB], STOWAGE_PERTURBATIONS))


def test_an_ensemble_resumes_member_by_member_and_a_member_reruns_alone(tmp_path):
    import viz3d

    two = _ensemble_study(tmp_path, 2)
    assert "0 of 2 runs reused, 2 run now" in two.note
    three = _ensemble_study(tmp_path, 3)  # member m is the same run in an ensemble of any size
    assert "2 of 3 runs reused, 1 run now" in three.note
    assert three.runs[:2] == two.runs and [r.member for r in three.runs] == [0, 1, 2]
    (cell,) = three.cells
    assert len(cell.runs) == 3 and cell.count("not reached") == 3
    forces = [r.peak_force for r in three.runs]
    assert len(set(forces)) == 3 and all(f > 0 for f in forces)  # the members differ
    member = three.runs[1]
    assert member.overrides[:3] == (SHORT_HAUL, "ship.heel=5.0", "ship.trim=0.0")
    traj = viz3d.simulate(viz3d.load_scene(SCENE, list(member.overrides)))
    assert float(traj.extras["stowage_peak_force"]) == member.peak_force


def test_the_command_refuses_bad_ensemble_flags_naming_them(tmp_path, capsys):
    for flags, words in ((["--ensemble", "0"], "--ensemble: expected a positive integer"),
                         (["--ensemble", "3", "--perturb", "ship.length=0.1"], "--perturb: expected a key among"),
                         (["--ensemble", "3", "--perturb", "ship.mu=-0.1"], "--perturb: expected for ship.mu")):
        # one short run if a check is missed: the test fails at once instead of running the default study
        assert main(["stowage", str(SCENE), *flags, "--heel=0", "--trim=0", "--set", "sim.t_end=0.01",
                     "--out", str(tmp_path)]) == 2
        assert words in capsys.readouterr().err
    assert not (tmp_path / "runs.jsonl").exists()


def test_the_payout_moves_the_windlass_along_its_guide_and_the_anchor_down():
    import numpy as np
    import pytest

    from viz3d.scene.load import load_scene
    from viz3d.scene.schema import SceneError

    def start(payout):
        data = load_scene(SCENE, [f"ship.payout={payout}"]).data
        guide = next(j for j in data["joints"] if j["name"] == "windlass_guide")
        return {b["name"]: np.array(b["position"]) for b in data["bodies"]}, np.array(guide["axis"])

    (p0, a), (p1, _) = start(0.0), start(1e-4)
    assert np.allclose(p1["windlass"] - p0["windlass"], -1e-4 * a, rtol=0, atol=1e-15)
    for body in ("shackle", "shank", "flukes"):
        d = p1[body] - p0[body]
        assert abs(d[0]) < 1e-15 and abs(d[1]) < 1e-15 and d[2] <= -1e-4  # straight down, at least the payout
    with pytest.raises(SceneError, match="ship.payout"):
        load_scene(SCENE, ["ship.payout=0.01"])
