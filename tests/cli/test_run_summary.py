"""`rblog run`'s summary prints only figures that measure an error in the scene at hand.

Theory: the total energy (kinetic + gravitational) is an invariant of free flight only when no
applied force or torque does work; each body's |L| about its centre of mass only when no torque
acts (gravity and a force through the centre of mass leave it alone). Where bodies touch, contact
impulses turn them and restitution and friction take energy, so a drift of either says nothing
about the integration (the 500-box pile printed "|L| drift (rel) 6.557e+03"). There the summary
says why instead, and gives the deepest overlap at the logged samples, which the test recomputes
from the logged poses (a box on the ground: its lowest corner).
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from click.testing import CliRunner

import rblog
from rblog.contract.orientation import quat_wxyz_to_matrix
from rblog_cli.main import main

from conftest import SAMPLES_DIR

HALF = np.array([0.2, 0.1, 0.05])  # m, the dropped box's half extents

#: a box dropped tilted onto the ground: it lands on a corner and comes to rest
DROP = f"""
[sim]
dt = 1e-3
duration = 1.0
gravity = [0.0, 0.0, -9.81]

[ground]

[[body]]
name = "box"
shape = "box"
half_extents = [{HALF[0]}, {HALF[1]}, {HALF[2]}]
mass = 2.0
position = [0.0, 0.0, 0.5]
axis_angle = {{ axis = [1.0, 2.0, 0.5], angle_deg = 30.0 }}
"""

#: two free boxes with applied loads: a torque on one, a force on the other
LOADED = """
[sim]
dt = 1e-3
duration = 0.5
gravity = [0.0, 0.0, -9.81]

[[body]]
name = "{name}"
shape = "box"
half_extents = [0.3, 0.2, 0.1]
mass = 1.0
angular_velocity = [0.1, 2.0, 0.3]
{load}
"""

NUMBER = r"[-+]?\d\.\d+e[-+]\d+"


def _run(tmp_path, scene_text: str, *args):
    scene = tmp_path / "scene.toml"
    scene.write_text(scene_text, encoding="utf-8")
    res = CliRunner().invoke(main, ["run", str(scene), *args])
    assert res.exit_code == 0, (res.output, res.exception)
    return res.stdout


def test_contact_scene_prints_no_drift_numbers_and_says_why(tmp_path):
    out = _run(tmp_path, DROP, "--no-log")
    assert not re.search(r"energy drift \(rel\)\s+" + NUMBER, out), out
    assert not re.search(r"\|L\| drift \(rel\)\s+" + NUMBER, out), out
    assert "not shown: bodies touch" in out, out
    assert re.search(r"deepest penetration\s+\d+\.\d+ mm", out), out
    assert re.search(r"max \|\|R\^T R - I\|\|_F\s+" + NUMBER, out), out  # applies to every scene


def test_contact_scene_json_has_nulls_with_reasons(tmp_path):
    d = json.loads(_run(tmp_path, DROP, "--no-log", "--json"))
    assert d["energy_drift_rel"] is None and d["angular_momentum_drift_rel"] is None
    assert set(d["not_applicable"]) == {"energy_drift_rel", "angular_momentum_drift_rel"}
    assert all("touch" in why for why in d["not_applicable"].values())
    assert isinstance(d["ortho_error_max"], float)


def test_deepest_penetration_is_the_logged_poses_deepest_corner(tmp_path):
    """Every step logged: the summary's deepest penetration is the lowest corner's depth below
    the ground (z = 0) over the logged poses, computed here from position and quaternion."""
    mcap = tmp_path / "drop.mcap"
    d = json.loads(_run(tmp_path, DROP, "--json", "--log-every", "1", "--mcap", str(mcap),
                        "--rrd", str(tmp_path / "drop.rrd")))
    traj = rblog.load(mcap)
    corners = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)]) * HALF
    r = quat_wxyz_to_matrix(traj.quat_wxyz[:, 0])  # (T, 3, 3) body -> world
    lowest = traj.position[:, 0, 2][:, None] + np.einsum("tj,kj->tk", r[:, 2], corners)
    depth = max(0.0, -float(lowest.min()))
    assert depth > 1e-8  # it sinks into the ground a little at rest (measured 6.0e-8 m)
    # the narrowphase's box-plane depth is the lowest corner's: equal to round-off (measured
    # 1.8e-17 m apart)
    assert d["contact_penetration_max_m"] == pytest.approx(depth, abs=1e-14)


def test_free_scene_without_loads_prints_both_drifts():
    res = CliRunner().invoke(main, ["run", str(SAMPLES_DIR / "tumbling_box.toml"), "--no-log",
                                    "--duration", "1"])
    assert res.exit_code == 0, res.output
    assert re.search(r"energy drift \(rel\)\s+" + NUMBER, res.stdout), res.stdout
    assert re.search(r"\|L\| drift \(rel\)\s+" + NUMBER, res.stdout), res.stdout
    assert "not shown" not in res.stdout and "penetration" not in res.stdout


@pytest.mark.parametrize("load, energy_shown, spin_shown", [
    ("torque = [0.0, 0.0, 0.5]", False, False),   # a torque does work and changes L
    ("force = [0.5, 0.0, 0.0]", False, True),     # a force through the centre does work only
])
def test_applied_loads_hide_the_drifts_they_change(tmp_path, load, energy_shown, spin_shown):
    out = _run(tmp_path, LOADED.format(name="loaded", load=load), "--no-log")
    assert bool(re.search(r"energy drift \(rel\)\s+" + NUMBER, out)) == energy_shown, out
    assert bool(re.search(r"\|L\| drift \(rel\)\s+" + NUMBER, out)) == spin_shown, out
    d = json.loads(_run(tmp_path, LOADED.format(name="loaded", load=load), "--no-log", "--json"))
    assert (d["energy_drift_rel"] is not None) == energy_shown
    assert (d["angular_momentum_drift_rel"] is not None) == spin_shown
    if spin_shown:  # torque-free spin: |L| is kept to round-off by the default rk4
        assert d["angular_momentum_drift_rel"] < 1e-12
