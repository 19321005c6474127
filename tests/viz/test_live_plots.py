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
