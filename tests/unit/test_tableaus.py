"""Butcher tableaus validate themselves; the registry holds consistent methods."""

import numpy as np
import pytest

from viz3d.integrators import INTEGRATORS, ButcherTableau


@pytest.mark.parametrize("name", sorted(INTEGRATORS))
def test_registered_tableaus_are_consistent(name):
    integ = INTEGRATORS[name]()
    tab = integ.tableau
    assert integ.name == name
    assert np.isclose(tab.b.sum(), 1.0)
    np.testing.assert_allclose(tab.a.sum(axis=1), tab.c)
    # order conditions up to the declared order (autonomous, for order <= 4)
    c, A, b = tab.c, tab.a, tab.b
    conditions = {1: [b.sum() - 1], 2: [b @ c - 1 / 2], 3: [b @ c**2 - 1 / 3, b @ A @ c - 1 / 6],
                  4: [b @ c**3 - 1 / 4, b @ (c * (A @ c)) - 1 / 8, b @ A @ c**2 - 1 / 12, b @ A @ A @ c - 1 / 24]}
    for p in range(1, integ.order + 1):
        assert np.allclose(conditions[p], 0.0, atol=1e-14), f"order condition {p} fails"


@pytest.mark.parametrize("kw,msg", [
    (dict(c=[0, 1], a=[[0, 0], [0.5, 0]], b=[0.5, 0.5]), "rows of a"),
    (dict(c=[0, 1], a=[[0, 0], [1, 0]], b=[0.5, 0.6]), "sum\\(b\\)"),
    (dict(c=[0.5, 1], a=[[0.5, 0], [1, 0]], b=[0.5, 0.5]), "strictly lower"),
])
def test_invalid_tableaus_raise(kw, msg):
    with pytest.raises(ValueError, match=msg):
        ButcherTableau("bad", 2, **kw)
