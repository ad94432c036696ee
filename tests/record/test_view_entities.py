"""The Rerun view entities a user reads (no viewer needed; tests/record/test_viewer.py looks at
them in the real viewer): the drift plot on a log scale with the check's tolerance as a line,
each small scene's body-frame angular velocity, a camera that frames the bodies."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import rblog
from rblog.record import rerun_writer as W


def test_drift_tolerance_line_is_the_checks_tolerance():
    from rblog.analyze import tolerances

    assert W.DRIFT_TOLERANCE == tolerances.DRIFT_ORTHO_ERROR


def test_drift_log10_floors_zero_and_keeps_nan():
    out = W.drift_log10([0.0, 1e-15, 1.63, -1e-3, np.nan])
    np.testing.assert_allclose(out[:4], [-17.0, -15.0, math.log10(1.63), -3.0])
    assert np.isnan(out[4])


def _columns(path, entity):
    import rerun as rr

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = rr.chunk.RrdReader(str(path))
        store = r.recordings()[0]
        return [c for c in r.stream(store=store) if c.entity_path == entity]


def _two_spinners(tmp_path, n_bodies=2):
    """n bodies turning at constant w (world z) with R = rotation about z by w t: in the body
    frame, w has components (0, 0, w) as well, while a tilted body shows them mixed."""
    model = rblog.body_table(name=[f"b{i}" for i in range(n_bodies)], shape=["sphere"] * n_bodies,
                             size=[0.1] * n_bodies, mass=[1.0] * n_bodies, gravity=[0, 0, 0])
    T, w = 20, 2.0
    t = np.arange(T) * 0.01
    # body 0 tilted 90 degrees about x: its body z is world -y; spin about world z = body y
    c, s = np.cos(w * t / 2), np.sin(w * t / 2)
    qz = np.stack([c, 0 * c, 0 * c, s], axis=1)              # rotation about world z
    qx = np.array([np.cos(np.pi / 4), np.sin(np.pi / 4), 0, 0])  # 90 degrees about x
    # q = qz * qx (first tilt, then spin about world z)
    q0 = np.stack([qz[:, 0] * qx[0], qz[:, 0] * qx[1],
                   qz[:, 3] * qx[1], qz[:, 3] * qx[0]], axis=1)
    q = np.repeat(qz[:, None], n_bodies, axis=1)
    q[:, 0] = q0
    path = tmp_path / "spin.rrd"
    with rblog.Recorder(model, rrd=str(path), dt=0.01) as rec:
        rec.write(t=t, position=np.zeros((T, n_bodies, 3)), quat_wxyz=q,
                  velocity=np.zeros((T, n_bodies, 3)),
                  angular_velocity=np.tile([0.0, 0.0, w], (T, n_bodies, 1)))
    return path, w


def test_small_scenes_plot_each_bodys_angular_velocity_in_its_frame(tmp_path):
    """The per-body w plot is in the body frame (R^T w): the tilted body spins about its own y
    axis, the other about its z. In world components both would read (0, 0, 2) throughout, and
    a flip about a body's intermediate axis would not show."""
    path, w = _two_spinners(tmp_path)
    got = {}
    for name in ("b0", "b1"):
        cols = _columns(path, f"/{W.OMEGA_ENTITY}/{name}")
        assert cols, name
        vals = []
        for c in cols:
            if c.is_static:
                continue
            for v in c.to_record_batch().column(
                    next(i for i, f in enumerate(c.to_record_batch().schema) if "scalars" in f.name)
            ).to_pylist():
                vals.append(v)
        got[name] = np.array(vals)
    np.testing.assert_allclose(got["b1"], np.tile([0, 0, w], (len(got["b1"]), 1)), atol=1e-9)
    np.testing.assert_allclose(np.abs(got["b0"]), np.tile([0, w, 0], (len(got["b0"]), 1)),
                               atol=1e-9)


def test_large_scenes_have_no_per_body_plots(tmp_path):
    model = rblog.body_table(name=[f"b{i}" for i in range(W.OMEGA_PLOT_MAX_BODIES + 1)],
                             shape=["sphere"] * (W.OMEGA_PLOT_MAX_BODIES + 1),
                             size=[0.1] * (W.OMEGA_PLOT_MAX_BODIES + 1),
                             mass=[1.0] * (W.OMEGA_PLOT_MAX_BODIES + 1))
    n, T = W.OMEGA_PLOT_MAX_BODIES + 1, 3
    path = tmp_path / "many.rrd"
    with rblog.Recorder(model, rrd=str(path), dt=0.01) as rec:
        rec.write(t=np.arange(T) * 0.01, position=np.zeros((T, n, 3)),
                  quat_wxyz=np.tile([1.0, 0, 0, 0], (T, n, 1)), velocity=np.zeros((T, n, 3)),
                  angular_velocity=np.zeros((T, n, 3)))
    assert not _columns(path, f"/{W.OMEGA_ENTITY}/b0")
    assert _columns(path, f"/{W.DRIFT_ENTITY}/tolerance")


def _in_view(eye, target, points, radius, aspect, fov_y_deg=W.VIEW_FOV_Y_DEG):
    """Largest |x| / half width and |y| / half height of the points' spheres on the screen."""
    fwd = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(fwd, [0, 0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    rel = points - eye
    depth = rel @ fwd
    ty = math.tan(math.radians(fov_y_deg) / 2)
    x = (np.abs(rel @ right) + radius) / (depth * ty * aspect)
    y = (np.abs(rel @ up) + radius) / (depth * ty)
    return float(np.max(x)), float(np.max(y))


@pytest.mark.parametrize("shape", ["flat pile", "tall column", "one body"])
def test_camera_frames_the_bodies_and_fills_the_view(shape):
    """Every body is in view and the farthest fills most of it. (Before, the camera stood 1.4
    extents of the bounding box away: the pile took ~15 % of the view.)"""
    rng = np.random.default_rng(1)
    if shape == "flat pile":
        pts = rng.uniform([-1.5, -1.5, 0.05], [1.5, 1.5, 0.4], (500, 3))
    elif shape == "tall column":
        pts = rng.uniform([-0.2, -0.2, 0.0], [0.2, 0.2, 4.0], (50, 3))
    else:
        pts = np.array([[0.0, 0.0, 1.0]])
    r, aspect = 0.09, 1.3
    eye, target = W.frame_camera(pts, r, aspect=aspect)
    q = W.FRAME_QUANTILE if len(pts) >= W.FRAME_TRIM_MIN_BODIES else 1.0
    x, y = _in_view(eye, target, pts, r, aspect)
    if q == 1.0:
        assert max(x, y) <= W.FRAME_FILL + 1e-9
    assert max(x, y) >= 0.9 * W.FRAME_FILL, (x, y)
