"""Cost of finding shape contacts against the number of shapes (a benchmark, not a test).

    python benchmarks/bench_collision.py [--n 50,100,200,400,800] [--out docs/bench_collision.png]

N capsules (chain-link size: radius 2 cm, length 10 cm) are scattered at one density (about
1.5 touching neighbours each) in a box above a faceted triangle-mesh floor they partly overlap,
all in one group that collides with itself and with the floor (``viz3d.contact.collision``). For
each N: the broad phase's candidate pairs (bounding spheres overlapping; then the capsules' cores,
segment plus radius, overlapping) against the N (N - 1) / 2 pairs an all-pairs test would try,
the contacts found, and the wall time of one ``detect`` (broad phase, Coal's narrow phase,
reduction) and of the force evaluation on top of it (best of ``repeats``). For N <= 200 also the
all-pairs narrow phase (every pair handed to Coal), the cost the broad phase avoids. Prints a
Markdown table and writes a log-log chart. Times are wall-clock on this machine: compare the rows
of one run with each other.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from viz3d.contact.collision import Collisions, PairLaw, Shape, support_points
from viz3d.contact.laws import Linear
from viz3d.kinematics import Configuration, pose_from, twist_from

ROOT = Path(__file__).resolve().parents[1]
RADIUS, LENGTH = 0.02, 0.10


def scene(n: int, seed: int = 0) -> tuple[Collisions, Configuration]:
    import trimesh

    rng = np.random.default_rng(seed)
    side = (n / 40.0) ** (1 / 3) * 0.25  # constant density: ~1.5 neighbours per capsule
    capsule = [Shape(f"link{i}", i, "capsule", (RADIUS, LENGTH), support=support_points("capsule", (RADIUS, LENGTH), None))
               for i in range(n)]
    slab = trimesh.creation.box(extents=[side + 0.2, side + 0.2, 0.1]).subdivide().subdivide()
    v = np.asarray(slab.vertices) + [side / 2, side / 2, -0.05]
    floor = Shape("floor", n, "mesh", vertices=v, faces=np.asarray(slab.faces), support=support_points("mesh", (), v),
                  group=1)
    pair_law = np.array([[0, 0], [0, -1]])
    world = Collisions(tuple(capsule) + (floor,), ("links", "ground"), pair_law, (PairLaw(Linear(1e5, 10.0)),), n)
    W_r = rng.uniform(0.0, side, (n, 3))
    W_r[:, 2] -= 0.02  # the lowest ones overlap the floor
    pose = pose_from(W_r, Rotation.random(n, random_state=seed).as_matrix())
    cfg = Configuration(0.0, pose, twist_from(rng.normal(0.0, 0.1, (n, 3)), np.zeros((n, 3)), pose))
    return world, cfg


def best_of(f, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - t0)
    return best


def all_pairs_narrow_phase(world: Collisions, cfg: Configuration) -> float:
    """Wall time of handing every pair of moving shapes to Coal (what no broad phase costs)."""
    import coal

    w = world._world()
    r, R = world.shape_poses(cfg)
    moving = np.flatnonzero(w["moving"])
    tf = {i: coal.Transform3s(R[i], r[i]) for i in moving}
    t0 = time.perf_counter()
    for a, i in enumerate(moving):
        for j in moving[a + 1:]:
            res = coal.CollisionResult()
            coal.collide(w["geometry"][i], tf[i], w["geometry"][j], tf[j], w["point"], res)
    return time.perf_counter() - t0


def measure(n: int, repeats: int) -> dict:
    world, cfg = scene(n)
    world.detect(cfg)  # build the Coal geometries once
    r, R = world.shape_poses(cfg)
    row = {"n": n, "pairs": n * (n - 1) // 2, "candidates": len(world.candidates(r)),
           "cores": len(world.candidates(r, R)), "contacts": world.detect(cfg).m,
           "broad_ms": 1e3 * best_of(lambda: world.candidates(r, R), repeats),
           "detect_ms": 1e3 * best_of(lambda: world.detect(cfg), repeats),
           "forces_ms": 1e3 * best_of(lambda: world.wrench(cfg), repeats),
           "all_pairs_ms": 1e3 * all_pairs_narrow_phase(world, cfg) if n <= 200 else np.nan}
    return row


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", default="50,100,200,400,800")
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "bench_collision.png")
    args = p.parse_args(argv)
    rows = [measure(int(n), args.repeats) for n in args.n.split(",")]
    print("| shapes | all pairs | bounds overlap | cores overlap | contacts | broad phase [ms] | detect [ms] "
          "| detect + forces [ms] | all-pairs narrow phase [ms] |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['n']} | {r['pairs']} | {r['candidates']} | {r['cores']} | {r['contacts']} | {r['broad_ms']:.2f} | "
              f"{r['detect_ms']:.2f} | {r['forces_ms']:.2f} | {r['all_pairs_ms']:.1f} |")
    n = np.array([r["n"] for r in rows], float)
    slope = np.polyfit(np.log(n), np.log([r["forces_ms"] for r in rows]), 1)[0]
    print(f"\ndetect + forces grows as N^{slope:.2f} (all pairs: N^2)")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    ax.loglog(n, [r["forces_ms"] for r in rows], "o-", label="detect + forces (broad phase, Coal)")
    ax.loglog(n, [r["broad_ms"] for r in rows], "s-", label="broad phase alone (k-d tree, core test)")
    small = [r for r in rows if np.isfinite(r["all_pairs_ms"])]
    ax.loglog([r["n"] for r in small], [r["all_pairs_ms"] for r in small], "x--", label="all-pairs narrow phase")
    ax.set_xlabel("capsules")
    ax.set_ylabel("wall time per evaluation [ms]")
    ax.set_title(f"Shape contacts: cost against N (slope {slope:.2f})")
    ax.legend()
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=120)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
