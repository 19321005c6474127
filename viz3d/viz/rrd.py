"""Reading a ``.rrd`` recording back into NumPy arrays (rerun-sdk 0.41: ``rerun.chunk.RrdReader``).

The layout written by ``viz3d.viz.recorder_rerun`` (entities ``/plots/...`` on the ``sim_time``
timeline, ``/world/...``)::

    from viz3d.viz.rrd import entities, read_scalars
    t, E = read_scalars("out/arm.rrd", "/plots/energy/total")   # t (n,) [s], E (n, 1) [J]

Open recordings with the rerun-sdk version pinned in pyproject.toml (rerun's file format moves
between releases).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: Index column of simulated time: ``duration[ns]``.
TIMELINE = "sim_time"


def _chunks(path: str | Path):
    from rerun.chunk import RrdReader

    return RrdReader(Path(path)).stream().to_chunks()


def read_column(path: str | Path, entity: str, column: str, timeline: str = TIMELINE) -> tuple[np.ndarray, np.ndarray]:
    """``(t [s], values (n, ...))`` of one component column of a non-static entity, sorted by time.

    ``column`` is ``"<Archetype>:<field>"``, e.g. ``"Scalars:scalars"``,
    ``"Transform3D:translation"``. Raises ``KeyError`` if the recording has no such column.
    """
    import pyarrow as pa

    ts, vs = [], []
    for chunk in _chunks(path):
        if chunk.entity_path != entity or chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        if column not in batch.schema.names:
            continue
        ts.append(batch.column(timeline).cast(pa.int64()).to_numpy() * 1e-9)
        vs.append(np.stack([np.asarray(v) for v in batch.column(column).to_pylist()]))
    if not ts:
        raise KeyError(f"{entity}:{column} not in {path}")
    t, v = np.concatenate(ts), np.concatenate(vs)
    order = np.argsort(t, kind="stable")  # a long series arrives in several chunks
    return t[order], v[order]


def read_scalars(path: str | Path, entity: str, timeline: str = TIMELINE) -> tuple[np.ndarray, np.ndarray]:
    """``(t [s], values (n, k))`` of a scalar series, e.g. ``/plots/energy/total``."""
    t, v = read_column(path, entity, "Scalars:scalars", timeline)
    return t, v.reshape(len(t), -1)


def entities(path: str | Path) -> set[tuple[str, bool]]:
    """Every ``(entity path, is_static)`` in the recording."""
    return {(c.entity_path, c.is_static) for c in _chunks(path)}
