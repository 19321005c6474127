"""Independent references for tests/hydro, written without any viz3d code.

* Chopra (1967) and the issue's statement of it: the incompressible force on a rigid vertical dam,
  F = (16 / pi^3) sum 1/(2n - 1)^3 rho a h^2 = 0.5428 rho a h^2 (four decimals).
* Catalan's constant G = 0.915965594177219015... (OEIS A006752): the incompressible pressure at
  the base of a rigid dam is (8 G / pi^2) rho a h = 0.7425 rho a h.
* Westergaard (1933): p = (7/8) rho a sqrt(h (h - y)), base 0.875 rho a h, force (7/12) rho a h^2.
* Seed 000, chapter 4: rho = 1000 kg/m^3, h = 100 m, c = 1493 m/s; first cut-off 23.45 rad/s.
* Riemann zeta values (Abramowitz & Stegun, Table 23.3): zeta(3), zeta(5), zeta(7).
"""

import numpy as np

CHOPRA_FORCE_COEFFICIENT = 0.5428          # F / (rho a h^2), printed to 4 decimals
CATALAN = 0.915965594177219015054603514932
BASE_PRESSURE_COEFFICIENT = 8.0 * CATALAN / np.pi**2   # p(0, 0) / (rho a h)
WESTERGAARD_BASE = 7.0 / 8.0
WESTERGAARD_FORCE = 7.0 / 12.0

SEED_RHO, SEED_DEPTH, SEED_C = 1000.0, 100.0, 1493.0
SEED_FIRST_CUTOFF = 23.45                  # rad/s, printed to 2 decimals

ZETA3 = 1.2020569031595942854
ZETA5 = 1.0369277551433699263
ZETA7 = 1.0083492773819228268


def half_unit(printed: float, decimals: int) -> float:
    """Rounding tolerance of a number printed with ``decimals`` decimals."""
    return 0.5 * 10.0 ** (-decimals)
