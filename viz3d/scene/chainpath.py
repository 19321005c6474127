"""Where a generated chain's joints go: along a polyline (``[chain] path``), one link length apart;
and how its links are named (``<prefix><i>``, joints ``<prefix>_j<i>``: ``viz3d.scene.load``)."""

from __future__ import annotations

import re

import numpy as np

from viz3d.scene.schema import SceneError


def path_nodes(path: np.ndarray, n: int, L: float, source: str) -> tuple[np.ndarray, np.ndarray]:
    """``n + 1`` joint points a distance ``L`` apart along the polyline ``path`` (k, 3) [m], from its
    first point (each the first point past the previous one on the polyline at that distance; past
    the last point the chain goes on along the last segment), and the normal of the plane the
    polyline lies in (the universal joints' first axis)."""
    seg = np.diff(path, axis=0)
    if np.any(np.linalg.norm(seg, axis=1) == 0.0):
        raise SceneError(source, "chain.path", "points distinct from each other and from chain.anchor")
    nodes, k, t = [path[0]], 0, 0.0  # current point: path[k] + t seg[k]
    for _ in range(n):
        p = nodes[-1]
        while True:
            last = k == len(seg) - 1
            # solve |path[k] + s seg[k] - p| = L for s >= t (the segment, or the last one's extension)
            q, d = path[k] - p, seg[k]
            A, B, C = d @ d, 2 * q @ d, q @ q - L * L
            s = (-B + np.sqrt(max(B * B - 4 * A * C, 0.0))) / (2 * A)
            if last or s <= 1.0:
                t = max(s, t)
                break
            k, t = k + 1, 0.0
        nodes.append(path[k] + t * seg[k])
    nodes = np.array(nodes)
    d = np.diff(nodes, axis=0)
    normal = np.zeros(3)
    for u, v in zip(d[:-1], d[1:]):
        c = np.cross(u, v)
        if np.linalg.norm(c) > 1e-9 * L * L:
            normal = c / np.linalg.norm(c)
            break
    if not normal.any():
        normal = normal_to(d[0] / L)
    elif np.max(np.abs(d @ normal)) > 1e-9 * L:
        raise SceneError(source, "chain.path", "points in one plane with chain.anchor (the links' universal joints "
                         "need one normal)")
    return nodes, normal


def normal_to(d: np.ndarray) -> np.ndarray:
    """A unit vector normal to ``d``."""
    e = np.eye(3)[int(np.argmin(np.abs(d)))]
    w = np.cross(d, e)
    return w / np.linalg.norm(w)


def link_index(name: str, prefix: str) -> int | None:
    """``i`` of the chain link named ``<prefix><i>``; None for any other name."""
    m = re.fullmatch(re.escape(prefix) + r"(\d+)", name)
    return int(m.group(1)) if m else None
