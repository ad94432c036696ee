"""Cost per contact point of a hull pile against the box pile (issue: "no slower per contact
point than the box pile").

The same 64 bodies (a 4 x 4 x 4 grid 0.18 m x 0.18 m x 0.3 m apart, random orientations, speeds
up to 0.3 m/s, spins up to 2 rad/s, seeded; friction 0.6, restitution 0.2) dropped on the
ground, dt 1e-3, 2 s, in three shapes: 0.1 m cubes as boxes (the box pile), the same cubes as
hulls (8 vertices: the hull path against the box path on one geometry), and hexagonal nuts
(samples/shapes.toml's, 12 vertices); and samples/shapes.toml itself ("shapes sample": 24 bodies,
two of them hulls, the others capsules, cylinders, balls, boxes and compounds, beside a static
slope). Each pile steps in chunks of --chunk steps, the piles in turn (interleaved, so the
machine's load slows all alike); CPU time (time.process_time) around the stepping calls. Per
contact point: that CPU time over the contact points summed over the steps (world.stats); the
collide and solve stages' share from the engine's own profile (cycle counter, wall time); and
what sets the solve's cost: points a manifold, velocity sweeps a step, awake bodies.

    python benchmarks/bench_hull_pile.py [--steps 2000] [--chunk 100] [--piles box,cube hull]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from rblog.engine import integrators as rot
from rblog.engine import profile
from rblog.engine.contact import ContactParams, ContactWorld
from rblog.engine.scene import parse_scene

CUBE = ("[[-0.05,-0.05,-0.05],[0.05,-0.05,-0.05],[-0.05,0.05,-0.05],[0.05,0.05,-0.05],"
        "[-0.05,-0.05,0.05],[0.05,-0.05,0.05],[-0.05,0.05,0.05],[0.05,0.05,0.05]]")
NUT = ("[[0.07,0,-0.03],[0.035,0.060622,-0.03],[-0.035,0.060622,-0.03],[-0.07,0,-0.03],"
       "[-0.035,-0.060622,-0.03],[0.035,-0.060622,-0.03],[0.07,0,0.03],[0.035,0.060622,0.03],"
       "[-0.035,0.060622,0.03],[-0.07,0,0.03],[-0.035,-0.060622,0.03],[0.035,-0.060622,0.03]]")
SCENE = """
[sim]
dt = 1e-3
duration = 2.0
seed = 3
[ground]
restitution = 0.2
friction = 0.6
[[generator]]
layout = "grid"
grid = [4, 4, 4]
spacing = [0.18, 0.18, 0.3]
origin = [-0.27, -0.27, 0.2]
random_orientation = true
speed = [0.0, 0.3]
spin = [0.0, 2.0]
name_prefix = "b"
[generator.body]
{shape}
mass = 0.1
restitution = 0.2
friction = 0.6
"""
PILES = {
    "box": 'shape = "box"\nhalf_extents = [0.05, 0.05, 0.05]',
    "cube hull": f'shape = "hull"\nvertices = {CUBE}',
    "nut hull": f'shape = "hull"\nvertices = {NUT}',
    "shapes sample": None,
}
SAMPLE = Path(__file__).resolve().parents[1] / "samples" / "shapes.toml"


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--chunk", type=int, default=100)
    ap.add_argument("--piles", default=",".join(PILES), help="comma-separated: " + ", ".join(PILES))
    a = ap.parse_args(argv)
    runs = {}
    for name in a.piles.split(","):
        shape = PILES[name]
        if shape is None:
            sc = parse_scene(SAMPLE.read_text(), str(SAMPLE))
        else:
            sc = parse_scene(SCENE.format(shape=shape), f"<{name} pile>")
        w = ContactWorld(sc.model, ContactParams.from_dict(sc.contact), rot.METHOD_SPLITTING,
                         rot.ORTHO_NORMALIZE)
        n = sc.model.n_bodies
        outs = [np.zeros((1, n, 3)), np.zeros((1, n, 3)), np.zeros((1, n, 4)),
                np.zeros((1, n, 3, 3)), np.zeros((1, n, 3))]
        w.profile_ticks = np.zeros(profile.N_PROF, np.int64)
        runs[name] = dict(w=w, s=sc.state.copy(), outs=outs, cpu=0.0)
    done = 0
    while done < a.steps:
        k = min(a.chunk, a.steps - done)
        for r in runs.values():
            s = r["s"]
            t0 = time.process_time()
            r["w"].advance(1e-3, k, k, False, s.position, s.linear_momentum, s.quat_wxyz,
                           s.rotation, s.angular_momentum_world, *r["outs"])
            r["cpu"] += time.process_time() - t0
        done += k
    base = None
    for name, r in runs.items():
        st = r["w"].stats
        us = 1e6 * r["cpu"] / max(st[3], 1)
        base = base or us
        tick = r["w"].profile_ticks / profile.ticks_per_second()
        stage = {k: tick[profile.STAGES.index(k)] for k in ("collide", "solve")}
        print(f"{name:13s} CPU {r['cpu']:.3f} s, {st[3] / max(st[0], 1):.1f} points a step, "
              f"{us:.2f} us a contact point ({us / base:.2f}x the box pile); collide "
              f"{1e6 * stage['collide'] / max(st[3], 1):.2f} us, solve "
              f"{1e6 * stage['solve'] / max(st[3], 1):.2f} us a point (wall); "
              f"{st[3] / max(st[2], 1):.2f} points a manifold, {st[8] / max(st[0], 1):.1f} sweeps "
              f"a step, {st[4] / max(st[0], 1):.1f} awake bodies")


if __name__ == "__main__":
    main()
