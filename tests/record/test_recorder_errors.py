"""The writer API's friction (issue 31): RecordError is public, a body without a shape is
accepted, unknown shapes and wrongly shaped arrays are one-line RecordErrors naming the argument,
the value and what was expected (each of these failed before: a bare KeyError or ValueError, or
nothing at all), and the contract's fixed values are checked and documented."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import rblog
from rblog.contract.model import SHAPE_NONE
from rblog.record.recorder import CONTACT_ROWS_SEPARATION, KIND_VALUES

REPO = Path(__file__).resolve().parents[2]


def _one_line(err) -> str:
    msg = str(err.value)
    assert "\n" not in msg and isinstance(err.value, rblog.RblogError), msg
    return msg


def test_record_error_is_exported():
    assert issubclass(rblog.RecordError, rblog.RblogError)
    from rblog.record import RecordError

    assert RecordError is rblog.RecordError


@pytest.mark.parametrize("shape, value", [(["cylinder"], "'cylinder'"), ([7], "7"), ("capsule", "'capsule'")])
def test_unknown_shape_is_one_line(shape, value):
    with pytest.raises(rblog.RecordError) as err:
        rblog.body_table(name=["c"], shape=shape, size=[[0.1, 0.2, 0.0]], mass=[1.0])
    msg = _one_line(err)
    assert "shape[0]" in msg and value in msg and "'sphere', 'box', 'none'" in msg


def test_body_without_shape():
    model = rblog.body_table(name=["cyl", "ball"], shape=["none", "sphere"], size=[[0, 0, 0], [0.1, 0, 0]],
                             mass=[1.0, 2.0], inertia_diag=[[0.1, 0.1, 0.05], [0.008] * 3])
    assert model.body_shape.tolist() == [SHAPE_NONE, 0]
    assert model.body_bounding_radius[0] == 0.0
    with pytest.raises(rblog.RecordError) as err:  # no size to compute an inertia from
        rblog.body_table(name=["cyl"], shape=["none"], size=[[0, 0, 0]], mass=[1.0])
    assert "inertia_diag" in _one_line(err)
    with pytest.raises(rblog.RecordError) as err:  # a size would be judged as a box's
        rblog.body_table(name=["cyl"], shape=["none"], size=[[0.1, 0, 0]], mass=[1.0],
                         inertia_diag=[[1, 1, 1]])
    assert "size[0]" in _one_line(err)


def test_shapeless_body_round_trips(tmp_path):
    model = rblog.body_table(name=["cyl"], shape=["none"], size=[[0, 0, 0]], mass=[1.0],
                             inertia_diag=[[0.1, 0.1, 0.05]], restitution=float("nan"))
    t = np.arange(3) * 0.01
    z = np.zeros((3, 1, 3))
    for p in ("a.mcap", "a.rrd"):
        with rblog.Recorder(model, **{p.split(".")[1]: str(tmp_path / p)}, dt=0.01) as rec:
            rec.write(t=t, position=z, quat_wxyz=np.tile([1.0, 0, 0, 0], (3, 1, 1)), velocity=z,
                      angular_velocity=z)
        got = rblog.load(tmp_path / p)
        assert got.model.body_shape.tolist() == [SHAPE_NONE], p
        assert np.isnan(got.model.body_restitution[0]), p


@pytest.mark.parametrize("kwargs, names", [
    (dict(group=[1, 2]), ("group", "(2,)", "(3,)")),
    (dict(mass=[1.0, 2.0]), ("mass", "(2,)", "(3,)")),
    (dict(mass=[1.0, -2.0, 1.0]), ("mass[1]", "-2.0", "positive")),
    (dict(friction="high"), ("friction", "'high'", "numbers")),
    (dict(name="abc"), ("name", "'abc'", "list")),
])
def test_bad_body_table_arrays_are_one_line(kwargs, names):
    args = dict(name=["a", "b", "c"], shape="sphere", size=[0.1, 0.1, 0.1], mass=[1.0] * 3)
    args.update(kwargs)
    with pytest.raises(rblog.RecordError) as err:
        rblog.body_table(**args)
    msg = _one_line(err)
    assert all(s in msg for s in names), msg


def _ball():
    model = rblog.body_table(name=["ball"], shape=["sphere"], size=[0.1], mass=[1.0], ground=True)
    t = np.arange(3) * 0.01
    z = np.zeros((3, 1, 3))
    state = dict(t=t, position=z + [0, 0, 0.1], quat_wxyz=np.tile([1.0, 0, 0, 0], (3, 1, 1)),
                 velocity=z, angular_velocity=z)
    rows = dict(step=[1, 2], body_a=[0, 0], body_b=[-1, -1], point=[[0, 0, 0]] * 2,
                normal=[[0, 0, 1.0]] * 2, separation=[0.0, 0.0], normal_impulse=[0.0981] * 2)
    return model, state, rows


@pytest.mark.parametrize("change, names", [
    (dict(point=[[0, 0, 0]] * 3), ("contacts.point", "(3, 3)", "(2, 3)")),
    (dict(normal_impulse=[0.1]), ("contacts.normal_impulse", "(1,)", "(2,)")),
    (dict(kind=[0, 2]), ("contacts.kind", "2", "1 (impact)")),
    (dict(impulse=[0.1, 0.1]), ("'impulse'", "normal_impulse")),
    (dict(normal=None), ("'normal' missing",)),
    (dict(separation=["x", "y"]), ("contacts.separation", "numbers")),
])
def test_bad_contact_rows_are_one_line(change, names):
    model, state, rows = _ball()
    for k, v in change.items():  # None: the field is left out
        rows.pop(k) if v is None else rows.__setitem__(k, v)
    with pytest.raises(rblog.RecordError) as err:
        rblog.Recorder(model, dt=0.01).write(**state, contacts=rows)
    msg = _one_line(err)
    assert all(s in msg for s in names), msg


def test_bad_state_array_is_one_line():
    model, state, _ = _ball()
    state["velocity"] = np.zeros((3, 2, 3))
    with pytest.raises(rblog.RecordError) as err:
        rblog.Recorder(model, dt=0.01).write(**state)
    assert "velocity" in _one_line(err) and "(3, 1, 3)" in str(err.value)


def test_contact_rows_separation_values():
    model, state, rows = _ball()
    for ok in CONTACT_ROWS_SEPARATION + ("before the step (contacts found at its start)",):
        rblog.Recorder(model, dt=0.01, engine_settings={"contact_rows": {"separation": ok}}).write(
            **state, contacts=rows)
    with pytest.raises(rblog.RecordError) as err:
        rblog.Recorder(model, dt=0.01, engine_settings={"contact_rows": {"separation": "start"}})
    msg = _one_line(err)
    assert "'start'" in msg and "'after the step' or 'before the step'" in msg


def test_docs_list_the_fixed_values():
    """docs/log-format.md lists every value of the fields that take fixed ones."""
    doc = (REPO / "docs" / "log-format.md").read_text(encoding="utf-8")
    for value in CONTACT_ROWS_SEPARATION:
        assert f"`{value}`" in doc
    assert "-1 = none" in doc and all(f"{k} = " in doc for k in KIND_VALUES)
    from rblog.record._common import COMBINE_RULES

    assert all(f"`{r}`" in doc for r in COMBINE_RULES)


def test_docs_show_contacts_in_recorder_write():
    """docs/recording.md shows contact rows handed to Recorder.write, and the example runs."""
    import re

    text = (REPO / "docs" / "recording.md").read_text(encoding="utf-8")
    blocks = [b for b in re.findall(r"```python\n(.*?)```", text, re.S)
              if "contacts=rows" in b and "rblog.Recorder" in b]
    assert blocks, "docs/recording.md has no Recorder.write example with contacts"
    ns: dict = {}
    exec(compile(blocks[0], "docs/recording.md", "exec"), ns)  # noqa: S102 - the repo's docs
    traj, results = ns["rec"].trajectory, ns["results"]
    assert len(traj.contacts.step) == 20 and traj.warnings == []
    assert all(r.passed or r.skipped for r in results), [r.reason for r in results if not r.passed]
    momentum = next(r for r in results if r.analyzer == "momentum")
    assert not momentum.skipped  # the rows were read and judged
