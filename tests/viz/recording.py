"""Reading .rrd files back in tests (rerun-sdk 0.41: rerun.chunk.RrdReader + pyarrow)."""

import numpy as np
import pyarrow as pa
from rerun.chunk import RrdReader


def read_column(path, entity, column, timeline="sim_time"):
    """(t [s], values (N, ...)) of one component column of a non-static entity, time-sorted."""
    ts, vs = [], []
    for chunk in RrdReader(path).stream().to_chunks():
        if chunk.entity_path == entity and not chunk.is_static:
            rb = chunk.to_record_batch()
            if column not in rb.schema.names:
                continue
            ts.append(rb.column(timeline).cast(pa.int64()).to_numpy() * 1e-9)
            vs.append(np.stack([np.asarray(v) for v in rb.column(column).to_pylist()]))
    if not ts:
        raise KeyError(f"{entity}:{column} not in {path}")
    t, v = np.concatenate(ts), np.concatenate(vs)
    order = np.argsort(t, kind="stable")
    return t[order], v[order]


def read_scalars(path, entity, timeline="sim_time"):
    t, v = read_column(path, entity, "Scalars:scalars", timeline)
    return t, v.reshape(len(t), -1)


def entities(path):
    return {(c.entity_path, c.is_static) for c in RrdReader(path).stream().to_chunks()}
