"""Collisions and resting contact: closed-form physics, conservation, conventions, stages.

Every test builds its Model by hand (rblog.study.scenes helpers) and calls
ContactWorld.advance directly, as the simulator does.
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from rblog.engine import integrators as rot, rotation
from rblog.engine.contact import ContactParams, ContactWorld
from rblog.engine.contact.narrowphase import UnsupportedShapePair
from rblog.study.scenes import box_pile, box_stack, make_model, make_state
from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE
from rblog.contract.trajectory import CONTACT_IMPACT, STATIC_BODY

G = 9.81
SPLIT = (rot.METHOD_SPLITTING, rot.ORTHO_NORMALIZE)


def simulate(world, state, dt, n_steps, stride=1, sample_last=False):
    """Advance in one call; return (samples dict, contacts, bad_step, bad_body)."""
    n = world.n_bodies
    s = n_steps // stride + 1
    out = dict(position=np.zeros((s, n, 3)), linear_momentum=np.zeros((s, n, 3)),
               quat_wxyz=np.zeros((s, n, 4)), rotation=np.zeros((s, n, 3, 3)),
               angular_momentum=np.zeros((s, n, 3)))
    ns, bad_step, bad_body, contacts = world.advance(
        dt, n_steps, stride, sample_last, state.position, state.linear_momentum, state.quat_wxyz,
        state.rotation, state.angular_momentum_world, out["position"], out["linear_momentum"],
        out["quat_wxyz"], out["rotation"], out["angular_momentum"])
    return {k: v[:ns] for k, v in out.items()}, contacts, bad_step, bad_body


# ---- impacts ---------------------------------------------------------------------------------

def test_bouncing_sphere_apexes():
    """r = 0.1 m, 1 kg, centre dropped from 1.1 m (h0 = 1 m above its resting height), e = 0.8,
    dt = 1e-3: the first four apexes are e^(2n) h0 (Newton's restitution), none lost, no sinking."""
    r, h0, e = 0.1, 1.0, 0.8
    model = make_model([SHAPE_SPHERE], [r], [1.0], restitution=e, ground_restitution=0.0)
    world = ContactWorld(model, ContactParams(), *SPLIT)
    state = make_state(model, [[0.0, 0.0, r + h0]])
    out, contacts, bad, _ = simulate(world, state, 1e-3, 4000)
    assert bad == -1
    z = out["position"][:, 0, 2] - r
    vz = out["linear_momentum"][:, 0, 2]
    turn = [k for k in range(1, len(z)) if vz[k - 1] > 0.0 >= vz[k]]  # first sample past apex
    assert len(turn) >= 5, "a bounce was lost"
    for n, k in enumerate(turn[:4], start=1):
        expected = e ** (2 * n) * h0
        # the sample is within dt of the apex time, so at most g dt^2 / 2 = 4.9e-6 m below it
        # (measured 4.7e-6, 7.4e-9, 1.3e-5, 9.1e-8 relative for n = 1..4; 2.8e-6 .. 2.5e-5 when
        # the flight was symplectic)
        assert 0.0 <= expected - z[k] <= G * 1e-6 / 2 + 1e-15, (n, z[k], expected)
        # the flight is exact, so its energy height z + vz^2 / 2g is the apex itself (issue:
        # within 1e-5; measured 8.9e-16, 8.0e-15, 1.2e-14, 1.6e-14 relative for n = 1..4)
        energy_height = z[k] + vz[k] ** 2 / (2 * G)
        assert abs(energy_height / expected - 1.0) < 1e-12, (n, energy_height, expected)
    assert -z.min() <= 1e-6  # peak penetration (measured: 0; a sphere on a plane never sinks)
    assert np.any(contacts.kind == CONTACT_IMPACT)


@pytest.mark.parametrize("e", [1.0, 0.5])
def test_head_on_spheres_conserve_momentum_and_lose_newton_energy(e):
    """1 kg at 2 m/s meets 3 kg at -1 m/s, no gravity, on a line off the origin."""
    m1, m2 = 1.0, 3.0
    model = make_model([SHAPE_SPHERE] * 2, [0.1, 0.1], [m1, m2], restitution=e,
                       gravity=(0, 0, 0), ground=False)
    world = ContactWorld(model, ContactParams(), *SPLIT)
    state = make_state(model, [[-0.5, 0.3, 0.2], [0.5, 0.3, 0.2]], [[2, 0, 0], [-1, 0, 0]])
    p0 = state.linear_momentum.sum(0)
    l0 = (np.cross(state.position, state.linear_momentum) + state.angular_momentum_world).sum(0)
    ke0 = 0.5 * m1 * 2 ** 2 + 0.5 * m2 * 1 ** 2
    out, contacts, _, _ = simulate(world, state, 1e-3, 1000)
    p = out["linear_momentum"].sum(1)
    l_tot = (np.cross(out["position"], out["linear_momentum"]) + out["angular_momentum"]).sum(1)
    assert np.abs(p - p0).max() <= 1e-12 * np.abs(p0).max()
    assert np.abs(l_tot - l0).max() <= 1e-12 * np.abs(l0).max()
    v = out["linear_momentum"][-1] / np.array([m1, m2])[:, None]
    ke = 0.5 * m1 * v[0] @ v[0] + 0.5 * m2 * v[1] @ v[1]
    mu = m1 * m2 / (m1 + m2)
    assert abs(ke - (ke0 - 0.5 * mu * (1 - e * e) * 3.0 ** 2)) <= 1e-9
    assert len(contacts) == 1 and contacts.kind[0] == CONTACT_IMPACT


@pytest.mark.parametrize("e, mu", [(0.6, 0.7), (0.0, 0.0)])
def test_off_centre_box_impact_conserves_pair_momenta(e, mu):
    """Two spinning boxes hit off-centre in zero g (bouncing, or sliding along each other for
    e = mu = 0): the pair's linear and angular momentum (about the origin) stay put to
    round-off; the contact record follows the conventions."""
    model = make_model([SHAPE_BOX] * 2, [[0.1, 0.2, 0.15], [0.2, 0.1, 0.1]], [2.0, 3.0],
                       restitution=e, friction=mu, gravity=(0, 0, 0), ground=False)
    world = ContactWorld(model, ContactParams(), *SPLIT)
    q = [rotation.axis_angle_to_quat_np([1, 2, 3], 0.4), rotation.axis_angle_to_quat_np([3, -1, 2], 1.1)]
    state = make_state(model, [[-0.6, 0.05, 0.02], [0.6, -0.1, 0.08]],
                       [[3, 0.2, 0], [-2, 0, 0.3]], quat_wxyz=q, omega=[[1, 2, 3], [-2, 1, 0.5]])
    p0 = state.linear_momentum.sum(0)
    l0 = (np.cross(state.position, state.linear_momentum) + state.angular_momentum_world).sum(0)
    out, contacts, _, _ = simulate(world, state, 1e-3, 600)
    p = out["linear_momentum"].sum(1)
    l_tot = (np.cross(out["position"], out["linear_momentum"]) + out["angular_momentum"]).sum(1)
    assert len(contacts) > 0
    assert np.abs(p - p0).max() <= 1e-12 * np.linalg.norm(p0) * 10
    assert np.abs(l_tot - l0).max() <= 1e-12 * np.linalg.norm(l0) * 10
    assert np.all(contacts.normal_impulse >= 0.0)
    # normal from b into a: a's centre lies on the +normal side of the contact point
    for k in range(len(contacts)):
        a = contacts.body_a[k]
        step = contacts.step[k] - 1
        assert np.dot(out["position"][step, a] - contacts.point[k], contacts.normal[k]) > 0.0


def test_groups_decide_who_collides():
    """Different non-zero groups pass through each other; group 0 meets everyone."""
    def run(groups):
        # a ground far below keeps the contact pipeline on (no gravity: it is never reached)
        model = make_model([SHAPE_SPHERE] * 2, [0.1, 0.1], [1.0, 1.0], gravity=(0, 0, 0),
                           ground=True, groups=groups)
        world = ContactWorld(model, ContactParams(), *SPLIT)
        state = make_state(model, [[-0.5, 0, 5], [0.5, 0, 5]], [[1, 0, 0], [-1, 0, 0]])
        out, contacts, _, _ = simulate(world, state, 1e-3, 1000, stride=1000)
        return out["position"][-1, 0, 0], len(contacts), world

    x, n, world = run([1, 2])
    assert x > 0.4 and n == 0  # passed through
    assert "no two bodies can collide" in dict(world.explain())["broadphase: sort-and-sweep"]
    for groups in ([1, 1], [0, 2]):
        x, _, _ = run(groups)
        assert x < -0.4  # bounced back


def test_fast_sphere_does_not_tunnel_through_thin_wall():
    """A 5 cm sphere at 200 m/s against a 1 cm static box at dt = 1e-2 (2 m per step)."""
    model = make_model([SHAPE_SPHERE], [0.05], [1.0], restitution=0.0, gravity=(0, 0, 0),
                       ground=False, static_box_position=np.array([[1.0, 0, 0]]),
                       static_box_quat_wxyz=np.array([[1.0, 0, 0, 0]]),
                       static_box_half_extents=np.array([[0.005, 1.0, 1.0]]),
                       static_box_restitution=np.zeros(1), static_box_friction=np.zeros(1))
    world = ContactWorld(model, ContactParams(), *SPLIT)
    state = make_state(model, [[-3.0, 0, 0]], [[200.0, 0, 0]])
    out, _, _, _ = simulate(world, state, 1e-2, 50)
    assert out["position"][:, 0, 0].max() <= 1.0 - 0.005 - 0.05 + 1e-9


# ---- resting contact -------------------------------------------------------------------------

@pytest.mark.parametrize("dt", [1e-3, 1e-2])
@pytest.mark.parametrize("sleep", [False, True])
def test_resting_cube(dt, sleep):
    """A 0.2 m cube (1 kg) on the ground for 5 s: after 0.5 s no sinking, no motion, no drift."""
    model = make_model([SHAPE_BOX], [[0.1, 0.1, 0.1]], [1.0])
    world = ContactWorld(model, ContactParams(sleep=sleep), *SPLIT)
    x0 = np.array([0.3, -0.2, 0.1])
    state = make_state(model, [x0])
    n = int(round(5.0 / dt))
    out, _, _, _ = simulate(world, state, dt, n)
    k = int(round(0.5 / dt))
    x = out["position"][k:, 0]
    assert (0.1 - x[:, 2]).max() <= 1e-4  # penetration (measured: 0)
    assert np.abs(out["linear_momentum"][k:, 0]).max() <= 1e-6  # speed, 1 kg (measured ~1e-27)
    assert np.abs(x[:, :2] - x0[:2]).max() <= 1e-6  # horizontal drift (measured: 0)
    assert world.n_awake == (0 if sleep else 1)


def test_sliding_box_stops_after_v2_over_2_mu_g():
    mu, v0 = 0.3, 2.0
    model = make_model([SHAPE_BOX], [[0.1, 0.1, 0.1]], [1.0], restitution=0.0, friction=mu)
    world = ContactWorld(model, ContactParams(), *SPLIT)
    state = make_state(model, [[0, 0, 0.1]], [[v0, 0, 0]])
    out, _, _, _ = simulate(world, state, 1e-3, 1500, stride=10)
    d = out["position"][-1, 0, 0]
    assert abs(d / (v0 ** 2 / (2 * mu * G)) - 1.0) < 0.01  # measured -0.15 % (= h v0 / 2)
    assert abs(out["linear_momentum"][-1, 0, 0]) < 1e-9


def test_sliding_sphere_ends_rolling_at_five_sevenths():
    mu, v0, r = 0.3, 2.0, 0.1
    model = make_model([SHAPE_SPHERE], [r], [1.0], restitution=0.0, friction=mu)
    world = ContactWorld(model, ContactParams(), *SPLIT)
    state = make_state(model, [[0, 0, r]], [[v0, 0, 0]])
    out, _, _, _ = simulate(world, state, 1e-3, 2000, stride=100)
    v = out["linear_momentum"][-1, 0, 0]
    w = out["angular_momentum"][-1, 0, 1] / (0.4 * r * r)
    assert abs(v / (5 * v0 / 7) - 1.0) < 0.01  # measured 7e-15
    assert abs(w * r - v) < 1e-9  # rolling without slipping


def test_stack_of_ten_boxes_stands():
    """10 cubes of 0.2 m at dt = 1e-2 for 10 s: the top box moves <= 0.2 mm (measured 60 um;
    8 um before the velocity-solve changes), penetration <= 0.1 mm (measured 47 um)."""
    model, state = box_stack(10)
    top0 = state.position[-1].copy()
    world = ContactWorld(model, ContactParams(sleep=False), *SPLIT)
    out, contacts, bad, _ = simulate(world, state, 1e-2, 1000, stride=10)
    assert bad == -1
    assert np.linalg.norm(out["position"][:, -1] - top0, axis=1).max() <= 2e-4
    assert -contacts.separation.min() <= 1e-4


def stack_loads_after_one_step(params):
    """Relative error of the first step's normal impulses in a 10-cube stack built at rest,
    against statics: the contact under cube k carries the weight of the cubes above it and its
    own, (10 - k) m g h."""
    model, state = box_stack(10)
    world = ContactWorld(model, params, *SPLIT)
    h = 1e-2
    _, c, _, _ = simulate(world, state, h, 1, stride=1)
    loads = {}
    for a, b, j in zip(c.body_a, c.body_b, c.normal_impulse):
        loads[(int(a), int(b))] = loads.get((int(a), int(b)), 0.0) + j
    assert len(loads) == 10
    return max(abs(v / ((10 - (max(a, b) if b >= 0 else 0)) * G * h) - 1.0)
               for (a, b), v in loads.items())


def test_over_relaxation_carries_a_stack_load_in_fewer_sweeps():
    """Plain Gauss-Seidel moves a load through n bodies in ~n^2 sweeps, over-relaxed in ~n: with
    80 sweeps the default factor gets the stack's loads within 1% (measured 0.016%), plain
    Gauss-Seidel still misses by > 10% (measured 16%). Every manifold of the stack has a body
    in two manifolds, so all of them are relaxed."""
    over = ContactParams(sleep=False, velocity_tolerance=0.0, max_velocity_iterations=80)
    assert over.over_relaxation > 1.0
    assert stack_loads_after_one_step(over) <= 0.01
    plain = ContactParams(sleep=False, velocity_tolerance=0.0, max_velocity_iterations=80,
                          over_relaxation=1.0)
    assert stack_loads_after_one_step(plain) > 0.1
    with pytest.raises(ValueError):
        ContactParams(over_relaxation=2.0)
    with pytest.raises(ValueError):
        ContactParams(over_relaxation=0.0)


def test_sleeping_box_wakes_when_hit():
    """A resting cube falls asleep; a cube dropped on it wakes it; both end at rest."""
    model = make_model([SHAPE_BOX] * 2, [[0.1] * 3] * 2, [1.0, 1.0], restitution=0.0)
    world = ContactWorld(model, ContactParams(), *SPLIT)
    state = make_state(model, [[0, 0, 0.1], [0, 0, 5.0]])
    simulate(world, state, 1e-3, 800)
    assert world.awake[0] == 0 and world.awake[1] == 1
    out, _, _, _ = simulate(world, state, 1e-3, 3000, stride=100)
    assert world.stats[6] >= 1  # an island was woken
    # measured |dz| 9.3e-8 and 4.5e-8 m (the allowed penetration is 5e-5 m)
    assert abs(state.position[1, 2] - 0.3) < 1e-6 and abs(state.position[0, 2] - 0.1) < 1e-6
    assert world.n_awake == 0


# ---- stages, conventions, errors -------------------------------------------------------------

def test_explain_picks_stages_for_the_scene():
    free = make_model([SHAPE_SPHERE] * 3, [0.1] * 3, [1.0] * 3, gravity=(0, 0, 0), ground=False,
                      groups=[1, 2, 3])
    names = [s for s, _ in ContactWorld(free, ContactParams(), *SPLIT).explain()]
    assert names[0].startswith("kick (external forces): skipped")
    assert "contacts: none possible" in names
    spheres = make_model([SHAPE_SPHERE] * 2, [0.1] * 2, [1.0] * 2)
    expl = dict(ContactWorld(spheres, ContactParams(), *SPLIT).explain())
    assert "isotropic shortcut" in expl and "sleeping" in expl
    assert "collide_sphere_plane" in expl["narrowphase: table dispatch"]
    forced = dict(ContactWorld(spheres, ContactParams(), *SPLIT, force_all_stages=True).explain())
    assert "isotropic shortcut" not in forced and "sleeping: off" in forced


def test_forced_stages_give_the_same_motion():
    """Shortcuts change the cost, not the physics (sleeping off in both)."""
    model = make_model([SHAPE_BOX, SHAPE_SPHERE], [[0.1, 0.1, 0.1], 0.1], [1.0, 2.0])
    res = []
    for force in (False, True):
        world = ContactWorld(model, ContactParams(sleep=False), *SPLIT, force_all_stages=force)
        state = make_state(model, [[0, 0, 0.5], [0.05, 0.0, 0.9]], [[0.3, 0, 0], [0, 0, 0]])
        out, _, _, _ = simulate(world, state, 1e-3, 500, stride=50)
        res.append(out["position"])
    # The full inertia transform rounds differently (1e-13 m by 0.38 s); the box's flat landing
    # on four points at 0.39 s (a rank-3 normal block, regularised) amplifies that: measured
    # max |dx| 1.1e-9 m at 0.4 s, <= 2e-19 m up to 0.3 s (1.5e-12 m before the
    # bounces went down to the derived restitution threshold and free flight became exact;
    # 5e-11 m now with the old 1 m/s threshold). rtol=0, so that allclose's default rtol of
    # 1e-5 (5 um here) cannot hide a real difference.
    np.testing.assert_allclose(res[0], res[1], rtol=0, atol=5e-9)


def test_contact_record_conventions():
    model = make_model([SHAPE_SPHERE], [0.1], [1.0], restitution=0.0)
    world = ContactWorld(model, ContactParams(), *SPLIT)
    state = make_state(model, [[0, 0, 0.1]])
    _, c, _, _ = simulate(world, state, 1e-3, 20, stride=10)
    assert list(c.step) == [10, 20] and np.all(c.t == 0.0)
    assert np.all(c.body_a == 0) and np.all(c.body_b == STATIC_BODY)
    # measured: all three exact (0 difference); rtol=0 and a round-off atol, not allclose's
    # default rtol = 1e-5
    np.testing.assert_allclose(c.normal, np.broadcast_to([0.0, 0.0, 1.0], c.normal.shape),
                               rtol=0, atol=1e-15)
    np.testing.assert_allclose(c.normal_impulse, 1.0 * G * 1e-3, rtol=1e-14, atol=0)  # m g h
    np.testing.assert_allclose(c.point, 0.0, rtol=0, atol=1e-12)


def test_non_finite_state_stops_and_reports():
    model = make_model([SHAPE_SPHERE] * 2, [0.1] * 2, [1.0] * 2)
    world = ContactWorld(model, ContactParams(), *SPLIT)
    state = make_state(model, [[0, 0, 1.0], [1.0, 0, 1.0]])
    state.linear_momentum[1, 0] = np.nan
    out, _, bad_step, bad_body = simulate(world, state, 1e-3, 10)
    assert (bad_step, bad_body) == (1, 1) and len(out["position"]) == 0


def test_unsupported_shape_is_an_error():
    model = make_model([SHAPE_SPHERE], [0.1], [1.0])
    model.body_shape = np.array([7])
    with pytest.raises(UnsupportedShapePair):
        ContactWorld(model, ContactParams(), *SPLIT)


def test_params_table_round_trip_and_validation():
    p = ContactParams.from_dict({"velocity_iterations": 6, "sleep": False})
    assert p.velocity_iterations == 6 and not p.sleep
    assert ContactParams.from_dict(p.to_dict()) == p
    with pytest.raises(ValueError):
        ContactParams.from_dict({"no_such_key": 1})
    with pytest.raises(ValueError):
        ContactParams(position_correction_rate=0.0)


@pytest.mark.parametrize("method", list(rot.METHOD_CODES.values()))
def test_every_integrator_runs_contacts_deterministically(method):
    """Each integrator drives the rotations; two runs hash the same (Box2D's determinism test)."""
    ortho = rot.ORTHO_POLAR if method == rot.METHOD_SEED else rot.ORTHO_NORMALIZE
    digests = []
    for _ in range(2):
        model, state = box_pile(12, seed=3, top=1.0, per_row=2)
        world = ContactWorld(model, ContactParams(), method, ortho)
        out, c, bad, _ = simulate(world, state, 2e-3, 600, stride=100)
        assert bad == -1
        h = hashlib.sha256(out["position"].tobytes() + out["rotation"].tobytes()
                           + c.normal_impulse.tobytes())
        digests.append(h.hexdigest())
        assert state.position[:, 2].min() > 0.0
    assert digests[0] == digests[1]


@pytest.mark.slow
def test_pile_of_500_boxes():
    """500 cubes of 0.1 m dropped from up to 2 m, 4 s at dt = 2e-3: runs to the end; the deepest
    overlap at any sampled state (rblog's narrowphase, every 10 steps) stays small."""
    from rblog.engine.contact.measure import max_penetration

    model, state = box_pile(500)
    z0 = state.position[:, 2].copy()
    world = ContactWorld(model, ContactParams(), *SPLIT)
    worst = 0.0
    for _ in range(200):
        out, _, bad, _ = simulate(world, state, 2e-3, 10, stride=10)
        assert bad == -1
        worst = max(worst, max_penetration(world, state.position, state.rotation))
    # issue target 0.5 mm: measured 0.22-0.25 mm over seeds 0-2 (0.25-0.31 mm sampling every
    # step; before the project stage 0.9-1.5 mm, from tumbling boxes whose corners swung in
    # within one step; MuJoCo on the same pile: ~40 mm)
    assert worst <= 0.5e-3
    # settled into a pile: nothing above where it was dropped, and the kinetic energy left is a
    # tiny fraction of the potential energy released (~4 kJ). Measured 1.0e-7 at seed 0, where
    # two columns land as 8- and 9-box towers whose tops keep swaying at up to 1 cm/s (KE
    # 1e-5 .. 4e-4 J, bounded over 8 s), 3e-9 at seed 1; 7e-10 and 1e-9 before the flight was
    # exact and bounces went down to the derived threshold (the shape a pile settles into is
    # chaotic: "top below 0.6 m", the old test, failed at seed 1 before as well, 0.65 m).
    assert (state.position[:, 2] - z0).max() < 0.0
    m = model.body_mass
    ke = 0.5 * (state.linear_momentum ** 2 / m[:, None]).sum()
    lb = np.einsum("nji,nj->ni", state.rotation, state.angular_momentum_world)
    ke += 0.5 * (lb ** 2 / model.body_inertia_diag).sum()
    released = (m * G * (z0 - state.position[:, 2])).sum()
    assert ke <= 1e-6 * released


def test_sphere_isotropic_shortcut_matches_full_inertia():
    """The isotropic shortcut is exact: spheres behave the same with it forced off."""
    model = make_model([SHAPE_SPHERE] * 2, [0.1, 0.15], [1.0, 2.0], friction=0.8)
    outs = []
    for force in (False, True):
        world = ContactWorld(model, ContactParams(sleep=False), *SPLIT, force_all_stages=force)
        state = make_state(model, [[0, 0, 0.1], [0.2, 0.0, 0.6]], [[1.0, 0, 0], [0, 0.5, 0]],
                           omega=[[0, 0, 3.0], [1.0, 0, 0]])
        out, _, _, _ = simulate(world, state, 1e-3, 400, stride=40)
        outs.append(out)
    for k in ("position", "linear_momentum", "angular_momentum"):
        assert np.allclose(outs[0][k], outs[1][k], rtol=0, atol=1e-12)




def test_box_rests_on_a_static_box_table():
    """A cube dropped onto a static box (no ground) comes to rest on its top face."""
    model = make_model([SHAPE_BOX], [[0.1, 0.1, 0.1]], [1.0], restitution=0.0, ground=False,
                       static_box_position=np.array([[0.0, 0.0, 0.5]]),
                       static_box_quat_wxyz=np.array([[1.0, 0.0, 0.0, 0.0]]),
                       static_box_half_extents=np.array([[0.5, 0.5, 0.05]]),
                       static_box_restitution=np.zeros(1), static_box_friction=np.full(1, 0.5))
    world = ContactWorld(model, ContactParams(), *SPLIT)
    state = make_state(model, [[0.1, -0.1, 1.0]],
                       quat_wxyz=[rotation.axis_angle_to_quat_np([0, 0, 1], 0.3)])
    out, contacts, bad, _ = simulate(world, state, 1e-3, 2000, stride=100)
    assert bad == -1
    assert abs(state.position[0, 2] - 0.65) < 1e-4  # table top 0.55 + half extent 0.1
    assert np.all(contacts.body_b[-4:] == STATIC_BODY)
    assert world.n_awake == 0  # at rest, asleep


# ---- project stage (end-of-step penetration) -------------------------------------------------

def _random_unit_quat(rng):
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


@pytest.mark.parametrize("dt", [1e-3, 2e-3])
def test_tumbling_box_landing_on_a_box_edge_stays_within_target(dt):
    """Cubes of 0.1 m spinning at 20-50 rad/s (corner speeds 1.7-4.3 m/s) and falling at 1-4 m/s
    land, in random orientations, on and over the top rim of a cube resting on the ground: 300
    drops. Within a step such a corner can swing over the rim, or an incident edge slide past
    it, where none of the step's contact points is (the step's manifolds are clipped at its
    start). The project stage re-runs the narrowphase at the end of every step and pushes any
    point deeper than projection_depth out to it, so no overlap is ever deeper than the issue's
    target of 0.5 mm (to first order it is at most projection_depth = 0.2 mm; the rest is the
    linearisation of the correction)."""
    from rblog.engine.contact.measure import max_penetration

    params = ContactParams()
    assert params.projection_depth <= 0.5e-3
    e = 0.05
    n = 2
    model = make_model([SHAPE_BOX] * n, [[e] * 3] * n, [0.1] * n, restitution=0.2, friction=0.6)
    outs = [np.zeros((1, n, 3)), np.zeros((1, n, 3)), np.zeros((1, n, 4)), np.zeros((1, n, 3, 3)),
            np.zeros((1, n, 3))]
    worst = 0.0
    drops = 0
    for seed in range(300):
        rng = np.random.default_rng(seed)
        ang, off = rng.uniform(0.0, 2.0 * np.pi), rng.uniform(0.04, 0.1)
        # lowest point of the tumbling cube at most 1 cm above the resting cube's top face
        p0 = [off * np.cos(ang), off * np.sin(ang), 2 * e + np.sqrt(3) * e + rng.uniform(0, 0.01)]
        w = rng.normal(size=3)
        w *= rng.uniform(20.0, 50.0) / np.linalg.norm(w)
        v = [rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), -rng.uniform(1.0, 4.0)]
        state = make_state(model, [p0, [0.0, 0.0, e]], [v, [0.0, 0.0, 0.0]],
                           quat_wxyz=[_random_unit_quat(rng), [1.0, 0.0, 0.0, 0.0]],
                           omega=[w, [0.0, 0.0, 0.0]])
        world = ContactWorld(model, ContactParams(), *SPLIT)
        if max_penetration(world, state.position, state.rotation) > 0.0:
            continue  # this random start overlaps already
        drops += 1
        for _ in range(int(round(0.15 / dt))):
            _, bad, _, _ = world.advance(dt, 1, 1, False, state.position, state.linear_momentum,
                                         state.quat_wxyz, state.rotation,
                                         state.angular_momentum_world, *outs)
            assert bad == -1
            worst = max(worst, max_penetration(world, state.position, state.rotation))
    assert drops >= 250
    assert worst <= 0.5e-3, worst  # measured 0.20 mm at dt = 1 ms, 0.25 mm at 2 ms


def test_projection_resolves_an_overlap_without_velocity():
    """Two cubes at rest in zero g, overlapping d = 3 mm face to face. The velocity solve leaves
    them at rest (vn = 0 already meets vn >= 0); the split impulses remove
    min(beta (d - slop), max_correction_speed dt) = 1 mm; the project stage pushes the other
    2 mm out to projection_depth in the same step. Only positions move: both momenta stay
    exactly zero and the pair's centre of mass stays put (face-face: a translation, which the
    linearised projection gets exactly once its Gauss-Seidel sweeps over the four coupled
    corners have converged; they converge geometrically, to 1 % here)."""
    from rblog.engine.contact.measure import max_penetration

    e, d, dt = 0.05, 3e-3, 1e-3
    params = ContactParams(sleep=False)
    model = make_model([SHAPE_BOX] * 2, [[e] * 3] * 2, [1.0, 2.0], gravity=(0, 0, 0),
                       ground=False)
    world = ContactWorld(model, params, *SPLIT)
    state = make_state(model, [[0.0, 0.0, 0.0], [2 * e - d, 0.0, 0.0]])
    com0 = (model.body_mass[:, None] * state.position).sum(0) / model.body_mass.sum()
    _, _, bad, _ = simulate(world, state, dt, 1)
    assert bad == -1
    pen = max_penetration(world, state.position, state.rotation)
    assert abs(pen - params.projection_depth) <= 0.01 * params.projection_depth, pen
    assert np.all(state.linear_momentum == 0.0) and np.all(state.angular_momentum_world == 0.0)
    com1 = (model.body_mass[:, None] * state.position).sum(0) / model.body_mass.sum()
    assert np.abs(com1 - com0).max() <= 1e-15
    # from there on the split impulses take it to the slop; the project stage stays idle
    simulate(world, state, dt, 200)
    assert max_penetration(world, state.position, state.rotation) <= params.projection_depth
    assert np.all(state.linear_momentum == 0.0)


def test_projection_settings_are_validated():
    with pytest.raises(ValueError):
        ContactParams(projection_depth=0.0)
    with pytest.raises(ValueError):
        ContactParams(projection_iterations=-1)
    with pytest.raises(ValueError):
        ContactParams(projection_iterations=1.5)
    assert ContactParams.from_dict({"projection_iterations": 0}).projection_iterations == 0



def test_slow_body_pushing_a_sleeping_one_conserves_momentum():
    """Frictionless ground: box 1 rests on it and falls asleep; box 0 slides into it at 2 cm/s
    (slow enough that the wake-before-solve test lets the sleeper stand in as static for the
    first contact step). The ground pushes only along z, so the pair's x momentum must stay what
    it was at every sample, and a plastic push (e = 0) leaves both at 1 cm/s."""
    m, a = 1.0, 0.1
    model = make_model([SHAPE_BOX, SHAPE_BOX], [a, a], [m, m], restitution=0.0, friction=0.0)
    world = ContactWorld(model, ContactParams(), *SPLIT)
    # box 0 starts 0.3 m from box 1 (0.1 m gap) at 0.02 m/s: contact after ~5 s; at dt = 1e-3
    # it closes h v = 2e-5 m per step, under allowed_penetration (5e-5 m): "slow"
    state = make_state(model, [[-0.3, 0.0, a], [0.0, 0.0, a]], [[0.02, 0, 0], [0, 0, 0]])
    px0 = state.linear_momentum[:, 0].sum()
    out, contacts, bad, _ = simulate(world, state, 1e-3, 8000, stride=10)
    assert bad == -1
    assert world.stats[7] > 0  # ST_SLEPT: box 1 did sleep before it was hit
    px = out["linear_momentum"][:, :, 0].sum(1)
    assert np.abs(px - px0).max() <= 1e-12 * px0  # before the fix: 2.7e-11 lost; after: 0
    # the sleeper took the push and the pair moves on at the centre-of-mass speed, 1 cm/s each
    # (measured 0.009987 and 0.010013: in the one step the sleeper stood in as static the push
    # was a little stiffer than a plastic one between two awake boxes)
    np.testing.assert_allclose(out["linear_momentum"][-1, :, 0], [0.01, 0.01], rtol=0, atol=5e-5)
