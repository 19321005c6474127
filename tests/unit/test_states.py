"""``viz3d.system.States``: the kernel's batches of output states as arrays, each ``State`` built when
indexed, equal to the one the run would have held."""

import numpy as np

from viz3d.system import State, States


def _states(n=5, n_q=7, n_v=6, n_aux=2):
    rng = np.random.default_rng(3)
    memories = [("contact phases", k) for k in range(n)]
    return [State(0.1 * k, rng.normal(size=n_q), rng.normal(size=n_v), rng.normal(size=(1, 3, 3)),
                  rng.normal(size=n_aux), memories[k], ("anchor", k)) for k in range(n)]


def _same(a: State, b: State) -> bool:
    return (a.t == b.t and np.array_equal(a.q, b.q) and np.array_equal(a.v, b.v) and np.array_equal(a.chart, b.chart)
            and np.array_equal(a.w, b.w) and a.memory is b.memory and a.element_memory is b.element_memory)


def test_each_state_of_a_batch_is_the_state_it_was_built_from():
    states = _states()
    batch = States.of(states)
    assert len(batch) == len(states)
    assert all(_same(a, b) for a, b in zip(batch, states))
    assert _same(batch[-1], states[-1])
    np.testing.assert_array_equal(batch.Y[2], states[2].y)


def test_slices_masks_and_joins_keep_rows_and_memories_together():
    states = _states()
    batch = States.of(states)
    mask = np.array([True, False, True, True, False])
    assert all(_same(a, b) for a, b in zip(batch[mask], [s for s, m in zip(states, mask) if m]))
    assert batch[np.ones(5, bool)] is batch
    joined = States.join([batch[:2], batch[2:]])
    assert all(_same(a, b) for a, b in zip(joined, states))


def test_states_without_work_integrals_give_empty_ones():
    states = _states(n_aux=0)
    batch = States.of(states)
    assert batch[0].w.size == 0 and np.array_equal(batch[0].y, states[0].y)
