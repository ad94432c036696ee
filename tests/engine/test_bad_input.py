"""Engine-side reliability: bad input answered with the value and the allowed range, call
splitting that cannot change a result, a drift figure independent of the potential's zero, and
determinism across processes (log bytes)."""

from __future__ import annotations

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


def test_determinism_across_processes(tmp_path):
    """Two processes, same scene: the .mcap files are byte-identical, the .rrd files (which
    carry a random recording id) hold identical samples."""
    logs = []
    for i in range(2):
        rrd, mcap = tmp_path / f"{i}.rrd", tmp_path / f"{i}.mcap"
        subprocess.run([RBLOG, "run", str(SAMPLES_DIR / "mixed.toml"), "--duration", "1",
                        "--rrd", str(rrd), "--mcap", str(mcap)], check=True, capture_output=True)
        logs.append((rrd, mcap))
    assert logs[0][1].read_bytes() == logs[1][1].read_bytes()
    a, b = rblog.load(logs[0][0]), rblog.load(logs[1][0])
    for k in ("step", "position", "quat_wxyz", "linear_momentum", "angular_momentum"):
        assert getattr(a, k).tobytes() == getattr(b, k).tobytes(), k
