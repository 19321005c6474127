"""Centrifugal geometric stiffening (``viz3d.flexible.floating.with_geometric_stiffening``) against the
classical frequencies of a uniform cantilever turning about its root, out of the plane of rotation
(flapwise: no centrifugal softening there): first frequency ``omega / sqrt(EI / rho A L^4)`` = 3.6816,
4.1373, 4.7973, 5.5850 at the spin ``Omega / sqrt(EI / rho A L^4)`` = 1, 2, 3, 4 (Hodges & Rutkowski
1981; Wright, Smith, Thresher & Wang 1982, hub radius 0)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import eigh

import viz3d
from viz3d.flexible import Material, Section, analytic_modes
from viz3d.flexible.floating import floating_bar, with_geometric_stiffening
from viz3d.scene.schema import SceneError

from conftest import SCENES

#: (spin, first frequency), both over sqrt(EI / rho A L^4).
TABLE = [(1.0, 3.6816), (2.0, 4.1373), (3.0, 4.7973), (4.0, 5.5850)]
#: Half a unit of the table's last digit, relative.
TABLE_RTOL = 0.5e-4 / 3.6


@pytest.mark.parametrize("spin, frequency", TABLE)
def test_first_flapwise_frequency_of_a_rotating_cantilever(spin, frequency):
    modes = analytic_modes("euler_bernoulli", 10.0, Material(7e10, 3000.0, 0.3), Section(4e-4, 2e-7, 0.0775), 8,
                           ("clamped", "free"))
    bar = with_geometric_stiffening(floating_bar(modes))
    unit = np.sqrt(7e10 * 2e-7 / (3000.0 * 4e-4 * 10.0**4))
    omega2 = eigh(bar.K + (spin * unit) ** 2 * bar.K_omega, bar.M_ee, eigvals_only=True)[0]
    # Ritz with 8 non-rotating modes: converged far below the table's digits (the rotating mode 1 is
    # mostly the non-rotating one)
    assert abs(np.sqrt(omega2) / unit / frequency - 1.0) <= TABLE_RTOL


def test_the_stiffening_centre_is_the_supported_end_and_the_tension_vanishes_at_the_free_end():
    m = Material(7e10, 3000.0, 0.3)
    s = Section(4e-4, 2e-7, 0.0775)
    root = with_geometric_stiffening(floating_bar(analytic_modes("euler_bernoulli", 10.0, m, s, 3, ("clamped", "free"))))
    tip = with_geometric_stiffening(floating_bar(analytic_modes("euler_bernoulli", 10.0, m, s, 3, ("free", "clamped"))))
    assert root.x_s == 0.0 and tip.x_s == 10.0
    # mirror images: the same stiffness for the mirrored shapes (slopes change sign, products do not)
    np.testing.assert_allclose(np.diag(root.K_omega), np.diag(tip.K_omega), rtol=1e-9)


def test_a_rod_cannot_be_stiffened():
    with pytest.raises(SceneError, match="geometric_stiffening"):
        viz3d.build(viz3d.load_scene(SCENES / "spin_up_beam.toml", ("bodies.beam.theory=rod",)))
