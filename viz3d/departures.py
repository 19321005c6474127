"""Bodies that leave a run: the links of a chain hauled in past its windlass (seed 004, issue 11).

A ``[chain]`` with ``leave = true`` models only the chain that still moves. Its first link (the one
joined to ``attach``, the body that hauls it) leaves the run once its far joint has passed the
chain's ``anchor`` point, the plane there normal to the chain's first direction: the link is then
wholly beyond the hull (seed 004's chain past the windlass's wildcat). The run goes on with a
*generation* of the system without that body:

* the link's joint to ``attach`` is gone, and its joint to the next link (or, for the last link,
  to the shackle) now holds that link to ``attach``, at the point and with the axes the link had
  at that instant in ``attach``'s axes (``frame1``/``frame2``, ``local1``/``local2``: a joint given
  on each body), so the positions stay on the constraints and every remaining coordinate keeps its
  value: the system is rebuilt from the scene (``viz3d.scene.build.build_system``) and the state
  moved onto it (``moved_state``);
* the velocities are made consistent with that joint (``velocities_held``): the leaving link was turning
  about its joint to ``attach``, so the point it held moved otherwise than ``attach`` does; the
  joint's plastic impulse takes the difference, the projection of the velocities onto the new
  system's velocity constraints in the mass metric, and the kinetic energy it takes is booked as
  dissipated (the ledger's ``State.w[-2]``). Without it a formulation that does not project
  velocities (Baumgarte's) opened each new joint by up to 15 mm on the anchor hoist;
* the link's kinetic and potential energy leave with it: the energy ledger's reference drops by the
  change of the ledger's total and dissipated energy at that instant (the link's energy: what the
  impulse took is in both), so the ledger stays closed (``viz3d.simulate``);
* the force elements' memory (stick anchors of shape contacts) is carried over for the shapes that
  stay.

Departures are checked every ``leave_dt`` of simulated time from the start of the run (a multiple
of the step), so a run's departures do not depend on how its driver batches its steps or frames.
Frames keep the bodies and joints of the first generation (``Generation.bodies``, ``joints``): a body
that has left has NaN poses, a joint that has left NaN reactions (``expand_columns``).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, replace

import numpy as np

from viz3d._typing import FloatArray, IntArray
from viz3d.dynamics import body_state, energies
from viz3d.scene.chainpath import link_index
from viz3d.scene.schema import SceneError
from viz3d.stabilization import project_velocities
from viz3d.system import State, System, state_size


@dataclass(frozen=True)
class Generation:
    """One stretch of a run between departures.

    Attributes
    ----------
    scene : viz3d.scene.load.Scene
        The scene this generation's system is built from (the first generation's: the user's).
    system : System
    bodies : ndarray of int, shape (nb,)
        Each body's index among the first generation's bodies.
    joints : ndarray of int, shape (nj,)
        Each joint's index among the first generation's joints (``System.joint_names``).
    """

    scene: object
    system: System
    bodies: IntArray
    joints: IntArray


@dataclass(frozen=True)
class ChainExit:
    """The rule of a leaving chain (``[chain] leave = true``).

    Attributes
    ----------
    prefix : str
        Its links are ``<prefix><i>``.
    attach : str
        The body that hauls it in (``[chain] attach``).
    anchor : ndarray, shape (3,)
        Where the chain starts, world [m].
    inward : ndarray, shape (3,)
        Unit direction of its first link at the start, from ``anchor`` into the chain.
    every : int
        Steps between checks (``leave_dt / dt``).
    """

    prefix: str
    attach: str
    anchor: FloatArray
    inward: FloatArray
    every: int

    @classmethod
    def of(cls, scene, dt: float) -> "ChainExit | None":
        """The scene's leaving chain (None: none); ``SceneError`` for a chain that cannot leave."""
        chain = scene.data.get("chain")
        if not chain or not chain.get("leave"):
            return None
        src = scene.source()
        every = round(chain["leave_dt"] / dt)
        if every < 1 or abs(every * dt - chain["leave_dt"]) > 1e-9 * chain["leave_dt"]:
            raise SceneError(src, "chain.leave_dt", f"a multiple of sim.dt = {dt:g} s", chain["leave_dt"])
        if "rtol" in scene.data["sim"]:
            raise SceneError(src, "sim.rtol", "fixed steps with chain.leave (no rtol: departures are checked between "
                             "fixed samples)", scene.data["sim"]["rtol"])
        if scene.data.get("contacts"):
            raise SceneError(src, "contacts", "none with chain.leave (shape collisions, [collision], are fine)",
                             len(scene.data["contacts"]))
        if chain["attach"] == "ground" or "end" in chain:
            raise SceneError(src, "chain.leave", "a chain hauled by a body (attach), not held at both ends or by ground",
                             True)
        _check_references(scene.data, chain["prefix"], src)
        links = [b for b in scene.data["bodies"] if link_index(b["name"], chain["prefix"]) is not None]
        first = np.asarray(links[0]["position"], float) - np.asarray(chain["anchor"], float)
        return cls(chain["prefix"], chain["attach"], np.asarray(chain["anchor"], float),
                   first / np.linalg.norm(first), every)

    def leaving(self, system: System, state: State) -> int | None:
        """The body index of the first link if its far joint has passed ``anchor`` (None otherwise)."""
        link = self._first_link(system)
        if link is None:
            return None
        far = _far_joint(system, link, self.attach)
        if far is None:
            return None
        js, k, side = far
        cfg = body_state(system, state.q, state.v, state.chart, state.t)
        p = cfg.pose.W_r[link] + cfg.pose.R_WB[link] @ js.B_s[k, side]
        return link if float((p - self.anchor) @ self.inward) <= 0.0 else None

    def _first_link(self, system: System) -> int | None:
        indexed = [(i, b) for b, name in enumerate(system.bodies.names)
                   if (i := link_index(name, self.prefix)) is not None]
        return min(indexed)[1] if indexed else None

    def without(self, gen: Generation, state: State, link: int) -> tuple[Generation, State]:
        """The generation after ``link`` leaves ``gen`` at ``state``, and the state on it."""
        from viz3d.scene.build import build_system

        system = gen.system
        name = system.bodies.names[link]
        data = copy.deepcopy(gen.scene.data)
        cfg = body_state(system, state.q, state.v, state.chart, state.t)
        held = _held_joint(system, data, link, self.attach, cfg)
        joint_in = _joint_between(data, name, self.attach)
        data["bodies"] = [b for b in data["bodies"] if b["name"] != name]
        data["joints"] = [held if j["name"] == held["name"] else j for j in data["joints"] if j["name"] != joint_in]
        data["forces"] = [f for f in data["forces"] if f.get("joint") != joint_in]
        scene = replace(gen.scene, data=data)
        new = build_system(scene)
        keep = np.array([b for b in range(system.n_bodies) if b != link], int)
        joint_index = {n: i for i, n in enumerate(system.joint_names)}
        gen1 = Generation(scene, new, gen.bodies[keep], np.array([gen.joints[joint_index[n]] for n in new.joint_names],
                                                                 int))
        return gen1, velocities_held(new, moved_state(system, new, state, keep))


def velocities_held(system: System, state: State) -> State:
    """``state`` with its velocities projected onto ``system``'s velocity constraints in the mass metric
    (``viz3d.stabilization.project_velocities``: the plastic impulse of a joint that now holds what moved
    otherwise), the kinetic energy that takes added to the ledger's dissipated energy (``State.w[-2]``, when
    the run has a ledger)."""
    v = project_velocities(system, state.q, state.v, state.chart, state.memory, t=state.t)
    if not system.n_aux:
        return state.replace(v=v)
    w = state.w.copy() if state.w.size else np.zeros(system.n_aux)  # (zeros: a run's start, not yet set)
    w[-2] += energies(system, state)[0] - energies(system, state.replace(v=v))[0]
    return state.replace(v=v, w=w)


def moved_state(old: System, new: System, state: State, keep: IntArray) -> State:
    """``state`` of ``old`` on ``new``, whose bodies are ``old``'s bodies ``keep`` (all rigid, floating),
    with the same joints' rows, force elements and contact sets: the frame coordinates and twists of
    the bodies kept, the work integrals and contact phases as they are, the stick anchors of the shapes
    kept."""
    nf, nq = old.n_frames, old.n_q_body
    frames = np.flatnonzero(np.isin(old.frame_body, keep))  # (the leaving bodies are rigid and floating)
    q = np.concatenate([state.q[:nf * nq].reshape(nf, nq)[frames].reshape(-1), state.q[nf * nq:]])
    v = np.concatenate([state.v[:6 * nf].reshape(nf, 6)[frames].reshape(-1), state.v[6 * nf:]])
    memory = state.element_memory
    if memory:
        memory = tuple(m if m is None else _anchors_kept(e_old, e_new, m, keep)
                       for e_old, e_new, m in zip(old.forces, new.forces, memory))
    return State(state.t, q, v, state.chart[frames], state.w.copy(), state.memory, memory)


def _anchors_kept(old_element, new_element, anchors, keep: IntArray):
    """The stick anchors (``viz3d.contact.collision.StickAnchors``) of the contacts between shapes that
    stay, renumbered to ``new_element``'s shapes."""
    new_body = np.full(old_element.n_bodies + 1, -1)
    new_body[keep] = np.arange(len(keep))
    new_body[old_element.n_bodies] = new_element.n_bodies  # ground stays ground
    index = {key: i for i, key in enumerate(_shape_keys([s.body for s in new_element.shapes]))}
    old_keys = _shape_keys([new_body[s.body] for s in old_element.shapes])  # (body -1: it left)
    shape_map = np.array([index.get(key, -1) for key in old_keys], int)
    shape = shape_map[anchors.shape]
    ok = (shape >= 0).all(axis=1)
    return replace(anchors, shape=shape[ok], anchor=anchors.anchor[ok], mark=anchors.mark[ok])


def _shape_keys(bodies: list[int]) -> list[tuple[int, int]]:
    """Each shape's identity across generations: (its body, its rank among that body's shapes)."""
    seen: dict[int, int] = {}
    keys = []
    for b in bodies:
        keys.append((int(b), seen.get(b, 0)))
        seen[b] = seen.get(b, 0) + 1
    return keys


def expand(values: FloatArray, index: IntArray, n: int, axis: int = 1) -> FloatArray:
    """``values`` with axis ``axis`` (of length ``len(index)``) spread over ``n`` entries at ``index``,
    NaN elsewhere (the bodies or joints that have left)."""
    shape = list(values.shape)
    shape[axis] = n
    out = np.full(shape, np.nan)
    where = [slice(None)] * len(shape)
    where[axis] = index
    out[tuple(where)] = values
    return out


# ----------------------------------------------------------------------------- the joints rewritten


def _joint_between(data: dict, a: str, b: str) -> str:
    return next(j["name"] for j in data["joints"] if {j["body1"], j["body2"]} == {a, b})


def _far_joint(system: System, link: int, attach: str):
    """``(joint set, index, side)`` of the link's other joint than its joint to ``attach``."""
    a = system.bodies.index(attach) if attach != "ground" else system.n_bodies
    for js in system.joint_sets:
        for k in range(js.n_joints):
            b1, b2 = js.body[k]
            if link in (b1, b2) and a not in (b1, b2):
                return js, k, 0 if b1 == link else 1
    return None


def _held_joint(system: System, data: dict, link: int, attach: str, cfg) -> dict:
    """The scene entry of the link's far joint rewritten onto ``attach``: each side's point and frame
    in its body's axes, the link's side carried into ``attach``'s axes at the configuration ``cfg``."""
    js, k, side = _far_joint(system, link, attach)
    name = js.names[k]
    entry = next(j for j in data["joints"] if j["name"] == name)
    a = system.bodies.index(attach) if attach != "ground" else system.n_bodies
    W_r, R = cfg.pose.W_r, cfg.pose.R_WB
    s = [np.asarray(js.B_s[k, i], float) for i in (0, 1)]
    s[side] = R[a].T @ (W_r[link] + R[link] @ s[side] - W_r[a])
    bodies = [entry["body1"], entry["body2"]]
    bodies[side] = attach
    out = {"name": name, "type": entry["type"], "body1": bodies[0], "body2": bodies[1], "local1": s[0].tolist(),
           "local2": s[1].tolist()}
    if getattr(js, "B_A", None) is not None:  # a framed joint: its axes too (a ball joint has none)
        A = [np.asarray(js.B_A[k, i], float) for i in (0, 1)]
        A[side] = R[a].T @ R[link] @ A[side]
        out.update(frame1=A[0].tolist(), frame2=A[1].tolist())
    return out


def _check_references(data: dict, prefix: str, src: str) -> None:
    """A leaving chain's links may be named only by its own joints and dampers and by collision groups:
    refuse contacts, drives, gauges and force elements on them (they would outlive the link)."""
    def is_link(x) -> bool:
        return isinstance(x, str) and link_index(x, prefix) is not None

    chain_joints = {j["name"] for j in data["joints"] if is_link(j["body1"]) or is_link(j["body2"])}
    for table in ("contacts", "gauges", "forces", "drives"):
        for i, entry in enumerate(data.get(table, []) or []):
            names = [entry.get(k) for k in ("body", "body1", "body2")]
            if any(is_link(x) for x in names):
                raise SceneError(src, f"{table}[{i}]", f"no body of the leaving chain '{prefix}*' (it leaves the run)",
                                 next(x for x in names if is_link(x)))
            if table == "drives" and entry.get("joint") in chain_joints:
                raise SceneError(src, f"drives[{i}].joint", "not a joint of the leaving chain (it leaves the run)",
                                 entry["joint"])


class Departures:
    """A run's departures: its ``ChainExit`` rule and the generations so far (``Generation``), the first
    the scene's own system. Held by ``viz3d.simulate.Simulation``, which calls ``next`` at each check
    (``steps_to_check``) and moves on to the generation it gives.

    Attributes
    ----------
    rule : ChainExit
    generations : list of Generation
    log : list of (float, str)
        When each body left, and which [s].
    """

    def __init__(self, rule: ChainExit, scene, system: System):
        self.rule = rule
        self.generations = [Generation(scene, system, np.arange(system.n_bodies), np.arange(len(system.joint_names)))]
        self.log: list[tuple[float, str]] = []

    @classmethod
    def of(cls, scene, system: System) -> "Departures | None":
        rule = ChainExit.of(scene, scene.data["sim"]["dt"])
        return None if rule is None else cls(rule, scene, system)

    @property
    def layout(self) -> System:
        """The first generation's system: the bodies and joints every frame is given in."""
        return self.generations[0].system

    @property
    def current(self) -> Generation:
        return self.generations[-1]

    def steps_to_check(self, n_samples: int) -> int:
        """Samples from sample ``n_samples`` to the next check (``rule.every`` when at one)."""
        return self.rule.every - n_samples % self.rule.every

    def next(self, state: State) -> tuple[Generation, State] | None:
        """The generation after the first link leaves at ``state`` (of the current one), and the state
        on it; None when no link leaves now."""
        gen = self.current
        link = self.rule.leaving(gen.system, state)
        if link is None:
            return None
        gen1, state1 = self.rule.without(gen, state, link)
        self.generations.append(gen1)
        before = state.w[-2] if state.w.size else 0.0
        taken = f"; its joint's impulse took {state1.w[-2] - before:.3g} J" if state1.w.size else ""
        self.log.append((state.t, f"{gen.system.bodies.names[link]} left the run (hauled in past "
                                  f"{self.rule.attach}{taken})"))
        return gen1, state1

    def generation_of(self, state) -> Generation:
        """The generation a state (or a ``States``) belongs to, by its number of coordinates (each
        departure removes a floating body's)."""
        return next(g for g in reversed(self.generations) if g.system.n_q == state_size(state))
