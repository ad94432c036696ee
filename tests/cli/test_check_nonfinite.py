"""`rblog check` on a log whose figures are not finite: its report prints them, no traceback."""

from __future__ import annotations

from click.testing import CliRunner

from rblog_cli.main import main

from conftest import DIVERGING  # ortho_error overflows to inf, the state near step 155


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
