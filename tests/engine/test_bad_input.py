"""Engine-side reliability: bad input answered with the value and the allowed range, call
splitting that cannot change a result, a drift figure independent of the potential's zero, and
a free body turning without bound stopped as diverged. (Determinism across processes and thread
counts, as log bytes: tests/cli/test_thread_determinism.py.)"""

from __future__ import annotations

import re
import subprocess
import sys
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest

import rblog
import rblog.engine.runner as runner
from rblog.engine.constants import ContactParams
from rblog.engine.scene import CONTACT_RANGES, load_scene, parse_scene
from rblog.errors import SceneError

from conftest import SAMPLES_DIR

RBLOG = str(Path(sys.executable).with_name("rblog"))

BOX = """
[sim]
dt = 1e-3
duration = 0.5
[[body]]
shape = "sphere"
radius = 0.1
mass = 1.0
"""


def _rejected(name: str) -> list:
    """Values of ContactParams.<name> that its validate() rejects, from a few probes."""
    bad = []
    d = getattr(ContactParams(), name)
    probes = (-1, 0, 3) if isinstance(d, int) and not isinstance(d, bool) else (-1.0, 0.0, 3.0)
    for v in probes:
        try:
            ContactParams(**{name: v}).validate()
        except ValueError:
            bad.append(v)
    return bad


def test_contact_ranges_cover_every_checked_setting():
    """CONTACT_RANGES (what the message says) names every setting validate() can reject."""
    checked = {f.name for f in fields(ContactParams) if _rejected(f.name)}
    assert checked == set(CONTACT_RANGES)


@pytest.mark.parametrize("name", sorted(CONTACT_RANGES))
def test_contact_value_out_of_range_names_value_and_range(name):
    v = _rejected(name)[0]
    with pytest.raises(SceneError) as e:
        parse_scene(BOX + f"[contact]\n{name} = {v!r}\n", "s.toml")
    msg = str(e.value)
    assert msg.startswith(f"s.toml: contact.{name}: ")
    assert CONTACT_RANGES[name] in msg and f"got {v!r}" in msg


@pytest.mark.parametrize("key,typo,suggest", [("sim", "durration", "duration"),
                                               ("body[0]", "radus", "radius")])
def test_unknown_key_suggests(key, typo, suggest):
    text = BOX.replace("duration = 0.5", f"duration = 0.5\n{typo} = 1") if key == "sim" \
        else BOX + f"{typo} = 1\n"
    with pytest.raises(SceneError, match=f"did you mean '{suggest}'"):
        parse_scene(text, "s.toml")


def test_quaternion_far_from_unit_warns_within_tolerance_silent():
    s = parse_scene(BOX + "quat_wxyz = [1.3, 0.0, 0.0, 0.0]\n", "s.toml")
    assert len(s.warnings) == 1 and "|q| = 1.3" in s.warnings[0]
    assert np.allclose(s.state.quat_wxyz[0], [1, 0, 0, 0], rtol=0, atol=1e-15)
    s = parse_scene(BOX + "quat_wxyz = [0.7071068, 0.7071068, 0.0, 0.0]\n", "s.toml")
    assert s.warnings == []  # |q| - 1 = 4e-8: hand-written decimals


@pytest.mark.parametrize("override", [{"dt": 1e-300}, {"dt": 1.0}])
def test_run_rejects_dt_options(override):
    s = parse_scene(BOX, "s.toml")
    with pytest.raises(SceneError, match="--dt"):
        runner.simulate(s, **override)


@pytest.mark.parametrize("sample", ["box_stack", "mixed", "newton_pair", "spinning_bodies"])
def test_call_split_does_not_change_the_result(sample, monkeypatch):
    """Runs sized by wall time must equal one long call bit for bit: one step per call (a tiny
    budget) against whole blocks (a huge one)."""
    s = load_scene(SAMPLES_DIR / f"{sample}.toml")
    out = []
    for budget, growth in ((1e3, 1e12), (1e-9, 1.0)):
        monkeypatch.setattr(runner, "CALL_WALL_BUDGET_S", budget)
        monkeypatch.setattr(runner, "CALL_GROWTH_MAX", growth)
        out.append(runner.simulate(s, duration=min(s.sim.duration, 0.3))[0])
    a, b = out
    for k in ("step", "position", "quat_wxyz", "linear_momentum", "angular_momentum"):
        assert np.array_equal(getattr(a, k), getattr(b, k)), k
    assert np.array_equal(a.contacts.step, b.contacts.step)
    assert np.array_equal(a.contacts.normal_impulse, b.contacts.normal_impulse)


def test_energy_drift_does_not_depend_on_the_origin():
    """Lifting the whole scene (bodies and ground) 1 km changes E by m g h, not the drift."""
    text = (SAMPLES_DIR / "bouncing_ball.toml").read_text()
    base = parse_scene(text, "a.toml")
    lifted = parse_scene(text, "b.toml")
    lifted.state.position[:, 2] += 1000.0
    lifted.model.ground_offset = base.model.ground_offset + 1000.0
    _, sa = runner.simulate(base, duration=1.0)
    _, sb = runner.simulate(lifted, duration=1.0)
    assert sa.energy_drift_rel > 0
    # 1 km of lift costs ~12 of 16 digits of position; measured relative difference ~1e-9
    assert sb.energy_drift_rel == pytest.approx(sa.energy_drift_rel, rel=1e-6)


# ---------------------------------------------------------------------------------------------
# a free body that turns without bound: the run stops as diverged (issue 19)

TWISTED = """
[sim]
dt = 1e-3
duration = 0.1
gravity = [0.0, 0.0, 0.0]
integrator = "{integrator}"
[[body]]
name = "twisted"
shape = "sphere"
radius = 0.1
mass = 1.0
torque = [{torque!r}, 0.0, 0.0]
"""


@pytest.mark.parametrize("integrator", ["seed", "seed-quat", "splitting", "rk4", "exact", "exact4"])
def test_free_body_turning_beyond_bound_stops_as_diverged(tmp_path, integrator):
    """A constant torque tau about x on a sphere (I = 2/5 m r^2 = 0.004 kg m^2, k = 1/I = 250):
    every integrator kicks L by tau dt a step, so after step n L = n dt tau and the sphere turns
    |omega| dt = k n dt^2 tau per step. With tau = 7e7 N m that is 17,500 n rad: beyond
    MAX_ROTATION_PER_STEP_RAD = 1e6 rad first at n = ceil(1e6 / 17,500 + eps) = 58 (57.14 is
    far from an integer). The state stays finite (|L| <= 7e3), so before this check the run went
    on to the end silently; now it stops at step 58, exit 3, the .mcap keeps steps 0..57."""
    from rblog.engine.constants import MAX_ROTATION_PER_STEP_RAD
    from rblog.errors import SimulationDiverged
    from rblog.record.mcap_writer import McapRecorder

    tau, k, dt = 7e7, 1.0 / (0.4 * 1.0 * 0.1**2), 1e-3
    n_first = int(np.floor(MAX_ROTATION_PER_STEP_RAD / (k * dt * dt * tau))) + 1
    assert n_first == 58
    path = tmp_path / "t.mcap"
    with pytest.raises(SimulationDiverged) as info:
        runner.run(parse_scene(TWISTED.format(integrator=integrator, torque=tau), "t.toml"),
                   log_every=1, recorders=[McapRecorder(str(path))])
    e = info.value
    assert (e.step, e.body, e.body_name, e.exit_code) == (n_first, 0, "twisted", 3)
    turn = float(re.search(r"turns (\S+) rad in one step", str(e)).group(1))
    assert turn == pytest.approx(k * n_first * dt * dt * tau, rel=5e-3)  # printed to 3 digits
    assert "\n" not in str(e)
    traj = rblog.load(path)
    assert traj.truncated
    np.testing.assert_array_equal(traj.step, np.arange(n_first))
    assert any("diverged at step 58" in w for w in traj.warnings), traj.warnings
    # up to there, L is the torque's impulse
    np.testing.assert_allclose(traj.angular_momentum[:, 0, 0], traj.step * dt * tau, rtol=1e-12)


def test_torque_1e40_on_free_body_exits_3(tmp_path):
    """The issue's case through the CLI: 1e40 N m turns the sphere k dt^2 tau = 2.5e36 rad in the
    first step; one line, exit 3 (before: exit 0, ran on silently)."""
    (tmp_path / "s.toml").write_text(TWISTED.format(integrator="rk4", torque=1e40))
    p = subprocess.run([RBLOG, "run", str(tmp_path / "s.toml"), "--mcap", str(tmp_path / "x.mcap")],
                       capture_output=True, text=True, cwd=tmp_path)
    assert p.returncode == 3, p.stderr
    err = [ln for ln in p.stderr.splitlines() if ln.startswith("rblog: error")]
    assert len(err) == 1 and "Traceback" not in p.stderr
    assert "diverged at step 1 " in err[0] and "turns 2.5e+36 rad in one step" in err[0]
