"""The penetration analyzer's rule table (rblog.analyze.penetration.RULES): every rule names
constants that exist and tests that exist, so the table cannot drift from the code it cites."""

from __future__ import annotations

import ast
from pathlib import Path

from rblog.analyze import penetration
from rblog.analyze import tolerances as T

ROOT = Path(__file__).resolve().parents[2]


def test_rule_names_are_unique():
    names = [r.name for r in penetration.RULES]
    assert len(names) == len(set(names)) >= 10


def test_every_constant_exists():
    for r in penetration.RULES:
        for c in r.constants:
            assert hasattr(T, c) or hasattr(penetration, c), (r.name, c)


def test_every_rule_has_a_measurement_and_tests_that_exist():
    for r in penetration.RULES:
        assert r.measured and r.case and r.then, r.name
        assert len(r.tests) >= 1, r.name
        for ref in r.tests:
            path, name = ref.split("::")
            tree = ast.parse((ROOT / path).read_text())
            defined = {n.name for n in ast.walk(tree) if isinstance(n, ast.FunctionDef)}
            assert name in defined, (r.name, ref)
