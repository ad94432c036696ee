"""What the engine adapters share: quaternion algebra, the choice of each body's contract frame,
and the buffered stream of samples into an :class:`rblog.record.Recorder`."""

from __future__ import annotations

import numpy as np

from rblog.contract.model import SHAPE_BOX, SHAPE_NONE, SHAPE_SPHERE
from rblog.contract.orientation import quat_wxyz_to_matrix

#: a geom is centred on the centre of mass when they are closer than this fraction of its size
CENTRE_REL = 1e-9
#: the inertia is diagonal in a frame when its off-diagonal terms are below this fraction of its
#: trace (a box geom and MuJoCo's own principal axes agree to round-off, ~1e-16)
DIAGONAL_REL = 1e-9
#: samples gathered before they go to the writers as one block
BLOCK_SAMPLES = 256


class Fields:
    """An MjModel's (or MjData's) attributes, each fetched from the bindings once (every
    access of ``m.jnt_type`` builds a new numpy view): the loops over bodies, joints and geoms
    read these."""

    def __init__(self, m):
        self._m = m

    def __getattr__(self, name):
        value = getattr(self._m, name)
        setattr(self, name, value)
        return value


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a ⊗ b of (..., 4) scalar-first quaternions (rotate by b, then by a)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw], axis=-1)


def body_frame(inertia_principal, q_inertial, geom=None):
    """The contract frame of one body, relative to the engine's body frame.

    Args:
        inertia_principal: (3,) principal moments (kg m^2) in the engine's inertial frame.
        q_inertial: (4,) that frame's orientation in the engine's body frame (MuJoCo's
            ``body_iquat``; identity for Bullet, whose base frame is the inertial frame).
        geom: None, or (shape code, (3,) size, (3,) centre and (4,) orientation of the geom in the
            engine's body frame, (3,) the centre of mass in the engine's body frame).

    Returns (shape code, (3,) contract size, (3,) inertia diagonal in the contract frame, (4,)
    quaternion of the contract frame in the engine's body frame). The contract needs a diagonal
    inertia and a box centred on the centre of mass with its axes along the body frame's: a box
    (or sphere) whose frame diagonalizes the inertia gives the frame and keeps its shape; otherwise
    the frame is the principal one and the body has no shape (SHAPE_NONE).
    """
    moments = np.asarray(inertia_principal, np.float64)
    qi = np.asarray(q_inertial, np.float64) / np.linalg.norm(q_inertial)
    if geom is not None:
        code, size, centre, q_geom, com = geom
        size = np.asarray(size, np.float64)
        scale = max(float(np.max(np.abs(size))), 1e-300)
        if np.linalg.norm(np.asarray(centre, float) - np.asarray(com, float)) <= CENTRE_REL * scale:
            if code == SHAPE_SPHERE:
                return SHAPE_SPHERE, np.array([size[0], 0.0, 0.0]), moments.copy(), qi
            if code == SHAPE_BOX:
                qg = np.asarray(q_geom, np.float64) / np.linalg.norm(q_geom)
                ri, rg = quat_wxyz_to_matrix(qi), quat_wxyz_to_matrix(qg)
                r = rg.T @ ri  # inertial frame -> geom frame
                tensor = r @ np.diag(moments) @ r.T  # the inertia in the geom's frame
                off = tensor - np.diag(np.diag(tensor))
                if np.max(np.abs(off)) <= DIAGONAL_REL * max(float(np.trace(tensor)), 1e-300):
                    return SHAPE_BOX, size[:3].copy(), np.diag(tensor).copy(), qg
    return SHAPE_NONE, np.zeros(3), moments.copy(), qi


class EngineRecorder:
    """What every engine adapter's recorder shares: ``close`` (write what is gathered, then close
    the :class:`rblog.record.Recorder` in ``self.recorder``, marked truncated when asked), use
    as a context manager (an exception closes the log truncated, with its message as the
    reason) and ``trajectory``. A subclass implements :meth:`flush`."""

    recorder = None

    def flush(self) -> None:
        """Write the samples gathered so far."""
        raise NotImplementedError

    def close(self, truncated: bool = False, reason: str | None = None) -> None:
        try:
            if not truncated:
                self.flush()
        finally:
            self.recorder.close(truncated=truncated, reason=reason)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        self.close(truncated=exc_type is not None, reason=None if exc is None else str(exc))

    @property
    def trajectory(self):
        """The run so far (needs ``keep``, the default without an output path)."""
        self.flush()
        return self.recorder.trajectory


class SampleStream:
    """Samples (step, t, position, quat_wxyz, velocity, world angular velocity, contact rows)
    gathered and written to an :class:`rblog.record.Recorder` a block at a time."""

    def __init__(self, recorder, block: int = BLOCK_SAMPLES):
        self.recorder, self.block = recorder, int(block)
        self._clear()

    def _clear(self):
        self.steps, self.x, self.q, self.v, self.w, self.c = [], [], [], [], [], []
        self.channels: dict[str, list] = {}

    def __len__(self):
        return len(self.steps)

    def add(self, step, x, q, v, w, contacts=None, channels=None) -> None:
        """``channels``: per-interval arrays of this sample ({"impulse_contact_linear": (N, 3),
        ...}; the same names at every sample)."""
        for name, a in (channels or {}).items():
            self.channels.setdefault(name, []).append(a)
        self.steps.append(int(step))
        self.x.append(x)
        self.q.append(q)
        self.v.append(v)
        self.w.append(w)
        if contacts is not None and len(contacts["step"]):
            self.c.append(contacts)
        if len(self.steps) >= self.block:
            self.flush()

    def flush(self, dt: float | None = None) -> None:
        if not self.steps:
            return
        rec = self.recorder
        dt = rec.info.dt if dt is None else dt
        steps = np.array(self.steps, np.int64)
        arrays = dict(t=steps * dt, step=steps, position=np.array(self.x), quat_wxyz=np.array(self.q),
                      velocity=np.array(self.v), angular_velocity=np.array(self.w))
        if self.c:
            arrays["contacts"] = {k: np.concatenate([c[k] for c in self.c]) for k in self.c[0]}
        arrays.update({name: np.array(a) for name, a in self.channels.items()})
        self._clear()
        rec.write(**arrays)


__all__ = ["BLOCK_SAMPLES", "SampleStream", "body_frame", "quat_mul"]
