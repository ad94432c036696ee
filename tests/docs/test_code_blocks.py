"""Every code block of README.md and docs/ runs, so that a snippet cannot rot.

A page is followed as a user follows it: its blocks in order, in one scratch folder that holds
`samples/` and `.venv/bin/` (links to the repository's and this Python's), each block as its
language says:

* ``python``: run by this Python as a script; it must exit 0.
* ``sh``: each command line (``\\`` continuations joined) run by bash with ``.venv/bin`` first on
  PATH; it must exit 0, or 1 (what `rblog check`, `findings` and `run --check` answer for a
  flagged run, which pages show on purpose). Set-up lines (``python3 -m venv``, ``pip install``)
  are not run: they install the package under test, and CI runs README's own. ``rerun FILE``
  opens a window: the test asserts the program exists and FILE is a log that reads.
* ``toml``: a scene; it must load.
* ``python fragment``: a piece of a program (names defined elsewhere on the page, ``...``): it
  must compile, not run.
* ``text`` (output, diagrams) and ``proto`` (a schema) are not run.

A block without a language fails: every block says what it is.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PAGES = ["README.md", *sorted(p.relative_to(REPO).as_posix() for p in (REPO / "docs").glob("*.md"))]
RUNS = {"python", "sh", "toml"}
NOT_RUN_LANGS = {"text", "proto"}
#: compiled, not run
FRAGMENT = "python fragment"
#: pages whose blocks take more than ~10 s in all on the 2-core machine (measured at load ~10:
#: README 16 s, live-audit.md 12 s, cluster.md with its sweeps on 2 workers); the others 0.2-5 s
SLOW = {"README.md", "docs/live-audit.md", "docs/cluster.md"}
SETUP = re.compile(r"^(python3 -m venv|(\.venv/bin/)?pip3? install)\b")
#: `rblog check`/`findings`/`run --check` exit 1 when a run is flagged; 2 and above are errors
SH_OK = (0, 1)

FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```[ \t]*$", re.M | re.S)


def blocks(page: str) -> list[tuple[int, str, str]]:
    """(line, language, code) of every fenced block of ``page``; the language of a block fenced
    ```python fragment``` is ``python fragment``."""
    text = (REPO / page).read_text(encoding="utf-8")
    out = []
    for m in FENCE.finditer(text):
        words = m.group(1).split()
        lang = " ".join(words[:2]) if words[1:2] == ["fragment"] else (words or [""])[0]
        out.append((text.count("\n", 0, m.start()) + 1, lang, m.group(2)))
    return out


def _commands(code: str) -> list[str]:
    out, cur = [], ""
    for line in code.splitlines():
        if line.rstrip().endswith("\\"):
            cur += line.rstrip()[:-1] + " "
            continue
        cur += line
        if cur.strip() and not cur.strip().startswith("#"):
            out.append(cur.strip())
        cur = ""
    return out


def _scratch(tmp_path: Path) -> dict:
    (tmp_path / "samples").symlink_to(REPO / "samples")
    (tmp_path / ".venv").mkdir()
    (tmp_path / ".venv" / "bin").symlink_to(Path(sys.executable).parent)
    env = dict(os.environ)
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    env["MPLBACKEND"] = "Agg"
    return env


def _run_sh(cmd: str, cwd: Path, env: dict, where: str):
    if SETUP.match(cmd):
        return
    argv = shlex.split(cmd, comments=True)
    if Path(argv[0]).name == "rerun":  # opens a window: the program exists, the file reads
        import rblog

        exe = argv[0] if os.sep in argv[0] else str(Path(sys.executable).with_name("rerun"))
        assert os.access(cwd / exe, os.X_OK), f"{where}: {argv[0]} is not a program here"
        rblog.load(cwd / argv[1])
        return
    p = subprocess.run(cmd, shell=True, executable="/bin/bash", cwd=cwd, env=env,
                       capture_output=True, text=True, timeout=900)
    assert p.returncode in SH_OK, f"{where}: `{cmd}` exited {p.returncode}:\n{p.stderr[-2000:]}"


def _run_python(code: str, cwd: Path, env: dict, where: str, k: int):
    script = cwd / f"block_{k}.py"
    script.write_text(code, encoding="utf-8")
    p = subprocess.run([sys.executable, script.name], cwd=cwd, env=env, capture_output=True,
                       text=True, timeout=900)
    assert p.returncode == 0, f"{where}: exited {p.returncode}:\n{p.stderr[-3000:]}"


def _run_page(page: str, tmp_path: Path):
    env = _scratch(tmp_path)
    for k, (line, lang, code) in enumerate(blocks(page)):
        where = f"{page}:{line}"
        assert lang in RUNS | NOT_RUN_LANGS | {FRAGMENT}, \
            f"{where}: a block with language {lang!r} (expected one of " \
            f"{', '.join(sorted(RUNS | NOT_RUN_LANGS | {FRAGMENT}))}; output is ```text)"
        if lang == FRAGMENT:
            compile(code, where, "exec")
        if lang == "sh":
            for cmd in _commands(code):
                _run_sh(cmd, tmp_path, env, where)
        elif lang == "python":
            _run_python(code, tmp_path, env, where, k)
        elif lang == "toml":
            from rblog.engine.scene import parse_scene

            parse_scene(code, where)


def _params():
    for page in PAGES:
        marks = [pytest.mark.slow] if page in SLOW else []
        yield pytest.param(page, marks=marks, id=page)


@pytest.mark.parametrize("page", list(_params()))
def test_page_code_blocks_run(page, tmp_path):
    _run_page(page, tmp_path)


def test_every_page_is_covered_and_tagged():
    """Every block of every page says its language (the slow pages too), and README's two set-up
    commands are the ones CI runs."""
    for page in PAGES:
        for line, lang, _ in blocks(page):
            assert lang in RUNS | NOT_RUN_LANGS | {FRAGMENT}, \
                f"{page}:{line}: untagged or unknown block"
    readme = [c for _, lang, code in blocks("README.md") if lang == "sh"
              for c in _commands(code)]
    assert readme[:2] == [
        "python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/rblog run "
        "samples/tumbling_box.toml",
        'python3 -m venv .venv && .venv/bin/pip install -e ".[test]" && .venv/bin/python -m '
        "pytest -q"]


def test_readme_is_a_front_door():
    """README stays short: what rblog is, set-up, the next commands, links (the rest in docs/)."""
    assert len((REPO / "README.md").read_text(encoding="utf-8").splitlines()) <= 200
    assert len((REPO / "benchmarks" / "RESULTS.md").read_text(encoding="utf-8").splitlines()) <= 400
