"""Independent reference for tests/hydro: finite elements for the reservoir's Helmholtz problem.

Written without any viz3d code. Bilinear (Q1) elements on a uniform grid of the truncated
reservoir [0, L + L_pml] x [0, h], assembled as Kronecker products of 1-D matrices:

    int (1/s) p_x v_x + s p_y v_y - s k^2 p v  +  j omega q int_{y=0} s p v dx  =  int_{x=0} rho phi v dy

(k = omega / c; time factor exp(j omega t)), the weak form of p_xx + p_yy + k^2 p = 0 with
p_x = -rho phi on the dam face x = 0, p_y = j omega q p on the bottom, p = 0 on the free surface
y = h. Beyond x = L a perfectly matched layer stretches x into x + int (s - 1) dx with
s = 1 + (a - j b) ((x - L) / L_pml)^2: the imaginary part damps waves travelling upstream
(exp(-j k_x x)), the real part speeds up the decay of evanescent ones; p = 0 closes the layer.
Neither the layer nor the grid knows the series solution (no modes, no cut-off frequencies).

The discretisation error is O(dx^2) away from the corner (x, y) = (0, h), where the pressure of
a wall with phi(h) != 0 behaves like r log r; tests compare two grids to estimate it.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve


def _linear_1d(nodes: np.ndarray, coefficient: np.ndarray):
    """Stiffness and mass matrices of 1-D linear elements with a per-element coefficient."""
    d = np.diff(nodes)
    n = nodes.size
    k = coefficient / d
    m = coefficient * d / 6.0
    K = sp.diags([np.r_[k, 0] + np.r_[0, k], -k, -k], [0, 1, -1], shape=(n, n), format="csr")
    M = sp.diags([2 * (np.r_[m, 0] + np.r_[0, m]), m, m], [0, 1, -1], shape=(n, n), format="csr")
    return K, M


def solve(rho, h, c, omega, phi, *, n_y=40, length=100.0, pml_length=200.0, pml_real=10.0, pml_imag=4.0,
          admittance=0.0):
    """Pressure on the dam face x = 0 at the nodes y = 0, dx, ..., h.

    Parameters
    ----------
    rho, h, c : density [kg/m^3], depth [m], sound speed [m/s] (np.inf: Laplace)
    omega : circular frequency [rad/s]
    phi : callable, wall acceleration shape phi(y)
    n_y : elements over the depth (the grid is square, dx = h / n_y)
    length, pml_length : plain part and layer of the truncated reservoir [m]
    pml_real, pml_imag : a and b of the stretching
    admittance : q [s/m] of the bottom condition p_y = j omega q p

    Returns
    -------
    y : (n_y + 1,) heights [m]; p : (n_y + 1,) complex pressure per unit acceleration [Pa s^2/m]
    """
    dx = h / n_y
    n_x = int(round((length + pml_length) / dx))
    x = np.linspace(0.0, n_x * dx, n_x + 1)
    y = np.linspace(0.0, h, n_y + 1)
    xm = 0.5 * (x[1:] + x[:-1])
    ramp = np.clip((xm - length) / pml_length, 0.0, None) ** 2
    s = 1.0 + (pml_real - 1j * pml_imag) * ramp
    Kx_inv, _ = _linear_1d(x, 1.0 / s)
    _, Mx_s = _linear_1d(x, s)
    Ky, My = _linear_1d(y, np.ones(n_y))
    k2 = 0.0 if not np.isfinite(c) else (omega / c) ** 2
    E0 = sp.csr_matrix(([1.0], ([0], [0])), shape=(n_y + 1, n_y + 1))
    A = (sp.kron(Kx_inv, My) + sp.kron(Mx_s, Ky) - k2 * sp.kron(Mx_s, My)
         + 1j * omega * admittance * sp.kron(Mx_s, E0))
    e0 = np.zeros(n_x + 1)
    e0[0] = 1.0
    f = np.kron(e0, My @ (rho * phi(y)))
    keep = (np.arange(n_x + 1)[:, None] < n_x) & (np.arange(n_y + 1)[None, :] < n_y)
    keep = keep.ravel()
    A = A.tocsr()[keep][:, keep]
    p = np.zeros((n_x + 1) * (n_y + 1), dtype=complex)
    p[keep] = spsolve(A.tocsc(), f[keep])
    return y, p.reshape(n_x + 1, n_y + 1)[0]
