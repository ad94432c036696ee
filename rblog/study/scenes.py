"""Reference scenes built in code, shared by the contact tests and benchmarks.

Each returns ``(model, state)`` with :class:`rblog.contract.model.Model` and :class:`rblog.engine.state.State`
filled by hand (no scene file), SI units, z up, ground plane z = 0.
"""

from __future__ import annotations

import numpy as np

from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE, Model
from rblog.engine.state import State
from rblog.engine.rotation import quat_to_matrix_np


def inertia_diag(shape: int, size, mass: float) -> np.ndarray:
    """Principal moments of a solid sphere (size = radius) or box (size = half extents)."""
    if shape == SHAPE_SPHERE:
        r = float(np.ravel(size)[0])
        return np.full(3, 0.4 * mass * r * r)
    a, b, c = 2.0 * np.asarray(size, float)
    return mass / 12.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])


def make_model(shapes, sizes, masses, restitution=0.5, friction=0.5, gravity=(0.0, 0.0, -9.81),
               ground=True, ground_restitution=0.0, ground_friction=None, groups=None,
               **statics) -> Model:
    """A model of spheres and boxes. ``sizes[i]`` is a radius or three half extents; materials
    are scalars (every body) or sequences; ``statics`` go to Model (static_box_*...)."""
    n = len(shapes)
    size = np.zeros((n, 3))
    inertia = np.zeros((n, 3))
    for i, (s, sz, m) in enumerate(zip(shapes, sizes, masses)):
        if s == SHAPE_SPHERE:
            size[i, 0] = float(np.ravel(sz)[0])
        else:
            size[i] = np.broadcast_to(np.asarray(sz, float), 3)
        inertia[i] = inertia_diag(s, size[i] if s == SHAPE_BOX else size[i, 0], m)
    return Model(
        body_name=[f"body{i}" for i in range(n)], body_shape=np.asarray(shapes, np.int64),
        body_size=size, body_mass=np.asarray(masses, float), body_inertia_diag=inertia,
        body_force_world=np.zeros((n, 3)), body_torque_world=np.zeros((n, 3)),
        body_restitution=np.broadcast_to(np.asarray(restitution, float), n).copy(),
        body_friction=np.broadcast_to(np.asarray(friction, float), n).copy(),
        body_group=(np.zeros(n, np.int64) if groups is None else np.asarray(groups, np.int64)),
        gravity=np.asarray(gravity, float), ground=ground,
        ground_restitution=float(ground_restitution),
        ground_friction=float(friction if ground_friction is None else ground_friction),
        **statics)


def make_state(model: Model, position, velocity=None, quat_wxyz=None, omega=None) -> State:
    """State from positions, velocities (m/s), orientations and angular velocities (rad/s)."""
    n = model.n_bodies
    x = np.array(position, float).reshape(n, 3)
    v = np.zeros((n, 3)) if velocity is None else np.array(velocity, float).reshape(n, 3)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)) if quat_wxyz is None else np.array(quat_wxyz, float)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    r = quat_to_matrix_np(q)
    ang = np.zeros((n, 3))
    if omega is not None:
        w = np.array(omega, float).reshape(n, 3)
        for i in range(n):
            ang[i] = r[i] @ (model.body_inertia_diag[i] * (r[i].T @ w[i]))
    return State(x, v * model.body_mass[:, None], q, r, ang)


def box_stack(n: int = 10, half: float = 0.1, mass: float = 1.0, friction: float = 0.5):
    """n cubes of half extent ``half`` stacked exactly touching on the ground."""
    model = make_model([SHAPE_BOX] * n, [[half] * 3] * n, [mass] * n, restitution=0.0,
                       friction=friction)
    pos = [[0.0, 0.0, half + 2.0 * half * k] for k in range(n)]
    return model, make_state(model, pos)


def box_pile(n: int = 500, half: float = 0.05, mass: float = 1.0, top: float = 2.0,
             per_row: int = 7, spacing: float = 0.2, seed: int = 0, friction: float = 0.5,
             restitution: float = 0.2):
    """``n`` cubes (edge 2 * half) in random orientations dropped from a column of layers.

    Layers of per_row x per_row boxes ``spacing`` apart (more than a box diagonal, so nothing
    overlaps at the start), from z = 2 half up to ``top`` (the highest centre), so the boxes land
    on each other and settle into a pile about three boxes deep."""
    rng = np.random.default_rng(seed)
    per_layer = per_row * per_row
    n_layers = -(-n // per_layer)
    diag = 2.0 * half * np.sqrt(3.0)
    dz = (top - 2.0 * half) / max(n_layers - 1, 1)
    if dz < diag or spacing < diag:
        raise ValueError("pile layout would overlap: raise top or spacing, or add per_row")
    pos = np.zeros((n, 3))
    for i in range(n):
        layer, k = divmod(i, per_layer)
        ix, iy = divmod(k, per_row)
        pos[i] = [(ix - (per_row - 1) / 2) * spacing, (iy - (per_row - 1) / 2) * spacing,
                  2.0 * half + layer * dz]
    jitter = 0.5 * (spacing - diag)
    pos[:, :2] += rng.uniform(-jitter, jitter, (n, 2))
    q = rng.normal(size=(n, 4))
    model = make_model([SHAPE_BOX] * n, [[half] * 3] * n, [mass] * n, restitution=restitution,
                       friction=friction, ground_restitution=restitution)
    return model, make_state(model, pos, quat_wxyz=q)


def loose_pile(n: int = 500, half: float = 0.05, mass: float = 1.0, pitch: float = 0.2,
               layer_gap: float = 0.3, per_row: int = 10, offset: float = 0.02,
               max_tilt: float = 0.3, friction: float = 0.5, restitution: float = 0.2,
               seed: int = 0):
    """The loose pile of the performance issue: ``n`` cubes (edge 2 * half) in layers of
    per_row x per_row at ``pitch`` (m), layers ``layer_gap`` (m) apart from z = 2 half, each box
    shifted by up to ``offset`` (m) in x and y and tilted by up to ``max_tilt`` (rad) about a
    random axis, dropped on the ground. 500 boxes: five layers of 10 x 10; 100: one layer; 10:
    one row. Nothing overlaps at the start: the gap between neighbours' centres (pitch - 2 offset
    = 0.16 m, layer_gap 0.3 m) exceeds a box diagonal (0.173 m) vertically and a tilted box's
    horizontal reach (half (cos t + sqrt 2 sin t) = 0.069 m for t = 0.3) twice horizontally."""
    rng = np.random.default_rng(seed)
    per_layer = per_row * per_row
    pos = np.zeros((n, 3))
    for i in range(n):
        layer, k = divmod(i, per_layer)
        ix, iy = divmod(k, per_row)
        pos[i] = [(ix - (per_row - 1) / 2) * pitch, (iy - (per_row - 1) / 2) * pitch,
                  2.0 * half + layer * layer_gap]
    pos[:, :2] += rng.uniform(-offset, offset, (n, 2))
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    angle = rng.uniform(0.0, max_tilt, n)
    q = np.concatenate([np.cos(0.5 * angle)[:, None], np.sin(0.5 * angle)[:, None] * axis], 1)
    model = make_model([SHAPE_BOX] * n, [[half] * 3] * n, [mass] * n, restitution=restitution,
                       friction=friction, ground_restitution=restitution)
    return model, make_state(model, pos, quat_wxyz=q)
