"""The velocity solve's kernels give bitwise the same logs (issue 29: wide SIMD with a scalar twin).

The colours of the constraint graph are solved four manifolds at a time, in AVX2 registers where
the processor has them, else in pairs of 128-bit ones, or one lane after another by the scalar
kernel (csrc/engine/contact_lanes.hpp); every lane does the scalar code's operations in its
order, so the three must give the same bytes. Each run is a fresh process with
RBLOG_SOLVER_PATH set (read when the core is imported), and the .mcap records and the .rrd
samples are compared byte for byte (test_thread_determinism's _same_logs).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import SAMPLES_DIR

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "cli"))
from test_thread_determinism import RBLOG, _same_logs  # noqa: E402


def _run(tmp_path, scene, path, duration, threads=1):
    rrd, mcap = tmp_path / f"{scene.stem}-{path}.rrd", tmp_path / f"{scene.stem}-{path}.mcap"
    env = {**os.environ, "RBLOG_SOLVER_PATH": path, "RBLOG_THREADS": str(threads)}
    p = subprocess.run([RBLOG, "run", str(scene), "--duration", str(duration), "--rrd", str(rrd),
                        "--mcap", str(mcap)], env=env, capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    return rrd, mcap


def test_solver_path_switch():
    from rblog.engine import _core

    kernel = _core.solver_kernel()
    try:
        _core.set_solver_path("scalar")
        assert _core.solver_kernel() == "scalar"
        _core.set_solver_path("sse2")
        assert _core.solver_kernel() == "sse2"
        with pytest.raises(ValueError):
            _core.set_solver_path("avx512")
    finally:
        _core.set_solver_path("auto")
    assert _core.solver_kernel() in ("avx2", "scalar")
    assert kernel in ("avx2", "sse2", "scalar")


@pytest.mark.parametrize("sample,duration", [("pile", 0.6), ("mixed", 1.0)])
def test_scalar_and_wide_kernels_log_same_bytes(tmp_path, sample, duration):
    """pile: at 0.6 s the two lowest layers have landed (hundreds of manifolds, box faces of four
    points in the block solve, friction at the disc); mixed: spheres, boxes, a ramp."""
    scene = SAMPLES_DIR / f"{sample}.toml"
    scalar = _run(tmp_path, scene, "scalar", duration)
    traj = _same_logs(scalar, _run(tmp_path, scene, "auto", duration))
    _same_logs(scalar, _run(tmp_path, scene, "sse2", duration))
    assert len(traj.contacts) > 0  # bodies did touch
