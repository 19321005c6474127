"""Every scene in scenes/ runs headless and passes its own [checks]."""

import warnings

import numpy as np
import pytest

import viz3d

from conftest import scene_files

SCENE_FILES = scene_files()  # multibody scenes (hydro: tests/hydro/test_hydro_scenes.py)
CONTACTS = [p for p in SCENE_FILES if any(c["events"] for c in viz3d.load_scene(p).data["contacts"])]


def test_all_required_scenes_ship():
    names = {p.stem for p in SCENE_FILES}
    assert {"spherical_pendulum", "double_pendulum", "chain", "heavy_top", "torque_free", "robot_arm",
            "top_through_vertical"} <= names


def _run_with_checks(path):
    """Run a scene to its checks' t_end: (scene, checks, trajectory), after the checks every
    scene has (its warnings, its final status)."""
    scene = viz3d.load_scene(path)
    checks = scene.data["checks"]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        traj = viz3d.simulate(scene, t_end=checks.get("t_end"))
    if checks["no_warnings"]:
        assert not caught, [str(w.message) for w in caught]
    assert traj.status == checks["status"], traj.status
    return scene, checks, traj


@pytest.mark.parametrize("path", SCENE_FILES, ids=lambda p: p.stem)
def test_scene_runs_headless_and_passes_its_checks(path):
    scene, checks, traj = _run_with_checks(path)
    for key in ("position", "rotation", "velocity", "omega", "energy_total", "reaction_force"):
        assert np.all(np.isfinite(getattr(traj, key))), f"NaN in {key}"
    assert traj.t[-1] == pytest.approx(checks.get("t_end", scene.data["sim"]["t_end"]))
    if "max_constraint_violation" in checks:
        assert traj.max_constraint_violation <= checks["max_constraint_violation"]
    if "max_energy_drift_rel" in checks:
        assert traj.energy_drift_rel <= checks["max_energy_drift_rel"]
    if "min_chart_switches" in checks:
        assert traj.chart_switches.sum() >= checks["min_chart_switches"]
    if any(c["events"] for c in scene.data["contacts"]):  # located contacts: their ledger and report
        _contact_checks(traj, checks)
    elif "collision" in scene.data:  # shape contacts: how many, never negative forces
        x = traj.extras
        assert np.all(np.isfinite(x["collision_normal_force"])) and np.all(x["collision_normal_force"] >= 0)
        if "min_contacts" in checks:
            assert x["collision_contacts"].max() >= checks["min_contacts"]


def test_contact_scenes_ship():
    assert {p.stem for p in CONTACTS} >= {"bouncing_sphere", "impact_free_bar", "impact_clamped_bar"}


def _contact_checks(traj, checks):
    x = traj.extras
    for key in ("contact_force", "penetration", "gauge_strain", "energy_dissipated", "energy_balance_error"):
        assert np.all(np.isfinite(x[key])), f"NaN in {key}"
    assert np.all(x["contact_force"] >= 0)
    if "max_energy_balance_error" in checks:  # relative to the largest energy of the run
        scale = max(np.abs(traj.energy_total).max(), traj.energy_kinetic.max())
        assert np.abs(x["energy_balance_error"]).max() <= checks["max_energy_balance_error"] * scale
    if "restitution" in checks:
        assert float(x["restitution"]) == pytest.approx(checks["restitution"], abs=checks["restitution_tol"])
    if "min_contacts" in checks:
        assert int(x["contact_count"]) >= checks["min_contacts"]
