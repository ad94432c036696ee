"""A fixed slice of the loose pile for instruction counts (valgrind --tool=callgrind), so that two
builds can be compared stage by stage without the wall-clock noise of a shared machine.

    python benchmarks/callgrind_pile.py --save pile500.npz          # 1 s of the 500-box pile
    valgrind --tool=callgrind --callgrind-out-file=cg.out \\
        python benchmarks/callgrind_pile.py --load pile500.npz --steps 200
    callgrind_annotate --inclusive=yes cg.out | grep rb::

``--save`` steps the pile from its drop (bench_pile's scene) and stores the state; ``--load``
steps on from a stored state (the contact cache starts cold: the first step has no warm start,
alike for every build). ``--scene FILE`` steps a scene file from its start instead (its own
contact settings), e.g. samples/shapes.toml (run with RBLOG_THREAD_HANDOVER=0 under valgrind).
One thread unless ``--threads``. The installed module is stripped; for the stages' names build
it with symbols (pip install -e . with -Ccmake.build-type=RelWithDebInfo
"-Ccmake.define.CMAKE_CXX_FLAGS=-g -fno-stack-protector" -Cinstall.strip=false: the Release
build's code, nanobind's strip flag off).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

from rblog.engine import _core
from rblog.engine import integrators as rot
from rblog.engine.contact import ContactParams, ContactWorld
from rblog.engine.scene import parse_scene
from rblog.study.scenes import loose_pile

FIELDS = ("position", "linear_momentum", "quat_wxyz", "rotation", "angular_momentum_world")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--boxes", type=int, default=500)
    ap.add_argument("--dt", type=float, default=1e-3)
    ap.add_argument("--save", help="step --steps from the drop and store the state here")
    ap.add_argument("--load", help="step --steps on from this stored state")
    ap.add_argument("--scene", help="step this scene file (.toml) from its start instead")
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--solver", default="pgs", help="ContactParams.solver: pgs or soft_step")
    ap.add_argument("--substeps", type=int, default=4, help="the soft step's substeps")
    ap.add_argument("--contact-hertz", type=float, default=None,
                    help="the soft step's contact_hertz (default: the substeps' cap)")
    args = ap.parse_args(argv)
    _core.set_threads(args.threads)
    if args.scene:
        sc = parse_scene(Path(args.scene).read_text(), args.scene)
        model, state, params = sc.model, sc.state.copy(), ContactParams.from_dict(sc.contact)
    else:
        model, state = loose_pile(args.boxes)
        params = ContactParams(solver=args.solver, substeps=args.substeps,
                               contact_hertz=args.contact_hertz)
    if args.load:
        z = np.load(args.load)
        for f in FIELDS:
            getattr(state, f)[...] = z[f]
    world = ContactWorld(model, params, rot.METHOD_SPLITTING, rot.ORTHO_NORMALIZE)
    n = model.n_bodies
    outs = [np.zeros((1, n, 3)), np.zeros((1, n, 3)), np.zeros((1, n, 4)), np.zeros((1, n, 3, 3)),
            np.zeros((1, n, 3))]
    _, bad, _, _ = world.advance(args.dt, args.steps, args.steps, False, state.position,
                                 state.linear_momentum, state.quat_wxyz, state.rotation,
                                 state.angular_momentum_world, *outs)
    if bad >= 0:
        sys.exit(f"diverged at step {bad}")
    st = world.stats
    print(f"{args.steps} steps: {st[3] / max(st[0], 1):.0f} points, {st[8] / max(st[0], 1):.1f} "
          f"sweeps per step, {world.n_awake} awake")
    if args.save:
        np.savez(args.save, **{f: getattr(state, f) for f in FIELDS})


if __name__ == "__main__":
    main()
