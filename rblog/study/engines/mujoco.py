"""A scene in MuJoCo: MJCF from the body table, stepping, state and contacts for the Recorder.

Translation (see rblog/study/engines/__init__.py for the common part):

* each body: ``<body>`` with a ``<freejoint/>``, an explicit ``<inertial>`` (mass, principal
  moments, at the body origin = centre of mass: MuJoCo's own geom-density inertia is never used)
  and one sphere, box, capsule, cylinder or mesh geom (``size="r h"``: MuJoCo's capsule and
  cylinder are the scene's, radius and half length along the geom's z = the body's z), or a
  compound's parts as several geoms of the body at their ``pos`` / ``quat``; the ground: a plane
  geom turned so that its +z is the scene's ground normal; static boxes: box geoms of the world
  body. Constant forces/torques: ``xfrc_applied`` (world frame, at the centre of mass).
* collision groups: group 0 touches everything (contype bit 0, conaffinity all bits), group g
  (1..30) has contype bit g and conaffinity bits 0 and g, so two different non-zero groups never
  touch; more than 30 groups exit 2.
* materials: MuJoCo combines two geoms' friction by the max and their ``solref`` by a
  solmix-weighted mean. Each geom gets its own friction (``condim`` 3: sliding only; 1 when
  frictionless) and a restitution through the direct solref form ``solref="-k -b"``: reference
  acceleration ``-b v - k r`` of a spring-damper with ``omega0 = sqrt(k) = omega_dt / dt``,
  ``b = 2 zeta omega0`` and the damping ratio ``zeta(e)`` of :func:`zeta_of_restitution` (the
  spring-damper that lets go when its force vanishes, as MuJoCo's contact does), impedance 0.99
  (``solimp="0.99 0.99 0.001"``) so the soft constraint follows the reference. Where the
  default combination would differ from rblog's effective pair values (different materials), an
  explicit ``<contact><pair>`` with the effective friction and solref overrides it.
* state and contacts: read by :mod:`rblog.adapters.mujoco` (the one translation of MuJoCo's
  conventions): after each logged step ``d.contact`` holds the contacts found at the start of that
  step (separation ``dist`` before the solve) and ``efc_force`` the solved force over the step;
  the rows log impulse = force * dt, decoded from the pyramidal (or elliptic) cone rows.
"""

from __future__ import annotations

import math

import numpy as np

from rblog.contract.model import GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER, GEOM_MESH, GEOM_SPHERE
from rblog.study.engines import EngineMissing, EngineUnsupported, body_mesh, body_parts, geom_mesh, \
    initial_world_omega, pair_materials, parse_options, z_to

#: MJCF geom type and size of each body geom the translation takes (sizes: rblog.contract.model)
MJCF_GEOM = {GEOM_SPHERE: ("sphere", lambda s: s[:1]), GEOM_BOX: ("box", lambda s: s),
             GEOM_CAPSULE: ("capsule", lambda s: s[:2]), GEOM_CYLINDER: ("cylinder", lambda s: s[:2]),
             GEOM_MESH: ("mesh", None)}

#: omega0 dt of the contact spring (explicit stepping is unstable near 2; 0.2 resolves an impact
#: in ~15 steps; the same value rblog.study.peers uses)
DEFAULT_OMEGA_DT = 0.2
#: solimp of every contact: impedance 0.99 at any depth (dmin, dmax, width m)
SOLIMP = "0.99 0.99 0.001"
#: most explicit <pair> elements (geom pairs with mixed materials) before giving up
MAX_EXPLICIT_PAIRS = 20000
#: most collision groups (contype/conaffinity have 32 bits; bit 0 is "touches everything")
MAX_GROUPS = 30

OPTIONS = {
    "integrator": "Euler (default), RK4, implicit, implicitfast",
    "solver": "PGS, CG, Newton (default)",
    "cone": "pyramidal (default), elliptic",
    "iterations": "solver iterations (default 100)",
    "ls_iterations": "line-search iterations",
    "tolerance": "solver tolerance",
    "noslip_iterations": "no-slip iterations (default 0)",
    "impratio": "frictional-to-normal impedance ratio",
    "omega_dt": f"contact spring omega0 * dt (default {DEFAULT_OMEGA_DT})",
}


def restitution_of_zeta(zeta: float) -> float:
    """Rebound of a linear spring-damper contact that lets go when its force vanishes.

    Penetration r >= 0 obeys r'' + 2 zeta w r' + w^2 r = 0 from r = 0, r' = v0; the contact
    pushes with m (w^2 r + 2 zeta w r') and lets go at the first t_c > 0 where that force is 0
    (still r > 0 deep: MuJoCo's soft contact, whose force cannot pull). With w = 1 (e does not
    depend on w) and d = sqrt(|1 - zeta^2|):

    * zeta < 1: r = e^{-zeta t} sin(d t) / d; the force vanishes at d t_c = pi - atan2(2 zeta d,
      1 - 2 zeta^2), e = -r'(t_c) / v0 = e^{-zeta t_c} (zeta sin(d t_c) / d - cos(d t_c));
    * zeta > 1: roots s1,2 = -zeta +- d, r = (e^{s1 t} - e^{s2 t}) / (2 d); the force vanishes at
      e^{2 d t_c} = (1 + 2 zeta s2) / (1 + 2 zeta s1) = (2 zeta^2 - 1 + 2 zeta d)^2 (the two
      factors multiply to 1), e = -r'(t_c) / v0.

    e falls from 1 (zeta = 0) through e^-2 (zeta = 1) towards 0 as zeta grows; an oscillator
    released at r = 0 instead rebounds with exp(-pi zeta / d), more than this for every zeta.
    """
    z = float(zeta)
    if z <= 0.0:
        return 1.0
    if abs(z - 1.0) < 1e-9:
        z = 1.0 + 1e-9  # e is continuous through critical damping
    if z < 1.0:
        d = math.sqrt(1.0 - z * z)
        th = math.pi - math.atan2(2.0 * z * d, 1.0 - 2.0 * z * z)
        return math.exp(-z * th / d) * (z * math.sin(th) / d - math.cos(th))
    d = math.sqrt(z * z - 1.0)
    s1, s2 = -z + d, -z - d
    tc = math.log(2.0 * z * z - 1.0 + 2.0 * z * d) / d
    return -(s1 * math.exp(s1 * tc) - s2 * math.exp(s2 * tc)) / (2.0 * d)


def zeta_max(omega_dt: float) -> float:
    """Largest damping ratio the translation sets: b dt = 2 zeta omega_dt <= 1 (past b dt ~ 2
    MuJoCo's step reverses the approach velocity each step and the contact blows up; at
    omega_dt 0.2 that is zeta 2.5, e 0.033)."""
    return 0.5 / float(omega_dt)


def zeta_of_restitution(e: float, omega_dt: float | None = None) -> float:
    """Damping ratio whose force-released contact (:func:`restitution_of_zeta`) rebounds with e,
    by bisection (e falls monotonically in zeta), capped at :func:`zeta_max` (an e below that
    cap's rebound, e = 0 among them, gets the cap)."""
    hi = zeta_max(DEFAULT_OMEGA_DT if omega_dt is None else omega_dt)
    e = float(e)
    if e >= 1.0:
        return 0.0
    if e <= restitution_of_zeta(hi):
        return hi
    lo = 0.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if restitution_of_zeta(mid) > e:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-15 * hi:
            break
    return 0.5 * (lo + hi)


def _f(x) -> str:
    return " ".join(repr(float(v)) for v in np.atleast_1d(x))


class MujocoRun:
    """One scene in MuJoCo: ``step(k)``, ``state()``, ``contacts(step)``, ``close()``."""

    #: frame of the angular velocity ``state()`` returns
    OMEGA_FRAME = "world"

    def __init__(self, scene, dt: float, options=()):
        try:
            import mujoco
        except Exception as e:  # noqa: BLE001
            raise EngineMissing("mujoco", e) from None
        self.mj = mujoco
        self.version = mujoco.__version__
        self.scene, self.dt = scene, dt
        opts = parse_options("mujoco", options, OPTIONS)
        self.omega_dt = float(opts.pop("omega_dt", DEFAULT_OMEGA_DT))
        self.xml, self.n_pairs = self.mjcf(opts)
        try:
            self.m = mujoco.MjModel.from_xml_string(self.xml)
        except ValueError as e:
            raise EngineUnsupported("mujoco", f"the model ({str(e).splitlines()[0]})") from None
        self.d = mujoco.MjData(self.m)
        model, st = scene.model, scene.state
        n = model.n_bodies
        w_world = initial_world_omega(scene)
        for i in range(n):
            self.d.qpos[7 * i:7 * i + 3] = st.position[i]
            self.d.qpos[7 * i + 3:7 * i + 7] = st.quat_wxyz[i] / np.linalg.norm(st.quat_wxyz[i])
            self.d.qvel[6 * i:6 * i + 3] = st.linear_momentum[i] / model.body_mass[i]
            self.d.qvel[6 * i + 3:6 * i + 6] = st.rotation[i].T @ w_world[i]  # body frame
        self.d.xfrc_applied[1:n + 1, :3] = model.body_force_world
        self.d.xfrc_applied[1:n + 1, 3:] = model.body_torque_world
        mujoco.mj_forward(self.m, self.d)
        from rblog.adapters.mujoco import Kinematics, inspect, settings

        # where each body is and its state: the adapter's one translation (each body's
        # inertial frame is its body frame here: <inertial pos="0 0 0" diaginertia=...>)
        self.layout = inspect(self.m, self.d)[1]
        self.kinematics = Kinematics(self.m, self.layout)
        # MuJoCo's solver settings as the adapters read them, and what this translation of the
        # scene sets on top
        self.settings = {
            **settings(self.m),
            "contact_model": "soft: direct solref -k -b, k = (omega_dt/dt)^2, b = 2 zeta(e) sqrt(k)",
            "omega_dt": self.omega_dt, "solimp": SOLIMP, "condim": 3, "margin": 0.0,
            "explicit_pairs": self.n_pairs,
            "contact_rows": {"separation": "before the step (contacts found at its start)",
                             "impulse": "solved force over the step * dt", "speculative": False},
            "ignored_scene_tables": ["contact"] if scene.contact else [],
        }

    # --- model ------------------------------------------------------------------------------
    def _solref(self, e: float) -> str:
        e = float(e)
        omega0 = self.omega_dt / self.dt
        k = omega0 * omega0
        b = 2.0 * zeta_of_restitution(e, self.omega_dt) * omega0
        return f"{-k!r} {-b!r}"

    def _contact_attrs(self, e: float, mu: float) -> str:
        e, mu = float(e), float(mu)
        fr = f' friction="{max(mu, 0.0)!r} 0 0" condim="{3 if mu > 0 else 1}"'
        return f' solref="{self._solref(e)}" solimp="{SOLIMP}"' + fr

    def mjcf(self, opts: dict) -> tuple[str, int]:
        model = self.scene.model
        n = model.n_bodies
        groups = sorted({int(g) for g in model.body_group if g != 0})
        if len(groups) > MAX_GROUPS:
            raise EngineUnsupported("mujoco", f"{len(groups)} collision groups (body.group): "
                                    f"contype/conaffinity bitmasks hold at most {MAX_GROUPS}")
        bit = {g: 1 << (k + 1) for k, g in enumerate(groups)}
        all_bits = (1 << (len(groups) + 1)) - 1

        def filt(g: int) -> str:
            if g == 0:
                return f' contype="1" conaffinity="{all_bits}"'
            return f' contype="{bit[g]}" conaffinity="{bit[g] | 1}"'

        opt_attrs = " ".join(f'{k}="{v}"' for k, v in opts.items())
        parts = ['<mujoco model="rblog">',
                 f'<option timestep="{self.dt!r}" gravity="{_f(model.gravity)}" {opt_attrs}/>',
                 '<size memory="64M"/>', "<worldbody>"]
        if model.ground:
            q = z_to(model.ground_normal)
            pos = np.asarray(model.ground_normal, float) / np.linalg.norm(model.ground_normal) \
                * model.ground_offset
            parts.append(f'<geom name="ground" type="plane" size="0 0 1" pos="{_f(pos)}" quat="{_f(q)}"'
                         f'{filt(0)}{self._contact_attrs(model.ground_restitution, model.ground_friction)}/>')
        for j in range(len(model.static_box_position)):
            parts.append(
                f'<geom name="static{j}" type="box" size="{_f(model.static_box_half_extents[j])}" '
                f'pos="{_f(model.static_box_position[j])}" quat="{_f(model.static_box_quat_wxyz[j])}"'
                f'{filt(0)}{self._contact_attrs(model.static_box_restitution[j], model.static_box_friction[j])}/>')
        assets = []
        geom_names = []  # each body's geom names (g{i}; a compound's parts g{i}_{k})
        for i, body in enumerate(body_parts(model, "mujoco", tuple(MJCF_GEOM))):
            geoms, names_i = [], []
            for k, (code, size, pos, quat, g) in enumerate(body):
                kind, sz = MJCF_GEOM[code]
                name = f"g{i}" if len(body) == 1 else f"g{i}_{k}"
                mesh = f"mesh{i}" if len(body) == 1 else f"mesh{i}_{k}"
                if code == GEOM_MESH:
                    # the hull of the vertices is MuJoCo's collision shape of a mesh; its compiler
                    # moves the mesh into its own frame and the geom with it (the world shape
                    # stays)
                    v = body_mesh(model, i)[0] if len(body) == 1 else \
                        geom_mesh(model, g, model.body_name[i])
                    assets.append(f'<mesh name="{mesh}" vertex="{_f(v.ravel())}"/>')
                    geom = f'type="mesh" mesh="{mesh}"'
                else:
                    geom = f'type="{kind}" size="{_f(sz(size))}"'
                # a compound's part at its pose in the body frame (MuJoCo's geom pos / quat)
                pose = "" if len(body) == 1 else f' pos="{_f(pos)}" quat="{_f(quat)}"'
                geoms.append(f'<geom name="{name}" {geom}{pose}{filt(int(model.body_group[i]))}'
                             f'{self._contact_attrs(model.body_restitution[i], model.body_friction[i])}/>')
                names_i.append(name)
            geom_names.append(names_i)
            parts.append(
                f'<body name="b{i}"><freejoint/>'
                f'<inertial pos="0 0 0" mass="{float(model.body_mass[i])!r}" '
                f'diaginertia="{_f(model.body_inertia_diag[i])}"/>' + "".join(geoms) + '</body>')
        parts.append("</worldbody>")
        if assets:
            parts.insert(parts.index("<worldbody>"), "<asset>" + "".join(assets) + "</asset>")
        # explicit pairs where MuJoCo's own mix differs from rblog's effective pair material
        kinds, e_eff, mu_eff, can = pair_materials(model)
        names = list(geom_names)  # per item of pair_materials: its geoms
        if model.ground:
            names.append(["ground"])
        names += [[f"static{j}"] for j in range(len(model.static_box_position))]
        e_own = np.concatenate([model.body_restitution, [model.ground_restitution] if model.ground else [],
                                model.static_box_restitution])
        mu_own = np.concatenate([model.body_friction, [model.ground_friction] if model.ground else [],
                                 model.static_box_friction])
        differ = (e_own[:, None] != e_own[None, :]) | (mu_own[:, None] != mu_own[None, :])
        ii, jj = np.nonzero(np.triu(can & differ, 1))
        geom_pairs = [(ga, gb_, a, b) for a, b in zip(ii.tolist(), jj.tolist())
                      for ga in names[a] for gb_ in names[b]]
        if len(geom_pairs) > MAX_EXPLICIT_PAIRS:
            raise EngineUnsupported("mujoco", f"materials: {len(geom_pairs)} geom pairs need an "
                                    f"explicit <pair> for rblog's combine rule (at most "
                                    f"{MAX_EXPLICIT_PAIRS})")
        if geom_pairs:
            parts.append("<contact>")
            for g1, g2, a, b in geom_pairs:
                mu = float(mu_eff[a, b])
                parts.append(f'<pair geom1="{g1}" geom2="{g2}" condim="{3 if mu > 0 else 1}" '
                             f'friction="{mu!r} {mu!r} 0 0 0" solref="{self._solref(float(e_eff[a, b]))}" '
                             f'solimp="{SOLIMP}"/>')
            parts.append("</contact>")
        parts.append("</mujoco>")
        return "".join(parts), len(geom_pairs)

    # --- stepping ---------------------------------------------------------------------------
    def step(self, k: int) -> None:
        self.mj.mj_step(self.m, self.d, nstep=int(k))

    def state(self):
        """(position (N,3), quat_wxyz (N,4), velocity (N,3), angular velocity (N,3)), world frame,
        centre of mass: rblog.adapters.mujoco.Kinematics (xipos, ximat, cvel) at qpos/qvel."""
        x, _, v, w = self.kinematics(self.d.qpos, self.d.qvel)
        return x, self.kinematics.quat_wxyz(), v, w

    def contacts(self, step: int):
        """The contacts of the step that ended at ``step``, in the contract's convention
        (rblog.adapters.mujoco's rows: mj_contactForce's force on geom2 x dt)."""
        from rblog.adapters.mujoco import contacts

        return contacts(self.m, self.d, self.layout, step)

    def close(self):
        pass
