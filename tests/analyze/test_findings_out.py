"""Findings where people look: `rblog check --rrd` (one Rerun recording with the run and its
findings), `rblog check --mcap` / `rblog findings LOG OUT.mcap` (the run with foxglove.Log messages
and markers), and `rblog convert` (.mcap -> .rrd keeps the geometry), on the log of a pybullet run with a real fault (its second bounce keeps e = 0.21 of
a configured 0.8)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from rblog.analyze import check
from rblog.record import McapRecorder, RerunRecorder, load

pytest.importorskip("pybullet")
from engine_logs import engine_samples, to_trajectory  # noqa: E402

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    traj = to_trajectory(engine_samples("pybullet", str(REPO / "samples" / "bouncing_ball.toml"),
                                        log_every=10))
    d = tmp_path_factory.mktemp("findings")
    paths = {}
    for ext, cls in ((".rrd", RerunRecorder), (".mcap", McapRecorder)):
        p = d / f"pybullet_ball{ext}"
        rec = cls(str(p))
        rec.open(traj.model, traj.info)
        rec.write(traj)
        rec.close()
        paths[ext] = p
    return traj, paths, d


def _cli(*args):
    from rblog_cli.main import main

    return CliRunner().invoke(main, [str(a) for a in args])


def _chunks(path):
    import rerun as rr

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = rr.chunk.RrdReader(str(path))
        store = r.recordings()[0]
        return store, list(r.stream(store=store))


@pytest.mark.parametrize("kind", [".rrd", ".mcap"])
def test_check_rrd_writes_one_recording_with_the_run_and_its_findings(logs, kind):
    """`rblog check LOG --rrd F.rrd` writes ONE file with the run and the findings, for an .rrd
    and an .mcap log alike, and prints the command that opens exactly that file. (Before, an
    .mcap log gave a findings-only file with a fresh recording id and the command `rerun
    LOG.mcap F.rrd`, which opens two unrelated recordings.)"""
    traj, paths, d = logs
    results = check(load(paths[kind]))
    n_findings = sum(len(r.findings) for r in results)
    assert n_findings >= 1
    out = d / f"checked-from{kind.replace('.', '-')}.rrd"
    res = _cli("check", paths[kind], "--rrd", out)
    assert res.exit_code == 1, res.output
    from rblog_cli.report import program

    assert f"(open with: {program('rerun')} {out})" in res.output, res.output
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import rerun as rr

        assert len(rr.chunk.RrdReader(str(out)).recordings()) == 1
    store, chunks = _chunks(out)
    ents = {c.entity_path for c in chunks}
    assert {"/rblog/state", "/world/bodies/spheres", "/world/findings/bodies"} <= ents, ents
    # the run itself reads back from the file, sample for sample
    back = load(out)
    np.testing.assert_array_equal(back.position, traj.position)
    # one temporal text-log row per line of each finding's wrapped text, and nothing static on
    # the findings entities: a static row hides every temporal row of its entity in the viewer
    from rblog.record.findings import finding_rows

    text = [c for c in chunks if c.entity_path.startswith("/findings")]
    assert not [c for c in text if c.is_static], [c.entity_path for c in text]
    rows = finding_rows(traj, check(traj))
    assert len(rows) == n_findings
    assert sum(c.num_rows for c in text) == sum(len(w.lines) for w in rows)


def test_findings_rows_name_analyzer_body_value_limit_and_message(logs):
    from rblog.record.findings import finding_rows

    traj, paths, d = logs
    results = check(traj)
    rows = finding_rows(traj, results)
    assert rows and [w.t for w in rows] == sorted(w.t for w in rows)
    for w in rows:
        analyzer, body, value, message = w.text.split(" | ", 3)
        assert analyzer in {r.analyzer for r in results}
        assert body == "ball", w.text
        assert value.startswith("value ") and " vs limit " in value, w.text
        assert message == next(f.message for r in results for f in r.findings
                               if r.analyzer == w.analyzer and f.t == w.t)


def test_a_long_finding_wraps_into_rows_that_fit_the_table():
    """The Rerun findings table shows one line of text per row and cuts a longer one at the
    panel's edge: a finding's text is wrapped into lines of at most FINDINGS_WRAP_CHARS, every
    word kept, in order."""
    from rblog.record.findings import FINDINGS_WRAP_CHARS, Row

    message = " ".join(f"word{k}" for k in range(120))  # ~900 characters
    w = Row("energy", 20.0, 2000, [0], "box", 0.0086, 0.001, "1", message)
    assert len(w.lines) >= len(w.text) // FINDINGS_WRAP_CHARS
    assert all(len(line) <= FINDINGS_WRAP_CHARS for line in w.lines), w.lines
    assert " ".join(line.strip() for line in w.lines) == w.text
    assert all(line.startswith("    ") for line in w.lines[1:])  # continuations indented
    assert Row("drift", 0.0, 0, [0], "box", 1.0, 1e-6, "1", "short").lines == [
        "drift | box | value 1 vs limit 1e-06 | short"]


def test_check_mcap_writes_the_run_with_foxglove_logs_and_markers(logs):
    """`rblog check LOG --mcap F.mcap` (and `rblog findings LOG F.mcap`): one MCAP file with the
    run, the findings as foxglove.Log and SceneUpdate markers on the flagged bodies' frames;
    rblog reads the run back from it."""
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    traj, paths, d = logs
    results = check(load(paths[".rrd"]))
    want = sorted(round(f.t * 1e9) for r in results for f in r.findings)
    for args, out in ((("check", paths[".rrd"], "--mcap"), d / "checked.mcap"),
                      (("findings", paths[".mcap"]), d / "findings.mcap")):
        res = _cli(*args, out)
        assert res.exit_code == 1, res.output
        assert "Foxglove" in res.output, res.output
        with open(out, "rb") as f:
            msgs = list(make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages(
                topics=["/rblog/findings", "/rblog/findings/markers"]))
        logs_ = [(m.log_time, p) for s, c, m, p in msgs if c.topic == "/rblog/findings"]
        marks = [(m.log_time, p) for s, c, m, p in msgs if c.topic == "/rblog/findings/markers"]
        assert [t for t, _ in logs_] == want
        assert all(p.level == 4 and " vs limit " in p.message for _, p in logs_)  # 4: ERROR
        assert len(marks) == len(want)
        ents = [e for _, p in marks for e in p.entities]
        assert {e.frame_id for e in ents} == {"ball"}
        assert all(e.spheres and e.texts and e.lifetime.ToNanoseconds() > 0 for e in ents)
        back = load(out)
        np.testing.assert_array_equal(back.position, traj.position)


def test_convert_mcap_to_rrd_keeps_shapes_and_state(logs):
    traj, paths, d = logs
    out = d / "converted.rrd"
    res = _cli("convert", paths[".mcap"], out)
    assert res.exit_code == 0, res.output
    _, chunks = _chunks(out)
    ents = {c.entity_path for c in chunks}
    assert {"/world/bodies/spheres", "/world/ground", "/rblog/state"} <= ents, ents
    a, b = load(paths[".mcap"]), load(out)
    np.testing.assert_array_equal(a.position, b.position)
    assert len(a.contacts) == len(b.contacts)


def test_convert_rejects_an_unknown_extension(logs):
    traj, paths, d = logs
    res = _cli("convert", paths[".mcap"], d / "out.txt")
    assert res.exit_code == 2 and "must end in .rrd or .mcap" in res.output


def test_convert_mcap_to_rrd_carries_boxes_and_static_boxes(tmp_path):
    """A box and a sphere over a static box, written to .mcap by the writer API: the converted
    .rrd has every shape kind's view entity, so Rerun shows the shapes."""
    import rblog

    model = rblog.body_table(name=["box", "ball"], shape=["box", "sphere"],
                             size=[[0.1, 0.05, 0.02], [0.1, 0, 0]], mass=[1.0, 1.0], ground=True,
                             static_box_position=[[0, 0, 0.5]], static_box_quat_wxyz=[[1, 0, 0, 0]],
                             static_box_half_extents=[[0.5, 0.5, 0.1]])
    k = 5
    src = tmp_path / "two.mcap"
    with rblog.Recorder(model, mcap=str(src), dt=0.01) as rec:
        rec.write(t=np.arange(k) * 0.01, position=np.tile([[0, 0, 1.0], [0.3, 0, 1.0]], (k, 1, 1)),
                  quat_wxyz=np.tile([1.0, 0, 0, 0], (k, 2, 1)), velocity=np.zeros((k, 2, 3)),
                  angular_velocity=np.zeros((k, 2, 3)))
    out = tmp_path / "two.rrd"
    res = _cli("convert", src, out)
    assert res.exit_code == 0, res.output
    _, chunks = _chunks(out)
    ents = {c.entity_path for c in chunks}
    assert {"/world/bodies/boxes", "/world/bodies/spheres", "/world/ground",
            "/world/statics/0"} <= ents, ents
