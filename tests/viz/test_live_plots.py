"""The live viewer's plots (``viz3d.realtime.plot_series``) for drives and force elements."""

import numpy as np
import pytest

import viz3d

from conftest import SCENES


@pytest.mark.parametrize("scene, title", [("slider_crank", "Drive effort [N or N m]"),
                                          ("shapes_on_a_ramp", "Shape contacts: normal force [N]")])
def test_live_plots_show_drive_efforts_and_element_plots(scene, title):
    """The viewer's plots (viz3d.realtime.plot_series) include a scene's drives and its force
    elements' own plots, each series read from the frame's scalars."""
    from viz3d.realtime import make_driver

    driver = make_driver(viz3d.load_scene(SCENES / f"{scene}.toml"))
    titles = [t for t, _ in driver.plots]
    assert title in titles
    values = driver.plot_values(driver.frame())
    assert len(values) == sum(len(labels) for _, labels in driver.plots)
    assert all(np.isfinite(values))


def test_the_hoist_plots_the_chain_tension_at_the_hawse_and_the_ledger():
    """anchor_hoist: the chain's tension at the hawse (an output element, viz3d.outputs.HawseTension)
    and the energy ledger (a drive works) are live plots; the tension read from the frame is the
    reaction force of the chain joint whose upper end is nearest to the hawse point, computed here
    from the frame's poses and reactions."""
    from viz3d.realtime import make_driver

    driver = make_driver(viz3d.load_scene(SCENES / "anchor_hoist.toml"))
    titles = [t for t, _ in driver.plots]
    assert "Chain tension at the hawse [N]" in titles and "Energy ledger [J]" in titles
    frame = driver.frame()
    spec, system = driver.scene.data["stowage"], driver.system
    names, joints = list(system.bodies.names), list(system.joint_names)
    links = [i for i in range(len(names)) if f"link{i}" in names]
    b = [names.index(f"link{i}") for i in links]
    j = [joints.index(f"link_j{i}") for i in links]
    half = 0.5 * np.linalg.norm(frame.W_r[b[1]] - frame.W_r[b[0]])
    ends = frame.W_r[b] - half * frame.R_WB[b][:, :, 2]
    k = int(np.argmin(np.linalg.norm(ends - np.asarray(spec["hawse"]), axis=1)))
    expected = np.linalg.norm(frame.reaction_force[j[k]])
    assert expected > 0.0
    assert frame.scalars["stowage/hawse_tension"] == pytest.approx(expected, rel=1e-12)
