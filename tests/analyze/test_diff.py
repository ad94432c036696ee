"""rblog diff: two hand-made logs of one scene with a known divergence.

B is A with body "b" displaced along x by d(t) = 1e-3 exp(2 t) m and turned by 0.05 rad about z:
its position divergence grows at 2 /s, leaves 1e-2 m at t = ln(10) / 2 = 1.1513 s, and the angle
between orientations is 0.05 rad throughout; body "a" is identical in both.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

import rblog
from rblog.analyze.diff import IncompatibleLogs, diff
from rblog.record.recorder import body_table, trajectory_from_arrays
from rblog_cli.main import main


def _pair(T=301, dt=0.01, rename=None):
    t = np.arange(T) * dt
    model = body_table(name=["a", "b"], shape=["sphere", "box"], size=[[0.1, 0, 0], [0.1, 0.2, 0.3]],
                       mass=[1.0, 2.0], gravity=[0, 0, 0])
    pos = np.zeros((T, 2, 3))
    pos[:, 1, 0] = 1.0 + 0.5 * t
    q = np.zeros((T, 2, 4))
    q[..., 0] = 1.0
    vel = np.zeros((T, 2, 3))
    vel[:, 1, 0] = 0.5
    w = np.zeros((T, 2, 3))
    a = trajectory_from_arrays(model, dt=dt, t=t, position=pos, quat_wxyz=q, velocity=vel, angular_velocity=w)
    pos_b = pos.copy()
    pos_b[:, 1, 0] += 1e-3 * np.exp(2.0 * t)
    q_b = q.copy()
    q_b[:, 1] = [math.cos(0.025), 0, 0, math.sin(0.025)]
    model_b = body_table(name=rename or ["a", "b"], shape=["sphere", "box"],
                         size=[[0.1, 0, 0], [0.1, 0.2, 0.3]], mass=[1.0, 2.0], gravity=[0, 0, 0])
    b = trajectory_from_arrays(model_b, dt=dt, t=t, position=pos_b, quat_wxyz=q_b, velocity=vel,
                               angular_velocity=w)
    return a, b


def test_known_divergence():
    a, b = _pair()
    r = diff(a, b, position_tol_m=1e-2, angle_tol_rad=0.1)
    ba, bb = r.bodies
    assert ba.position_max_m == 0 and ba.angle_max_rad < 1e-7 and ba.first_exceed_t is None
    assert ba.growth_rate_per_s is None
    assert bb.growth_rate_per_s == pytest.approx(2.0, rel=1e-9)
    assert bb.first_exceed_t == pytest.approx(1.16, abs=0.006)  # first sample past ln(10)/2
    assert bb.first_exceed_t >= math.log(10) / 2
    assert bb.angle_max_rad == pytest.approx(0.05, rel=1e-9)
    assert abs(bb.angle_growth_rate_per_s) < 1e-9  # a constant angle does not grow
    assert bb.position_final_m == pytest.approx(1e-3 * math.exp(6.0), rel=1e-9)
    assert not r.within and r.n_exceed == 1
    # totals side by side: B's body b moves along x like A's, so momentum is equal
    assert r.totals["total_linear_momentum"]["max_abs_difference"] == 0.0
    # within once the tolerances allow it
    r2 = diff(a, b, position_tol_m=1.0, angle_tol_rad=0.1)
    assert r2.within


def test_incompatible_bodies_named():
    a, b = _pair(rename=["a", "c"])
    with pytest.raises(IncompatibleLogs, match=r"body 1 \('b'\): name 'b' vs 'c'"):
        diff(a, b)


def test_cli_exit_codes(tmp_path):
    a, b = _pair()
    paths = []
    for name, tr in (("a", a), ("b", b)):
        with rblog.Recorder(tr.model, mcap=str(tmp_path / f"{name}.mcap"), dt=0.01) as rec:
            rec.write(tr)
        paths.append(str(tmp_path / f"{name}.mcap"))
    run = CliRunner().invoke
    r = run(main, ["diff", *paths, "--json", "--png", str(tmp_path / "d.png")])
    assert r.exit_code == 1, r.output
    d = json.loads(r.output)
    assert d["within"] is False and d["bodies"][1]["growth_rate_per_s"] == pytest.approx(2.0)
    assert (tmp_path / "d.png").stat().st_size > 1000
    r = run(main, ["diff", paths[0], paths[0]])
    assert r.exit_code == 0 and "within" in r.output
    r = run(main, ["diff", paths[0], str(tmp_path / "missing.mcap")])
    assert r.exit_code == 2 and "missing.mcap" in r.output
    _, c = _pair(rename=["a", "c"])
    with rblog.Recorder(c.model, mcap=str(tmp_path / "c.mcap"), dt=0.01) as rec:
        rec.write(c)
    r = run(main, ["diff", paths[0], str(tmp_path / "c.mcap")])
    assert r.exit_code == 2 and "'c'" in r.output and len(r.output.strip().splitlines()) == 1
