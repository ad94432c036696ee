"""Logs that frame and checksum correctly but hold contents no writer following the contract
produces (issue 41's fuzzing findings): each is mutated here from a log of samples/bouncing_ball.toml
and must be a one-line LogReadError naming the file, the channel and what was expected, and
`rblog check` of it one line and exit 2. Before the reader's validation (rblog/record/validate.py)
each gave IndexError / ValueError / DecodeError from numpy or protobuf."""

from __future__ import annotations

import io

import numpy as np
import pytest
from click.testing import CliRunner

import rblog
from rblog.errors import LogReadError
from rblog.record import McapRecorder
from rblog_cli.main import main

from conftest import SAMPLES_DIR


@pytest.fixture(scope="module")
def ball_mcap(tmp_path_factory):
    """0.5 s of the bouncing ball (it lands at t = sqrt(2 m / g) = 0.45 s: contact rows)."""
    d = tmp_path_factory.mktemp("bad_contents")
    scene = rblog.load_scene(SAMPLES_DIR / "bouncing_ball.toml")
    path = d / "ball.mcap"
    rblog.run(scene, duration=0.5, log_every=1, recorders=[McapRecorder(str(path))])
    return path


def _rewrite_mcap(src, dst, mutate):
    """Copy an MCAP file message by message through mcap's own writer (so framing and CRCs are
    valid), with ``mutate(kind, msg, index)`` editing the decoded rblog messages in place (or
    returning raw bytes to write instead); ``index`` counts the messages of that kind."""
    from mcap.reader import make_reader
    from mcap.writer import Writer
    from mcap_protobuf.decoder import DecoderFactory

    factory = DecoderFactory()
    out = io.BytesIO()
    w = Writer(out)
    w.start()
    schema_ids, channel_ids, counts = {}, {}, {}
    with open(src, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            if schema.id not in schema_ids:
                schema_ids[schema.id] = w.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channel_ids:
                channel_ids[channel.id] = w.register_channel(
                    channel.topic, channel.message_encoding, schema_ids[schema.id], channel.metadata)
            data = message.data
            if schema.name.startswith("rblog."):
                kind = schema.name[len("rblog."):]
                i = counts.get(kind, 0)
                counts[kind] = i + 1
                msg = factory.decoder_for(channel.message_encoding, schema)(data)
                got = mutate(kind, msg, i)
                data = got if isinstance(got, bytes) else msg.SerializeToString()
            w.add_message(channel_ids[channel.id], message.log_time, data, message.publish_time)
    w.finish()
    dst.write_bytes(out.getvalue())
    return dst


def _first_contacts(edit):
    def mutate(kind, msg, i):
        if kind == "Contacts" and i == 0:
            edit(msg)
    return mutate


def _drop_last(field):
    def edit(msg):
        del getattr(msg, field)[-1]
    return edit


def _set_first(field, value):
    def edit(msg):
        getattr(msg, field)[0] = value
    return edit


def _set_step(msg):
    msg.step = -7


def _corrupt_state(kind, msg, i):
    if kind == "State" and i == 3:
        return b"\x1a\xff\xff\xff\xff\x0f"  # field 3 (position), length 2^32-1: past the end


MUTATIONS = {
    # (mutation, what the one line must name)
    "separation shorter than body_a": (_first_contacts(_drop_last("separation")),
                                       ["separation", "expected"]),
    "point not a multiple of 3": (_first_contacts(_drop_last("point")), ["point", "3 for each"]),
    "body_a out of range": (_first_contacts(_set_first("body_a", 99)), ["body_a", "99"]),
    "body_b out of range": (_first_contacts(_set_first("body_b", -5)), ["body_b", "-5"]),
    "kind not 0 or 1": (_first_contacts(_set_first("kind", 7)), ["kind", "7"]),
    "non-finite separation": (_first_contacts(_set_first("separation", float("inf"))),
                              ["separation", "finite"]),
    "step matching no sample": (_first_contacts(_set_step), ["step -7", "matches no sample"]),
    "corrupt State protobuf": (_corrupt_state, ["/rblog/state", "protobuf"]),
}


def _one_line_error(path, needles):
    with pytest.raises(LogReadError) as err:
        rblog.load(path)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(str(path)), msg
    for n in needles:
        assert n in msg, msg
    res = CliRunner().invoke(main, ["check", str(path)])
    assert res.exit_code == 2, res.output
    assert res.exception is None or isinstance(res.exception, SystemExit), res.exception
    errors = [line for line in res.output.splitlines() if line.startswith("rblog: error")]
    assert len(errors) == 1 and str(path) in errors[0] and needles[0] in errors[0], res.output
    assert "IndexError" not in res.output and "ValueError" not in res.output, res.output


def test_the_copy_itself_reads_back(ball_mcap, tmp_path):
    """The rewriting does not by itself damage the log: an unmutated copy reads back the same."""
    copy = _rewrite_mcap(ball_mcap, tmp_path / "copy.mcap", lambda kind, msg, i: None)
    a, b = rblog.load(ball_mcap), rblog.load(copy)
    assert len(a.contacts) > 0 and a.n_samples == b.n_samples
    assert np.array_equal(a.position, b.position) and np.array_equal(a.contacts.point, b.contacts.point)


@pytest.mark.parametrize("case", sorted(MUTATIONS))
def test_mutated_mcap_is_one_line(ball_mcap, tmp_path, case):
    mutate, needles = MUTATIONS[case]
    bad = _rewrite_mcap(ball_mcap, tmp_path / "bad.mcap", mutate)
    _one_line_error(bad, needles)


def _run_record(edit):
    def mutate(kind, msg, i):
        if kind == "Run":
            edit(msg)
    return mutate


@pytest.mark.parametrize("field, value, needles", [
    ("body_mass", [], ["body_mass", "expected 1"]),
    ("body_mass", [-1.0], ["body_mass", "positive"]),
    ("body_inertia_diag", [0.004, 0.004], ["body_inertia_diag", "expected 3"]),
    ("body_shape", [5], ["body_shape", "5"]),
    ("gravity", [0.0, 0.0], ["gravity", "expected 3"]),
    ("body_size", [float("nan"), 0.0, 0.0], ["body_size", "finite"]),
])
def test_mutated_body_table_is_one_line(ball_mcap, tmp_path, field, value, needles):
    def edit(msg):
        del getattr(msg, field)[:]
        getattr(msg, field).extend(value)
    bad = _rewrite_mcap(ball_mcap, tmp_path / "bad.mcap", _run_record(edit))
    _one_line_error(bad, needles)


def _varint(x: int) -> bytes:
    out = bytearray()
    while True:
        b, x = x & 0x7F, x >> 7
        out.append(b | (0x80 if x else 0))
        if not x:
            return bytes(out)


def _rewrite_rrd(src, dst, edit):
    """Copy an .rrd file message by message, with ``edit(entity, batch)`` returning a changed
    pyarrow RecordBatch (or None: unchanged) for the recording's chunks; the changed batch is
    encoded as the writer does (Arrow IPC stream, LZ4 block, the ArrowMsg's size and payload
    fields replaced), so the result is a well-framed file whose contents are what ``edit`` made."""
    import struct

    import pyarrow as pa

    from rblog.record import safe_rrd

    data = src.read_bytes()
    msgs, _ = safe_rrd.messages(src)
    out = bytearray(data[:safe_rrd.HEADER_BYTES])
    end = safe_rrd.HEADER_BYTES
    for off, kind, payload in msgs:
        payload = bytes(payload)
        end = off + 16 + len(payload)
        if kind == safe_rrd.KIND_ARROW:
            store, _, batch = safe_rrd.decode_arrow_msg(payload)
            entity = (batch.schema.metadata or {}).get(b"rerun:entity_path", b"").decode()
            new = edit(entity, batch) if store == safe_rrd.STORE_RECORDING else None
            if new is not None:
                sink = pa.BufferOutputStream()
                with pa.ipc.new_stream(sink, new.schema) as w:
                    w.write_batch(new)
                raw = sink.getvalue().to_pybytes()
                body = pa.compress(raw, codec="lz4_raw", asbytes=True)
                f = safe_rrd._fields(payload)
                f[3], f[5] = len(raw), body
                payload = b"".join(
                    _varint(num << 3 | (0 if isinstance(v, int) else 2))
                    + (_varint(v) if isinstance(v, int) else _varint(len(v)) + v)
                    for num, v in sorted(f.items()))
        out += struct.pack("<QQ", kind, len(payload)) + payload
    out += data[end:]  # the footer
    dst.write_bytes(bytes(out))
    return dst


def _replace_column(batch, name, array):
    import pyarrow as pa

    i = next(i for i, f in enumerate(batch.schema)
             if (f.metadata or {}).get(b"rerun:component", b"").decode().endswith(name))
    field = batch.schema.field(i)
    cols = [array if j == i else batch.column(j) for j in range(batch.num_columns)]
    schema = batch.schema.set(i, pa.field(field.name, array.type, field.nullable, field.metadata))
    return pa.RecordBatch.from_arrays(cols, schema=schema)


@pytest.fixture(scope="module")
def ball_rrd(tmp_path_factory):
    from rblog.record import RerunRecorder

    d = tmp_path_factory.mktemp("bad_rrd")
    scene = rblog.load_scene(SAMPLES_DIR / "bouncing_ball.toml")
    path = d / "ball.rrd"
    rblog.run(scene, duration=0.5, log_every=1, recorders=[RerunRecorder(str(path))])
    return path


def test_the_rrd_copy_itself_reads_back(ball_rrd, tmp_path):
    def same(entity, batch):  # re-encoded but equal
        return batch if entity.endswith("rblog/model") else None

    copy = _rewrite_rrd(ball_rrd, tmp_path / "copy.rrd", same)
    a, b = rblog.load(ball_rrd), rblog.load(copy)
    assert np.array_equal(a.position, b.position) and a.model.ground_offset == b.model.ground_offset
    assert len(a.contacts) > 0


@pytest.mark.parametrize("field, values, needles", [
    ("ground_offset", [], ["ground_offset", "expected 1"]),
    ("body_mass", [], ["body_mass", "expected 1"]),
    ("body_size", [0.1, 0.0], ["body_size", "expected 3"]),
])
def test_rrd_with_a_mutated_model_field(ball_rrd, tmp_path, field, values, needles):
    """The Rerun log's model entity with a field of the wrong length (ground_offset = [], a
    scalar with no value: IndexError in model_from_arrays before)."""
    import pyarrow as pa

    def edit(entity, batch):
        if not entity.endswith("rblog/model"):
            return None
        return _replace_column(batch, field, pa.array([values], pa.list_(pa.float64())))

    bad = _rewrite_rrd(ball_rrd, tmp_path / "bad.rrd", edit)
    _one_line_error(bad, needles)


def test_contact_rows_past_a_cut_are_dropped(ball_mcap, tmp_path):
    """A log cut short whose last contact rows lost their samples is read up to the cut, the
    orphan rows dropped with a warning (not refused): the status says truncated, and the last
    Contacts message is moved past every sample."""
    traj = rblog.load(ball_mcap)
    n_last = len(np.unique(traj.contacts.step)) - 1  # one Contacts message per step with contacts
    beyond = int(traj.step[-1]) + 5

    def mutate2(kind, msg, i):
        if kind == "Status":
            msg.truncated = True
            msg.reason = "cut"
        if kind == "Contacts" and i == n_last:
            msg.step = beyond

    cut = _rewrite_mcap(ball_mcap, tmp_path / "cut.mcap", mutate2)
    got = rblog.load(cut)
    assert got.truncated and any("contact row" in w for w in got.warnings), got.warnings
    assert beyond not in set(got.contacts.step.tolist())
    assert len(got.contacts) < len(traj.contacts)
