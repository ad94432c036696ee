"""Packaging and documentation that a user meets first: pyproject.toml declares nothing that does
not exist and nothing deprecated, README's scene example loads with every commented setting turned
on, README names no folder the repository lacks, benchmarks leave no MuJoCo log behind."""

from __future__ import annotations

import importlib.util
import os
import re
import tomllib

import pytest

from rblog.engine.scene import parse_scene

from conftest import REPO

PYPROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())
README = (REPO / "README.md").read_text()
#: README and the pages of docs/, where the topics README links to live
DOCS = {p.relative_to(REPO).as_posix(): p.read_text(encoding="utf-8")
        for p in [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]}


def test_license_is_an_spdx_string():
    """A TOML table ``license = {text = ...}`` is deprecated by setuptools (PEP 639)."""
    assert isinstance(PYPROJECT["project"]["license"], str)


def test_package_data_globs_match_files():
    data = PYPROJECT.get("tool", {}).get("setuptools", {}).get("package-data", {})
    for pkg, globs in data.items():
        root = REPO / pkg
        for g in globs:
            assert list(root.glob(g)), f"package-data {pkg}: {g!r} matches no file"


def test_scene_example_loads_with_its_commented_settings():
    """The first ```toml block of docs/scenes.md, with each ``# key = value`` line of [sim]
    uncommented (what a user does to try them), is a valid scene."""
    block = re.search(r"```toml\n(.*?)```", DOCS["docs/scenes.md"], re.S).group(1)
    lines = []
    for ln in block.splitlines():
        m = re.match(r"#\s*(\w+\s*=\s*\S.*)$", ln.strip())
        lines.append(m.group(1) if m else ln)
    scene = parse_scene("\n".join(lines), "docs/scenes.md")
    assert scene.sim.orthonormalize in (None, "normalize")


@pytest.mark.parametrize("page", ["README.md", "docs/scenes.md", "docs/integrators.md",
                                  "docs/contacts.md", "docs/recording.md", "docs/cli.md"])
def test_doc_paths_exist(page):
    """Every repository path README or a topic page quotes in backticks (a/b/ or a/b.ext), and
    every page README links to, exists. (Other pages also quote entity paths of the logs.)"""
    text = DOCS[page]
    for p in re.findall(r"`((?:[\w.-]+/)+[\w.-]*)`", text):
        if p.startswith(("http", ".venv", "/", "findings/", "rblog/status")) or "*" in p:
            continue
        assert (REPO / p).exists(), f"{page} names {p!r}, which the repository does not have"
    if page == "README.md":
        for p in re.findall(r"\]\(((?:docs|benchmarks)/[\w./-]+)\)", text):
            assert (REPO / p).exists(), f"README links to {p!r}, which does not exist"


def _bench_contact():
    spec = importlib.util.spec_from_file_location("bench_contact", REPO / "benchmarks" / "bench_contact.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_benchmark_mujoco_leaves_no_log_in_cwd(tmp_path, monkeypatch):
    """MuJoCo appends warnings to MUJOCO_LOG.TXT in the current directory; the benchmark runs
    it from a scratch directory."""
    bench = _bench_contact()
    monkeypatch.chdir(tmp_path)

    def warn_like_mujoco():
        with open("MUJOCO_LOG.TXT", "a") as f:
            f.write("WARNING: Nan, Inf or huge value in QACC at DOF 0.\n")
        return os.getcwd()

    where = bench.in_scratch_dir(warn_like_mujoco)
    assert where != str(tmp_path) and os.getcwd() == str(tmp_path)
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
    pytest.importorskip("mujoco")
    import mujoco

    # a real MuJoCo warning through run_mujoco's path: a model whose contact buffer overflows
    def overflow():
        m = mujoco.MjModel.from_xml_string(
            '<mujoco><size nconmax="1"/><worldbody><geom type="plane" size="1 1 .1"/>'
            + "".join(f'<body pos="{i * .3} 0 .05"><freejoint/><geom type="sphere" size=".1"/></body>'
                      for i in range(3)) + "</worldbody></mujoco>")
        d = mujoco.MjData(m)
        for _ in range(50):
            mujoco.mj_step(m, d)

    try:
        bench.in_scratch_dir(overflow)
    except Exception:  # noqa: BLE001 - newer MuJoCo may reject nconmax; the point is the cwd
        pass
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_docs_document_every_command():
    """Every command `rblog --help` lists has its own mention (`rblog NAME`) in docs/cli.md or
    docs/recording.md (README links both)."""
    from rblog_cli.main import main

    text = DOCS["docs/cli.md"] + DOCS["docs/recording.md"]
    missing = [name for name in main.commands if not re.search(rf"\brblog {name}\b", text)]
    assert not missing, f"docs/cli.md does not document: {', '.join(missing)}"


def test_readme_is_a_guide_of_today():
    """No project history (it belongs in git log), and extras as a checkout's user types them."""
    assert not re.search(r"\bissues?[- ]\d+", README, re.I), "README names an issue"
    assert "pip install 'rblog[" not in README and 'pip install "rblog[' not in README
    assert 'pip install -e ".[engines]"' in README and 'pip install -e ".[bench]"' in README
