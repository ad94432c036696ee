"""Report lines count in English: "1 body", "21 bodies"."""

from click.testing import CliRunner

from rblog_cli.main import main
from rblog_cli.report import count
from tests.conftest import SAMPLES_DIR


def test_count_says_one_body_and_many_bodies():
    assert [count(n, "body") for n in (0, 1, 2, 21)] == ["0 bodies", "1 body", "2 bodies", "21 bodies"]
    assert count(1, "sample") == "1 sample" and count(401, "sample") == "401 samples"


def test_run_summary_of_one_body_says_one_body():
    res = CliRunner().invoke(main, ["run", str(SAMPLES_DIR / "bouncing_ball.toml"), "--no-log"])
    assert res.exit_code == 0, res.output
    assert "4000 steps x 1 body," in res.output.splitlines()[0], res.output
