"""Scene files -> validated, fully resolved ``Scene`` values.

Order: read TOML -> apply ``--set`` overrides to the raw tables -> expand generators (``[chain]``)
-> validate against ``spec.SCENE_FILE`` -> cross-check names. A scene never executes code.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import tomllib
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np

from viz3d.geometry import contact_spheres
from viz3d.rotations import euler_from_matrix, frame_with_z
from viz3d.scene import ship, shorthand, spec
from viz3d.scene.budget import LIMITS, check_budget, check_chain_size
from viz3d.scene.chainpath import normal_to, path_nodes
from viz3d.scene.schema import Invalid, SceneError, allowed_path, validate


@dataclass(frozen=True)
class Scene:
    """A validated scene.

    Attributes
    ----------
    path : Path
        The scene file.
    data : dict
        Resolved tables (defaults filled in, generators expanded) after overrides.
    overrides : tuple of str
        The ``key.path=value`` overrides applied, in order.
    mesh_dirs : tuple of Path
        Folders besides the scene's own folder tree that mesh files may come from.
    """

    path: Path
    data: dict
    overrides: tuple[str, ...] = ()
    mesh_dirs: tuple[Path, ...] = ()

    @property
    def name(self) -> str:
        return self.data["scene"].get("name", self.path.stem)

    @property
    def kind(self) -> str:
        """What the scene computes: "multibody" (bodies in time) or "hydro" (a dam-reservoir study)."""
        return kind_of(self.data)

    @property
    def base_dir(self) -> Path:
        return self.path.parent

    @cached_property
    def json_text(self) -> str:
        """``data`` as JSON, keys sorted (``json.dumps(data, sort_keys=True)``), made once per scene
        (a ``Scene`` is a value: its tables are not changed once it is made)."""
        return json.dumps(self.data, sort_keys=True)

    def source(self) -> str:
        """How errors name this scene: the file, plus the overrides if any."""
        if not self.overrides:
            return str(self.path)
        return f"{self.path} (with --set {' --set '.join(self.overrides)})"


#: Tables that make a scene file another kind than "multibody" (each kind has its own schema, in its
#: module, imported only for a file of that kind: ``[reservoir]``, ``viz3d.scene.hydro``).
KIND_TABLES = {"reservoir": "hydro"}


def kind_of(tables: Mapping) -> str:
    """The kind of a scene from its (raw or validated) top-level tables."""
    return next((kind for table, kind in KIND_TABLES.items() if table in tables), "multibody")


def kind_of_file(path: str | Path) -> str:
    """The kind of the scene file at ``path`` (read, not validated)."""
    return kind_of(_read_toml(Path(path)))


def load_scene(path: str | Path, overrides: Iterable[str] | Mapping[str, Any] | None = None, *,
               mesh_dirs: Iterable[str | Path] = ()) -> Scene:
    """Read, override, expand and validate a scene file.

    Parameters
    ----------
    path : str or Path
    overrides : iterable of "key.path=value" strings, or mapping key.path -> value
        List elements are addressed by index or by their ``name`` (``bodies.rod.mass=2``).
        String values are parsed as TOML values (``1e-3``, ``[0, 0, 1]``, ``true``), falling back
        to a plain string (``sim.integrator=rk4``).
    mesh_dirs : iterable of paths
        Folders outside the scene's own folder tree that mesh files may be read from (a scene may
        only name files below its own folder unless the user allows another one explicitly).

    Raises
    ------
    SceneError
        Naming the file, the key path and what was expected.
    """
    path = Path(path)
    pairs = _override_pairs(overrides)
    texts = tuple(f"{k}={v}" for k, v in pairs)
    source = _source(path, texts)
    raw = _read_toml(path)
    for key, value in pairs:
        _set_path(raw, key, value, source)
    allowed = tuple(Path(d) for d in mesh_dirs)
    if kind_of(raw) == "hydro":  # its own tables (viz3d.scene.hydro): no bodies, nothing to expand
        from viz3d.scene import hydro

        data = validate(raw, hydro.HYDRO_FILE, source)
        hydro.check_consistency(data, source)
        return Scene(path, data, texts, allowed)
    if "impactor" in raw:  # the impact shorthand: validated as written, then expanded
        raw = shorthand.expand(validate(raw, shorthand.IMPACT_FILE, source), source)
    if "chain" in raw:
        check_chain_size(raw["chain"] if isinstance(raw["chain"], dict) else {},
                         validate(raw.get("limits", {}), LIMITS, source, "limits"), source)
    data = validate(expand_generators(raw, source), spec.SCENE_FILE, source)
    _cross_check(data, source)
    _check_mesh_files(data, path, allowed, source)
    check_consistency(data, source)
    return Scene(path, data, texts, allowed)


def check_consistency(data: dict, source: str) -> None:
    """Checks across keys of a validated scene: durations and steps that fit together, and the
    estimated size and cost against ``[limits]`` (``viz3d.scene.budget``)."""
    sim = data["sim"]
    for key in ("dt", "output_dt"):
        if sim.get(key, 0.0) > sim["t_end"]:
            raise SceneError(source, f"sim.{key}", f"at most sim.t_end = {sim['t_end']:g} s", sim[key])
    check_budget(data, source)


def with_sim(scene: Scene, **changes) -> Scene:
    """A copy of ``scene`` with ``sim`` keys changed (``None`` values ignored), validated like the
    same keys in the file (``--t-end``, ``--dt`` and ``sim.*`` overrides share one validation)
    and recorded as overrides. On adaptive runs (``sim.rtol``) ``dt`` is the interval between
    returned states and sets the frame interval ``sim.output_dt`` with it.

    Raises
    ------
    SceneError
        Naming the ``sim`` key and what was expected.
    """
    changes = {k: v for k, v in changes.items() if v is not None}
    if "rtol" in scene.data["sim"] and "dt" in changes and "output_dt" in scene.data["sim"]:
        changes["output_dt"] = changes["dt"]
    if not changes:
        return scene
    texts = tuple(f"sim.{k}={v!r}" for k, v in changes.items())
    source = _source(scene.path, scene.overrides + texts)
    fields = spec.SIM.fields
    data = json.loads(json.dumps(scene.data))
    for key, value in changes.items():
        if key not in fields:
            raise SceneError(source, f"sim.{key}", f"one of the known keys {sorted(fields)} (unknown key)")
        try:
            data["sim"][key] = fields[key].check(value)
        except Invalid as exc:
            raise SceneError(source, f"sim.{key}", exc.expected, value) from None
    check_consistency(data, source)
    return dataclasses.replace(scene, data=data, overrides=scene.overrides + texts)





def _source(path: Path, texts: tuple[str, ...]) -> str:
    return str(path) if not texts else f"{path} (with --set {' --set '.join(texts)})"


def _check_mesh_files(data: dict, path: Path, allowed: tuple[Path, ...], source: str) -> None:
    """Every mesh shape names a file or a generator (not both); files lie in the scene's folder tree
    or in a folder the user allowed; generators exist and take the parameters given."""
    from viz3d.anchoring import generated_mesh

    shapes = [(f"bodies[{i}].shape", b.get("shape", {})) for i, b in enumerate(data["bodies"])]
    shapes += [(f"collision.ground[{k}]", g) for k, g in enumerate(data.get("collision", {}).get("ground", []))]
    for where, shape in shapes:
        if shape.get("type") != "mesh":
            continue
        if ("file" in shape) == ("generator" in shape):
            raise SceneError(source, f"{where}.file", "a mesh file or a generator (exactly one of the two)")
        if "generator" in shape:
            try:
                generated_mesh(shape["generator"], shape.get("params", {}))
            except ValueError as exc:
                raise SceneError(source, f"{where}.params", f"parameters its generator takes ({exc})",
                                 shape.get("params", {})) from None
            continue
        allowed_path(path.parent, shape["file"], allowed, source, f"{where}.file")


def _read_toml(path: Path) -> dict:
    if not path.is_file():
        raise SceneError(str(path), "", "an existing scene file (not found)")
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(str(path), "", f"valid TOML ({exc})") from None
    except UnicodeDecodeError as exc:
        raise SceneError(str(path), "", f"UTF-8 text ({exc})") from None


def parse_value(text: str) -> Any:
    """A TOML value from ``text``; a bare word stays a string."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def _override_pairs(overrides) -> list[tuple[str, Any]]:
    if overrides is None:
        return []
    if isinstance(overrides, Mapping):
        return list(overrides.items())
    pairs = []
    for item in overrides:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise SceneError("--set", item, "key.path=value")
        pairs.append((key.strip(), parse_value(value.strip())))
    return pairs


def _set_path(raw: dict, key: str, value: Any, source: str) -> None:
    parts = key.split(".")
    node: Any = raw
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        where = ".".join(parts[: i + 1])
        if isinstance(node, list):
            idx = _list_index(node, part)
            if idx is None:
                raise SceneError(source, where, f"an index 0..{len(node) - 1} or the name of an element")
            if last:
                node[idx] = value
            node = node[idx]
        elif isinstance(node, dict):
            if last:
                node[part] = value
            else:
                node = node.setdefault(part, {})
        else:
            raise SceneError(source, where, "a table or array to index into", node)


def _list_index(node: list, part: str) -> int | None:
    if part.isdigit():
        return int(part) if int(part) < len(node) else None
    for i, item in enumerate(node):
        if isinstance(item, dict) and item.get("name") == part:
            return i
    return None


# ---------------------------------------------------------------- generators


def expand_generators(raw: dict, source: str) -> dict:
    """Expand generator tables into the raw scene: ``[chain]`` appends its bodies and joints;
    ``[incline]`` tilts ``sim.gravity`` about y by ``angle_deg`` and gives its ``mu`` to the contacts
    with friction that have none."""
    shaped = any(isinstance(c, dict) and c.get("geometry") == "body_shape" for c in raw.get("contacts", []) or [])
    if "ship" in raw:  # writes a [chain] among the rest
        raw = ship.expand(raw, validate(raw["ship"], spec.SHIP, source, "ship"), source)
    if "chain" not in raw and "incline" not in raw and not shaped:
        return raw
    raw = copy.deepcopy(raw)
    if "chain" in raw:
        sim = raw.get("sim", {}) if isinstance(raw.get("sim", {}), dict) else {}
        gravity = np.asarray(validate(sim, spec.SIM, source, "sim")["gravity"], float)
        bodies, joints, forces = chain_elements(validate(raw["chain"], spec.CHAIN, source, "chain"), gravity, source)
        raw["bodies"] = list(raw.get("bodies", [])) + bodies
        raw["joints"] = list(raw.get("joints", [])) + joints
        raw["forces"] = list(raw.get("forces", [])) + forces
    if "incline" in raw:
        incline = validate(raw["incline"], spec.INCLINE, source, "incline")
        sim = raw.setdefault("sim", {}) if isinstance(raw.get("sim", {}), dict) else {}
        g = np.asarray(validate(sim, spec.SIM, source, "sim")["gravity"], float)
        angle = np.radians(incline["angle_deg"])
        c, s = np.cos(angle), np.sin(angle)
        sim["gravity"] = [float(c * g[0] - s * g[2]), float(g[1]), float(s * g[0] + c * g[2])]
        for contact in raw.get("contacts", []):
            if isinstance(contact, dict) and contact.get("friction", "none") != "none" and "mu" in incline:
                contact.setdefault("mu", incline["mu"])
    if shaped:
        raw["contacts"] = [c for i, entry in enumerate(raw["contacts"]) for c in _shape_contacts(raw, entry, i, source)]
    return raw


def _shape_contacts(raw: dict, entry, i: int, source: str) -> list:
    """A contact with ``geometry = "body_shape"`` as one contact per sphere of body 1's shape
    (``viz3d.geometry.contact_spheres``), named ``<name>_<k>``; other entries unchanged."""
    if not isinstance(entry, dict) or entry.get("geometry") != "body_shape":
        return [entry]
    where = f"contacts[{i}]"
    for key in ("point1", "local1", "x1", "radius"):
        if key in entry:
            raise SceneError(source, f"{where}.{key}", "no point or radius with geometry = 'body_shape' (body 1's shape "
                             "gives them)")
    body = next((b for b in raw.get("bodies", []) if isinstance(b, dict) and b.get("name") == entry.get("body1")), None)
    shape = body.get("shape") if body else None
    if not isinstance(shape, dict):
        raise SceneError(source, f"{where}.geometry", f"'sphere' (body {entry.get('body1')!r} has no shape)", "body_shape")
    try:
        spheres = contact_spheres(validate(shape, spec.SHAPE, source, "shape"),
                                  validate(entry, spec.CONTACT, source, where)["rim_points"])
    except ValueError as exc:
        raise SceneError(source, f"{where}.geometry", f"'sphere' for this body's shape ({exc})", "body_shape") from None
    name = entry.get("name", f"contact{i}")
    return [{**entry, "name": f"{name}_{k}", "geometry": "sphere", "local1": c.tolist(), "radius": r}
            for k, (c, r) in enumerate(spheres)]


def chain_elements(chain: dict, gravity=(0.0, 0.0, -9.81), source: str = "<scene>"
                   ) -> tuple[list[dict], list[dict], list[dict]]:
    """Raw body, joint and force tables of an N-link capsule chain (see ``spec.CHAIN``): from the
    anchor along ``direction``, or with ``end`` hanging between the two as a circular arc."""
    n, L, r = chain["n"], chain["link_length"], chain["radius"]
    anchor, omega = np.asarray(chain["anchor"], float), np.asarray(chain["omega"], float)
    if "end" in chain:
        if np.any(omega):
            raise SceneError(source, "chain.omega", "no initial rotation for a chain between two anchors", chain["omega"])
        nodes, normal = _arc_nodes(anchor, np.asarray(chain["end"], float), n, L, np.asarray(gravity, float), source)
    elif chain["path"]:
        nodes, normal = path_nodes(np.vstack([anchor, chain["path"]]), n, L, source)
    else:
        d = np.asarray(chain["direction"], float)
        d /= np.linalg.norm(d)
        nodes, normal = anchor + np.arange(n + 1)[:, None] * L * d, normal_to(d)
    mass = {"mass": chain["mass"]} if "mass" in chain else {"density": chain["density"]}
    p = chain["prefix"]
    bodies, joints, forces = [], [], []
    for i in range(n):
        d = (nodes[i + 1] - nodes[i]) / L
        c = 0.5 * (nodes[i] + nodes[i + 1])
        bodies.append({
            "name": f"{p}{i}", "shape": {"type": "capsule", "radius": r, "height": L}, **mass,
            "position": c.tolist(), "euler": euler_from_matrix(frame_with_z(d)).tolist(),
            "velocity": np.cross(omega, c - anchor).tolist(), "omega": omega.tolist(), "color": chain["color"],
        })
        joint = {"name": f"{p}_j{i}", "type": "ball", "body1": f"{p}{i}",
                 "body2": chain["attach"] if i == 0 else f"{p}{i - 1}", "point": nodes[i].tolist()}
        held = i > 0 or chain["attach"] != "ground"  # a wildcat or a shackle holds the first link: no twist
        if held and chain["joint"] == "universal":
            before = (nodes[i] - nodes[i - 1]) / L if i > 0 else d
            joint.update(type="universal", axis1=normal.tolist(), axis2=np.cross(before, normal).tolist())
            if chain["joint_damping"] > 0.0:
                forces += [{"type": "joint_motor", "name": f"{p}_damper{i}_{k}", "joint": joint["name"], "coordinate": k,
                            "kp": 0.0, "kd": chain["joint_damping"]} for k in ("angle1", "angle2")]
        joints.append(joint)
    if "end" in chain:
        joints.append({"name": f"{p}_j{n}", "type": "ball", "body1": f"{p}{n - 1}", "body2": "ground",
                       "point": nodes[n].tolist()})
    return bodies, joints, forces


def _arc_nodes(A: np.ndarray, E: np.ndarray, n: int, L: float, gravity: np.ndarray, source: str):
    """Joint points (n + 1, 3) of n chords of length L on a circular arc from A to E sagging along
    gravity, and the unit normal of its plane. The chords subtend 2 beta each: span / L =
    sin(n beta) / sin(beta), solved for beta in (0, pi / n)."""
    from scipy.optimize import brentq

    S = float(np.linalg.norm(E - A))
    if not n * L > S > 0.0:
        raise SceneError(source, "chain.end", f"an end closer to the anchor than the chain's length {n * L:g} m (and "
                         "apart from it)", float(S))
    u = (E - A) / S
    down = gravity - (gravity @ u) * u
    if np.linalg.norm(down) < 1e-12 * max(np.linalg.norm(gravity), 1.0):
        down = normal_to(u)  # a vertical chord (or no gravity): sag sideways
    down /= np.linalg.norm(down)
    beta = brentq(lambda b: np.sin(n * b) / np.sin(b) - S / L, 1e-12 / n, np.pi / n * (1 - 1e-12), xtol=1e-15)
    R = L / (2 * np.sin(beta))
    C = 0.5 * (A + E) - R * np.cos(n * beta) * down
    phi = -n * beta + 2 * beta * np.arange(n + 1)
    nodes = C + R * (np.sin(phi)[:, None] * u + np.cos(phi)[:, None] * down)
    nodes[0], nodes[-1] = A, E
    return nodes, np.cross(u, down)


# ---------------------------------------------------------------- cross checks


def _cross_check(data: dict, source: str) -> None:
    bodies = data["bodies"]
    if not bodies:
        raise SceneError(source, "bodies", "at least one [[bodies]] table")
    _unique(bodies, "bodies", source)
    names = {b["name"] for b in bodies} | {"ground"}
    for i, b in enumerate(bodies):
        if b["type"] == "rigid":
            _check_body(b, f"bodies[{i}]", source)
    for i, j in enumerate(data["joints"]):
        j.setdefault("name", f"j{i}")
        _check_refs(j, ("body1", "body2"), names, f"joints[{i}]", source)
        _check_points(j, f"joints[{i}]", source)
    _unique(data["joints"], "joints", source)
    joint_names = {j["name"] for j in data["joints"]}
    for i, d in enumerate(data["drives"]):
        d.setdefault("name", f"drive{i}")
        if d["name"] in joint_names:
            raise SceneError(source, f"drives[{i}].name", "a name no joint has (drives are listed with the joints)", d["name"])
    _unique(data["drives"], "drives", source)
    for i, f in enumerate(data["forces"]):
        f.setdefault("name", f"{f['type']}{i}")
        where = f"forces[{i}]"
        _check_refs(f, ("body1", "body2", "body"), names, where, source)
        if f["type"] == "spring_damper":
            for side in "12":
                if (f"point{side}" in f) == (f"local{side}" in f):
                    raise SceneError(source, f"{where}.point{side}", f"exactly one of point{side} or local{side}")
        if f["type"] == "force" and "point" in f and "local" in f:
            raise SceneError(source, f"{where}.point", "at most one of point or local")
        if f.get("body") == "ground":
            raise SceneError(source, f"{where}.body", "a body (not ground)")
    _unique(data["forces"], "forces", source)
    for i, c in enumerate(data["contacts"]):
        c.setdefault("name", f"contact{i}")
        _check_refs(c, ("body1", "body2"), names, f"contacts[{i}]", source)
        for side in "12":
            if f"point{side}" in c and f"local{side}" in c:
                raise SceneError(source, f"contacts[{i}].point{side}", f"at most one of point{side} or local{side}")
    _unique(data["contacts"], "contacts", source)
    for i, g in enumerate(data["gauges"]):
        if "body" in g:
            _check_refs(g, ("body",), names, f"gauges[{i}]", source)


def _unique(items: list[dict], table: str, source: str) -> None:
    seen = set()
    for i, item in enumerate(items):
        if item["name"] in seen:
            raise SceneError(source, f"{table}[{i}].name", "a name not used before in this table", item["name"])
        seen.add(item["name"])


def _check_refs(item: dict, keys: tuple[str, ...], names: set[str], where: str, source: str) -> None:
    for key in keys:
        if key in item and item[key] not in names:
            raise SceneError(source, f"{where}.{key}", f"a body name ({', '.join(sorted(names))})", item[key])
    if "body1" in item and item["body1"] == item.get("body2"):
        raise SceneError(source, f"{where}.body2", "a body other than body1", item["body2"])
    if item.get("body1") == "ground":
        raise SceneError(source, f"{where}.body1", "a body (ground may only be body2)", "ground")


def _check_points(joint: dict, where: str, source: str) -> None:
    if joint["type"] != "ball":  # joints with frames: point optional (body 1's centre of mass)
        return
    has_point, has_locals = "point" in joint, ("local1" in joint, "local2" in joint)
    if has_point and any(has_locals):
        raise SceneError(source, f"{where}.point", "either point, or local1 and local2, not both")
    if not has_point and not all(has_locals):
        raise SceneError(source, f"{where}.point", "a joint point: point (world), or both local1 and local2")


def _check_body(b: dict, where: str, source: str) -> None:
    if "euler" in b and "euler_deg" in b:
        raise SceneError(source, f"{where}.euler_deg", "at most one of euler or euler_deg")
    has = {k: k in b for k in ("mass", "inertia", "density", "shape")}
    if has["density"]:
        if not has["shape"]:
            raise SceneError(source, f"{where}.shape", "a shape to compute mass properties from density")
        if has["mass"] or has["inertia"]:
            raise SceneError(source, f"{where}.density", "density alone, or mass (and inertia), not both")
    elif not has["mass"]:
        raise SceneError(source, f"{where}.mass", "mass (with inertia or a shape), or density with a shape")
    elif not has["inertia"] and not has["shape"]:
        raise SceneError(source, f"{where}.inertia", "an inertia tensor, or a shape to compute it from")
    if has["inertia"] and not has["mass"]:
        raise SceneError(source, f"{where}.mass", "a mass to go with the inertia tensor")
