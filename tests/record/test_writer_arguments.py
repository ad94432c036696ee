"""The writer API's arguments typed (issue 41): every argument of `rblog.Recorder` and
`rblog.body_table` of the wrong type or value is a one-line RecordError naming it (before:
TypeError from len(None) / list(None), ValueError from float('x'), int('x'), dict('str')), and a
material not given is unknown (NaN, docs/log-format.md "materials"), not 0.5."""

from __future__ import annotations

import math

import numpy as np
import pytest

import rblog

GOOD = dict(name=["ball"], shape=["sphere"], size=[[0.1, 0, 0]], mass=[1.0])


def _one_line(err, *needles):
    msg = str(err.value)
    assert "\n" not in msg and isinstance(err.value, rblog.RecordError), msg
    for n in needles:
        assert n in msg, msg
    return msg


@pytest.mark.parametrize("arg, value", [
    ("name", None), ("name", "ball"), ("name", [1]), ("name", []), ("shape", None),
    ("shape", {"a": 1}), ("size", None), ("size", "big"), ("mass", None), ("mass", [-1.0]),
    ("mass", ["x"]), ("inertia_diag", "x"), ("restitution", "x"), ("restitution", -0.5),
    ("friction", float("inf")), ("group", "x"), ("group", 1.5), ("force_world", [[1, 2]]),
    ("torque_world", [[np.nan, 0, 0]]), ("gravity", "down"), ("gravity", [0, 0, np.inf]),
    ("ground", "yes"), ("ground_offset", "x"), ("ground_offset", math.inf),
    ("ground_restitution", "x"), ("ground_friction", -1.0), ("ground_normal", [0, 1]),
    ("static_box_position", "x"), ("static_box_half_extents", [[1, 1]]),
])
def test_body_table_argument_of_wrong_type_or_value(arg, value):
    kw = dict(GOOD, **{arg: value})
    if arg.startswith("static_box") and arg != "static_box_position":
        kw["static_box_position"] = [[0, 0, 0]]
    with pytest.raises(rblog.RecordError) as err:
        rblog.body_table(**kw)
    _one_line(err, arg.split("_world")[0] if arg != "static_box_half_extents" else arg)


@pytest.mark.parametrize("arg, value", [
    ("dt", "x"), ("dt", -1.0), ("dt", math.nan), ("log_every", "x"), ("log_every", 0),
    ("log_every", 2.5), ("duration_s", "x"), ("engine_settings", "str"),
    ("engine_settings", [1, 2]), ("writer", 3), ("integrator", None), ("scene_path", 3),
    ("scene_toml", b"x"), ("scene_resolved", "x"), ("seed", "x"), ("seed", 1.5), ("keep", "x"),
    ("info", "x"), ("mcap_compression", None), ("writers", "x"), ("fail_fast", "x"),
    ("rrd", 3), ("mcap", 3.5), ("combine_friction", "x"),
    # found by the writer fuzz target: `np.zeros(0) not in (...)` raised numpy's ValueError
    ("combine_friction", np.zeros(0)), ("combine_restitution", np.ones(2)),
])
def test_recorder_argument_of_wrong_type_or_value(arg, value):
    model = rblog.body_table(**GOOD)
    with pytest.raises(rblog.RecordError) as err:
        rblog.Recorder(model, **{arg: value})
    _one_line(err, arg)


def test_recorder_model_of_wrong_type():
    with pytest.raises(rblog.RecordError) as err:
        rblog.Recorder({"name": ["ball"]})
    _one_line(err, "model", "dict")


def test_materials_not_given_are_unknown():
    m = rblog.body_table(**GOOD, ground=True, static_box_position=[[0, 0, -1]],
                         static_box_half_extents=[[1, 1, 0.1]])
    for v in (m.body_restitution, m.body_friction, m.static_box_restitution, m.static_box_friction,
              [m.ground_restitution], [m.ground_friction]):
        assert np.isnan(v).all(), v
    given = rblog.body_table(**GOOD, restitution=0.8, friction=0.3, ground=True,
                             ground_restitution=0.7, ground_friction=0.2)
    assert given.body_restitution.tolist() == [0.8] and given.body_friction.tolist() == [0.3]
    assert (given.ground_restitution, given.ground_friction) == (0.7, 0.2)


def test_unknown_materials_round_trip_and_are_not_judged(tmp_path):
    """A log written without materials reads back NaN (unknown) through both formats."""
    model = rblog.body_table(**GOOD, gravity=[0, 0, -9.81])
    t = np.arange(5) * 0.01
    x = np.zeros((5, 1, 3))
    x[:, 0, 2] = -0.5 * 9.81 * t**2
    v = np.zeros((5, 1, 3))
    v[:, 0, 2] = -9.81 * t
    q = np.tile([1.0, 0, 0, 0], (5, 1, 1))
    for p in ("m.mcap", "m.rrd"):
        kw = {"mcap" if p.endswith("mcap") else "rrd": str(tmp_path / p)}
        with rblog.Recorder(model, dt=0.01, **kw) as rec:
            rec.write(t=t, position=x, quat_wxyz=q, velocity=v, angular_velocity=np.zeros_like(v))
        back = rblog.load(tmp_path / p)
        assert np.isnan(back.model.body_restitution).all() and np.isnan(back.model.body_friction).all()


@pytest.mark.parametrize("arg, value", [("t", ["a", "b", "c"]), ("t", None), ("step", ["x"] * 3),
                                        ("step", [2**70] * 3)])
def test_write_argument_of_wrong_type(arg, value):
    """Found by the writer fuzz target: t = ['a', ...] raised numpy's ValueError in build_block."""
    model = rblog.body_table(**GOOD)
    arrays = dict(t=np.arange(3) * 0.01, position=np.zeros((3, 1, 3)),
                  quat_wxyz=np.tile([1.0, 0, 0, 0], (3, 1, 1)), velocity=np.zeros((3, 1, 3)),
                  angular_velocity=np.zeros((3, 1, 3)))
    arrays[arg] = value
    with pytest.raises(rblog.RecordError) as err:
        with rblog.Recorder(model, dt=0.01) as rec:
            rec.write(**arrays)
    _one_line(err, arg)
