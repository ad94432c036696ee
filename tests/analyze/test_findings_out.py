"""Findings where people look: `rblog check --rrd` (a Rerun recording with the run's recording id),
`rblog findings LOG OUT.mcap` (foxglove.Log messages), and `rblog convert` (.mcap -> .rrd keeps the
geometry), on the log of a pybullet run with a real fault (its second bounce keeps e = 0.21 of
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


def test_check_rrd_writes_findings_with_the_runs_recording_id(logs):
    traj, paths, d = logs
    n_findings = sum(len(r.findings) for r in check(load(paths[".rrd"])))
    assert n_findings >= 1
    out = d / "findings.rrd"
    res = _cli("check", paths[".rrd"], "--rrd", out)
    assert res.exit_code == 1, res.output
    run_store, _ = _chunks(paths[".rrd"])
    store, chunks = _chunks(out)
    assert store.recording_id == run_store.recording_id
    ents = {c.entity_path for c in chunks}
    assert {"/findings", "/world/findings/bodies", "/world/findings/impacts"} <= ents, ents
    # one text-log row per finding (plus the static header)
    rows = sum(c.num_rows for c in chunks if c.entity_path == "/findings" and not c.is_static)
    assert rows == n_findings


def test_findings_as_foxglove_log_in_mcap(logs):
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    traj, paths, d = logs
    results = check(load(paths[".mcap"]))
    want = sorted(round(f.t * 1e9) for r in results for f in r.findings)
    out = d / "findings.mcap"
    res = _cli("findings", paths[".mcap"], out)
    assert res.exit_code == 1, res.output
    with open(out, "rb") as f:
        msgs = list(make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages())
    assert [s.name for s, *_ in msgs] == ["foxglove.Log"] * len(want)
    assert [m.log_time for _, _, m, _ in msgs] == want
    assert all(p.level == 4 and "limit" in p.message for *_, p in msgs)  # 4: ERROR


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
