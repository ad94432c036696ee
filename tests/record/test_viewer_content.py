"""What the Rerun viewer is handed: a finding's row stands at the finding's onset, and the series
of one plot have colours that cannot be taken for each other.

Before: the drift finding of a stretching box stood at the end of the run (+2 s) though the drift
began at the first logged step, so scrubbing to the row showed the end; the energy plot's four
series and the momentum plot's six were the viewer's own picks (near-identical blues and
purples).
"""

from __future__ import annotations

import itertools
import warnings

import numpy as np
from click.testing import CliRunner

import rblog
from rblog.analyze import tolerances as T
from rblog.record import rerun_writer as W
from rblog_cli.main import main

from conftest import SAMPLES_DIR

#: the least distance (RGB, 0-255 each) between two series of one plot: the distance from pure
#: red to orange (255, 127, 0) is 127; two blues the viewer picks differ by ~40
MIN_RGB_DISTANCE = 90
#: the Rerun viewer's plot background in its dark theme (read off a screenshot: (13, 13, 13))
VIEWER_BACKGROUND_RGB = (13, 13, 13)
#: WCAG's contrast ratio for graphics (lines) against their background
MIN_CONTRAST = 3.0


def _contrast(a, b) -> float:
    """WCAG 2 contrast ratio of two sRGB colours (0-255): (L1 + 0.05) / (L2 + 0.05)."""
    def lum(c):
        c = np.asarray(c, float) / 255.0
        lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
        return float(lin @ [0.2126, 0.7152, 0.0722])
    la, lb = sorted((lum(a), lum(b)), reverse=True)
    return (la + 0.05) / (lb + 0.05)


def _chunks(path, entity):
    import rerun as rr

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = rr.chunk.RrdReader(str(path))
        return [c for c in r.stream(store=r.recordings()[0]) if c.entity_path == entity]


def _column(chunk, name):
    b = chunk.to_record_batch()
    return b.column(b.schema.names.index(name)).to_pylist()


def test_finding_row_stands_at_its_onset(tmp_path):
    """The notes' scheme without orthonormalization stretches R from the first step: the onset is
    the first logged sample whose ||R^T R - I||_F (computed here by numpy from the logged
    matrices) passes the drift tolerance; the row of the finding in the .rrd is at that time."""
    log, out = tmp_path / "stretch.mcap", tmp_path / "checked.rrd"
    r = CliRunner().invoke(main, ["run", str(SAMPLES_DIR / "tumbling_box.toml"), "--integrator",
                                  "seed", "--orthonormalize", "none", "--duration", "2",
                                  "--mcap", str(log)])
    assert r.exit_code == 0, r.output
    traj = rblog.load(log)
    rt_r = np.einsum("tnji,tnjk->tnik", traj.rotation, traj.rotation) - np.eye(3)
    err = np.linalg.norm(rt_r, axis=(2, 3))[:, 0]
    onset = int(np.argmax(err > T.DRIFT_ORTHO_ERROR))
    assert err[onset] > T.DRIFT_ORTHO_ERROR and onset < traj.n_samples // 10
    r = CliRunner().invoke(main, ["findings", str(log), str(out)])
    assert r.exit_code == 1, r.output
    rows = [c for c in _chunks(out, "/findings/drift") if not c.is_static]
    times = [t.total_seconds() for c in rows for t in _column(c, "sim_time")]
    assert times == [traj.t[onset]], (times, traj.t[onset])
    # and the finding itself still names its worst value, at the end of the run
    assert float(traj.t[-1]) == 2.0


def _rgb(packed: int) -> np.ndarray:
    return np.array([(packed >> 24) & 255, (packed >> 16) & 255, (packed >> 8) & 255], float)


def test_plot_series_have_distinct_colours(tmp_path):
    path = tmp_path / "b.rrd"
    r = CliRunner().invoke(main, ["run", str(SAMPLES_DIR / "free_fall.toml"), "--rrd", str(path),
                                  "--duration", "0.1"])
    assert r.exit_code == 0, r.output
    for plot, entities in (("energy", ["total", "translational", "rotational", "potential"]),
                           ("momentum", ["linear", "angular"])):
        colours = []
        for e in entities:
            static = [c for c in _chunks(path, f"/plots/{plot}/{e}") if c.is_static]
            assert static, (plot, e)
            colours += [_rgb(v) for v in _column(static[0], "SeriesLines:colors")[0]]
        assert len(colours) == (4 if plot == "energy" else 6)
        for a, b in itertools.combinations(colours, 2):
            assert np.linalg.norm(a - b) >= MIN_RGB_DISTANCE, (plot, a, b)
        # every line stands out from the dark background (total energy was (40, 40, 40) and
        # L_y (70, 70, 70): contrasts 1.3 and 2.0, near invisible in the screenshot of `mixed`)
        for c in colours:
            assert _contrast(c, VIEWER_BACKGROUND_RGB) >= MIN_CONTRAST, (plot, c)
    assert set(W.SERIES_COLOURS) == {f"plots/energy/{e}" for e in
                                     ("total", "translational", "rotational", "potential")} | {
        "plots/momentum/linear", "plots/momentum/angular"}
