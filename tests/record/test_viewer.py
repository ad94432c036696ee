"""The real Rerun viewer opens a sample run's .rrd, headless, and shows it without errors.

The native viewer from the rerun-sdk wheel runs with ``--headless`` (no window, no X server) on
Mesa's software Vulkan driver (Debian's ``mesa-vulkan-drivers``, lavapipe); it is driven through
its control API by ``scripts/screenshot.py``. Each test takes a few seconds.

Without that driver the tests skip and say why, except under CI (``CI`` set), where .ci/run
installs it and its absence is a failure.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("rblog_screenshot", REPO / "scripts" / "screenshot.py")
shot = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = shot  # dataclasses look their module up by name
_spec.loader.exec_module(shot)


@pytest.fixture(scope="module")
def viewer_ready():
    """Skip (saying why) when a system piece the headless viewer needs is missing; fail in CI."""
    why = shot.software_vulkan_missing()
    if why is None:
        try:
            shot.rerun_executable()
        except shot.ViewerUnavailable as e:
            why = str(e)
    if why is None:
        return
    why = f"headless Rerun viewer unavailable: {why}"
    if os.environ.get("CI"):
        pytest.fail(f"{why} (CI must install it: see .ci/run)")
    print(f"\nSKIP {why}", file=sys.__stderr__)
    warnings.warn(why)
    pytest.skip(why)


@pytest.fixture(scope="module")
def sample_rrd(tmp_path_factory) -> Path:
    """A sample run, recorded by rblog's own CLI: boxes and spheres, a static ramp, the ground
    and contacts, so that every view entity rblog writes is visualized."""
    rrd = tmp_path_factory.mktemp("viewer") / "mixed.rrd"
    shot.record_sample(REPO / "samples" / "mixed.toml", rrd)
    assert rrd.stat().st_size > 10_000
    return rrd


def _fmt(cap) -> str:
    return "\n".join(cap.problems) + "\n--- viewer stderr (tail) ---\n" + cap.stderr[-4000:]


def test_viewer_shows_a_sample_run_without_errors(viewer_ready, sample_rrd, tmp_path):
    png = tmp_path / "viewer.png"
    cap = shot.capture(sample_rrd, png, timeout=120.0, per_view=True)
    print(f"screenshot {png} after {cap.seconds:.1f} s")

    # every view is there, visible, and reported nothing; the viewer logged no error or warning
    classes = sorted(v.view_class for v in cap.views)
    assert "3D" in classes and classes.count("TimeSeries") >= 3, classes
    assert all(v.visible for v in cap.views), cap.views
    assert not cap.view_problems, _fmt(cap)
    assert not cap.log_errors, _fmt(cap)
    assert not cap.stderr_errors, _fmt(cap)

    # it loaded the whole run and sits at its end
    rec = next(r for r in cap.state.recordings if r.store_id == cap.state.active_recording)
    timelines = {t.name: t for t in rec.timelines}
    assert timelines["sim_time"].end == pytest.approx(4e9, rel=1e-6), rec.timelines  # 4 s run
    assert rec.current_timeline == "sim_time" and rec.current_time == timelines["sim_time"].end

    # the screenshot is a real, rendered frame, not a blank or single-colour image
    whole = shot.image_stats(png)
    assert whole["shape"][:2] == (shot.DEFAULT_SIZE[1], shot.DEFAULT_SIZE[0]), whole
    assert whole["std"] > 10 and whole["colours"] > 200, whole
    assert whole["non_background_fraction"] > 0.05, whole
    # the 3D view shows the (coloured) bodies, each plot a coloured line
    for v in cap.views:
        stats = shot.image_stats(cap.view_pngs[v.view_id])
        assert stats["std"] > 5 and stats["non_background_fraction"] > 0.01, (v.name, stats)
        if v.view_class == "3D":
            # the camera frames every body over the run: mixed.toml's balls end spread over
            # 9.7 m, so its 17 bodies of 0.1-0.2 m are small; measured 0.0015 of the view's
            # pixels coloured (2026-11-26), a grey or empty view has none
            assert stats["colourful_fraction"] > 0.0005, (v.name, stats)
        else:
            assert stats["colourful_fraction"] > 0.002, (v.name, stats)


def _broken_rrd(path: Path) -> Path:
    """A small recording with what the viewer must complain about: a mesh whose triangle indexes a
    missing vertex, an image in a 3D view with no camera, and a scalar series of strings."""
    code = f"""
import pyarrow as pa, rerun as rr, rerun.blueprint as rrb
rec = rr.RecordingStream("rblog-broken")
rec.save({str(path)!r})
rec.send_blueprint(rrb.Blueprint(rrb.Horizontal(rrb.Spatial3DView(origin="world"),
                                                rrb.TimeSeriesView(origin="plots"))))
rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
rec.log("world/box", rr.Boxes3D(half_sizes=[[0.3, 0.2, 0.1]], colors=[[31, 119, 180]]), static=True)
rec.log("world/mesh", rr.Mesh3D(vertex_positions=[[0, 0, 0], [1, 0, 0], [0, 1, 0]],
                                triangle_indices=[[0, 1, 7]]), static=True)
rec.log("world/image", rr.Image(bytes=bytes(10), width=4, height=4, color_model="RGB",
                                datatype="U8"), static=True)
bad = rr.ComponentDescriptor("Scalars:scalars", archetype="rerun.archetypes.Scalars",
                             component_type="rerun.components.Scalar")
for k in range(20):
    rec.set_time("sim_time", duration=0.1 * k)
    rec.log("plots/good", rr.Scalars([float(k)]))
    rec.log("plots/bad", [rr.AnyBatchValue(bad, pa.array(["oops"]))])
"""
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)
    return path


def test_viewer_check_catches_a_broken_recording(viewer_ready, tmp_path):
    """The checks above are not vacuous: on a recording the viewer cannot fully show, they fire."""
    cap = shot.capture(_broken_rrd(tmp_path / "broken.rrd"), tmp_path / "broken.png", timeout=120.0)
    text = _fmt(cap)
    assert any("pinhole" in p for p in cap.view_problems), text           # a view's own report
    assert any("out of bounds" in p for p in cap.log_errors), text        # viewer log: mesh
    assert any("Scalars:scalars" in p for p in cap.log_errors), text      # viewer log: datatype
    assert shot.image_stats(cap.png)["std"] > 10


def test_viewer_overlays_check_findings_on_a_run(viewer_ready, tmp_path):
    """A pybullet run of the bouncing ball (its second bounce keeps e = 0.21 of 0.8: a real
    fault) written to .rrd, checked with `rblog check --rrd`, and both opened together: the
    findings panel lists the finding and the ball is highlighted at the finding's time."""
    pytest.importorskip("pybullet")
    sys.path.insert(0, str(REPO / "tests" / "analyze"))
    from engine_logs import engine_samples, to_trajectory
    from rblog.analyze import check
    from rblog.record import RerunRecorder
    from rblog.record.findings import run_recording_id, write_findings_rrd

    traj = to_trajectory(engine_samples("pybullet", str(REPO / "samples" / "bouncing_ball.toml"),
                                        log_every=10))
    run = tmp_path / "pybullet_ball.rrd"
    rec = RerunRecorder(str(run))
    rec.open(traj.model, traj.info)
    rec.write(traj)
    rec.close()
    results = check(traj)
    findings = [f for r in results for f in r.findings]
    assert findings, [r.reason for r in results]
    out = tmp_path / "findings.rrd"
    write_findings_rrd(str(out), traj, results, run_recording_id(str(run)))
    first = min(findings, key=lambda f: f.t)
    # the test writes its screenshots beside its logs; RBLOG_REFRESH_DOCS=1 refreshes docs/'s copy
    import os

    png = (REPO / "docs" if os.environ.get("RBLOG_REFRESH_DOCS") else tmp_path) / "findings-overlay.png"
    cap = shot.capture(run, png, timeout=120.0, per_view=True, overlays=[out],
                       at_ns=int(first.t * 1e9))
    print(f"screenshot {png} after {cap.seconds:.1f} s")
    # one recording: the findings merged into the run
    assert len(cap.state.recordings) == 1, cap.state.recordings
    classes = [v.view_class for v in cap.views]
    names = [v.name for v in cap.views]
    assert "TextLog" in classes and "findings" in names, (classes, names)
    assert all(v.visible for v in cap.views), cap.views
    assert not cap.view_problems, _fmt(cap)
    assert not cap.log_errors, _fmt(cap)
    # the findings panel shows text; the 3D view shows the red highlight (R high, G and B low)
    import numpy as np
    from PIL import Image

    v3d = next(v for v in cap.views if v.view_class == "3D")
    img = np.asarray(Image.open(cap.view_pngs[v3d.view_id]).convert("RGB")).astype(int)
    red = (img[..., 0] > 150) & (img[..., 1] < 110) & (img[..., 2] < 110)
    # the ball is ~15 px across in the default camera (measured: 1.4e-5 of the view red); an
    # empty overlay gives exactly 0 (measured before the highlight was made opaque)
    assert red.mean() > 3e-6, red.mean()
    vlog = next(v for v in cap.views if v.view_class == "TextLog")
    assert shot.image_stats(cap.view_pngs[vlog.view_id])["non_background_fraction"] > 0.01
