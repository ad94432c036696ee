"""The consistency check on loose piles of boxes (issue 31): the kinematic check judges w against the orientation only over intervals without an impact (the
momentum analyzer's impact events), so the pile passes it from rblog, MuJoCo and pybullet.

Before, rblog's own log of the issue's pile (rblog.study.scenes.loose_pile: five layers of 10 x 10
boxes dropped on the ground, 2 s at 100 Hz) failed it: "angular_velocity does not turn the logged
orientation ... median 0.217 (relative) for 'box41', 'box60', 'box86'". Why that was not real,
measured independently on the same run logged at every 1 ms step (commit message of this test):
over each flagged 10 ms interval the orientation's turn equals the integral of the logged
per-step w to 6e-8 .. 3e-3 rad (box41, t = 0.68 s: turn 1.73e-3 rad, integral of w 1.73e-3 rad,
while the ends' mean w gives 1.44e-3 rad; t = 0.30 s: w reaches 13.2 rad/s inside an interval
whose end samples read 0.14 and 0.06 rad/s): the 10 ms samples miss what the contacts do between
them, not a logging fault.

The same pile with 125 boxes (five layers of 5 x 5) for 1 s fails the same way before (median
0.264 for one box) and runs in the default suite (14 s); the 500-box pile from the three engines
is behind ``-m slow`` (about 3 min per engine on a loaded 2-core machine).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from rblog_cli.main import main

ENGINES = ("rblog", "mujoco", "pybullet")


def loose_pile_toml(path, n=500, per_row=10, duration=2.0):
    """The issue's pile as a scene: rblog.study.scenes.loose_pile(n, per_row), dt 1 ms, logged at
    100 Hz (the default)."""
    from rblog.study.scenes import loose_pile
    from rblog.study.variants import to_toml

    model, state = loose_pile(n, per_row=per_row)
    doc = {"sim": {"dt": 1e-3, "duration": duration},
           "ground": {"restitution": float(model.ground_restitution),
                      "friction": float(model.ground_friction)},
           "body": [{"name": f"box{i}", "shape": "box",
                     "half_extents": [float(x) for x in model.body_size[i]],
                     "mass": float(model.body_mass[i]),
                     "restitution": float(model.body_restitution[i]),
                     "friction": float(model.body_friction[i]),
                     "position": [float(x) for x in state.position[i]],
                     "quat_wxyz": [float(x) for x in state.quat_wxyz[i]]} for i in range(n)]}
    path.write_text(to_toml(doc))
    return path


def body_frame_kinematics(traj):
    """The kinematic issue of ``traj`` with w logged in the body frame (R^T w, and L = I_world w
    to match, so that only the kinematic check can tell): a real logging fault."""
    from rblog.analyze.consistency import inspect

    rot = np.asarray(traj.rotation)
    inertia = np.asarray(traj.model.body_inertia_diag)[None]
    w_body = np.einsum("tnji,tnj->tni", rot, traj.angular_velocity)
    traj.angular_velocity = np.ascontiguousarray(w_body)
    traj.angular_momentum = np.ascontiguousarray(np.einsum(
        "tnij,tnj->tni", rot, inertia * np.einsum("tnji,tnj->tni", rot, w_body)))
    return [i for i in inspect(traj) if i.check == "kinematics"]


def test_small_loose_pile_passes_and_a_body_frame_w_in_it_does_not(tmp_path):
    import rblog
    from rblog.analyze import check

    scene = rblog.load_scene(str(loose_pile_toml(tmp_path / "pile125.toml", 125, 5, 1.0)))
    traj, _ = rblog.simulate(scene)
    (r,) = check(traj, only=["consistency"])
    assert r.passed, r.reason
    # the other direction, judged over the intervals without an impact (boxes tipping over,
    # sliding, rolling off the pile): measured median mismatch 1.6 on 3 boxes
    (issue,) = body_frame_kinematics(traj)
    assert issue.message.startswith("angular_velocity looks like body frame"), issue.message


def _consistency(log):
    res = CliRunner().invoke(main, ["check", "--json", "--only", "consistency", str(log)])
    assert res.exit_code in (0, 1), res.output
    (doc,) = json.loads(res.stdout)["logs"]
    (r,) = doc["results"]
    return r


@pytest.mark.slow
@pytest.mark.parametrize("engine", ENGINES)
def test_loose_pile_passes_the_consistency_check(tmp_path, engine):
    if engine != "rblog":
        pytest.importorskip(engine)
    scene = loose_pile_toml(tmp_path / "pile.toml")
    log = tmp_path / f"pile-{engine}.mcap"
    res = CliRunner().invoke(main, ["run", str(scene), "--engine", engine, "--mcap", str(log)])
    assert res.exit_code == 0, res.output
    r = _consistency(log)
    assert r["passed"], r["reason"]
    # the other direction on the same log: measured on 25 of rblog's boxes, median mismatch 1.72
    from rblog.record.reader import load

    (issue,) = body_frame_kinematics(load(log))
    assert issue.message.startswith("angular_velocity looks like body frame"), issue.message
