"""Deflection gauges (``viz3d.outputs.DeflectionGauges``) and the stress a flexible body's drawing
carries (``viz3d.frames.FlexibleDrawing.stresses``), against beam theory nobody here wrote:

* a pinned-pinned beam under its own weight q sags ``5 q L^4 / (384 E I)`` at midspan (Timoshenko &
  Gere). The deflection is quartic, inside the quintic element's space: the full FE model gives it
  to the round-off floor of K. Reduced to its lowest 4 modes (the four-bar's links), the static
  response is the modal series ``(4 q L^4 / pi^5 E I) sum_{k odd} (-1)^((k-1)/2) / k^5`` cut after
  k = 3: an alternating series, so the relative error lies between ``-5^-5 / S`` and 0
  (``S = 5 pi^5 / 1536``, the whole sum), widened by the FE error of the kept mode 3 (below);
* a cantilever under a tip load P has ``M(x) = P (L - x)``: surface stress ``-+ M c / I`` on the +-w
  fibres, ``P L c / I`` at the clamp. w is cubic, exact in the quintic space: the drawing's stress
  at every section matches to the round-off floor of K, or float32's resolution (the drawing's
  stresses are float32), whichever is larger.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from beam_exact import roundoff_floor

import viz3d
from viz3d.outputs import DeflectionGauges
from viz3d.scene.build import build
from viz3d.scene.schema import SceneError
from viz3d.scene.visuals import RING, SECTIONS, flexible_drawings
from viz3d.viz.colors import ANCHOR_RGB, StressColors

L, E, RHO, WIDTH, DEPTH, G = 0.2794, 70e9, 2700.0, 0.0254, 0.0016, 9.81
I = WIDTH * DEPTH**3 / 12
Q = RHO * WIDTH * DEPTH * G                       # weight per length [N/m]
F32 = float(np.finfo(np.float32).eps)

BEAM = f"""
[sim]
gravity = [0.0, 0.0, -{G}]
[[bodies]]
name = "beam"
type = "flexible"
frame = "fixed"
length = {L}
material = {{ E = {E}, rho = {RHO}, nu = 0.33 }}
section = {{ type = "rectangle", width = {WIDTH}, depth = {DEPTH} }}
theory = "euler_bernoulli"
model = "fe"
element = "quintic"
elements = 4
supports = ["pinned", "pinned"]
position = [0.0, 0.0, 0.0]
axis = [1.0, 0.0, 0.0]
bending_direction = [0.0, 0.0, 1.0]
[[gauges]]
name = "mid"
x = {L / 2}
quantity = "deflection"
"""


def _static_under_weight(system):
    """eta of the fixed-frame beam in equilibrium under gravity: K eta = rho A (g . d) int Phi dx."""
    fb = system.bodies.flexible[0]
    model = fb.bar.fields[0]
    g_w = np.array([0.0, 0.0, -G]) @ (fb.R0 @ fb.bar.directions[0])
    return np.linalg.solve(fb.bar.K, g_w * model.S1), roundoff_floor(fb.bar.K)


def _sag(write_scene, *overrides):
    system, _ = build(viz3d.load_scene(write_scene(BEAM), list(overrides)))
    (gauge,) = system.outputs
    assert isinstance(gauge, DeflectionGauges) and gauge.keys == ("deflection/mid",)
    eta, floor = _static_under_weight(system)
    return gauge.values(SimpleNamespace(eta=(eta,)))["deflection/mid"], floor, system


def test_midspan_sag_under_own_weight_is_5qL4_over_384EI(write_scene):
    w, floor, _ = _sag(write_scene)
    exact = -5 * Q * L**4 / (384 * E * I)         # gravity -z, bending direction +z: sags negative
    assert abs(w / exact - 1) <= floor


def test_four_mode_sag_is_within_the_modal_series_truncation(write_scene):
    w, floor, system = _sag(write_scene, "bodies.beam.modes=4")
    exact = -5 * Q * L**4 / (384 * E * I)
    S = 5 * np.pi**5 / 1536
    # FE error of the kept mode 3: its share of the sag is 3^-5 / S; its shape error is of the order of
    # the square root of its frequency error (Rayleigh quotient), the response's twice that.
    EI_rhoA = np.sqrt(E * I / (RHO * WIDTH * DEPTH))
    omega3 = system.bodies.flexible[0].bar.fields[0].frequencies()[2]
    fe3 = abs(omega3 / ((3 * np.pi / L) ** 2 * EI_rhoA) - 1)
    margin = 2 * 3.0**-5 / S * np.sqrt(fe3) + floor
    assert -5.0**-5 / S - margin <= w / exact - 1 <= margin
    assert w / exact - 1 < -0.5 * 5.0**-5 / S, "a 4-mode sag should show the truncation, not be exact"


def test_deflection_gauge_on_a_rod_or_off_the_bar_is_refused(write_scene):
    with pytest.raises(SceneError, match=r"gauges\[0\]\.x"):
        build(viz3d.load_scene(write_scene(BEAM.replace(f"x = {L / 2}", "x = 0.5"))))
    rod = BEAM.replace('theory = "euler_bernoulli"', 'theory = "rod"').replace('element = "quintic"\n', "")
    with pytest.raises(SceneError, match=r"gauges\[0\]\.quantity"):
        build(viz3d.load_scene(write_scene(rod.replace('["pinned", "pinned"]', '["clamped", "free"]'))))
    with pytest.raises(SceneError, match=r"gauges\[0\]\.quantity"):
        viz3d.load_scene(write_scene(BEAM.replace('quantity = "deflection"', 'quantity = "sag"')))


def _tip_loaded_cantilever(write_scene, P):
    text = BEAM.replace('["pinned", "pinned"]', '["clamped", "free"]')
    scene = viz3d.load_scene(write_scene(text))
    system, _ = build(scene)
    fb = system.bodies.flexible[0]
    eta = np.linalg.solve(fb.bar.K, fb.bar.fields[0].point_force(L, P))
    (drawing,) = flexible_drawings(scene, system)
    return drawing, eta, roundoff_floor(fb.bar.K)


def test_drawing_stress_is_M_c_over_I_along_a_tip_loaded_cantilever(write_scene):
    P = 2.0
    drawing, eta, floor = _tip_loaded_cantilever(write_scene, P)
    sigma = drawing.stresses(SimpleNamespace(eta=(eta,))).reshape(SECTIONS, RING)
    x = np.linspace(0.0, L, SECTIONS)
    c = drawing.ring @ np.array([0.0, 1.0, 0.0])  # body axes: the bending field's direction d = e_y
    exact = -P * (L - x)[:, None] * c[None, :] / I
    tol = max(floor, 2 * F32) * P * L * (DEPTH / 2) / I
    assert np.abs(sigma - exact).max() <= tol
    clamp = sigma[0]                                # the ring nearest the clamp (at it)
    assert np.abs(np.abs(clamp) - P * L * (DEPTH / 2) / I).max() <= tol
    assert np.all(clamp[c > 0] < 0) and np.all(clamp[c < 0] > 0)  # +w fibre compressed


def test_stress_colours_put_the_signs_at_the_two_ends_of_the_map(write_scene):
    P = 2.0
    drawing, eta, _ = _tip_loaded_cantilever(write_scene, P)
    sigma = drawing.stresses(SimpleNamespace(eta=(eta,))).reshape(SECTIONS, RING)
    c = drawing.ring[:, 1]
    sigma_clamp = P * L * (DEPTH / 2) / I
    for colors in (StressColors(sigma_clamp), StressColors()):   # the scene's scale, or the running max
        assert colors.observe([sigma]) == pytest.approx(sigma_clamp, rel=2 * F32)
        rgb = colors(sigma[0])
        assert np.all(rgb[c > 0] == ANCHOR_RGB[0]) and np.all(rgb[c < 0] == ANCHOR_RGB[-1])
        assert np.all(colors(sigma[-1]) == ANCHOR_RGB[2])       # free end: M = 0, the middle of the map
    mid = colors(np.array([-0.5, 0.5]) * sigma_clamp)
    assert np.all(mid == ANCHOR_RGB[[1, 3]])


def test_map_anchors_are_matplotlibs_coolwarm():
    mpl = pytest.importorskip("matplotlib")
    cmap = mpl.colormaps["coolwarm"]
    reference = np.array([cmap(v)[:3] for v in (0.0, 0.25, 0.5, 0.75, 1.0)]) * 255
    assert np.abs(ANCHOR_RGB - reference).max() <= 0.5 + 1e-9       # to RGB rounding
