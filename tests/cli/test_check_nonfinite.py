"""`rblog check` on a log whose figures are not finite: its report prints them, no traceback."""

from __future__ import annotations

import math
import re
import warnings

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
    assert "FAIL consistency" in res.output and ": not finite (tol" in res.output
    assert "nan" not in res.output


def test_drift_of_an_overflowing_rotation_names_its_exponential_rate(tmp_path):
    """Seed Euler without re-orthonormalization multiplies R by (I + h [w]x) each step, whose
    singular values are 1, sqrt(1 + (w h)^2) (twice): ||R^T R - I|| grows as (1 + (w h)^2)^k, an
    e-folding rate ln(1 + (w h)^2) / h = ln(10001) = 9.2104/s for w = 100 rad/s, h = 1 s, until it
    overflows. The report says so without a NaN or a numpy warning."""
    import rblog

    scene = tmp_path / "div.toml"
    scene.write_text(DIVERGING)
    log = tmp_path / "d.mcap"
    CliRunner().invoke(main, ["run", str(scene), "--mcap", str(log)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        (drift,) = rblog.check(rblog.load(log), only=["drift"])
    (f,) = drift.findings
    assert "is not finite from" in f.message, f.message
    rate = float(re.search(r"e-folding rate ([0-9.]+)/s", f.message).group(1))
    assert abs(rate - math.log(1 + 100.0 ** 2)) < 5e-3, f.message  # printed to 3 digits: 9.21
