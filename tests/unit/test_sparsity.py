"""The coupling pattern of a system's forces and constraints (``viz3d.sparsity``) against dense
finite differences: every entry outside the pattern is exactly zero, and the grouped Jacobian
equals the dense one."""

from __future__ import annotations

import numpy as np
import pytest

from viz3d.dynamics import body_state, flat_velocity, generalized_forces, retract
from viz3d.integrators.implicit import FD_REL, fd_jacobian
from viz3d.sparsity import column_bodies, column_groups, grouped_fd_jacobian, sparse_fd_plan

from systems import random_state, random_system


def _forces(system, state, of_velocity=False):
    def f(w):
        q, v = (state.q, w) if of_velocity else (retract(system, state.q, w, state.chart), state.v)
        cfg = body_state(system, q, v, state.chart, state.t)
        return flat_velocity(system, *generalized_forces(system, cfg, state.memory))
    return f


def _systems():
    from numerics.test_kernel_elements import every_element_system

    for seed, flexible in ((0, False), (1, False), (2, True)):
        system = random_system(nb=7, seed=seed, flexible=flexible, kinds=("ball", "revolute", "universal"))
        yield f"random{seed}", system, random_state(system, seed)
    system, state = every_element_system()
    yield "every_element", system, state


@pytest.mark.parametrize("name, system, state", list(_systems()), ids=lambda x: x if isinstance(x, str) else "")
@pytest.mark.parametrize("of_velocity", [False, True])
def test_the_pattern_holds_every_nonzero_and_the_grouped_jacobian_is_the_dense_one(name, system, state, of_velocity):
    """Derivatives with respect to positions (the force tangent K) and velocities (D)."""
    f = _forces(system, state, of_velocity)
    x = state.v.copy() if of_velocity else np.zeros(system.n_v)
    r0 = f(x)
    dense = fd_jacobian(f, x, r0)
    groups, rows_of = sparse_fd_plan(system)
    pattern = np.zeros_like(dense, dtype=bool)
    for j, r in enumerate(rows_of):
        pattern[r, j] = True
    assert np.all(dense[~pattern] == 0.0)
    assert len(groups) < system.n_v  # columns do share evaluations
    step = FD_REL * np.maximum(np.abs(x), 1.0)
    grouped = grouped_fd_jacobian(f, x, r0, groups, rows_of, step).toarray()
    scale = np.abs(dense).max()
    np.testing.assert_allclose(grouped, dense, rtol=0, atol=1e-6 * scale)


def test_a_chain_needs_three_groups_of_bodies_whatever_its_length():
    for n in (5, 20, 80):
        A = np.eye(n, dtype=bool) | np.eye(n, k=1, dtype=bool) | np.eye(n, k=-1, dtype=bool)
        cb = np.repeat(np.arange(n), 6)
        groups = column_groups(cb, A)
        assert len(groups) == 3 * 6
        for g in groups:  # no two columns of a group reach a common row
            reach = A[cb[g]]
            assert reach.sum(axis=0).max() <= 1


def test_columns_of_frames_then_elastic_coordinates():
    system = random_system(nb=3, seed=4, flexible=True)
    cb = column_bodies(system)
    assert len(cb) == system.n_v
    assert np.all(cb[:6 * system.n_frames] == np.repeat(system.frame_body, 6))
