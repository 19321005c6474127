"""Seed 003's printed formulas, as read from the PDF transcription (/work/shared/seeds/
003_c0e74001a3375ea9.txt; A. G. Hossne, Ingeniería 11(1), 25-36, 2007), written without viz3d code.

Dof order (the seed's S = q1..q8): [u1, w1, w1', w1'', u2, w2, w2', w2'']; L the element length;
in eq. 44 T = m/2 [...] with m the mass per unit length, so the vectors and matrices below carry
no m. The transcription loses the matrix layout (it prints column fragments) and the time dots and
superscripts of eq. 44; the reading of each fragment is in docs/seed003_element.md. Entries are
sympy expressions in L, EI, EA, x.

``ERRATA`` lists every printed entry that differs from the derivation (tests/flexible/
test_beam_elements.py checks that the differences are exactly these, and that the document lists them).
"""

from __future__ import annotations

import sympy as sp

x, L, EI, EA = sp.symbols("x L EI EA", positive=True)
R = sp.Rational

# ---- eq. 34: transverse shape functions phi_2, phi_3, phi_4, phi_6, phi_7, phi_8 -----------------
EQ34 = {
    "phi2": 1 - 10 * x**3 / L**3 + 15 * x**4 / L**4 - 6 * x**5 / L**5,
    "phi3": x - 6 * x**3 / L**2 + 8 * x**4 / L**3 - 3 * x**5 / L**4,
    "phi4": x**2 / 2 - 3 * x**3 / (2 * L) + 3 * x**4 / (2 * L**2) - x**5 / (2 * L**3),
    "phi6": 10 * x**3 / L**3 - 15 * x**4 / L**4 + 6 * x**5 / L**5,
    "phi7": -4 * x**3 / L**2 + 7 * x**4 / L**3 - 3 * x**5 / L**4,
    "phi8": x**3 / (2 * L) - x**4 / L**2 - x**5 / (2 * L**3),   # "x3/2L - x4/L2 - x5/2L3"
}

# ---- eq. 38: [C]^-1, rows (B0, A0, A1, A2, B1, A3, A4, A5), columns q1..q8 -------------------------
EQ38 = sp.Matrix([
    [1, 0, 0, 0, 0, 0, 0, 0],
    [0, 1, 0, 0, 0, 0, 0, 0],
    [0, 0, 1, 0, 0, 0, 0, 0],
    [0, 0, 0, R(1, 2), 0, 0, 0, 0],
    [-1 / L, 0, 0, 0, 1 / L, 0, 0, 0],
    [0, -10 / L**3, -6 / L**2, -3 / (2 * L), 0, 10 / L**3, -4 / L**2, 1 / (2 * L)],
    [0, 15 / L**4, 8 / L**3, 3 / (2 * L**2), 0, -15 / L**4, 7 / L**3, -1 / L**2],
    [0, -6 / L**5, -3 / L**4, -1 / (2 * L**3), 0, 6 / L**5, -3 / L**5, 1 / (2 * L**3)],  # "7/L3 -3/L5"
])

# ---- eqs. 45-50: shape integrals of the kinetic energy ------------------------------------------
EQ45_E = sp.Matrix([[L / 2, 0, 0, 0, L / 2, 0, 0, 0]])                      # int N_u dx
EQ47_G = sp.Matrix([[0, L / 2, L**2 / 10, L**3 / 120, 0, L / 2, -L**2 / 10, L**3 / 120]])  # int N_w dx
EQ48_N = sp.Matrix([[L / 6, 0, 0, 0, L / 3, 0, 0, 0]])                      # int x N_u dx, "(N) = L/6 ... L/3"
EQ49_L = sp.Matrix([[0, L**2 / 7, 4 * L**3 / 105, L**4 / 280, 0, 5 * L**2 / 14, -13 * L**3 / 210, L**4 / 210]])
EQ46_B = sp.zeros(8, 8)                                                      # int N_u^T N_u dx
EQ46_B[0, 0], EQ46_B[0, 4], EQ46_B[4, 0], EQ46_B[4, 4] = L / 3, L / 6, L / 6, L / 3
EQ50_A = sp.zeros(8, 8)                                                      # int N_u^T N_w dx
EQ50_A[0, :] = sp.Matrix([[0, 5 * L / 14, 13 * L**2 / 210, L**3 / 210, 0, L / 7, -4 * L**2 / 105, L**3 / 280]])
EQ50_A[4, :] = sp.Matrix([[0, L / 7, 4 * L**2 / 280, L**3 / 280, 0, 5 * L / 14, -13 * L**2 / 210, L**3 / 210]])

# ---- eq. 51: "mass matrix" = int N_w^T N_w dx (axial rows and columns zero; the axial part is [B]) ---
_W = [1, 2, 3, 5, 6, 7]  # transverse positions in S
_EQ51_W = sp.Matrix([
    [181 * L / 462, 311 * L**2 / 4620, 281 * L**3 / 55440, 25 * L / 231, -151 * L**2 / 4620, 181 * L**3 / 55440],
    [311 * L**2 / 4620, 52 * L**3 / 3465, 23 * L**4 / 18480, 151 * L**2 / 4620, -19 * L**3 / 1980, 13 * L**4 / 13860],
    [281 * L**3 / 55440, 23 * L**4 / 18480, L**5 / 9240, 181 * L**3 / 55440, -13 * L**4 / 13860, L**5 / 11088],
    [25 * L / 231, 151 * L**2 / 4620, 181 * L**3 / 55440, 181 * L / 462, -311 * L**2 / 4620, 281 * L**3 / 55440],
    [-151 * L**2 / 4620, -19 * L**3 / 1980, -13 * L**4 / 13860, -311 * L**2 / 4620, 52 * L**3 / 3465, -23 * L**4 / 18480],
    [181 * L**3 / 55440, 13 * L**4 / 13860, L**5 / 11088, 281 * L**3 / 55440, -23 * L**4 / 18480, L**5 / 9240],
])
EQ51 = sp.zeros(8, 8)
for _i, _a in enumerate(_W):
    for _j, _b in enumerate(_W):
        EQ51[_a, _b] = _EQ51_W[_i, _j]

# ---- eq. 56: stiffness ---------------------------------------------------------------------------
_a, _b, _c = 120 * EI / (7 * L**3), 60 * EI / (7 * L**2), 3 * EI / (7 * L)
EQ56 = sp.Matrix([
    [EA / L, 0, 0, 0, -EA / L, 0, 0, 0],
    [0, _a, _b, _c, 0, -_a, _b, -_c],
    [0, _b, 192 * EI / (35 * L), 11 * EI / 35, 0, -_b, 108 * EI / (35 * L), -4 * EI / 35],
    [0, _c, 11 * EI / 35, 3 * EI * L / 35, 0, -_c, 4 * EI / 35, EI * L / 70],
    [-EA / L, 0, 0, 0, EA / L, 0, 0, 0],
    [0, -_a, -_b, -_c, 0, _a, -_b, _c],
    [0, _b, 108 * EI / (35 * L), 4 * EI / 35, 0, -_b, 192 * EI / (35 * L), -11 * EI / 35],
    [0, -_c, -4 * EI / 35, EI * L / 70, 0, _c, -11 * EI / 35, 3 * EI * L / 35],
])

# ---- eq. 44: kinetic energy, T = m/2 [sum of coefficient * term] ----------------------------------
#: Coefficient of each term as printed (time dots restored as the derivation has them; the
#: transcription drops them). Terms: see test_planar_beam.py::seed_eq44.
EQ44_COEFFICIENTS = {
    "xd1^2 L": 1, "yd1^2 L": 1, "yd1 thd L^2": 1, "thd^2 L^3/3": 1,
    "xd1 E.Sd": 2, "Sd.B.Sd": 1, "thd Sd.A.S": -2, "xd1 thd G.S": -1, "thd^2 S.M.S": 1,
    "yd1 thd E.S": 2, "yd1 G.Sd": 2, "thd^2 N.S": 2, "thd L.Sd": 2, "thd^2 S.B.S": 1,
    "thd S.A.Sd": 2, "Sd.M.Sd": 1,
}

#: Printed entries that differ from the derivation: id -> (printed, derived) as text.
ERRATA = {
    "eq34 phi8": ("- x^5/(2 L^3)", "+ x^5/(2 L^3)"),
    "eq38 [A5, q7]": ("-3/L^5", "-3/L^4"),
    "eq44 xd1 thd G.S": ("-1", "-2"),
    "eq48 N[q1]": ("L/6", "L^2/6"),
    "eq48 N[q5]": ("L/3", "L^2/3"),
    "eq50 A[q5, q3]": ("4 L^2/280", "4 L^2/105"),
}
