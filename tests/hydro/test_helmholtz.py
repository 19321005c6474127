"""The series against an independent finite-element solution of the truncated reservoir (helmholtz_fe).

The FE error is O(dx^2) for the base pressure and the face integrals, so with grids dx and dx/2
the fine grid's error is about |FE(dx) - FE(dx/2)| / 3 (Richardson). The series must lie within
|FE(dx) - FE(dx/2)| of the fine solution (a margin of 3 over that estimate; the series is summed to
SERIES_RTOL, its bound two orders below the FE differences of about 1e-4 rho h), and the coarse grid
must be at least twice as far from it as the fine one (the FE converges to the series, not elsewhere).
"""

from __future__ import annotations

import helmholtz_fe as fe
import numpy as np
import pytest

from viz3d.hydro import dam as D
from viz3d.hydro.reservoir import Reservoir, added_mass, pressure
from viz3d.hydro.shapes import SmoothShapes

RHO, H, C = 1000.0, 100.0, 1493.0
GRIDS = (20, 40)
SERIES_RTOL = 1e-6
BAR = D.cantilever_dam().bar


def first_mode(y):
    return BAR.displacement(y)[:, 0] / np.abs(BAR.displacement([H])[0, 0])


CASES = {
    # name: (sound speed, reflection, omega, shape)
    "incompressible, uniform": (np.inf, 1.0, 0.0, lambda y: np.ones_like(y)),
    "seed, uniform, 20 rad/s": (C, 1.0, 20.0, lambda y: np.ones_like(y)),
    "seed, uniform, 80 rad/s (two radiating terms)": (C, 1.0, 80.0, lambda y: np.ones_like(y)),
    "seed, dam mode 1, 40 rad/s": (C, 1.0, 40.0, first_mode),
    "alpha 0.5, quadratic, at the rigid cut-off": (C, 0.5, 23.452, lambda y: (y / H) ** 2),
    "alpha 0, quadratic, 60 rad/s": (C, 0.0, 60.0, lambda y: (y / H) ** 2),
}


def fe_quantities(c, alpha, omega, shape, n_y):
    """Base pressure, face force int p dy and generalized force int phi p dy from the FE solution."""
    reservoir = Reservoir(RHO, H, c, alpha)
    y, p = fe.solve(RHO, H, c, omega, shape, n_y=n_y, admittance=reservoir.admittance)
    return np.array([p[0], np.trapezoid(p, y), np.trapezoid(shape(y) * p, y)])


def series_quantities(c, alpha, omega, shape):
    reservoir = Reservoir(RHO, H, c, alpha)
    base = pressure(reservoir, shape, omega, [0.0], rtol=SERIES_RTOL).value[0, 0]
    pair = SmoothShapes.from_function(lambda y: np.column_stack([np.ones_like(y), shape(y)]), H)
    A = added_mass(reservoir, pair, omega, rtol=SERIES_RTOL).value[0]
    return np.array([base, A[0, 1], A[1, 1]])


@pytest.mark.parametrize("name", list(CASES))
def test_series_agrees_with_finite_elements(name):
    c, alpha, omega, shape = CASES[name]
    coarse, fine = (fe_quantities(c, alpha, omega, shape, n) for n in GRIDS)
    series = series_quantities(c, alpha, omega, shape)
    difference = np.abs(coarse - fine)
    assert np.all(np.abs(series - fine) <= difference), (series, fine, coarse)
    assert np.all(np.abs(series - coarse) >= 2.0 * np.abs(series - fine)), (series, fine, coarse)
