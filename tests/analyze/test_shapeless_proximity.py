"""Bodies without a shape in the contract (capsules: SHAPE_NONE, their geoms in the log) meet
between two samples: the proximity finds them from their geoms, so the hit is judged as a contact
of the two (never as free flight), and a planted energy gain at the hit is still flagged."""

from __future__ import annotations

import numpy as np

import rblog
from rblog.analyze.base import Context
from rblog.engine.runner import simulate
from rblog.engine.scene import load_scene

# two capsules (r = 0.05 m, h = 0.1 m, along z) in zero gravity, a at 2 m/s head-on into b at
# rest: their axes are parallel, 0.407 m apart, so the gap is 0.407 - 2 r = 0.307 m and they meet
# at t = 0.1535 s, between the samples at 0.15 and 0.16 s (logged every 10 steps). b gains energy
# (1.125 J for e = 0.5): judged alone, as if against static geometry, that is a false gain.
SCENE = """
[sim]
dt = 1e-3
duration = 0.3
gravity = [0.0, 0.0, 0.0]
log_every = 10
[[body]]
name = "a"
shape = "capsule"
radius = 0.05
half_length = 0.1
mass = 1.0
position = [-0.2035, 0.0, 0.0]
velocity = [2.0, 0.0, 0.0]
restitution = 0.5
[[body]]
name = "b"
shape = "capsule"
radius = 0.05
half_length = 0.1
mass = 1.0
position = [0.2035, 0.0, 0.0]
velocity = [0.0, 0.0, 0.0]
restitution = 0.5
"""


def _run(tmp_path):
    p = tmp_path / "capsules.toml"
    p.write_text(SCENE)
    traj, _ = simulate(load_scene(p))
    return traj


def test_capsules_meeting_between_samples_are_a_contact(tmp_path):
    traj = _run(tmp_path)
    assert (traj.model.body_shape < 0).all()  # no contract shape: judged through the geoms
    prox = Context(traj).proximity(1e-3)
    k = int(np.searchsorted(traj.t, 0.15 - 1e-9))  # the sample before the hit
    row = (prox.iv_k == k) & (prox.iv_a == 0) & (prox.iv_b == 1)
    assert row.sum() == 1
    # closed form at t = 0.15 s (free flight at 2 m/s, exact in zero gravity): the gap
    # 0.307 - 2 * 0.15 = 0.007 m (point bodies would be 0.107 m apart)
    np.testing.assert_allclose(prox.iv_sep0[row], 0.007, atol=1e-9)
    res = {r.analyzer: r for r in rblog.check(traj, only=["momentum", "energy"])}
    for name in ("momentum", "energy"):
        assert res[name].passed and res[name].judged, (name, res[name].findings[:2])
    # the hit was judged as a contact event of the pair
    assert res["energy"].stats.get("contact_events", 0) >= 1


def test_energy_planted_at_the_hit_is_flagged(tmp_path):
    """The other direction: both capsules leave the hit 1.5x as fast as the engine says (0.75
    and 2.25 m/s for e = 0.5's 0.5 and 1.5: kinetic energy 2.8125 J after against 2 J before):
    flagged as energy gained across the pair's contact."""
    traj = _run(tmp_path)
    k = int(np.searchsorted(traj.t, 0.16 - 1e-9))  # first sample after the hit
    m = traj.model.body_mass
    dv = 0.5 * traj.velocity[k:].copy()
    traj.velocity[k:] += dv
    traj.linear_momentum[k:] += m[None, :, None] * dv
    traj.position[k:] += dv * (traj.t[k:] - 0.1535)[:, None, None]
    res = {r.analyzer: r for r in rblog.check(traj, only=["energy"])}
    assert any("across a contact" in f.message and sorted(f.bodies) == [0, 1]
               for f in res["energy"].findings), res["energy"].findings[:3]


def test_a_tilted_capsule_is_as_high_as_its_lowest_end(tmp_path):
    """The ground separation of a capsule (no contract shape) is its lowest end's: centre height
    0.5 m, axis tilted 30 deg from the vertical: 0.5 - h cos 30 - r (a point: 0.5 m)."""
    p = tmp_path / "tilted.toml"
    p.write_text("[sim]\ndt = 1e-3\nduration = 0.01\n[ground]\n[[body]]\nname = \"c\"\n"
                 "shape = \"capsule\"\nradius = 0.05\nhalf_length = 0.1\nmass = 1.0\n"
                 "position = [0.0, 0.0, 0.5]\n"
                 "axis_angle = { axis = [1.0, 0.0, 0.0], angle_deg = 30.0 }\n")
    traj, _ = simulate(load_scene(p))
    prox = Context(traj).proximity(1e-3)
    np.testing.assert_allclose(prox.ground_sep[0, 0], 0.5 - 0.1 * np.cos(np.pi / 6) - 0.05,
                               atol=1e-12)


# a capsule (r = 0.05 m, h = 0.1 m) lying on the ground along x, at rest, logged every 10 steps
LYING = """
[sim]
dt = 1e-3
duration = 0.3
log_every = 10
[[body]]
name = "c"
shape = "capsule"
radius = 0.05
half_length = 0.1
mass = 1.0
position = [0.0, 0.0, 0.05]
axis_angle = { axis = [0.0, 1.0, 0.0], angle_deg = 90.0 }
friction = 0.5
"""


def _lying(tmp_path):
    p = tmp_path / "lying.toml"
    p.write_text(LYING)
    traj, _ = simulate(load_scene(p))
    return traj


def test_a_capsule_on_the_ground_is_judged(tmp_path):
    """A shapeless body on the ground stays judged (only its friction cone against a static
    box, whose face at the contact its centre does not tell, is not): a capsule at rest passes,
    and a 0.5 m/s sideways kick planted at one sample (0.5 N s that no logged impulse carries)
    is flagged on that body and interval."""
    traj = _lying(tmp_path)
    res = {r.analyzer: r for r in rblog.check(traj, only=["momentum"])}
    assert res["momentum"].passed and res["momentum"].judged, res["momentum"].findings[:2]
    k = int(np.searchsorted(traj.t, 0.15 - 1e-9))
    traj.velocity[k:, 0, 0] += 0.5
    traj.linear_momentum[k:, 0, 0] += 0.5
    traj.position[k:, 0, 0] += 0.5 * (traj.t[k:] - traj.t[k])
    res = {r.analyzer: r for r in rblog.check(traj, only=["momentum"])}
    hit = [f for f in res["momentum"].findings
           if f.bodies == [0] and "between t = 0.14 and 0.15 s" in f.message
           and "linear momentum" in f.message and "by 0.5 kg m/s" in f.message]
    assert hit, [f.message for f in res["momentum"].findings]
