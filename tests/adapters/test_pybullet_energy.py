"""pybullet's log states every work "none" (rblog.adapters.pybullet) while it logs the
multibody damping's impulse (``-m v k (1 + |v|)``, k = 0.04) and the motors' inside the joint
kind: `energy` leaves such a tree unjudged, saying why, and with every tree left out and no
contact event checked its verdict is "not judged", never a "pass" on nothing checked. Measured
from pybullet's own numbers on kuka under random velocity targets (50 N m): over steps 330-530
its energy drops 39.26 J, of which the motors' work (appliedJointMotorTorque x the step's mean
joint velocity) and the URDF's joint damping (0.5 N m s) are 38.98 J: the balance the analyzer
drew without them was a false alarm (benchmarks/truth_table.py).
"""

from __future__ import annotations

import numpy as np
import pytest

pb = pytest.importorskip("pybullet")

import rblog  # noqa: E402
from rblog.adapters.pybullet import PybulletRecorder, load_shipped  # noqa: E402


def test_kuka_energy_not_judged_without_the_damping_work():
    cid = pb.connect(pb.DIRECT)
    try:
        load_shipped("kuka_cube", cid)
        rec = PybulletRecorder(cid, keep=True, every=1)
        for _ in range(100):
            pb.stepSimulation(physicsClientId=cid)
            rec()
        rec.close()
    finally:
        pb.disconnect(physicsClientId=cid)
    traj = rec.trajectory
    lin, _ = traj.impulse("passive")
    assert np.abs(lin[1:]).max() > 0  # the damping acts (measured 4.0e-7 N s)
    res = next(r for r in rblog.check(traj, threads=1) if r.analyzer == "energy")
    assert res.verdict == "not judged"
    assert "passive impulse is logged, nonzero, with its work stated none" in res.reason
    assert "lbr_iiwa/lbr_iiwa_link_1" in res.reason
