"""Parametric triangle meshes of a ship's anchoring system (seed 004, ch. 2): the bow shell around the
hawse, the anchor pocket, the hawse pipe, and a stockless anchor's shank, flukes and shackle.

Hull pieces are built in the **shell frame** ``(f, u, n)``: ``f`` along the shell (forward), ``u`` up
along the shell, ``n`` the shell's outward normal; the origin ``O`` is where the pipe's axis pierces
the pocket floor (the plane ``n = 0``). The shell's outer surface is the plane ``n = depth`` (the
pocket is a rectangular recess of that depth), and the pipe leaves the floor into the hull along

    a = cos(gamma) u - sin(gamma) n,      gamma = ``pipe_angle_deg`` (pipe axis to the floor plane),

so its circular section of radius ``r`` cuts the floor in an ellipse of semi-axes ``r`` (along f) and
``r / sin(gamma)`` (along u). The pieces are open triangle soups (collision surfaces, faces toward
the water side: the shell's and floor's along ``+n``, the walls' into the pocket, the pipe's toward
its axis).

Anchor pieces are closed convex solids in the **anchor frame**: the crown pin on the ``y`` axis
through the origin, the shank along ``+z`` to the shackle eye at ``z = SHANK_EYE s``, the flukes a
tapered plate in the ``y``-``z`` plane (its thickness along ``x``) from behind the pin toward the
shackle. ``s = (m / 9300 kg)^(1/3)`` scales a generic stockless (Spek-type) anchor of 9300 kg: the
proportions below are ours (the seed's Navantia models are not published), its mass ``m`` is the
classification table's.

``MESHES`` maps a name to its builder; a scene names one with ``shape = { type = "mesh",
generator = "<name>", params = {...} }``.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from viz3d._typing import FloatArray, IntArray

#: Anchor proportions at 9300 kg [m] (scaled by s = (m / 9300 kg)^(1/3)).
SHANK_TAIL, SHANK_EYE = -0.25, 2.35            # shank from behind the pin to the shackle eye
SHANK_CROWN, SHANK_HEAD = (0.36, 0.30), (0.24, 0.20)   # (x, y) section at the crown and the head
FLUKE_BACK, FLUKE_TIP = -0.35, 1.45            # plate from behind the pin to the tips, along z
FLUKE_WIDTH = (2.2, 1.4)                        # along y, at the back and at the tips
FLUKE_THICKNESS = (0.30, 0.12)                  # along x, at the back and at the tips
SHACKLE = (0.16, 0.30, 0.40)                    # box (x, y, z), its pin at its lower end


def _box_points(z: float, wx: float, wy: float) -> FloatArray:
    return np.array([[sx * wx / 2, sy * wy / 2, z] for sx in (-1, 1) for sy in (-1, 1)])


def convex(points: FloatArray) -> tuple[FloatArray, IntArray]:
    """Vertices (m, 3) and outward triangles (k, 3) of the convex hull of ``points`` (scipy's Qhull)."""
    from scipy.spatial import ConvexHull

    hull = ConvexHull(points)
    faces = hull.simplices.copy()
    centre = points[hull.vertices].mean(axis=0)
    for k, (i, j, l) in enumerate(faces):  # orient outward
        if np.dot(np.cross(points[j] - points[i], points[l] - points[i]), points[i] - centre) < 0:
            faces[k] = (i, l, j)
    used = np.unique(faces)
    index = np.full(len(points), -1)
    index[used] = np.arange(len(used))
    return points[used].astype(float), index[faces]


def anchor_shank(mass: float = 9300.0) -> tuple[FloatArray, IntArray]:
    """Shank: a tapered bar along ``z`` from ``SHANK_TAIL s`` to ``SHANK_EYE s`` (anchor frame) [m]."""
    s = (mass / 9300.0) ** (1 / 3)
    return convex(s * np.vstack([_box_points(SHANK_TAIL, *SHANK_CROWN), _box_points(SHANK_EYE, *SHANK_HEAD)]))


def anchor_flukes(mass: float = 9300.0) -> tuple[FloatArray, IntArray]:
    """Flukes: a plate tapering in width and thickness from the crown to the tips (anchor frame) [m]."""
    s = (mass / 9300.0) ** (1 / 3)
    back = _box_points(FLUKE_BACK, FLUKE_THICKNESS[0], FLUKE_WIDTH[0])
    tips = _box_points(FLUKE_TIP, FLUKE_THICKNESS[1], FLUKE_WIDTH[1])
    return convex(s * np.vstack([back, tips]))


def anchor_shackle(mass: float = 9300.0) -> tuple[FloatArray, IntArray]:
    """Shackle: a box above the shank's eye, its pin at its lower end ``z = 0`` [m]."""
    s = (mass / 9300.0) ** (1 / 3)
    x, y, z = SHACKLE
    return convex(s * np.vstack([_box_points(0.0, x, y), _box_points(z, x, y)]))


def pipe_axis(pipe_angle_deg: float) -> FloatArray:
    """Unit axis ``a`` of the pipe into the hull, shell frame."""
    g = np.radians(pipe_angle_deg)
    return np.array([0.0, np.cos(g), -np.sin(g)])


def _angles(sections: int, corners: FloatArray) -> FloatArray:
    """Polar angles on the floor: ``sections`` uniform ones plus the pocket's corners', sorted."""
    uniform = np.linspace(-np.pi, np.pi, sections, endpoint=False)
    return np.unique(np.concatenate([uniform, corners]))


def _pocket_corners(pocket_width: float, pocket_top: float, pocket_bottom: float) -> FloatArray:
    w = pocket_width / 2
    return np.array([[w, pocket_top], [-w, pocket_top], [-w, -pocket_bottom], [w, -pocket_bottom]])


def _opening(theta: FloatArray, r: float, gamma: float) -> tuple[FloatArray, FloatArray]:
    """Floor points of the pipe's opening at polar angles ``theta`` and the pipe-wall angles ``phi``
    (around ``a`` from ``f``) of the wall lines through them."""
    a, b = r, r / np.sin(gamma)
    rho = 1.0 / np.sqrt((np.cos(theta) / a) ** 2 + (np.sin(theta) / b) ** 2)
    pts = np.column_stack([rho * np.cos(theta), rho * np.sin(theta), np.zeros_like(theta)])
    phi = np.arctan2(pts[:, 1] * np.sin(gamma) / r, pts[:, 0] / r)
    return pts, phi


def _rect_hit(theta: FloatArray, corners: FloatArray) -> FloatArray:
    """Where rays from the origin at polar angles ``theta`` leave the rectangle ``corners``."""
    w, top, bottom = corners[0, 0], corners[0, 1], -corners[2, 1]
    c, s = np.cos(theta), np.sin(theta)
    with np.errstate(divide="ignore"):
        tx = np.where(np.abs(c) > 1e-300, w / np.abs(c), np.inf)
        ty = np.where(s > 0, top / np.where(s > 0, s, 1.0), np.where(s < 0, bottom / np.where(s < 0, -s, 1.0), np.inf))
    t = np.minimum(tx, ty)
    return np.column_stack([t * c, t * s, np.zeros_like(t)])


def opening(pipe_radius: float, pipe_angle_deg: float) -> tuple[float, float]:
    """Semi-axes (along f, along u) of the ellipse the pipe cuts in the floor [m]."""
    return pipe_radius, pipe_radius / float(np.sin(np.radians(pipe_angle_deg)))


def _check_hawse(pipe_radius, pipe_angle_deg, pocket_width, pocket_top, pocket_bottom) -> None:
    if not 0.0 < pipe_angle_deg < 90.0:
        raise ValueError(f"pipe_angle_deg must lie in (0, 90), got {pipe_angle_deg}")
    _, long = opening(pipe_radius, pipe_angle_deg)
    if pocket_width / 2 <= pipe_radius or min(pocket_top, pocket_bottom) <= long:
        raise ValueError(f"the pocket (width {pocket_width:g}, top {pocket_top:g}, bottom {pocket_bottom:g} m) must "
                         f"contain the pipe's opening (semi-axes {pipe_radius:g} and {long:.3g} m)")


def pocket(pipe_radius: float = 0.35, pipe_angle_deg: float = 20.0, pocket_width: float = 2.8,
           pocket_top: float = 1.6, pocket_bottom: float = 1.4, depth: float = 0.35,
           sections: int = 48) -> tuple[FloatArray, IntArray]:
    """The pocket: its floor (plane ``n = 0`` with the pipe's elliptic opening) and its four walls up
    to the shell at ``n = depth``; shell frame [m]. ``pocket_top``/``pocket_bottom``: its extent
    above/below ``O`` along ``u``."""
    _check_hawse(pipe_radius, pipe_angle_deg, pocket_width, pocket_top, pocket_bottom)
    corners = _pocket_corners(pocket_width, pocket_top, pocket_bottom)
    theta = _angles(sections, np.arctan2(corners[:, 1], corners[:, 0]))
    inner, _ = _opening(theta, pipe_radius, np.radians(pipe_angle_deg))
    outer = _rect_hit(theta, corners)
    m = len(theta)
    V = np.vstack([inner, outer])
    k = np.arange(m)
    k1 = (k + 1) % m
    F = np.vstack([np.column_stack([k, m + k, m + k1]), np.column_stack([k, m + k1, k1])])  # +n faces
    walls_V, walls_F = [], []
    for c0, c1 in zip(corners, np.roll(corners, -1, axis=0)):  # counter-clockwise seen from +n
        quad = np.array([[*c0, 0.0], [*c1, 0.0], [*c1, depth], [*c0, depth]])
        base = len(V) + 4 * len(walls_V)
        walls_V.append(quad)
        walls_F.append(base + np.array([[0, 2, 1], [0, 3, 2]]))  # faces into the pocket
    return np.vstack([V, *walls_V]), np.vstack([F, *walls_F]).astype(int)


def hull_shell(pocket_width: float = 2.8, pocket_top: float = 1.6, pocket_bottom: float = 1.4, depth: float = 0.35,
               half_width: float = 4.0, above: float = 3.0, below: float = 5.0) -> tuple[FloatArray, IntArray]:
    """The shell plane ``n = depth`` from ``-half_width`` to ``half_width`` along ``f`` and ``-below`` to
    ``above`` along ``u``, with the pocket's rectangle cut out; faces along ``+n``; shell frame [m]."""
    w = pocket_width / 2
    if not (half_width > w and above > pocket_top and below > pocket_bottom):
        raise ValueError("the shell patch must extend beyond the pocket on every side")
    rects = [(-half_width, half_width, -below, -pocket_bottom), (-half_width, half_width, pocket_top, above),
             (-half_width, -w, -pocket_bottom, pocket_top), (w, half_width, -pocket_bottom, pocket_top)]
    V, F = [], []
    for x0, x1, y0, y1 in rects:
        base = 4 * len(V)
        V.append([[x0, y0, depth], [x1, y0, depth], [x1, y1, depth], [x0, y1, depth]])
        F.append(base + np.array([[0, 1, 2], [0, 2, 3]]))
    return np.array(V, float).reshape(-1, 3), np.vstack(F).astype(int)


def hawse_pipe(pipe_radius: float = 0.35, pipe_angle_deg: float = 20.0, pipe_length: float = 5.0,
               pocket_width: float = 2.8, pocket_top: float = 1.6, pocket_bottom: float = 1.4,
               sections: int = 48, segment: float | None = None) -> tuple[FloatArray, IntArray]:
    """The pipe's wall: a tube of radius ``pipe_radius`` along ``a`` from its elliptic opening in the
    floor to ``pipe_length`` along the axis (measured from ``O``), its wall lines meeting the floor's
    opening points exactly; faces toward the axis; shell frame [m]. ``segment``: triangle length
    along the axis (default the radius)."""
    _check_hawse(pipe_radius, pipe_angle_deg, pocket_width, pocket_top, pocket_bottom)
    gamma = np.radians(pipe_angle_deg)
    corners = _pocket_corners(pocket_width, pocket_top, pocket_bottom)
    theta = _angles(sections, np.arctan2(corners[:, 1], corners[:, 0]))
    _, phi = _opening(theta, pipe_radius, gamma)
    a = pipe_axis(pipe_angle_deg)
    e1, e2 = np.array([1.0, 0.0, 0.0]), np.array([0.0, np.sin(gamma), np.cos(gamma)])
    s0 = pipe_radius * np.sin(phi) / np.tan(gamma)  # where each wall line meets the floor
    if np.max(s0) >= pipe_length:
        raise ValueError(f"pipe_length {pipe_length:g} m must exceed the opening's reach {np.max(s0):.3g} m")
    rows = int(np.ceil((pipe_length - np.min(s0)) / (segment or pipe_radius)))
    frac = np.linspace(0.0, 1.0, rows + 1)
    s = s0[None, :] + frac[:, None] * (pipe_length - s0[None, :])          # (rows + 1, m)
    radial = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2           # (m, 3)
    V = (s[..., None] * a + pipe_radius * radial[None]).reshape(-1, 3)
    m = len(theta)
    i, k = np.meshgrid(np.arange(rows), np.arange(m), indexing="ij")
    k1 = (k + 1) % m
    p00, p01, p10, p11 = i * m + k, i * m + k1, (i + 1) * m + k, (i + 1) * m + k1
    F = np.vstack([np.column_stack([p00.ravel(), p11.ravel(), p10.ravel()]),
                   np.column_stack([p00.ravel(), p01.ravel(), p11.ravel()])])
    return V, F.astype(int)


#: Mesh builders a scene can name (``shape.generator``); each returns (vertices (m, 3), faces (k, 3)).
MESHES: dict[str, Callable[..., tuple[FloatArray, IntArray]]] = {
    "anchor_shank": anchor_shank, "anchor_flukes": anchor_flukes, "anchor_shackle": anchor_shackle,
    "hull_shell": hull_shell, "anchor_pocket": pocket, "hawse_pipe": hawse_pipe,
}


def generated_mesh(generator: str, params: dict) -> tuple[FloatArray, IntArray]:
    """Vertices and faces of the named builder with ``params``; raise ``ValueError`` naming what is wrong."""
    if generator not in MESHES:
        raise ValueError(f"unknown mesh generator {generator!r}: one of {sorted(MESHES)}")
    try:
        return MESHES[generator](**params)
    except TypeError as exc:
        raise ValueError(f"mesh generator {generator!r}: {exc}") from None
