"""Butcher tableaus validate themselves; the registry holds consistent methods; continuous
extensions have their declared order."""

import numpy as np
import pytest

from viz3d.integrators import INTEGRATORS, ButcherTableau, ExplicitRK
from viz3d.integrators.tableaus import DOP853, DOPRI5, RK4, order_defects, rooted_trees

TABLEAUS = sorted(n for n in INTEGRATORS if hasattr(INTEGRATORS[n](), "tableau"))
#: Rooted trees with n = 1..8 nodes (OEIS A000081): one order condition each.
TREE_COUNTS = [1, 1, 2, 4, 9, 20, 48, 115]
#: Dense-output order: slope of the interpolation error against h within this of order + 1.
DENSE_ORDER_TOL = 0.3


@pytest.mark.parametrize("name", TABLEAUS)
def test_registered_tableaus_are_consistent(name):
    integ = INTEGRATORS[name]()
    tab = integ.tableau
    assert integ.name == name
    assert np.isclose(tab.b.sum(), 1.0)
    np.testing.assert_allclose(tab.a.sum(axis=1), tab.c)
    # order conditions written out up to order 4 (autonomous) ...
    c, A, b = tab.c, tab.a, tab.b
    conditions = {1: [b.sum() - 1], 2: [b @ c - 1 / 2], 3: [b @ c**2 - 1 / 3, b @ A @ c - 1 / 6],
                  4: [b @ c**3 - 1 / 4, b @ (c * (A @ c)) - 1 / 8, b @ A @ c**2 - 1 / 12, b @ A @ A @ c - 1 / 24]}
    for p in range(1, min(integ.order, 4) + 1):
        assert np.allclose(conditions[p], 0.0, atol=1e-14), f"order condition {p} fails"
    # ... and all of them up to the declared order, which is exact: order + 1 fails
    assert np.abs(order_defects(A, b, integ.order)).max() < 1e-12
    assert np.abs(order_defects(A, b, integ.order + 1)).max() > 1e-6
    if tab.embedded:
        assert np.abs(order_defects(A, tab.b_hat, tab.error_order)).max() < 1e-12
        assert np.abs(order_defects(A, tab.b_hat, tab.error_order + 1)).max() > 1e-6


def test_rooted_trees_are_counted_as_in_the_literature():
    assert [len(rooted_trees(n)) for n in range(1, 9)] == TREE_COUNTS


def test_tree_conditions_match_the_written_ones():
    """The generated conditions of order <= 4, in some order, are the eight written out above."""
    c, A, b = RK4.c, RK4.a, RK4.b
    perturbed = b + np.array([1e-3, 0, 0, -1e-3])
    written = sorted([perturbed.sum() - 1, perturbed @ c - 1 / 2, perturbed @ c**2 - 1 / 3, perturbed @ A @ c - 1 / 6,
                      perturbed @ c**3 - 1 / 4, perturbed @ (c * (A @ c)) - 1 / 8, perturbed @ A @ c**2 - 1 / 12,
                      perturbed @ A @ A @ c - 1 / 24])
    np.testing.assert_allclose(sorted(order_defects(A, perturbed, 4)), written, atol=1e-15)


@pytest.mark.parametrize("kw,msg", [
    (dict(c=[0, 1], a=[[0, 0], [0.5, 0]], b=[0.5, 0.5]), "rows of a"),
    (dict(c=[0, 1], a=[[0, 0], [1, 0]], b=[0.5, 0.6]), "sum\\(b\\)"),
    (dict(c=[0.5, 1], a=[[0.5, 0], [1, 0]], b=[0.5, 0.5]), "strictly lower"),
    (dict(c=[0, 0.5], a=[[0, 0], [0.5, 0]], b=[0.5, 0.5]), "order condition"),   # a 1st-order method declared 2nd
])
def test_invalid_tableaus_raise(kw, msg):
    with pytest.raises(ValueError, match=msg):
        ButcherTableau("bad", 2, **kw)


@pytest.mark.parametrize("tableau,h0", [(DOPRI5, 0.2), (DOP853, 0.4)], ids=lambda x: getattr(x, "name", ""))
def test_continuous_extension_has_its_order(tableau, h0):
    """One step of y' = cos(t) y (y = exp(sin t)) from y(0) = 1: the largest error of the
    interpolant of order p over the step falls like h^(p + 1) (steps from h0 down, above
    round-off); at the step's end it is the step's own result."""
    method = ExplicitRK(tableau)

    def rhs(t, y):
        return np.cos(t) * y

    hs, errors, x = h0 / np.array([1.0, 2.0, 4.0]), [], np.linspace(0.0, 1.0, 41)
    for h in hs:
        y0 = np.array([1.0])
        res = method.step(rhs, 0.0, y0, h)
        interpolant = method.interpolant(rhs, 0.0, y0, h, res, rhs(h, res.y))
        errors.append(max(abs(interpolant(xi * h)[0] - np.exp(np.sin(xi * h))) for xi in x))
        np.testing.assert_allclose(interpolant(h), res.y, rtol=1e-12)
    slope = np.polyfit(np.log(hs), np.log(errors), 1)[0]
    assert abs(slope - (tableau.dense.order + 1)) <= DENSE_ORDER_TOL, (slope, errors)
