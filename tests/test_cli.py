"""The command line: run, check, list; exit codes; the trajectory file contract."""

import subprocess
import sys

import numpy as np
import pytest

import viz3d
from viz3d.cli import main
from viz3d.trajectory import ARRAY_FIELDS

from conftest import ROOT, SCENES, scene_files

CONTRACT = {  # field -> shape with n frames, b bodies, j joints
    "t": ("n",), "body_names": ("b",), "mass": ("b",), "inertia_body": ("b", 3, 3), "position": ("n", "b", 3),
    "rotation": ("n", "b", 3, 3), "euler": ("n", "b", 3), "velocity": ("n", "b", 3), "omega": ("n", "b", 3),
    "energy_kinetic": ("n",), "energy_potential": ("n",), "energy_total": ("n",), "constraint_violation": ("n",),
    "joint_names": ("j",), "reaction_force": ("n", "j", 3), "status": (), "scene_json": (),
}


def test_run_writes_the_documented_trajectory_file(tmp_path, capsys):
    out = tmp_path / "dp.npz"
    code = main(["run", str(SCENES / "double_pendulum.toml"), "--t-end", "0.05", "--out", str(out), "--no-progress"])
    assert code == 0
    text = capsys.readouterr().out
    for word in ("steps", "wall time", "real-time factor", "energy", "max |C|", "status      ok", str(out)):
        assert word in text
    with np.load(out) as z:
        sizes = {"n": len(z["t"]), "b": 2, "j": 2}
        for key, shape in CONTRACT.items():
            assert z[key].shape == tuple(sizes.get(s, s) for s in shape), key
        assert list(z["body_names"]) == ["upper", "lower"] and list(z["joint_names"]) == ["shoulder", "elbow"]
        assert str(z["status"]) == "ok"
    traj = viz3d.Trajectory.load(out)
    assert traj.scene["run"]["integrator"] == "rk4" and traj.t[-1] == pytest.approx(0.05)
    assert set(ARRAY_FIELDS) >= set(CONTRACT) - {"status", "scene_json"}


def test_run_with_overrides_and_bad_override(tmp_path, capsys):
    out = tmp_path / "c.npz"
    assert main(["run", str(SCENES / "chain.toml"), "--set", "chain.n=4", "--t-end", "0.01", "--out", str(out)]) == 0
    assert viz3d.Trajectory.load(out).position.shape[1] == 4
    assert main(["run", str(SCENES / "chain.toml"), "--set", "chain.n=zero", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "chain.n" in err and "integer" in err and "chain.toml" in err


def test_check_and_list(write_scene, capsys):
    assert main(["check", *map(str, sorted(SCENES.glob("*.toml")))]) == 0
    bad = write_scene('[[bodies]]\nname = "x"\nmass = 1.0\nposition = [0, 0, 0]\n')
    assert main(["check", str(bad)]) == 2
    assert "bodies[0].inertia" in capsys.readouterr().err
    assert main(["list"]) == 0
    listing = capsys.readouterr().out
    for word in ("heavy_top", "rk4", "euler_switching", "ball", "spring_damper", "projection"):
        assert word in listing


def test_failed_run_exits_1_and_still_writes_the_frames(tmp_path, capsys):
    out = tmp_path / "fail.npz"
    code = main(["run", str(SCENES / "top_through_vertical.toml"), "--set", "sim.rotation=euler_zxz", "--set",
                 "sim.formulation=index1", "--out", str(out)])
    assert code == 1
    traj = viz3d.Trajectory.load(out)
    assert "gimbal lock" in traj.status and len(traj.t) > 5


def test_python_dash_m_works():
    res = subprocess.run([sys.executable, "-m", "viz3d", "list"], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert res.returncode == 0 and "integrators" in res.stdout


def test_progress_bar_appears_only_for_runs_projected_over_two_seconds(monkeypatch):
    import importlib
    import io

    sim_mod = importlib.import_module("viz3d.simulate")  # the module; viz3d.simulate is the function

    clock = [0.0]
    monkeypatch.setattr(sim_mod.time, "perf_counter", lambda: clock[0])
    short, long_ = io.StringIO(), io.StringIO()
    bar = sim_mod.ProgressBar(100, short)
    clock[0] = 0.3
    bar.update(50)                                   # projected 0.6 s: stays silent
    bar.close()
    assert short.getvalue() == ""
    bar = sim_mod.ProgressBar(100, long_)
    clock[0] = 0.6
    bar.update(10)                                   # projected 3 s: drawn
    bar.close()
    assert "10.0%" in long_.getvalue() and "left" in long_.getvalue()


def test_unwritable_output_does_not_lose_the_run(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    code = main(["run", str(SCENES / "spherical_pendulum.toml"), "--t-end", "0.02", "--out", str(blocker / "x.npz")])
    assert code == 0
    err = capsys.readouterr().err
    assert "cannot write" in err and "saved to" in err
    saved = err.split("saved to ")[1].split(" instead")[0]
    assert viz3d.Trajectory.load(saved).t[-1] == pytest.approx(0.02)


def test_view_command_serves_on_loopback_and_prints_the_url(capsys):
    assert main(["view", str(SCENES / "heavy_top.toml"), "--port", "0", "--duration", "1.5"]) == 0
    out = capsys.readouterr().out
    assert "viz3d viewer: open http://127.0.0.1:" in out and "heavy_top" in out
    assert main(["run", str(SCENES / "heavy_top.toml"), "--view", "--port", "0", "--duration", "0.5", "--paused"]) == 0


def test_bench_prints_its_table_and_writes_chart_and_csv(tmp_path, capsys):
    out = tmp_path / "bench"
    code = main(["bench", str(SCENES / "double_pendulum.toml"), "--methods", "rk4,dopri5", "--dt", "4e-3,2e-3",
                 "--tol", "1e-8", "--t-end", "0.2", "--out", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    assert "self-convergence" in text and "| rk4 | dt=0.004 |" in text and "| dopri5 | rtol=1e-08 |" in text
    rows = (out / "bench.csv").read_text().splitlines()
    assert len(rows) == 4 and rows[0].startswith("method,setting,error_m")
    assert (out / "work_precision.png").stat().st_size > 10_000


def test_stability_prints_reasons_and_writes_chart_and_csv(tmp_path, capsys):
    out = tmp_path / "stab"
    code = main(["stability", str(SCENES / "impact_free_bar.toml"), "--sweep", "bar.modes=2,16", "--out", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    assert "restitution error above tolerance" in text and "| 16 | ok |" in text
    assert (out / "stability.csv").read_text().count("\n") == 3 and (out / "stability.png").exists()


@pytest.mark.parametrize("args, words", [
    (["stability", "SCENES/chain.toml"], ["--methods"]),
    (["stability", "SCENES/chain.toml", "--methods", "rk4", "--sweep", "forces.k"], ["--sweep", "key.path=V1,V2"]),
    (["bench", "SCENES/chain.toml", "--methods", "rk4"], ["--dt"]),
    (["bench", "SCENES/chain.toml", "--methods", "rk5", "--dt", "1e-3"], ["rk5"]),
])
def test_bench_and_stability_refuse_bad_arguments_saying_what_is_expected(args, words, capsys):
    code = main([a.replace("SCENES", str(SCENES)) for a in args])
    assert code == 2
    err = capsys.readouterr().err
    assert all(w in err for w in words), err


def _few_frames(path) -> float:
    """A simulated time holding three stored frames of the scene at ``path`` [s] (at least three steps)."""
    import tomllib

    sim = tomllib.loads(path.read_text()).get("sim", {})
    return 3 * max(sim.get("dt", 0.0), sim.get("output_dt", 0.0), 1e-4)


@pytest.mark.parametrize("path", scene_files(), ids=lambda p: p.stem)
def test_every_shipped_scene_runs_to_its_summary(path, tmp_path, capsys):
    """A few frames of each multibody scene through ``viz3d run``: the run and its printed summary
    (scene, method, energy or contact lines, kernel, verdicts) complete on every shipped scene."""
    out = tmp_path / "x.npz"
    assert main(["run", str(path), "--t-end", f"{_few_frames(path):.6g}", "--out", str(out), "--no-progress"]) == 0
    printed = capsys.readouterr().out
    assert "status      ok" in printed and f"wrote       {out}" in printed
    assert viz3d.Trajectory.load(out).t.size >= 2
