"""A chain hanging between two points (``[chain] end``, universal joints with dampers) settles on
the discrete catenary, which tends to the catenary as the links shrink (issue 11).

References written here, independent of the simulator:

* the discrete catenary of N uniform rods: the link angles that minimise the potential energy
  (the rods' centres' heights) with both ends pinned, by scipy's SLSQP on the angles;
* the catenary of the same length and weight per length: ``L = 2 a sinh(S / 2a)``, sag
  ``a (cosh(S / 2a) - 1)``, horizontal tension ``H = w a``, vertical ``w L / 2`` at each end.

The simulated chain starts as a circular arc and settles under the joints' dampers; after ``t``
its motion has decayed to the damped modes' ``exp(-t / tau)``: the bounds hold with that margin.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq, minimize

import viz3d

G, SPAN, LENGTH, RADIUS, RHO = 9.81, 1.0, 1.4, 0.005, 7800.0


def catenary(span: float, length: float, w: float) -> dict:
    """Sag [m] and end tensions [N] of a catenary of ``length`` between two points ``span`` apart at one
    height, weight ``w`` [N/m]."""
    a = brentq(lambda a: 2 * a * np.sinh(span / (2 * a)) - length, 1e-3 * span, 1e3 * span, xtol=1e-15)
    return {"sag": a * (np.cosh(span / (2 * a)) - 1), "H": w * a, "V": w * length / 2}


def discrete_catenary(n: int, span: float, length: float) -> np.ndarray:
    """Joint points (n + 1, 2) (x, z) of n uniform rods of length length / n pinned at (0, 0) and
    (span, 0) in equilibrium under gravity: the minimum of the sum of the rods' centre heights."""
    ell = length / n

    def centres_z(th):
        z = np.concatenate([[0.0], np.cumsum(ell * np.sin(th))])
        return 0.5 * (z[:-1] + z[1:])

    cons = [{"type": "eq", "fun": lambda th: np.sum(ell * np.cos(th)) - span},
            {"type": "eq", "fun": lambda th: np.sum(ell * np.sin(th))}]
    s = np.linspace(-1.0, 1.0, n)
    th0 = -np.arcsin(np.clip(s * 0.9, -1, 1)) * 0.9
    res = minimize(lambda th: np.sum(centres_z(th)), th0, constraints=cons, method="SLSQP",
                   options={"ftol": 1e-15, "maxiter": 2000})
    assert res.success, res.message
    th = res.x
    x = np.concatenate([[0.0], np.cumsum(ell * np.cos(th))])
    z = np.concatenate([[0.0], np.cumsum(ell * np.sin(th))])
    return np.column_stack([x, z])


def _hang(tmp_path, n: int, t_end: float):
    path = tmp_path / f"chain{n}.toml"
    path.write_text(f"""[sim]\nt_end = {t_end}\ndt = 5e-4\noutput_dt = 0.05\n
[chain]\nn = {n}\nlink_length = {LENGTH / n}\nradius = {RADIUS}\ndensity = {RHO}\nanchor = [0.0, 0.0, 0.0]
end = [{SPAN}, 0.0, 0.0]\njoint = "universal"\njoint_damping = {0.01 * 16 / n}
""")
    traj = viz3d.simulate(viz3d.load_scene(path))
    assert traj.status == "ok", traj.status
    return traj


def test_the_discrete_catenary_tends_to_the_catenary_at_second_order():
    """Sag and horizontal tension (H from the moments of the left half about its end, weight w per
    length carried at the rods' centres) approach the catenary's as O(1/N^2)."""
    w = 1.0
    ref = catenary(SPAN, LENGTH, w)
    sag, H = [], []
    for n in (8, 16, 32):
        nodes = discrete_catenary(n, SPAN, LENGTH)
        centres = 0.5 * (nodes[:-1] + nodes[1:])
        sag.append(abs(-nodes[:, 1].min() - ref["sag"]))
        H.append(abs(-w * LENGTH / n * centres[: n // 2, 0].sum() / nodes[n // 2, 1] - ref["H"]))
    for e in (sag, H):
        assert e[0] / e[1] > 3.5 and e[1] / e[2] > 3.5, e


@pytest.mark.parametrize("n", [8, 16])
def test_a_chain_between_two_points_settles_on_the_discrete_catenary(tmp_path, n):
    traj = _hang(tmp_path, n, 12.0)
    nodes = discrete_catenary(n, SPAN, LENGTH)
    centres = 0.5 * (nodes[:-1] + nodes[1:])
    got = traj.position[-1][:, [0, 2]]
    assert np.abs(traj.position[-1][:, 1]).max() < 1e-9  # stays in its plane
    err = np.abs(got - centres).max()
    assert err < 1e-6 * LENGTH, err
    # end forces: each end carries half the weight (exact for any n); the horizontal force is the
    # same all along the chain, H = -m g sum(x_c) / z_mid from the moments of the left half about A
    # (the middle joint's force is horizontal by symmetry), with the reference's centres
    m_link = RHO * (np.pi * RADIUS**2 * LENGTH / n + 4 / 3 * np.pi * RADIUS**3)
    V = n * m_link * G / 2
    H = -m_link * G * centres[: n // 2, 0].sum() / nodes[n // 2, 1]
    ends = [list(traj.joint_names).index(f"link_j{k}") for k in (0, n)]  # the two ball joints to ground
    F = np.abs(traj.reaction_force[-1, ends])
    # the motion left after t_end (positions within 1e-6 L) moves the forces by as little
    np.testing.assert_allclose(F[:, 2], V, rtol=1e-6)
    np.testing.assert_allclose(F[:, 0], H, rtol=1e-6)


@pytest.mark.parametrize("extra, key", [("end = [2.0, 0.0, 0.0]", "chain.end"), ("end = [0.0, 0.0, 0.0]", "chain.end"),
                                        ("end = [1.0, 0.0, 0.0]\nomega = [0.0, 0.0, 1.0]", "chain.omega")])
def test_a_chain_that_cannot_hang_between_its_anchors_is_refused(tmp_path, extra, key):
    from viz3d.scene.schema import SceneError

    path = tmp_path / "bad.toml"
    path.write_text(f"[chain]\nn = 4\nlink_length = 0.25\n{extra}\n")
    with pytest.raises(SceneError) as err:
        viz3d.load_scene(path)
    assert err.value.path == key and str(path) in str(err.value)


def test_the_initial_arc_has_the_link_lengths_and_ends_on_the_anchors():
    from viz3d.scene.load import _arc_nodes

    A, E = np.array([0.1, -0.2, 0.3]), np.array([0.9, 0.4, 0.1])
    nodes, normal = _arc_nodes(A, E, 7, 0.2, np.array([0.0, 0.0, -9.81]), "<test>")
    np.testing.assert_allclose(np.linalg.norm(np.diff(nodes, axis=0), axis=1), 0.2, rtol=1e-12)
    np.testing.assert_array_equal(nodes[[0, -1]], [A, E])
    assert nodes[1:-1, 2].max() < max(A[2], E[2])  # it sags
    np.testing.assert_allclose((nodes - A) @ normal, 0.0, atol=1e-15)  # in one plane
