"""The audit's geometry of every shape (rblog.analyze.shapes): CPU time per sample of the
broadphase and the narrowphase on a pile of mixed geoms on a floor.

500 geoms (spheres, capsules, cylinders, boxes, ellipsoids, 4-8 cm) on a 10 x 10 x 5 lattice of
0.15 m cells, jittered by 1 cm and turned at random at each of the samples, and a floor plane:
neighbours touch and overlap, as in a settled pile. Reported: candidate pairs per sample, CPU
time (time.process_time) per sample of each stage and per pair, and the pairs in contact.

    python benchmarks/bench_shapes.py [--geoms 500] [--samples 100]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.spatial.transform import Rotation

from rblog.analyze import shapes


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--geoms", type=int, default=500)
    ap.add_argument("--samples", type=int, default=100)
    a = ap.parse_args()
    rng = np.random.default_rng(0)
    g, t_n = a.geoms, a.samples
    types = np.append(rng.choice(["sphere", "capsule", "cylinder", "box", "ellipsoid"], g),
                      "plane")
    sizes = np.vstack([rng.uniform(0.04, 0.08, (g, 3)), np.zeros(3)])
    geoms = shapes.Geoms.build(types, sizes, body=np.append(np.arange(g), -1))
    side = int(np.ceil((g / 5) ** 0.5))
    cell = np.stack(np.meshgrid(np.arange(side), np.arange(side), np.arange(5), indexing="ij"),
                    -1).reshape(-1, 3)[:g] * 0.15
    pos = np.zeros((t_n, g + 1, 3))
    rot = np.broadcast_to(np.eye(3), (t_n, g + 1, 3, 3)).copy()
    for k in range(t_n):
        pos[k, :g] = cell + [0, 0, 0.07] + rng.normal(scale=0.01, size=(g, 3))
        rot[k, :g] = Rotation.random(g, random_state=k).as_matrix()
    t0 = time.process_time()
    k, i, j = shapes.broadphase(geoms, pos, rot, 1e-3)
    t1 = time.process_time()
    d = shapes.pair_distance(geoms, pos, rot, k, i, j)
    t2 = time.process_time()
    print(f"{g} geoms + floor, {t_n} samples: {len(k) / t_n:.0f} candidate pairs per sample, "
          f"{(d['sep'] <= 0).sum() / t_n:.0f} touching; CPU per sample: broadphase "
          f"{1e3 * (t1 - t0) / t_n:.2f} ms, narrowphase {1e3 * (t2 - t1) / t_n:.2f} ms "
          f"({1e6 * (t2 - t1) / max(len(k), 1):.2f} us per pair); not converged "
          f"{int((d['status'] != shapes.OK).sum())}")


if __name__ == "__main__":
    main()
