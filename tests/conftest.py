"""Shared fixtures for rblog's tests: scene text -> Scene, scene files on disk, the samples."""

from __future__ import annotations

from pathlib import Path

import pytest

from rblog.engine.scene import parse_scene

REPO = Path(__file__).resolve().parent.parent
SAMPLES_DIR = REPO / "samples"
#: the samples with free bodies only (no ground, no statics, nothing that can touch)
FREE_SAMPLES = ("tumbling_box", "free_fall", "spinning_bodies")


@pytest.fixture
def scene_from_text():
    """Validate scene TOML text (in memory) and return the Scene."""

    def make(text: str, path: str = "test_scene.toml"):
        return parse_scene(text, path)

    return make


@pytest.fixture
def scene_file(tmp_path):
    """Write scene TOML text to a file in a fresh temporary directory; returns its path (str)."""
    counter = iter(range(10**6))

    def write(text: str, name: str | None = None) -> str:
        p = tmp_path / (name or f"scene{next(counter)}.toml")
        p.write_text(text, encoding="utf-8")
        return str(p)

    return write


@pytest.fixture(scope="session")
def samples_dir() -> Path:
    return SAMPLES_DIR
