"""The `rblog check` analyzers, in both directions, on synthetic trajectories from closed forms.

No simulator is involved: every trajectory below is exact motion built from theory and turned into
a Trajectory by rblog.contract.trajectory.derive (the writer's own derivation of velocities, energies...).
The expected numbers come from that theory, never from the analyzers' output:

* ballistic flight: x = x0 + v0 t + g t^2 / 2; steady spin about a principal axis a:
  R = Rot(a, w t) R0, L = I3 w a (constant).
* torque-free symmetric top (I1 = I2 = Ip, I3): L is fixed in space and
  R(t) = Rot(L^, |L| t / Ip) R0 Rot(e3, -W t) with W = L3 (1/Ip - 1/I3), L3 = L.(R e3) constant
  (Landau & Lifshitz, Mechanics, section 33). Its kinetic energy is
  |L|^2 / (2 Ip) + L3^2 (1/I3 - 1/Ip) / 2.
* bouncing ball: parabolic arcs; impact n at speed V_n = e^n sqrt(2 g h0), leaving at e V_n, next
  impact 2 e V_n / g later.
* head-on collision of spheres (along the line of centres): u_a' = u_a - (1 + e) m_b / (m_a + m_b)
  (u_a - u_b), u_b' = u_b + (1 + e) m_a / (m_a + m_b) (u_a - u_b).
* box on a plane: support half-width along the normal n is sum_j h_j |n . A_j|.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rblog.analyze import ANALYZERS, CheckOptionError, check, default_tolerances
from rblog.analyze import geometry
from rblog.analyze import tolerances as TOL
from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE, Model
from rblog.contract.trajectory import CONTACT_IMPACT, CONTACT_RESTING, STATIC_BODY, Contacts, RunInfo, derive

G = np.array([0.0, 0.0, -9.81])
GM = 9.81
DT = 1e-3  # integrator step written in RunInfo
LOG_EVERY = 10
DT_S = DT * LOG_EVERY  # sample interval


# ---------------------------------------------------------------------------------------------
# building blocks


def inertia_of(shape: str, size, mass: float) -> np.ndarray:
    if shape == "sphere":
        return np.full(3, 0.4 * mass * size[0] ** 2)
    a, b, c = size
    return mass / 3.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])


def make_model(bodies, *, gravity=G, ground=False, ground_e=0.5, ground_mu=0.5, statics=()):
    """bodies: dicts with shape, size, mass, and optional e, mu, inertia, force, torque, group."""
    n = len(bodies)
    size = np.zeros((n, 3))
    for i, b in enumerate(bodies):
        s = np.atleast_1d(np.asarray(b["size"], float))
        size[i, : len(s)] = s
    st = list(statics)
    return Model(
        body_name=[b.get("name", f"b{i}") for i, b in enumerate(bodies)],
        body_shape=np.array([SHAPE_SPHERE if b["shape"] == "sphere" else SHAPE_BOX
                             for b in bodies]),
        body_size=size,
        body_mass=np.array([b["mass"] for b in bodies], float),
        body_inertia_diag=np.array([b.get("inertia", inertia_of(b["shape"], size[i], b["mass"]))
                                    for i, b in enumerate(bodies)], float),
        body_force_world=np.array([b.get("force", (0, 0, 0)) for b in bodies], float),
        body_torque_world=np.array([b.get("torque", (0, 0, 0)) for b in bodies], float),
        body_restitution=np.array([b.get("e", 0.5) for b in bodies], float),
        body_friction=np.array([b.get("mu", 0.5) for b in bodies], float),
        body_group=np.array([b.get("group", 0) for b in bodies], np.int64),
        gravity=np.asarray(gravity, float),
        ground=ground,
        ground_restitution=ground_e,
        ground_friction=ground_mu,
        static_box_position=np.array([s["position"] for s in st], float).reshape(-1, 3),
        static_box_quat_wxyz=np.array([s.get("quat", (1, 0, 0, 0)) for s in st],
                                      float).reshape(-1, 4),
        static_box_half_extents=np.array([s["half"] for s in st], float).reshape(-1, 3),
        static_box_restitution=np.array([s.get("e", 0.5) for s in st], float),
        static_box_friction=np.array([s.get("mu", 0.5) for s in st], float),
    )


def rot(axis, angle) -> np.ndarray:
    """Rodrigues: rotation by angle (T,) about the unit axis (3,) -> (T, 3, 3)."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    angle = np.atleast_1d(np.asarray(angle, float))
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + s * kx + (1 - c) * (kx @ kx)


def quat_of(r: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotations -> (..., 4) wxyz."""
    q = Rotation.from_matrix(r.reshape(-1, 3, 3)).as_quat()
    return q[:, [3, 0, 1, 2]].reshape(r.shape[:-2] + (4,))


def times(duration: float) -> np.ndarray:
    return np.arange(int(round(duration / DT_S)) + 1) * DT_S


def build(model, t, x, v, r, l, contacts=None, quat=None):
    """Trajectory from exact samples: x, v, L (T, N, 3), R (T, N, 3, 3)."""
    m = model.body_mass
    step = np.round(t / DT).astype(np.int64)
    info = RunInfo(integrator="exact", orthonormalize="none", dt=DT, log_every=LOG_EVERY,
                   duration_s=float(t[-1]), rblog_version="test",
                   writer="tests/analyze/test_analyze.py (closed form)")
    q = quat_of(r) if quat is None else quat
    return derive(model, info, step, t, np.ascontiguousarray(x), v * m[None, :, None], q,
                  np.ascontiguousarray(r), np.ascontiguousarray(l), contacts)


def contacts_of(rows) -> Contacts:
    """rows: dicts with step, t, a, b, point, normal, sep, jn, jt (3,), kind."""
    if not rows:
        return Contacts.empty()
    return Contacts(
        step=np.array([r["step"] for r in rows], np.int64),
        t=np.array([r["t"] for r in rows], float),
        body_a=np.array([r["a"] for r in rows], np.int64),
        body_b=np.array([r["b"] for r in rows], np.int64),
        point=np.array([r["point"] for r in rows], float),
        normal=np.array([r["normal"] for r in rows], float),
        separation=np.array([r.get("sep", 0.0) for r in rows], float),
        normal_impulse=np.array([r["jn"] for r in rows], float),
        friction_impulse=np.array([r.get("jt", (0, 0, 0)) for r in rows], float),
        kind=np.array([r["kind"] for r in rows], np.int8),
    )


def results(traj, **kw):
    return {r.analyzer: r for r in check(traj, **kw)}


def assert_clean(traj):
    res = results(traj)
    bad = {k: (r.reason, r.findings[:2]) for k, r in res.items() if not r.passed}
    assert not bad, bad
    return res


def flagged(traj, **kw):
    return {k for k, r in results(traj, **kw).items() if not r.passed}


# ---------------------------------------------------------------------------------------------
# closed-form cases


def ballistic(duration=1.5):
    """A spinning box tossed in gravity (steady spin about its principal axis 3), ground far
    below."""
    h = (0.2, 0.1, 0.05)
    model = make_model([dict(shape="box", size=h, mass=2.0)], ground=True)
    t = times(duration)
    x0, v0 = np.array([0.0, 0.0, 10.0]), np.array([1.0, 0.5, 5.0])
    x = (x0 + v0 * t[:, None] + 0.5 * G * t[:, None] ** 2)[:, None]
    v = (v0 + G * t[:, None])[:, None]
    r0 = rot([1, 1, 0], 0.4)[0]
    a = r0[:, 2]
    w = 3.0
    r = (rot(a, w * t) @ r0)[:, None]
    i3 = model.body_inertia_diag[0, 2]
    l = np.broadcast_to(i3 * w * a, (len(t), 1, 3))
    return build(model, t, x, v, r, l)


def top_params():
    h = (0.1, 0.1, 0.3)
    m = 1.0
    inertia = inertia_of("box", h, m)
    ip, i3 = inertia[0], inertia[2]
    r0 = rot([0.3, 1.0, 0.2], 0.7)[0]
    w_body0 = np.array([2.0, 0.0, 5.0])
    l_world = r0 @ (inertia * w_body0)
    return h, m, inertia, ip, i3, r0, l_world


def symmetric_top(duration=3.0, stretch=None, tilt_rate=0.0):
    """Torque-free symmetric top, exact. stretch(t) scales R (drift fault); tilt_rate rotates the
    body's axis away from its exact cone at that rate (rad/s) about an axis perpendicular to L,
    which changes the kinetic energy while L stays fixed (energy fault)."""
    h, m, inertia, ip, i3, r0, l_world = top_params()
    model = make_model([dict(shape="box", size=h, mass=m, inertia=inertia)], gravity=(0, 0, 0))
    t = times(duration)
    lmag = np.linalg.norm(l_world)
    lhat = l_world / lmag
    l3 = l_world @ r0[:, 2]
    big_w = l3 * (1 / ip - 1 / i3)
    r = rot(lhat, lmag / ip * t) @ r0 @ rot([0, 0, 1], -big_w * t)
    if tilt_rate:
        u = np.cross(lhat, [0.0, 0.0, 1.0])
        r = rot(lhat, lmag / ip * t) @ rot(u, tilt_rate * t) @ r0 @ rot([0, 0, 1], -big_w * t)
    q = quat_of(r)
    if stretch is not None:
        r = r * stretch(t)[:, None, None]
    x = np.broadcast_to([0.0, 0.0, 1.0], (len(t), 3))[:, None]
    v = np.zeros((len(t), 1, 3))
    l = np.broadcast_to(l_world, (len(t), 1, 3))
    return build(model, t, x, v, r[:, None], l, quat=q[:, None])


def bouncing_ball(e=0.8, e_config=None, h0=1.0, vx=0.5, duration=2.4, vx_after=None):
    """Sphere (r = 0.1 m, 1 kg) dropped from h0 (its bottom), exact arcs with restitution e.

    e_config: restitution written in the model (default e). vx_after: horizontal velocity after
    the first impact (a friction fault when it changes more than mu J_n allows)."""
    r_, m = 0.1, 1.0
    ec = e if e_config is None else e_config
    model = make_model([dict(shape="sphere", size=r_, mass=m, e=ec, mu=0.5)], ground=True,
                       ground_e=ec, ground_mu=0.5)
    t = times(duration)
    v0 = math.sqrt(2 * GM * h0)
    t_imp, speed_in = [math.sqrt(2 * h0 / GM)], [v0]
    while t_imp[-1] < duration:
        u = e * speed_in[-1]
        t_imp.append(t_imp[-1] + 2 * u / GM)
        speed_in.append(u)
    t_imp, speed_in = np.array(t_imp), np.array(speed_in)
    n = np.searchsorted(t_imp, t, side="right")  # impacts before each sample
    z = np.where(n == 0, r_ + h0 - 0.5 * GM * t ** 2, 0.0)
    vz = np.where(n == 0, -GM * t, 0.0)
    after = n > 0
    tau = t - t_imp[np.maximum(n - 1, 0)]
    up = e * speed_in[np.maximum(n - 1, 0)]
    z = np.where(after, r_ + up * tau - 0.5 * GM * tau ** 2, z)
    vz = np.where(after, up - GM * tau, vz)
    vxs = np.full_like(t, vx)
    xs = vx * t
    if vx_after is not None:
        vxs = np.where(after, vx_after, vx)
        xs = np.where(after, vx * t_imp[0] + vx_after * (t - t_imp[0]), xs)
    x = np.stack([xs, np.zeros_like(t), z], axis=1)[:, None]
    v = np.stack([vxs, np.zeros_like(t), vz], axis=1)[:, None]
    r = np.broadcast_to(np.eye(3), (len(t), 1, 3, 3))
    l = np.zeros((len(t), 1, 3))
    rows = []
    step = np.round(t / DT).astype(np.int64)
    for j, ti in enumerate(t_imp[t_imp < t[-1]]):
        k1 = int(np.searchsorted(t, ti))
        rows.append(dict(step=step[k1], t=t[k1], a=0, b=STATIC_BODY, point=(vx * ti, 0, 0),
                         normal=(0, 0, 1), sep=0.0, jn=m * (1 + e) * speed_in[j],
                         kind=CONTACT_IMPACT))
    traj = build(model, t, x, v, r, l, contacts=contacts_of(rows))
    return traj, t_imp[t_imp < t[-1]]


def head_on(e=1.0, alter_b=1.0, duration=1.2):
    """Two spheres colliding head-on along x at y = 0.5, z = 0.3, no gravity, exact."""
    ma, mb, ra, rb = 1.0, 3.0, 0.1, 0.15
    model = make_model([dict(shape="sphere", size=ra, mass=ma, e=e, mu=0.3),
                        dict(shape="sphere", size=rb, mass=mb, e=e, mu=0.3)], gravity=(0, 0, 0))
    t = times(duration)
    xa0, xb0 = np.array([-1.0, 0.5, 0.3]), np.array([1.0, 0.5, 0.3])
    ua, ub = 2.0, -1.0
    tc = (xb0[0] - xa0[0] - ra - rb) / (ua - ub)
    ua2 = ua - (1 + e) * mb / (ma + mb) * (ua - ub)
    ub2 = (ub + (1 + e) * ma / (ma + mb) * (ua - ub)) * alter_b
    after = (t > tc)[:, None]
    ex = np.array([1.0, 0.0, 0.0])
    xa = np.where(after, xa0 + ex * (ua * tc + ua2 * (t[:, None] - tc)), xa0 + ex * ua * t[:, None])
    xb = np.where(after, xb0 + ex * (ub * tc + ub2 * (t[:, None] - tc)), xb0 + ex * ub * t[:, None])
    va = np.where(after, ua2 * ex, ua * ex)
    vb = np.where(after, ub2 * ex, ub * ex)
    x = np.stack([xa, xb], axis=1)
    v = np.stack([va, vb], axis=1)
    r = np.broadcast_to(np.eye(3), (len(t), 2, 3, 3))
    l = np.zeros((len(t), 2, 3))
    k1 = int(np.searchsorted(t, tc))
    step = np.round(t / DT).astype(np.int64)
    rows = [dict(step=step[k1], t=t[k1], a=0, b=1, point=xa0 + ex * (ua * tc + ra),
                 normal=(-1, 0, 0), sep=0.0, jn=ma * abs(ua2 - ua), kind=CONTACT_IMPACT)]
    return build(model, t, x, v, r, l, contacts=contacts_of(rows)), (ua2, ub2, tc)


def resting_box(duration=2.0, sink=0.0, sink_from=1.0, slide=0.0, shake=0.0, log_contacts=True,
                kick=None):
    """A 0.2 m cube (1 kg) resting flat on the ground (turned 0.3 rad about z).

    sink: poses shifted this far below the ground from sink_from on (penetration fault).
    slide: constant horizontal speed (creep fault).  shake: vertical velocity alternating +-shake
    between samples (jitter fault).  kick: (kind, dv) a vertical velocity change of dv at t = 1 s,
    kind "step" (kept) or "spike" (one sample): a struck box, not jitter."""
    hh = 0.1
    model = make_model([dict(shape="box", size=(hh, hh, hh), mass=1.0, mu=0.5)], ground=True)
    t = times(duration)
    z = np.where(t >= sink_from, hh - sink, hh)
    x = np.stack([0.3 + slide * t, np.full_like(t, -0.2), z], axis=1)[:, None]
    vz = shake * (-1.0) ** np.arange(len(t))
    if kick is not None:
        k0 = int(np.searchsorted(t, 1.0))
        vz[k0:k0 + (1 if kick[0] == "spike" else len(t))] += kick[1]
    v = np.stack([np.full_like(t, slide), np.zeros_like(t), vz], axis=1)[:, None]
    r0 = rot([0, 0, 1], 0.3)[0]
    r = np.broadcast_to(r0, (len(t), 1, 3, 3))
    l = np.zeros((len(t), 1, 3))
    rows = []
    if log_contacts:
        step = np.round(t / DT).astype(np.int64)
        corners = [r0 @ np.array([sx * hh, sy * hh, -hh]) for sx in (-1, 1) for sy in (-1, 1)]
        for k in range(len(t)):
            for c in corners:
                rows.append(dict(step=step[k], t=t[k], a=0, b=STATIC_BODY, point=x[k, 0] + c,
                                 normal=(0, 0, 1), sep=z[k] - hh, jn=GM * DT / 4,
                                 kind=CONTACT_RESTING))
    return build(model, t, x, v, r, l, contacts=contacts_of(rows))


def stacked_boxes(duration=1.0, sink_top=0.0):
    """Two 0.2 m cubes stacked at rest on the ground (the top one turned 0.4 rad about z)."""
    hh = 0.1
    model = make_model([dict(shape="box", size=(hh, hh, hh), mass=1.0),
                        dict(shape="box", size=(hh, hh, hh), mass=1.0)], ground=True)
    t = times(duration)
    x = np.array([[0.0, 0.0, hh], [0.02, -0.01, 3 * hh - sink_top]])
    x = np.broadcast_to(x, (len(t), 2, 3))
    r = np.stack([np.eye(3), rot([0, 0, 1], 0.4)[0]])
    r = np.broadcast_to(r, (len(t), 2, 3, 3))
    z = np.zeros((len(t), 2, 3))
    return build(model, t, x, z, r, z)


def rolling_ball(v=1.5, duration=1.0):
    """A sphere rolling without slip along x on the ground: x = v t, w = v / r about y."""
    r_ = 0.1
    model = make_model([dict(shape="sphere", size=r_, mass=1.0)], ground=True)
    t = times(duration)
    x = np.stack([v * t, np.zeros_like(t), np.full_like(t, r_)], 1)[:, None]
    vel = np.broadcast_to([v, 0.0, 0.0], (len(t), 1, 3))
    r = rot([0, 1, 0], v / r_ * t)[:, None]
    i_ = model.body_inertia_diag[0, 1]
    l = np.broadcast_to([0.0, i_ * v / r_, 0.0], (len(t), 1, 3))
    return build(model, t, x, vel, r, l)


def sliding_box(v0=1.0, mu=0.5, decel=None, duration=0.6):
    """A 0.2 m cube sliding along x on the ground, decelerating by friction at mu g (exact) until
    it stops (decel: another deceleration, a friction fault when above mu g)."""
    hh = 0.1
    model = make_model([dict(shape="box", size=(hh, hh, hh), mass=1.0, mu=mu)], ground=True,
                       ground_mu=mu)
    t = times(duration)
    a = mu * GM if decel is None else decel
    ts = v0 / a
    tt = np.minimum(t, ts)
    xs = v0 * tt - 0.5 * a * tt ** 2
    vs = np.where(t < ts, v0 - a * t, 0.0)
    x = np.stack([xs, np.zeros_like(t), np.full_like(t, hh)], 1)[:, None]
    v = np.stack([vs, np.zeros_like(t), np.zeros_like(t)], 1)[:, None]
    r = np.broadcast_to(np.eye(3), (len(t), 1, 3, 3))
    return build(model, t, x, v, r, np.zeros((len(t), 1, 3))), ts


def ball_on_static_box(duration=1.0, sink=0.0):
    """A sphere resting on the top face of a static box (a table), no ground."""
    model = make_model([dict(shape="sphere", size=0.1, mass=1.0)],
                       statics=[dict(position=(0, 0, 0.5), half=(0.5, 0.5, 0.5))])
    t = times(duration)
    x = np.broadcast_to([0.1, 0.2, 1.1 - sink], (len(t), 1, 3))
    z = np.zeros((len(t), 1, 3))
    return build(model, t, x, z, np.broadcast_to(np.eye(3), (len(t), 1, 3, 3)), z)


def sphere_hits_box(alter=1.0, e=1.0, duration=1.0):
    """Zero g: a sphere flies along x into the centre of a box's face (impulse through both
    centres, no rotation): the head-on formulas hold."""
    ms, mb, r_, hb = 1.0, 2.0, 0.1, 0.2
    model = make_model([dict(shape="sphere", size=r_, mass=ms, e=e),
                        dict(shape="box", size=(hb, 0.3, 0.25), mass=mb, e=e)], gravity=(0, 0, 0))
    t = times(duration)
    xs0, xb0 = np.array([-1.0, 0.3, 0.2]), np.array([0.5, 0.3, 0.2])
    us, ub = 3.0, 0.0
    tc = (xb0[0] - xs0[0] - r_ - hb) / (us - ub)
    us2 = us - (1 + e) * mb / (ms + mb) * (us - ub)
    ub2 = (ub + (1 + e) * ms / (ms + mb) * (us - ub)) * alter
    after = (t > tc)[:, None]
    ex = np.array([1.0, 0, 0])
    xs = np.where(after, xs0 + ex * (us * tc + us2 * (t[:, None] - tc)), xs0 + ex * us * t[:, None])
    xb = np.where(after, xb0 + ex * (ub * tc + ub2 * (t[:, None] - tc)), xb0 + ex * ub * t[:, None])
    x = np.stack([xs, xb], 1)
    v = np.stack([np.where(after, us2 * ex, us * ex), np.where(after, ub2 * ex, ub * ex)], 1)
    r = np.broadcast_to(np.eye(3), (len(t), 2, 3, 3))
    return build(model, t, x, v, r, np.zeros((len(t), 2, 3)))


def ramp_box(theta=math.radians(30), mu=0.3, slide=True, duration=0.5):
    """A 0.2 m cube on a ramp (a static box turned by theta about y, friction mu on both), either
    sliding down at a = g (sin theta - mu cos theta) from rest, or resting (slide=False)."""
    hh = 0.1
    r_ramp = rot([0, 1, 0], theta)[0]
    q_ramp = quat_of(r_ramp[None])[0]
    model = make_model([dict(shape="box", size=(hh, hh, hh), mass=1.0, mu=mu)],
                       statics=[dict(position=(0, 0, 0), quat=q_ramp, half=(2.0, 1.0, 0.1), mu=mu)])
    t = times(duration)
    u = r_ramp[:, 0]  # downhill along the ramp
    p0 = r_ramp @ np.array([-1.0, 0.0, 0.1 + hh])
    a = GM * (math.sin(theta) - mu * math.cos(theta)) if slide else 0.0
    x = (p0 + 0.5 * a * t[:, None] ** 2 * u)[:, None]
    v = (a * t[:, None] * u)[:, None]
    r = np.broadcast_to(r_ramp, (len(t), 1, 3, 3))
    return build(model, t, x, v, r, np.zeros((len(t), 1, 3)))


def discrete_bounce(e=0.8, dt=DT, every=LOG_EVERY, duration=4.0, h0=1.0, r_=0.1, threshold=1.0):
    """A stand-in for a discrete engine (not closed form; only used to check that a correct
    first-order run is not flagged): symplectic Euler steps of a ball with a speculative ground
    contact, restitution e above ``threshold`` m/s and a plain landing below it."""
    z, v = r_ + h0, 0.0
    zs, vs = [z], [v]
    for s in range(int(round(duration / dt))):
        v -= GM * dt
        gap = z - r_
        if gap + v * dt < 0:  # would penetrate during this step
            if -v > threshold:
                v, z = -e * v, r_
            else:
                z, v = r_, 0.0
        else:
            z += v * dt
        if (s + 1) % every == 0:
            zs.append(z)
            vs.append(v)
    t = np.arange(len(zs)) * dt * every
    model = make_model([dict(shape="sphere", size=r_, mass=1.0, e=e)], ground=True, ground_e=e)
    zero = np.zeros_like(t)
    x = np.stack([zero, zero, np.array(zs)], 1)[:, None]
    vel = np.stack([zero, zero, np.array(vs)], 1)[:, None]
    return build(model, t, x, vel, np.broadcast_to(np.eye(3), (len(t), 1, 3, 3)),
                 np.zeros((len(t), 1, 3)))


# ---------------------------------------------------------------------------------------------
# the clean direction: nothing is flagged


def test_setup_matches_theory():
    """The symmetric top built above has the angular velocity theory gives (checks the fixture):
    w = |L| / Ip L^ - W a with a = R e3."""
    traj = symmetric_top()
    h, m, inertia, ip, i3, r0, l_world = top_params()
    lmag = np.linalg.norm(l_world)
    l3 = l_world @ r0[:, 2]
    a = traj.rotation[:, 0, :, 2]
    w_theory = lmag / ip * (l_world / lmag) - l3 * (1 / ip - 1 / i3) * a
    np.testing.assert_allclose(traj.angular_velocity[:, 0], w_theory, atol=1e-12)


CLEAN = {
    "ballistic": lambda: ballistic(),
    "top": lambda: symmetric_top(),
    "bounce": lambda: bouncing_ball()[0],
    "head_on_e1": lambda: head_on(1.0)[0],
    "head_on_e05": lambda: head_on(0.5)[0],
    "resting_box": lambda: resting_box(),
    "resting_box_no_contacts_logged": lambda: resting_box(log_contacts=False),
    "stacked_boxes": lambda: stacked_boxes(),
    "rolling_ball": lambda: rolling_ball(),
    "sliding_box": lambda: sliding_box()[0],
    "ball_on_static_box": lambda: ball_on_static_box(),
    "sphere_hits_box": lambda: sphere_hits_box(),
    "box_slides_down_ramp": lambda: ramp_box(),
    "box_rests_on_ramp": lambda: ramp_box(mu=0.7, slide=False),
    "discrete_bounce": lambda: discrete_bounce(),
}


@pytest.mark.parametrize("case", list(CLEAN))
def test_clean_cases_pass_every_analyzer(case):
    traj = CLEAN[case]()
    res = assert_clean(traj)
    # a lone body with no ground has nothing to rest on or pass through; free bodies have no
    # joints to hold
    lone = ({"penetration", "tunneling"} if case == "top" else set()) | {"joints"}
    assert {k for k, r in res.items() if r.skipped} == lone
    for r in res.values():
        json.dumps(r.to_dict(traj.model))  # JSON-able


def test_bounce_reports_effective_restitution_equal_to_e():
    e = 0.8
    traj, t_imp = bouncing_ball(e=e)
    mom = results(traj)["momentum"]
    impacts = [ev for ev in mom.events if ev["kind"] == "impact"]
    assert len(impacts) == len(t_imp) == 4
    for ev, ti in zip(impacts, t_imp):
        assert ev["restitution_effective"] == pytest.approx(e, rel=1e-9)
        assert ev["restitution_configured"] == e
        assert ev["t_before"] < ti <= ev["t"]
        assert ev["static"]
    # the approach speeds are those of theory: e^n sqrt(2 g h0)
    v0 = math.sqrt(2 * GM * 1.0)
    for n, ev in enumerate(impacts):
        assert ev["approach_speed_mps"] == pytest.approx(e ** n * v0, rel=1e-9)


@pytest.mark.parametrize("e", [1.0, 0.5])
def test_head_on_conserves_momentum_and_reports_restitution(e):
    traj, (ua2, ub2, tc) = head_on(e)
    mom = results(traj)["momentum"]
    assert mom.passed
    assert mom.stats["closed_groups"] == 1
    assert mom.stats["linear_rel_max"] < 1e-13
    assert mom.stats["angular_rel_max"] < 1e-13
    (ev,) = mom.events
    assert ev["bodies"] == [0, 1]
    assert ev["restitution_effective"] == pytest.approx(e, rel=1e-9)
    assert ev["approach_speed_mps"] == pytest.approx(3.0, rel=1e-12)
    # kinetic energy change = -(1/2) mu (1 - e^2) (du)^2 (theory), mu = ma mb / (ma + mb)
    mu = 1.0 * 3.0 / 4.0
    assert ev["energy_change_J"] == pytest.approx(-0.5 * mu * (1 - e * e) * 9.0, abs=1e-12)


def test_resting_box_reports_its_rest():
    traj = resting_box()
    pen = results(traj)["penetration"]
    (ev,) = pen.events
    assert ev["partner"] == -1 and ev["body"] == 0
    assert ev["duration_s"] == pytest.approx(traj.t[-1] - traj.t[0])
    assert ev["depth_max_m"] == pytest.approx(0.0, abs=1e-15)
    assert ev["jitter_mps"] == 0.0 and ev["creep_m"] == 0.0


def test_discrete_bounce_restitution_within_its_dt_tolerance():
    """The symplectic-Euler ball resolves each impact at a step boundary: its effective
    restitution is e within RESTITUTION_ABS + (1 + e) g dt / v (momentum docstring)."""
    e = 0.8
    mom = results(discrete_bounce(e))["momentum"]
    fast = [ev for ev in mom.events if ev["approach_speed_mps"] > 1.0]
    # theory: approach speeds e^n sqrt(2 g h0) > 1 m/s for n = 0..6
    assert len(fast) == 7
    for ev in fast:
        v = ev["approach_speed_mps"]
        assert abs(ev["restitution_effective"] - e) <= 0.01 + (1 + e) * GM * DT / v


def test_stacked_boxes_rest_on_the_ground_and_on_each_other():
    pen = results(stacked_boxes())["penetration"]
    rests = {ev["body"]: ev["partner"] for ev in pen.events}
    assert rests == {0: -1, 1: 0}
    assert pen.stats["rest_depth_max_m"] == pytest.approx(0.0, abs=1e-12)


def test_rolling_is_not_creep():
    # rolling without slip is not resting (every point but the contact moves): one rolling
    # stretch over the whole log, its slip v - w r = 0 to round-off, no rest to judge
    pen = results(rolling_ball())["penetration"]
    assert pen.passed
    (ev,) = pen.events
    assert ev["kind"] == "rolling" and ev["partner"] == -1
    assert ev["slip_max_mps"] == pytest.approx(0.0, abs=1e-12)
    assert ev["speed_mps"] == pytest.approx(1.5, rel=1e-12)


def test_sliding_box_friction_at_the_cone_edge_then_rest():
    traj, ts = sliding_box()
    res = assert_clean(traj)
    # kinetic friction: |J_t| = mu J_n exactly while sliding
    assert res["momentum"].stats["cone_excess_rel_max"] == pytest.approx(0.0, abs=1e-9)
    (ev,) = [e for e in res["penetration"].events if e["kind"] == "rest"]
    assert ev["t_start"] <= ts + DT_S


def test_ball_resting_on_a_static_box():
    pen = results(ball_on_static_box())["penetration"]
    (ev,) = pen.events
    assert ev["partner"] == 1  # N + 0: static box 0
    bad = results(ball_on_static_box(sink=2e-3))["penetration"]
    assert not bad.passed and "static box 0" in bad.findings[0].message
    assert bad.worst_value == pytest.approx(2e-3, rel=1e-9)


def test_collisions_are_found_without_logged_contacts():
    """Without contacts in the log, the collision is found from the velocity jump."""
    traj, _ = head_on(0.5)
    traj.contacts = Contacts.empty()
    mom = results(traj)["momentum"]
    assert mom.passed
    (ev,) = mom.events
    assert ev["bodies"] == [0, 1]
    assert ev["restitution_effective"] == pytest.approx(0.5, rel=1e-9)
    bad, _ = head_on(0.5, alter_b=1.05)
    bad.contacts = Contacts.empty()
    assert "momentum" in flagged(bad)
    ball, _ = bouncing_ball()
    ball.contacts = Contacts.empty()
    impacts = [ev for ev in results(ball)["momentum"].events if ev["kind"] == "impact"]
    assert len(impacts) == 4


# ---------------------------------------------------------------------------------------------
# the other direction: planted faults are flagged


def test_drift_flags_stretching_rotation_with_onset_and_growth():
    eps = 1e-6  # R scaled by (1 + eps t)
    traj = symmetric_top(stretch=lambda t: 1 + eps * t)
    res = results(traj)
    assert not res["drift"].passed
    t = traj.t
    # theory: ||R^T R - I||_F = sqrt(3) ((1 + eps t)^2 - 1), the largest ratio to its tolerance
    ortho = math.sqrt(3) * ((1 + eps * t) ** 2 - 1)
    onset = int(np.argmax(ortho > TOL.DRIFT_ORTHO_ERROR))
    d = res["drift"]
    assert d.stats["onset_t"] == pytest.approx(t[onset])
    assert d.worst_value == pytest.approx(ortho[-1], rel=1e-6)
    assert d.worst_t == pytest.approx(t[-1])
    # least-squares slope of a t + b t^2 over a symmetric grid is a + 2 b mean(t)
    tm = t[onset:].mean()
    assert d.stats["worst_growth_per_s"] == pytest.approx(math.sqrt(3) * (2 * eps + 2 * eps ** 2
                                                                         * tm), rel=1e-6)
    assert d.stats["distance_rel_max"] == pytest.approx(eps * t[-1], rel=1e-6)
    assert d.stats["det_error_max"] == pytest.approx((1 + eps * t[-1]) ** 3 - 1, rel=1e-6)
    assert d.findings[0].bodies == [0]
    # only rigidity is wrong here
    assert flagged(traj, skip=["energy"]) == {"drift"}


def test_drift_exponential_stretch_log_rate():
    lam = 0.05  # R scaled by exp(lam t): relative distance error exp(lam t) - 1
    traj = symmetric_top(stretch=lambda t: np.exp(lam * t))
    d = results(traj, only=["drift"])["drift"]
    assert not d.passed
    assert d.stats["distance_rel_max"] == pytest.approx(math.expm1(lam * traj.t[-1]), rel=1e-9)


def test_drift_flags_quaternion_norm():
    traj = symmetric_top()
    traj.quat_wxyz = traj.quat_wxyz * (1 + 1e-5)
    d = results(traj, only=["drift"])["drift"]
    assert not d.passed
    assert d.stats["quat_norm_error_max"] == pytest.approx(1e-5, rel=1e-6)


def test_momentum_flags_altered_post_impact_velocity():
    traj, (ua2, ub2, tc) = head_on(1.0, alter_b=1.05)
    res = results(traj)
    mom = res["momentum"]
    assert not mom.passed
    # theory: the total momentum changes by m_b (1.05 - 1) u_b' ; scale sum m max|v|
    du = 3.0 * (ub2 - ub2 / 1.05)
    scale = 1.0 * 2.5 + 3.0 * 1.0  # m_a max(|2|, |-2.5|) + m_b max(|-1|, |0.5 * 1.05|)
    lin = [f for f in mom.findings if "linear" in f.message]
    assert lin and lin[0].value == pytest.approx(abs(du) / scale, rel=1e-9)
    assert lin[0].bodies == [0, 1]
    assert traj.t[lin[0].step // LOG_EVERY - 1] < tc <= lin[0].t


def test_momentum_flags_wrong_restitution():
    traj, _ = bouncing_ball(e=0.8, e_config=0.7)
    mom = results(traj)["momentum"]
    assert not mom.passed
    rest = [f for f in mom.findings if "restitution" in f.message]
    assert len(rest) == 4
    assert all(f.value == pytest.approx(0.1, rel=1e-6) for f in rest)


def test_energy_gain_at_impact_is_flagged():
    traj, _ = bouncing_ball(e=1.1, e_config=0.8, duration=1.0)
    fl = flagged(traj)
    assert {"momentum", "energy"} <= fl
    en = results(traj)["energy"]
    # theory: energy gain (e^2 - 1) m V0^2 / 2 at the first impact, V0^2 = 2 g h0
    gain = [f for f in en.findings if "contact" in f.message]
    assert gain and "grows by" in gain[0].message
    assert f"{(1.1 ** 2 - 1) * GM:.3g} J" in gain[0].message


def test_momentum_flags_impulse_outside_friction_cone():
    # first impact: J_n = (1 + e) m V0 = 1.8 * 4.43 = 7.97 N s, mu J_n = 3.99 N s < |dvx| = 5.5
    traj, _ = bouncing_ball(vx=0.5, vx_after=-5.0, duration=0.8)
    mom = results(traj)["momentum"]
    assert not mom.passed
    cone = [f for f in mom.findings if "friction cone" in f.message]
    assert len(cone) == 1
    jn = 1.8 * math.sqrt(2 * GM)
    assert cone[0].value == pytest.approx((5.5 - 0.5 * jn) / math.hypot(5.5, jn), rel=1e-6)


def test_momentum_flags_altered_velocity_after_sphere_box_impact():
    assert "momentum" in flagged(sphere_hits_box(alter=0.97))


def test_momentum_flags_friction_beyond_the_cone():
    traj, _ = sliding_box(decel=2 * 0.5 * GM)  # twice what mu = 0.5 allows
    mom = results(traj)["momentum"]
    assert not mom.passed
    # theory: per interval J_n = m g dt, |J_t| = 2 mu m g dt, excess (|J_t| - mu J_n) / |J|
    jt, jn = 2 * 0.5, 1.0
    assert mom.worst_value == pytest.approx((jt - 0.5 * jn) / math.hypot(jt, jn), rel=1e-6)


def test_momentum_flags_a_box_held_on_a_ramp_steeper_than_its_friction():
    theta, mu = math.radians(30), 0.3  # tan 30 deg = 0.577 > 0.3: it must slide
    mom = results(ramp_box(theta, mu, slide=False))["momentum"]
    assert not mom.passed
    # theory: J = m g dt (vertical); J_n = J cos theta, |J_t| = J sin theta
    assert mom.worst_value == pytest.approx(math.sin(theta) - mu * math.cos(theta), rel=1e-9)
    assert "static box 0" in mom.findings[0].message


def test_momentum_flags_logged_impulse_outside_cone():
    traj = resting_box()
    traj.contacts.friction_impulse[5] = (0.6 * traj.contacts.normal_impulse[5], 0, 0)
    mom = results(traj)["momentum"]
    assert not mom.passed
    assert any("logged contact" in f.message for f in mom.findings)


def test_momentum_flags_kick_with_nothing_in_reach():
    traj = ballistic()
    k = 50
    traj.linear_momentum[k:, 0, 0] += 0.2
    traj.velocity[k:, 0, 0] += 0.1
    mom = results(traj)["momentum"]
    assert not mom.passed
    (f,) = [f for f in mom.findings if "linear" in f.message]
    assert "free flight" in f.message and "touching nothing" in f.message and f.t == pytest.approx(traj.t[k])


def test_penetration_flags_poses_below_ground_at_rest():
    sink = 3e-3
    traj = resting_box(sink=sink, sink_from=1.0)
    res = results(traj)
    pen = res["penetration"]
    assert not pen.passed
    assert pen.worst_value == pytest.approx(sink, rel=1e-9)
    assert pen.unit == "m"
    assert pen.worst_t == pytest.approx(1.0)
    assert pen.stats["rest_depth_max_m"] == pytest.approx(sink, rel=1e-9)
    # mean over the rest: half the samples at depth `sink` (t >= 1 s of [0, 2] s)
    t = traj.t
    assert pen.stats["rest_depth_mean_m"] == pytest.approx(sink * (t >= 1.0).mean(), rel=1e-9)
    assert "tunneling" not in flagged(traj)


@pytest.mark.parametrize("kind", ["step", "spike"])
def test_penetration_single_kick_is_not_jitter(kind):
    """A resting box whose velocity changes once (struck) is not jittering: a step makes two
    alternating second differences, a spike three, and jitter must persist over four."""
    pen = results(resting_box(kick=(kind, 0.04)))["penetration"]
    assert not any("jitters" in f.message for f in pen.findings), pen.findings
    assert pen.stats["jitter_max_mps"] == 0.0
    # the same velocities flipping every sample are jitter, at their full amplitude
    pen = results(resting_box(shake=0.04))["penetration"]
    assert pen.stats["jitter_max_mps"] == pytest.approx(0.04, rel=1e-9)


def hopping_ball(rows_in_the_air: bool):
    """A ball (r = 0.08 m, 0.2 kg) resting on the ground is struck at t = 0.5 s and hops: at two
    samples it is 0.193 and 0.041 mm up with the velocities of samples/mixed.toml's ball1 struck
    by ball4 (rblog, logged at 100 Hz; an every-step log of the same run shows the strike, the
    0.22 mm hop and two landings within 25 ms). A box rests far away, so the log carries contact
    rows at every sample. rows_in_the_air: the engine's rows for the ball at the two samples
    (False: none, as rblog logs a body touching nothing)."""
    r_, hh, m = 0.08, 0.1, 0.2
    model = make_model([dict(shape="sphere", size=r_, mass=m),
                        dict(shape="box", size=(hh, hh, hh), mass=1.0)], ground=True)
    t = times(1.0)
    k0 = int(np.searchsorted(t, 0.5))
    x = np.broadcast_to([[0.0, 0.0, r_], [1.0, 0.0, hh]], (len(t), 2, 3)).copy()
    v = np.zeros((len(t), 2, 3))
    x[k0, 0, 2] += 0.193e-3
    x[k0 + 1, 0, 2] += 0.041e-3
    v[k0, 0] = (-0.04275, -0.00609, -0.02211)
    v[k0 + 1, 0] = (0.0004, -0.00005, -0.01632)
    r = np.broadcast_to(np.eye(3), (len(t), 2, 3, 3))
    rows = []
    step = np.round(t / DT).astype(np.int64)
    for k in range(len(t)):
        if rows_in_the_air or k not in (k0, k0 + 1):
            rows.append(dict(step=step[k], t=t[k], a=0, b=STATIC_BODY, point=(0.0, 0.0, 0.0),
                             normal=(0, 0, 1), sep=0.0, jn=m * GM * DT, kind=CONTACT_RESTING))
        rows.append(dict(step=step[k], t=t[k], a=1, b=STATIC_BODY, point=(1.0, 0.0, 0.0),
                         normal=(0, 0, 1), sep=0.0, jn=GM * DT, kind=CONTACT_RESTING))
    return build(model, t, x, v, r, np.zeros((len(t), 2, 3)), contacts=contacts_of(rows)), v[:, 0]


def test_penetration_body_in_the_air_is_not_jitter():
    """A struck ball that hops between two samples is not jittering: where the engine logs no
    contact of the ball at all (at samples whose other rows show that it logs contacts) it
    touches nothing, as a support whose rows carry no load. The same log with rows claiming
    contact at those samples is jitter by the rule's definition: |v+ - 2 v + v-| / 4, its least
    over four consecutive samples."""
    traj, v = hopping_ball(rows_in_the_air=False)
    pen = results(traj)["penetration"]
    assert not any("jitters" in f.message for f in pen.findings), pen.findings
    traj, v = hopping_ball(rows_in_the_air=True)
    pen = results(traj)["penetration"]
    osc = np.zeros(len(v))
    osc[1:-1] = 0.25 * np.linalg.norm(v[2:] - 2.0 * v[1:-1] + v[:-2], axis=1)
    expect = np.lib.stride_tricks.sliding_window_view(osc, 4).min(axis=1).max()
    assert expect == pytest.approx(4.08e-3, rel=1e-3)  # the mixed.toml finding's value
    (f,) = [f for f in pen.findings if "jitters" in f.message]
    assert f.value == pytest.approx(expect, rel=1e-9)


def test_penetration_flags_jitter_and_creep():
    jit = results(resting_box(shake=0.01))["penetration"]
    assert not jit.passed and any("jitters" in f.message for f in jit.findings)
    assert jit.stats["jitter_max_mps"] == pytest.approx(0.01, rel=1e-9)
    slide = 1e-3
    traj = resting_box(slide=slide)
    crp = results(traj)["penetration"]
    assert not crp.passed and any("creeps" in f.message for f in crp.findings)
    # the box slips at a steady speed from its first sample: none of it is a settling slide, so
    # the whole stay counts (before: from t = SETTLE_S on, 1.9 of the 2 mm)
    assert crp.stats["creep_max_m"] == pytest.approx(slide * traj.t[-1], rel=1e-9)


def test_penetration_transient_depth_in_an_impact():
    traj, _ = bouncing_ball()
    k = int(np.searchsorted(traj.t, 0.4515)) + 0  # first sample after the first impact
    traj.position[k, 0, 2] = 0.1 - 0.02  # 2 cm into the ground (tol: 25% of r = 2.5 cm, 5 mm)
    pen = results(traj)["penetration"]
    assert not pen.passed
    assert pen.findings[0].value == pytest.approx(0.02, rel=1e-9)


def test_tunneling_flags_frame_through_the_ground():
    r_, z0, v0 = 0.1, 2.0, -20.0
    model = make_model([dict(shape="sphere", size=r_, mass=1.0)], ground=True)
    t = times(0.2)
    z = z0 + v0 * t - 0.5 * GM * t ** 2  # ghost ball: falls through
    x = np.stack([np.zeros_like(t), np.zeros_like(t), z], axis=1)[:, None]
    v = np.stack([np.zeros_like(t), np.zeros_like(t), v0 - GM * t], axis=1)[:, None]
    traj = build(model, t, x, v, np.broadcast_to(np.eye(3), (len(t), 1, 3, 3)),
                 np.zeros((len(t), 1, 3)))
    res = results(traj)
    tun = res["tunneling"]
    assert not tun.passed
    k = int(np.nonzero(z < 0)[0][0])
    (f,) = tun.findings
    assert f.value == pytest.approx(-z[k], rel=1e-12) and f.t == pytest.approx(t[k])
    assert "the ground" in f.message


def test_tunneling_flags_passing_through_a_thin_wall_between_samples():
    model = make_model([dict(shape="sphere", size=0.05, mass=1.0)], gravity=(0, 0, 0),
                       statics=[dict(position=(0, 0, 0.5), half=(0.02, 1.0, 1.0))])
    t = times(0.1)
    xs = -1.35 + 30.0 * t  # samples at x = -0.15 and +0.15: both clear of the wall
    x = np.stack([xs, np.zeros_like(t), np.full_like(t, 0.5)], axis=1)[:, None]
    v = np.broadcast_to([30.0, 0.0, 0.0], (len(t), 1, 3))
    traj = build(model, t, x, v, np.broadcast_to(np.eye(3), (len(t), 1, 3, 3)),
                 np.zeros((len(t), 1, 3)))
    tun = results(traj)["tunneling"]
    assert not tun.passed
    (f,) = tun.findings
    assert "static box 0" in f.message
    assert f.t == pytest.approx(0.05)
    # the path's midpoint inside the wall is its centre plane: depth = half thickness
    assert f.value == pytest.approx(0.02, rel=1e-9)
    # no sample overlaps: penetration sees nothing
    assert results(traj)["penetration"].passed


def test_tunneling_flags_bodies_passing_through_each_other():
    model = make_model([dict(shape="sphere", size=0.1, mass=1.0),
                        dict(shape="sphere", size=0.1, mass=1.0)], gravity=(0, 0, 0))
    t = times(0.1)
    xa = -1.1 + 20 * t  # relative position -0.2 at t = 0.05 s and +0.2 at 0.06 s
    x = np.stack([np.stack([xa, 0 * t, 0 * t], 1), np.stack([-xa, 0 * t, 0 * t], 1)], axis=1)
    v = np.zeros_like(x)
    v[:, 0, 0], v[:, 1, 0] = 20.0, -20.0
    traj = build(model, t, x, v, np.broadcast_to(np.eye(3), (len(t), 2, 3, 3)),
                 np.zeros((len(t), 2, 3)))
    tun = results(traj)["tunneling"]
    assert not tun.passed
    (f,) = tun.findings
    assert f.bodies == [0, 1] and f.t == pytest.approx(0.06)
    assert f.value == pytest.approx(0.1, abs=1e-12)  # closest approach 0 vs 0.5 (0.1 + 0.1)


def test_energy_flags_energy_growing_over_time():
    rate = 0.2  # rad/s tilt of the top's axis away from its cone: E changes, L does not
    traj = symmetric_top(tilt_rate=rate)
    res = results(traj)
    # the planted tilt turns the orientation without an angular velocity: consistency sees it too
    assert {k for k, r in res.items() if not r.passed} == {"energy", "consistency"}
    en = res["energy"]
    # theory: E(t) = |L|^2 / (2 Ip) + L3(t)^2 (1/I3 - 1/Ip) / 2, L3(t) = L.(R(t) e3)
    h, m, inertia, ip, i3, r0, l_world = top_params()
    l3 = np.einsum("i,ti->t", l_world, traj.rotation[:, 0, :, 2])
    e = l_world @ l_world / (2 * ip) + 0.5 * l3 ** 2 * (1 / i3 - 1 / ip)
    expect = np.abs(e - e[0]).max() / e.max()
    assert en.worst_value == pytest.approx(expect, rel=1e-9)
    assert en.findings[0].bodies == [0]


def test_energy_skips_bodies_with_torque():
    traj = symmetric_top()
    traj.model.body_torque_world[:] = (0.0, 0.0, 0.1)
    en = results(traj, only=["energy"])["energy"]
    assert en.skipped and en.passed and "torque" in en.reason


def test_constant_applied_force_is_conservative():
    """A body pushed by a constant force besides gravity: energy with the force's potential -F.x
    is conserved, and momentum changes by (m g + F) dt: clean."""
    f_ = np.array([2.0, -1.0, 0.0])
    model = make_model([dict(shape="sphere", size=0.1, mass=2.0, force=f_)])
    t = times(1.0)
    a = G + f_ / 2.0
    v0 = np.array([0.0, 1.0, 3.0])
    x = (np.array([0, 0, 5.0]) + v0 * t[:, None] + 0.5 * a * t[:, None] ** 2)[:, None]
    v = (v0 + a * t[:, None])[:, None]
    traj = build(model, t, x, v, np.broadcast_to(np.eye(3), (len(t), 1, 3, 3)),
                 np.zeros((len(t), 1, 3)))
    assert_clean(traj)


# ---------------------------------------------------------------------------------------------
# geometry against hand-computed cases


def test_box_box_separation():
    i3 = np.eye(3)[None]
    h = np.full((1, 3), 0.5)
    sep, n, _ = geometry.box_box(np.array([[0.9, 0.2, 0.0]]), i3, h, np.zeros((1, 3)), i3, h)
    assert sep[0] == pytest.approx(-0.1) and np.allclose(n[0], [1, 0, 0])
    sep, n, _ = geometry.box_box(np.array([[0.0, 0.0, -1.3]]), i3, h, np.zeros((1, 3)), i3, h)
    assert sep[0] == pytest.approx(0.3) and np.allclose(n[0], [0, 0, -1])
    # a cube turned 45 degrees about z next to an aligned one: its edge reaches sqrt(2)/2
    r45 = rot([0, 0, 1], math.pi / 4)
    sep, n, _ = geometry.box_box(np.array([[1.6, 0.0, 0.0]]), r45, h, np.zeros((1, 3)), i3, h)
    assert sep[0] == pytest.approx(1.6 - 0.5 - math.sqrt(0.5))


def test_sphere_box_separation():
    i3 = np.eye(3)[None]
    h = np.array([[0.5, 0.4, 0.3]])
    r = np.array([0.1])
    sep, n, p = geometry.sphere_box(np.array([[1.0, 1.0, 0.0]]), r, np.zeros((1, 3)), i3, h)
    assert sep[0] == pytest.approx(math.hypot(0.5, 0.6) - 0.1)
    sep, n, p = geometry.sphere_box(np.array([[0.0, 0.0, 0.25]]), r, np.zeros((1, 3)), i3, h)
    assert sep[0] == pytest.approx(-(0.05 + 0.1)) and np.allclose(n[0], [0, 0, 1])


def test_box_on_plane_support():
    theta = 0.3
    h = (0.2, 0.1, 0.05)
    model = make_model([dict(shape="box", size=h, mass=1.0)], ground=True)
    r = rot([1, 0, 0], theta)[None]
    pos = np.array([[[0.0, 0.0, 0.5]]])
    sep, height = geometry.plane_separation(model, pos, r)
    assert sep[0, 0] == pytest.approx(0.5 - 0.1 * math.sin(theta) - 0.05 * math.cos(theta))
    assert height[0, 0] == 0.5


def test_broadphase_finds_pairs_like_brute_force():
    rng = np.random.default_rng(3)
    n, t_n = 40, 6
    bodies = [dict(shape="sphere" if i % 2 else "box", size=(0.2, 0.1, 0.15), mass=1.0)
              for i in range(n)]
    model = make_model(bodies)
    pos = rng.uniform(-1.5, 1.5, (t_n, n, 3))
    r = quat_of(Rotation.random(t_n * n, random_state=4).as_matrix().reshape(t_n, n, 3, 3))
    rm = geometry.quat_to_matrix(r)
    prox = geometry.proximity(model, pos, rm, pad=0.0)
    rho = geometry.bounding_radius(model)
    got = set(zip(prox.iv_k.tolist(), prox.iv_a.tolist(), prox.iv_b.tolist()))
    lo = np.minimum(pos[:-1], pos[1:]) - rho[None, :, None]
    hi = np.maximum(pos[:-1], pos[1:]) + rho[None, :, None]
    mid = 0.5 * (pos[:-1] + pos[1:])
    reach = rho[None] + 0.5 * np.linalg.norm(pos[1:] - pos[:-1], axis=-1)
    want = set()
    for k in range(t_n - 1):
        for a in range(n):
            for b in range(a + 1, n):
                if (np.all(lo[k, a] <= hi[k, b]) and np.all(lo[k, b] <= hi[k, a])
                        and np.linalg.norm(mid[k, a] - mid[k, b]) <= reach[k, a] + reach[k, b]):
                    want.add((k, a, b))
    assert got == want and len(want) > 20


# ---------------------------------------------------------------------------------------------
# API


def test_check_selection_and_tolerance_overrides():
    traj = resting_box(sink=3e-3, sink_from=0.0)
    assert [r.analyzer for r in check(traj)] == list(ANALYZERS)
    assert [r.analyzer for r in check(traj, only=["penetration", "drift"])] == ["drift",
                                                                                "penetration"]
    assert "penetration" not in [r.analyzer for r in check(traj, skip=["penetration"])]
    # the same fault passes with a looser tolerance
    assert results(traj, tolerances={"penetration.depth_m": 4e-3, "penetration.depth_frac": 1}
                   )["penetration"].passed
    with pytest.raises(CheckOptionError, match="unknown tolerance"):
        check(traj, tolerances={"penetration.depth": 1})
    with pytest.raises(CheckOptionError, match="unknown analyzer"):
        check(traj, only=["nope"])
    with pytest.raises(CheckOptionError, match="number"):
        check(traj, tolerances={"energy.drift_rel": "lots"})
    assert set(default_tolerances()) >= {"drift.ortho_error", "penetration.depth_m"}


def test_result_to_dict_is_json_and_findings_name_bodies():
    traj = resting_box(sink=3e-3)
    (pen,) = check(traj, only=["penetration"])
    d = pen.to_dict(traj.model)
    s = json.loads(json.dumps(d))
    assert s["passed"] is False and s["unit"] == "m"
    assert s["findings"][0]["body_names"] == ["b0"]
    assert s["worst_step"] == int(traj.step[np.searchsorted(traj.t, 1.0)])


def test_nonfinite_state_is_reported_and_the_rest_analyzed():
    traj = ballistic()
    k = 40
    traj.position[k:, 0, 2] = np.nan
    res = results(traj)
    d = res["drift"]
    assert not d.passed
    assert "non-finite" in d.findings[0].message and d.findings[0].t == pytest.approx(traj.t[k])
    # the samples before are clean
    assert all(r.passed for name, r in res.items() if name != "drift")
    json.dumps(d.to_dict())


def test_skips_when_the_log_lacks_what_is_needed():
    model = make_model([dict(shape="sphere", size=0.1, mass=1.0)], gravity=(0, 0, 0))
    t = times(0.1)
    traj = build(model, t, np.zeros((len(t), 1, 3)), np.zeros((len(t), 1, 3)),
                 np.broadcast_to(np.eye(3), (len(t), 1, 3, 3)), np.zeros((len(t), 1, 3)))
    res = results(traj)
    assert res["penetration"].skipped and res["tunneling"].skipped
    assert all(r.passed for r in res.values())
    one = traj.slice(slice(0, 1))
    res1 = results(one)
    assert res1["momentum"].skipped and res1["energy"].skipped and not res1["drift"].skipped
