"""docs/recording.md's "Audit your MuJoCo or pybullet model" example runs as written, and says
what it prints."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


README = (REPO / "docs" / "recording.md").read_text(encoding="utf-8")


def _example() -> str:
    text = README
    sec = text.split("## Audit your MuJoCo or pybullet model", 1)[1]
    return re.search(r"```python\n(.*?)```", sec, re.S).group(1)


def test_readme_mujoco_example_runs(tmp_path, monkeypatch, capsys):
    pytest.importorskip("mujoco")
    monkeypatch.chdir(tmp_path)
    ns: dict = {}
    exec(compile(_example(), "docs/recording.md", "exec"), ns)  # noqa: S102 - the repo's docs
    out = capsys.readouterr().out
    assert (tmp_path / "crate.mcap").exists()
    lines = [ln.split()[:2] for ln in out.splitlines()]
    assert [a for a, _ in lines] == ["consistency", "drift", "momentum", "penetration", "energy",
                                     "tunneling", "joints"]
    verdict = dict(lines)
    # README: penetration fails (the corner digs 17.7 mm at the impact), the rest pass (a free
    # crate has no joints: skip)
    assert verdict.pop("joints") == "SKIP"
    assert verdict.pop("penetration") == "FAIL" and set(verdict.values()) == {"pass"}, out
    quoted = re.search(r"```text\n(penetration FAIL .*)\n```", README).group(1)
    assert quoted in out
    import numpy as np

    import rblog
    from rblog.contract.orientation import quat_wxyz_to_matrix

    traj = rblog.load(tmp_path / "crate.mcap")
    assert traj.model.body_name == ["crate"] and len(traj.contacts.step) > 0
    # the deepest corner from the logged poses by numpy (README's 17.7 mm), and the rest sink
    corners = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)]) * [0.1, 0.15, 0.05]
    r = quat_wxyz_to_matrix(traj.quat_wxyz[:, 0])
    lowest = (traj.position[:, 0, 2][:, None] + np.einsum("tj,kj->tk", r[:, 2], corners)).min(axis=1)
    assert -lowest.min() == pytest.approx(0.0177, abs=5e-5)
    assert 0.0 < -lowest[-1] < 2e-4 and abs(traj.velocity[-1, 0]).max() < 1e-3
