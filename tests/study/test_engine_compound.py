"""Compound bodies through ``rblog run --engine mujoco|pybullet|ode``: each engine holds the parts
at their poses in the body (MuJoCo geoms of one body, Bullet's createCollisionShapeArray, ODE geoms
with offsets), so a T of two boxes standing on its stem rests on the stem's end.

The T (its scene frame): a bar 0.4 x 0.06 x 0.06 centred at z = 0.13 on a stem 0.06 x 0.06 x 0.2
(|z| <= 0.1), one density: its centre of mass at c_z = V_bar 0.13 / (V_bar + V_stem) on the
axis, and standing on the stem's end its centre rests at 0.1 + c_z. As in
tests/study/test_engine_shapes.py, each engine lets a resting body sink by its own contact depth:
the centre's height below the closed form lies between the least and the deepest depth of the
engine's contact rows of the last step (a level face sinks by the depth of every point).
"""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from rblog.contract.model import GEOM_BOX
from rblog.engine.scene import parse_scene
from rblog.record.reader import load
from rblog.study.engines import run_engine

ENGINES = ("mujoco", "pybullet", "ode")
TEE = textwrap.dedent("""
    [sim]
    dt = 1e-3
    duration = 1.0
    [ground]
    restitution = 0.0
    [[body]]
    name = "tee"
    shape = "compound"
    density = 700
    restitution = 0.0
    position = [0.0, 0.0, 0.1]
    parts = [
      {shape = "box", half_extents = [0.2, 0.03, 0.03], position = [0, 0, 0.13]},
      {shape = "box", half_extents = [0.03, 0.03, 0.1]},
    ]
    """)


@pytest.mark.parametrize("engine", ENGINES)
def test_tee_stands_on_its_stem_in_every_engine(engine, tmp_path):
    pytest.importorskip("odepy" if engine == "ode" else engine)
    bar, stem = 0.4 * 0.06 * 0.06, 0.06 * 0.06 * 0.2
    z_rest = 0.1 + bar * 0.13 / (bar + stem)
    s = parse_scene(TEE, "tee.toml")
    path = tmp_path / "tee.mcap"
    run_engine(s, engine, mcap=str(path))
    got = load(path)
    assert not got.truncated and got.warnings == []
    gm = got.model
    on_body = np.asarray(gm.geom_body) == 0
    assert np.asarray(gm.geom_type)[on_body].tolist() == [GEOM_BOX, GEOM_BOX]
    dz = got.position[-1, 0, 2] - z_rest
    c = got.contacts
    last = c.step == c.step.max()
    sep = c.separation[last]
    # measured: MuJoCo -9.6e-8 m (its one depth -9.6e-8), Bullet -1.03e-5 m in [-1.09e-5,
    # -0.97e-5], ODE -1.9e-12 m (its depth -1.9e-12); the bar (0.06 lower if it were the
    # contact: 0.03 + c_z below) never touches
    assert sep.min() - 1e-12 <= dz <= sep.max() + 1e-12, (dz, sep.min(), sep.max())
    # upright (measured 4.7e-18, 6.7e-5, 2.1e-13)
    assert np.abs(got.quat_wxyz[:, 0] - [1.0, 0.0, 0.0, 0.0]).max() <= 1e-3


def test_mujoco_model_has_the_parts_as_geoms_of_one_body():
    mujoco = pytest.importorskip("mujoco")
    from rblog.study.engines.mujoco import MujocoRun

    s = parse_scene(TEE, "tee.toml")
    run = MujocoRun(s, 1e-3)
    try:
        m = run.m
        body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "b0")
        geoms = np.flatnonzero(np.asarray(m.geom_bodyid) == body)
        assert len(geoms) == 2
        # each part's pose in the body: the scene's (the body frame is the T's centre of mass)
        model = s.model
        rows = np.flatnonzero(np.asarray(model.geom_body) == 0)
        np.testing.assert_allclose(m.geom_pos[geoms], model.geom_pos_body[rows], rtol=0, atol=1e-15)
        np.testing.assert_allclose(m.geom_size[geoms], model.geom_size[rows], rtol=0, atol=0)
        # the scene's mass and inertia, not MuJoCo's from the geoms
        assert m.body_mass[body] == model.body_mass[0]
        np.testing.assert_allclose(m.body_inertia[body], model.body_inertia_diag[0], rtol=1e-15)
    finally:
        run.close()
