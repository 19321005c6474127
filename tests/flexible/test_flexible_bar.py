"""The common bar types: materials, sections, BarModel validation, rigid data and inertia integrals."""

import dataclasses

import flexible_refs as ref
import numpy as np
import pytest

from viz3d.flexible import BarModel, Material, PointMass, Section, fe_model, reduce
from viz3d.flexible.bar import rigid_mode_count

ROUNDOFF = 1e-13
#: FE rigid-mode frequencies are round-off, ~sqrt(eps) omega_max = 1e-8 omega_max; elastic ones of an
#: 8-element bar are above 1e-2 omega_max.
RIGID_RTOL = 1e-6

STEEL = Material(ref.E_STD, ref.RHO_EB, ref.NU_STD)
SECTION = Section.rectangle(ref.SIDE_STD, ref.SIDE_STD, ref.K_SHEAR_STD)
L = ref.L_STD


def test_material_derived_quantities():
    assert STEEL.shear_modulus == pytest.approx(210e9 / 2.6, rel=ROUNDOFF)
    assert STEEL.wave_speed == pytest.approx(5155.8, abs=0.05)  # digest section 2: c = 5155.8 m/s
    with pytest.raises(ValueError):
        Material(210e9, 7900, 0.5)


def test_section_constructors():
    rect = Section.rectangle(0.02, 0.05)
    # abs=0: pytest.approx adds abs=1e-12 otherwise, 1e-4 of these second moments [m^4]
    assert rect.area == pytest.approx(1e-3, rel=ROUNDOFF, abs=0)
    assert rect.second_moment == pytest.approx(0.02 * 0.05**3 / 12, rel=ROUNDOFF, abs=0)
    assert rect.depth == 0.05 and rect.shear_coefficient == pytest.approx(5 / 6)
    circ = Section.circle(0.02)
    assert circ.area == pytest.approx(np.pi * 1e-4, rel=ROUNDOFF, abs=0)
    assert circ.second_moment == pytest.approx(np.pi * 0.02**4 / 64, rel=ROUNDOFF, abs=0)
    assert circ.radius_of_gyration == pytest.approx(0.02 / 4)
    with pytest.raises(ValueError):
        Section(1e-4, -1.0, 0.01)


def test_model_validation():
    model = fe_model("rod", L, STEEL, SECTION, 4, ("clamped", "free"))
    with pytest.raises(ValueError, match="theory"):
        dataclasses.replace(model, theory="euler_bernoulli")
    bad = model.M.copy()
    bad[0, 1] += 1e-3 * np.abs(bad).max()
    with pytest.raises(ValueError, match="symmetric"):
        dataclasses.replace(model, M=bad)
    with pytest.raises(ValueError, match="off the bar"):
        dataclasses.replace(model, point_masses=(PointMass(2 * L, 1.0),))
    with pytest.raises(ValueError, match="supports"):
        dataclasses.replace(model, supports=("welded", "free"))
    with pytest.raises(ValueError):
        model.displacement([L * 1.01])
    with pytest.raises(ValueError, match="bending"):
        model.slope([0.1])
    assert not model.M.flags.writeable, "a frozen model's matrices are read-only"


def test_rigid_data_include_point_masses():
    pm = (PointMass(L, 2.0), PointMass(0.1, 0.5))
    model = fe_model("euler_bernoulli", L, STEEL, SECTION, 3, ("free", "free"), point_masses=pm)
    m_bar = STEEL.rho * SECTION.area * L
    assert model.mass == pytest.approx(m_bar + 2.5)
    assert model.static_moment == pytest.approx(m_bar * L / 2 + 2.0 * L + 0.05)
    assert model.inertia_origin == pytest.approx(m_bar * L**2 / 3 + 2.0 * L**2 + 0.5 * 0.01)


def test_inertia_integrals_of_nodal_coordinates_are_the_rigid_ones():
    """With nodal coordinates, a rigid translation q = 1 and rotation q = x (theta = 1) reproduce
    S1 . q = mass, S2 . q = static moment, and S2 . q(rotation) = inertia about x = 0."""
    pm = (PointMass(0.2, 0.7),)
    model = fe_model("euler_bernoulli", L, STEEL, SECTION, 5, ("free", "free"), point_masses=pm)
    nodes = model.basis.nodes
    translation = np.column_stack([np.ones_like(nodes), np.zeros_like(nodes)]).ravel()
    rotation = np.column_stack([nodes, np.ones_like(nodes)]).ravel()
    assert model.S1 @ translation == pytest.approx(model.mass, rel=ROUNDOFF)
    assert model.S2 @ translation == pytest.approx(model.static_moment, rel=ROUNDOFF)
    assert model.S2 @ rotation == pytest.approx(model.inertia_origin, rel=ROUNDOFF)
    assert np.all(model.S_psi == 0), "Euler-Bernoulli neglects rotary inertia"
    assert translation @ model.M @ translation == pytest.approx(model.mass, rel=ROUNDOFF)


@pytest.mark.parametrize("kind,supports,expected", [
    ("axial", ("free", "free"), 1), ("axial", ("pinned", "free"), 0), ("bending", ("free", "free"), 2),
    ("bending", ("pinned", "free"), 1), ("bending", ("clamped", "free"), 0), ("bending", ("pinned", "pinned"), 0),
])
def test_rigid_mode_count_matches_the_zero_frequencies(kind, supports, expected):
    assert rigid_mode_count(kind, supports) == expected
    theory = "rod" if kind == "axial" else "timoshenko"
    omega = fe_model(theory, L, STEEL, SECTION, 8, supports).frequencies()
    assert np.count_nonzero(omega < RIGID_RTOL * omega[-1]) == expected, omega[:3]


def test_reduce_rejects_impossible_mode_counts():
    model = fe_model("rod", L, STEEL, SECTION, 4, ("clamped", "free"))
    with pytest.raises(ValueError, match="modes"):
        reduce(model, 5)
    assert isinstance(reduce(model, 4), BarModel)
