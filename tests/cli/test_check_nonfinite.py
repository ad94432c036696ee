"""`rblog check` on a log whose figures are not finite: its report prints them, no traceback."""

from __future__ import annotations

from click.testing import CliRunner

from rblog_cli.main import main

#: the notes' scheme without orthonormalization at h w = 100: R's first column grows by
#: sqrt(1 + h^2 w^2) per step, so ortho_error overflows to inf within ~40 steps and the state near
#: step 155 (tests/engine/test_runner.py's diverging run)
DIVERGING = """
[sim]
dt = 1.0
duration = 1000.0
gravity = [0, 0, 0]
integrator = "seed"
orthonormalize = "none"
log_every = 1
[[body]]
name = "spinner"
shape = "sphere"
radius = 0.1
mass = 1.0
angular_velocity = [0.0, 0.0, 100.0]
"""


def test_check_reports_a_non_finite_finding(tmp_path):
    scene = tmp_path / "div.toml"
    scene.write_text(DIVERGING)
    log = tmp_path / "d.mcap"
    run = CliRunner().invoke(main, ["run", str(scene), "--mcap", str(log)])
    assert run.exit_code == 3, run.output
    res = CliRunner().invoke(main, ["check", str(log)])
    assert res.exception is None or isinstance(res.exception, SystemExit), repr(res.exception)
    assert res.exit_code == 1, res.output
    assert "FAIL consistency" in res.output and ": nan (tol" in res.output
