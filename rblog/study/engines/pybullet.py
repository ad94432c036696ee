"""A scene in pybullet (Bullet): bodies, stepping, state and contacts for the Recorder.

Translation (common part: rblog/study/engines/__init__.py):

* each body: ``createMultiBody`` with a sphere, box, capsule, cylinder or convex hull collision
  shape (``GEOM_CAPSULE`` / ``GEOM_CYLINDER``: ``radius`` and ``height`` = 2 half_length, the
  capsule's cylinder part, along the shape's z = the body's z; a hull: ``GEOM_MESH`` with the
  body-frame ``vertices``, Bullet's convex hull of them, its collision margin set to 0: Bullet
  grows a hull by its margin, 1 mm by default), or a compound's parts as one
  ``createCollisionShapeArray`` at their poses in the body frame (no hull parts), the scene's
  mass and
  ``localInertiaDiagonal`` (principal moments, body frame: Bullet's own from the shape is
  replaced), linear/angular damping 0 and
  rolling/spinning friction 0; the ground: a static plane turned so its +z is the ground normal;
  static boxes: static multibodies. Constant force/torque: ``applyExternalForce`` /
  ``applyExternalTorque`` in the world frame before every step (Bullet clears them after each).
* collision groups: ``setCollisionFilterGroupMask`` with the same bit layout as MuJoCo's
  contype/conaffinity (group 0 touches all; groups 1..30 touch group 0 and themselves).
* materials: Bullet multiplies the two restitutions and the two frictions of a contact. Friction:
  each feature gets ``sqrt(mu)``, so a pair gets ``sqrt(mu_a mu_b)``, rblog's rule, exactly.
  Restitution: per-feature values r with ``r_a r_b = max(e_a, e_b)`` for every pair that can touch
  are solved in log space (least squares); if no such values exist within RESTITUTION_REL, the run
  exits 2 naming the pair (Bullet has no per-pair restitution).
* state, contacts and impulses: read after every step by :class:`rblog.adapters.pybullet.Stepper`,
  the one translation of Bullet's conventions (``impulses()`` gives each interval's sums). After
  each step ``getContactPoints()`` lists the manifold points of that step:
  Bullet refreshes the manifolds by collision detection at the start of the step, so
  ``contactDistance`` is the separation before the step's solve and integration; ``normalForce``
  and the two lateral frictions are the applied impulses over the step divided by dt. Bullet also
  keeps speculative points (separated by up to its contact breaking threshold, no force): they are
  dropped, as rblog logs only points that pushed or touch.
"""

from __future__ import annotations

import numpy as np

from rblog.contract.model import GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER, GEOM_MESH, GEOM_SPHERE
from rblog.study.engines import EngineMissing, EngineUnsupported, body_mesh, body_parts, initial_world_omega, \
    pair_materials, parse_options, z_to

#: relative mismatch of a pair's restitution product r_a r_b from max(e_a, e_b) accepted
RESTITUTION_REL = 1e-9
#: restitution 0 in log space (Bullet treats any product below its threshold as no bounce)
RESTITUTION_FLOOR = 1e-6
MAX_GROUPS = 30

OPTIONS = {
    "integrator": "default (Bullet's semi-implicit Euler; the only one)",
    "numSolverIterations": "solver iterations (default 50)",
    "solverResidualThreshold": "solver residual threshold",
    "contactERP": "contact error reduction",
    "erp": "joint error reduction",
    "frictionERP": "friction error reduction",
    "useSplitImpulse": "0/1 split impulse (default 1)",
    "splitImpulsePenetrationThreshold": "split impulse threshold (m)",
    "restitutionVelocityThreshold": "no bounce below this approach speed (m/s)",
    "contactBreakingThreshold": "manifold point breaking distance (m)",
    "enableConeFriction": "0/1 cone friction",
    "deterministicOverlappingPairs": "0/1",
}
_INT_OPTIONS = {"numSolverIterations", "useSplitImpulse", "enableConeFriction",
                "deterministicOverlappingPairs"}


def restitution_factors(model) -> np.ndarray:
    """Per feature (bodies, ground, static boxes) r with r_a r_b = max(e_a, e_b) for every pair
    that can touch (least squares in log space, checked). Raises EngineUnsupported if none."""
    kinds, e_eff, _, can = pair_materials(model)
    ii, jj = np.nonzero(np.triu(can, 1))
    f = len(kinds)
    if len(ii) == 0:
        return np.ones(f)
    target = np.log(np.maximum(e_eff[ii, jj], RESTITUTION_FLOOR))
    a = np.zeros((len(ii), f))
    a[np.arange(len(ii)), ii] = 1.0
    a[np.arange(len(ii)), jj] = 1.0
    x, *_ = np.linalg.lstsq(a, target, rcond=None)
    got = np.exp(x[ii] + x[jj])
    want = np.maximum(e_eff[ii, jj], RESTITUTION_FLOOR)
    rel = np.abs(got - want) / want
    if rel.max() > RESTITUTION_REL * 1e3 and np.abs(got - want).max() > 1e-6:
        k = int(np.argmax(rel))
        name = lambda i: (repr(model.body_name[i]) if kinds[i] == "body" else kinds[i])  # noqa: E731
        raise EngineUnsupported(
            "pybullet", f"restitution max(e_a, e_b) for every pair: Bullet multiplies the two "
            f"restitutions and no per-body values give {float(want[k]):.3g} for {name(ii[k])} "
            f"with {name(jj[k])} (best {float(got[k]):.3g}) together with the other pairs")
    return np.exp(x)


class PybulletRun:
    """One scene in pybullet: ``step(k)``, ``state()``, ``contacts(step)``, ``close()``."""

    #: frame of the angular velocity ``state()`` returns (getBaseVelocity: world)
    OMEGA_FRAME = "world"

    def __init__(self, scene, dt: float, options=()):
        try:
            import pybullet as pb
        except Exception as e:  # noqa: BLE001
            raise EngineMissing("pybullet", e) from None
        from importlib.metadata import version

        self.pb = pb
        try:
            self.version = version("pybullet")
        except Exception:  # noqa: BLE001
            self.version = str(pb.getAPIVersion())
        self.scene, self.dt = scene, dt
        opts = parse_options("pybullet", options, OPTIONS)
        integ = opts.pop("integrator", "default")
        if integ != "default":
            raise EngineUnsupported("pybullet", f"integrator {integ!r} (Bullet has one: default)")
        model, st = scene.model, scene.state
        n = model.n_bodies
        groups = sorted({int(g) for g in model.body_group if g != 0})
        if len(groups) > MAX_GROUPS:
            raise EngineUnsupported("pybullet", f"{len(groups)} collision groups (body.group)")
        bodies = body_parts(model, "pybullet", (GEOM_SPHERE, GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER,
                                                GEOM_MESH))
        shapes = [body[0][:2] for body in bodies]
        r_fac = restitution_factors(model)
        mu_fac = np.sqrt(np.concatenate([model.body_friction,
                                         [model.ground_friction] if model.ground else [],
                                         model.static_box_friction]))
        cid = self.cid = pb.connect(pb.DIRECT)
        try:
            pb.setGravity(*map(float, model.gravity), physicsClientId=cid)
            pb.setTimeStep(dt, physicsClientId=cid)
            params = {"numSubSteps": 0}
            for k, v in opts.items():
                try:
                    params[k] = int(v) if k in _INT_OPTIONS else float(v)
                except ValueError:
                    raise EngineUnsupported("pybullet", f"option {k}={v!r} (expected a number)") from None
            pb.setPhysicsEngineParameter(**params, physicsClientId=cid)
            self.ids = []
            w_world = initial_world_omega(scene)
            bit = {g: 1 << (k + 1) for k, g in enumerate(groups)}
            all_bits = (1 << (len(groups) + 1)) - 1
            for i, (code, size) in enumerate(shapes):
                if len(bodies[i]) > 1:
                    col = _compound_shape(pb, cid, bodies[i], model.body_name[i])
                elif code == GEOM_SPHERE:
                    col = pb.createCollisionShape(pb.GEOM_SPHERE, radius=float(size[0]), physicsClientId=cid)
                elif code == GEOM_BOX:
                    col = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[float(x) for x in size],
                                                  physicsClientId=cid)
                elif code == GEOM_MESH:  # Bullet's btConvexHullShape of the vertices
                    col = pb.createCollisionShape(pb.GEOM_MESH,
                                                  vertices=body_mesh(model, i)[0].tolist(),
                                                  physicsClientId=cid)
                else:
                    col = pb.createCollisionShape(pb.GEOM_CAPSULE if code == GEOM_CAPSULE else pb.GEOM_CYLINDER,
                                                  radius=float(size[0]), height=2.0 * float(size[1]),
                                                  physicsClientId=cid)
                q = st.quat_wxyz[i] / np.linalg.norm(st.quat_wxyz[i])
                bid = pb.createMultiBody(baseMass=float(model.body_mass[i]), baseCollisionShapeIndex=col,
                                         basePosition=[float(x) for x in st.position[i]],
                                         baseOrientation=[float(q[1]), float(q[2]), float(q[3]), float(q[0])],
                                         physicsClientId=cid)
                if code == GEOM_MESH and len(bodies[i]) == 1:  # the hull itself: Bullet grows a
                    # convex hull by its margin
                    pb.changeDynamics(bid, -1, collisionMargin=0.0, physicsClientId=cid)
                pb.changeDynamics(bid, -1, localInertiaDiagonal=[float(x) for x in model.body_inertia_diag[i]],
                                  linearDamping=0.0, angularDamping=0.0, restitution=float(r_fac[i]),
                                  lateralFriction=float(mu_fac[i]), rollingFriction=0.0,
                                  spinningFriction=0.0, physicsClientId=cid)
                g = int(model.body_group[i])
                if groups:
                    pb.setCollisionFilterGroupMask(bid, -1, 1 if g == 0 else bit[g],
                                                   all_bits if g == 0 else (bit[g] | 1), physicsClientId=cid)
                v = st.linear_momentum[i] / model.body_mass[i]
                pb.resetBaseVelocity(bid, [float(x) for x in v], [float(x) for x in w_world[i]],
                                     physicsClientId=cid)
                self.ids.append(bid)
            self.static_ids = []
            k = n
            if model.ground:
                plane = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=cid)
                nrm = np.asarray(model.ground_normal, float) / np.linalg.norm(model.ground_normal)
                q = z_to(nrm)
                gid = pb.createMultiBody(0, plane, basePosition=[float(x) for x in nrm * model.ground_offset],
                                         baseOrientation=[float(q[1]), float(q[2]), float(q[3]), float(q[0])],
                                         physicsClientId=cid)
                pb.changeDynamics(gid, -1, restitution=float(r_fac[k]), lateralFriction=float(mu_fac[k]),
                                  rollingFriction=0.0, spinningFriction=0.0, physicsClientId=cid)
                self.static_ids.append(gid)
                k += 1
            for j in range(len(model.static_box_position)):
                col = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[float(x) for x in model.static_box_half_extents[j]],
                                              physicsClientId=cid)
                q = model.static_box_quat_wxyz[j]
                sid = pb.createMultiBody(0, col, basePosition=[float(x) for x in model.static_box_position[j]],
                                         baseOrientation=[float(q[1]), float(q[2]), float(q[3]), float(q[0])],
                                         physicsClientId=cid)
                pb.changeDynamics(sid, -1, restitution=float(r_fac[k]), lateralFriction=float(mu_fac[k]),
                                  rollingFriction=0.0, spinningFriction=0.0, physicsClientId=cid)
                self.static_ids.append(sid)
                k += 1
            self.index = {bid: i for i, bid in enumerate(self.ids)}
            self.loaded = [i for i in range(n) if np.any(model.body_force_world[i] != 0)
                           or np.any(model.body_torque_world[i] != 0)]
            eng = pb.getPhysicsEngineParameters(physicsClientId=cid)
            # the adapter's reading of Bullet: its rows are the scene's bodies (created first, in
            # order; the static ground and boxes are world geometry), damping 0 as set above
            from rblog.adapters.pybullet import Stepper, inspect

            world = inspect(cid, damping={b: (0.0, 0.0) for b in self.ids})
            if [b for b, _ in world.rows] != self.ids:
                raise EngineUnsupported("pybullet", "the scene's bodies as Bullet rows (the "
                                        "adapter read them in another order)")
            self.stepper = Stepper(world, cid, dt)
            # per body: contact, applied (the scene's constant loads) and passive (damping 0 here,
            # still logged) logged, actuator, joint and integration none
            self.impulse_supplied = np.tile(np.array([1, 1, 1, 2, 2, 2], np.int64), (n, 1))
        except BaseException:
            pb.disconnect(physicsClientId=cid)
            raise
        self.settings = {
            "engine": "pybullet", "version": self.version, "api_version": int(pb.getAPIVersion()),
            "integrator": "default", "timestep": float(dt),
            **{k: (v if isinstance(v, (int, float, str)) else str(v)) for k, v in eng.items()},
            "combine_native": {"friction": "product", "restitution": "product"},
            "material_translation": {"friction": "sqrt(mu) per feature",
                                     "restitution": "r_a r_b = max(e_a, e_b), log-space least squares"},
            "restitution_factors": [float(x) for x in r_fac],
            "contact_rows": {"separation": "before the step's integration (manifold refreshed at "
                                           "its start)", "impulse": "force * dt", "speculative":
                             "dropped (points with no force and positive distance)"},
            "ignored_scene_tables": ["contact"] if scene.contact else [],
        }

    def step(self, k: int) -> None:
        """k steps; after each, the adapter's Stepper reads the state and the contacts and adds
        the step's impulses (contact, passive, applied) to those of the interval."""
        pb, cid = self.pb, self.cid
        model, st = self.scene.model, self.stepper
        for j in range(int(k)):
            for i in self.loaded:
                bid = self.ids[i]
                f = model.body_force_world[i]
                pb.applyExternalForce(bid, -1, [float(x) for x in f], [float(x) for x in st.state[0][i]],
                                      pb.WORLD_FRAME, physicsClientId=cid)
                pb.applyExternalTorque(bid, -1, [float(x) for x in model.body_torque_world[i]],
                                       pb.WORLD_FRAME, physicsClientId=cid)
                st.pending[0][i] += f * self.dt  # at the centre of mass: no moment
                st.pending[1][i] += model.body_torque_world[i] * self.dt
                st.pending_any = True
            pb.stepSimulation(physicsClientId=cid)
            st.after_step(rows=j == int(k) - 1)  # the contact rows of the logged step

    def state(self):
        """(position, quat_wxyz, velocity, angular velocity), world frame, as the adapter reads
        them (the bodies' base frames are their contract frames here)."""
        x, q, v, w = self.stepper.state
        return x, q[:, [3, 0, 1, 2]], v, w

    def contacts(self, step: int):
        """The contacts of the step that ended at ``step`` (rblog.adapters.pybullet's rows)."""
        return self.stepper.contact_rows(step)

    def impulses(self) -> dict:
        """The impulses (N s, N m s; world frame, about each centre of mass) summed over the steps
        since the last call: {"impulse_contact_linear": (N, 3), ...} for the kinds
        ``impulse_supplied`` logs (contact, applied, passive)."""
        return {f"impulse_{k}": v for k, v in self.stepper.take().items()
                if not k.startswith("joint")}

    def close(self):
        try:
            self.pb.disconnect(physicsClientId=self.cid)
        except Exception:  # noqa: BLE001 - already gone
            pass


def _compound_shape(pb, cid, parts, name) -> int:
    """``createCollisionShapeArray`` of a compound body's parts (a btCompoundShape), each at its
    pose in the body frame (``collisionFramePositions`` / ``Orientations``, xyzw). A hull part
    is refused by name: the array call takes mesh files, not vertices."""
    kinds = {GEOM_SPHERE: pb.GEOM_SPHERE, GEOM_BOX: pb.GEOM_BOX, GEOM_CAPSULE: pb.GEOM_CAPSULE,
             GEOM_CYLINDER: pb.GEOM_CYLINDER}
    if any(code not in kinds for code, *_ in parts):
        raise EngineUnsupported("pybullet", f"body {name!r}: a hull part of a compound "
                                "(createCollisionShapeArray takes no vertices)")
    return pb.createCollisionShapeArray(
        shapeTypes=[kinds[c] for c, *_ in parts],
        radii=[float(s[0]) for _, s, *_ in parts],
        halfExtents=[[float(x) for x in s] if c == GEOM_BOX else [0.0, 0.0, 0.0]
                     for c, s, *_ in parts],
        lengths=[2.0 * float(s[1]) if c in (GEOM_CAPSULE, GEOM_CYLINDER) else 0.0
                 for c, s, *_ in parts],
        collisionFramePositions=[[float(x) for x in p] for _, _, p, _, _ in parts],
        collisionFrameOrientations=[[float(q[1]), float(q[2]), float(q[3]), float(q[0])]
                                    for _, _, _, q, _ in parts],
        physicsClientId=cid)
