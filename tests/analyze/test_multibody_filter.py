"""Links of one pybullet multibody never collide (Bullet's default without
URDF_USE_SELF_COLLISION): kuka_iiwa's first link sits 10 mm inside its fixed base and r2d2's legs
50 mm inside its body parts, with no contact in pybullet (``getContactPoints`` between them is
empty: measured here). The log's filter keeps those pairs out, so penetration passes on both,
and a planted fault beside them is still caught: the cube's logged position lowered 20 mm into
the floor from sample 40 on is flagged on the cube, at that sample, about 20 mm deep."""

from __future__ import annotations

import numpy as np
import pytest

import rblog

pb = pytest.importorskip("pybullet")
pytest.importorskip("pybullet_data")
from rblog.adapters.pybullet import PybulletRecorder, load_shipped  # noqa: E402

STEPS = 120


def _record(name):
    cid = pb.connect(pb.DIRECT)
    try:
        load_shipped(name, cid)
        rec = PybulletRecorder(cid, keep=True)
        self_contacts = 0
        for _ in range(STEPS):
            pb.stepSimulation(physicsClientId=cid)
            rec()
            for k in range(pb.getNumBodies(physicsClientId=cid)):
                b = pb.getBodyUniqueId(k, physicsClientId=cid)
                self_contacts += len(pb.getContactPoints(b, b, physicsClientId=cid))
        rec.close()
        return rec.trajectory, self_contacts
    finally:
        pb.disconnect(physicsClientId=cid)


def _penetration(traj):
    return next(r for r in rblog.check(traj, only=["penetration"]))


@pytest.mark.parametrize("name", ["kuka_cube", "r2d2"])
def test_links_of_one_multibody_are_not_judged_as_touching(name):
    traj, self_contacts = _record(name)
    assert self_contacts == 0  # pybullet's own: no contact inside a multibody
    res = _penetration(traj)
    assert res.passed, res.reason


def test_a_sunk_cube_beside_the_arm_is_caught():
    traj, _ = _record("kuka_cube")
    cube = next(i for i, s in enumerate(traj.model.body_name) if s.startswith("cube"))
    pos = traj.position.copy()
    k0 = 40
    pos[k0:, cube, 2] -= 0.02
    traj.position = pos
    res = _penetration(traj)
    assert not res.passed
    hit = [f for f in res.findings if cube in f.bodies]
    assert hit and all(set(f.bodies) <= {cube, -1} for f in res.findings), \
        [f.message for f in res.findings]
    # the 20 mm planted, plus pybullet's own resting depth (getClosestPoints: ~0.1 mm at rest)
    assert abs(max(f.value for f in hit) - 0.02) < 2e-3, [f.message for f in hit]
    assert min(f.step for f in hit) >= k0
