"""The layout's rules, checked from the code's own imports (docs/architecture.md).

Each room of rblog/ may import only the rooms below it:

    contract  <-  engine  <-  study
        ^            ^
        +-- record, analyze      (cli/ over all of them; nothing in rblog imports cli/)
        +-- record <- adapters   (other engines' own models into the contract; used by study)

The analyzers never import the engine: an audit must not share the code it audits.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PKG = REPO / "rblog"

#: room -> rooms of rblog it may import (besides itself and rblog.errors / rblog.__version__)
ALLOWED = {
    "contract": set(),
    "engine": {"contract"},
    "record": {"contract"},
    "analyze": {"contract"},
    "adapters": {"contract", "record"},
    "study": {"contract", "engine", "record", "analyze", "adapters"},
}
#: the one known crossing, with its reason: the Rerun writer sizes its footer from the run loop's
#: block size (rblog.engine.runner.samples_per_block), imported lazily.
EXCEPTIONS = {("rblog/record/rerun_writer.py", "rblog.engine.runner"),
              # contract v2: reading a log (and building one in memory) runs the audit's own
              # consistency checks, so that a log meaning something else never loads silently;
              # imported lazily, and the checks use only the contract's channels
              ("rblog/record/reader.py", "rblog.analyze.consistency"),
              ("rblog/record/recorder.py", "rblog.analyze.consistency"),
              # the live audit (issue 31): the recorder that runs the analyzers on each block as
              # it is written, over the suite's public API (rblog.analyze.live)
              ("rblog/record/live_audit.py", "rblog.analyze.live")}
#: a module longer than this states why at its top ("Why this module is long:")
MAX_LINES = 500


def _imports(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            if node.level:
                raise AssertionError(f"{path}: relative import (use absolute rblog.* imports)")
            out.append(node.module)
            out += [f"{node.module}.{a.name}" for a in node.names if node.module == "rblog"]
    return out


def _modules():
    return sorted(p for p in PKG.rglob("*.py") if "__pycache__" not in p.parts)


@pytest.mark.parametrize("room", sorted(ALLOWED))
def test_rooms_import_only_what_they_may(room):
    bad = []
    for path in (PKG / room).rglob("*.py"):
        rel = path.relative_to(REPO).as_posix()
        for mod in _imports(path):
            parts = mod.split(".")
            if parts[0] == "rblog_cli":
                bad.append(f"{rel}: {mod} (the library never imports the CLI)")
            if parts[0] != "rblog" or len(parts) < 2:
                continue
            target = parts[1]
            if target in (room, "errors", "__version__") or target not in ALLOWED:
                continue
            if target not in ALLOWED[room] and (rel, ".".join(parts[:3])) not in EXCEPTIONS:
                bad.append(f"{rel}: imports {mod}")
    assert not bad, "\n".join(bad)


def test_the_rules_can_fail(tmp_path):
    # the checker itself: an analyzer importing the engine is caught
    p = tmp_path / "x.py"
    p.write_text("from rblog.engine.rotation import quat_to_mat\nimport rblog_cli.main\n")
    assert "rblog.engine.rotation" in _imports(p) and "rblog_cli.main" in _imports(p)


def test_every_room_says_what_lives_there():
    for room in ALLOWED:
        doc = ast.get_docstring(ast.parse((PKG / room / "__init__.py").read_text()))
        assert doc and len(doc) > 200, f"rblog/{room}/__init__.py needs a docstring"


@pytest.mark.parametrize("path", _modules(), ids=lambda p: p.relative_to(PKG).as_posix())
def test_long_modules_say_why(path):
    n = len(path.read_text(encoding="utf-8").splitlines())
    if n <= MAX_LINES:
        return
    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
    assert "Why this module is long:" in doc, f"{path.name} has {n} lines and no reason at its top"
