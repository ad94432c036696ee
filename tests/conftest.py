"""Shared fixtures for rblog's tests: scene text -> Scene, scene files on disk, the samples."""

from __future__ import annotations

from pathlib import Path

import pytest

from rblog.engine.scene import parse_scene

REPO = Path(__file__).resolve().parent.parent
SAMPLES_DIR = REPO / "samples"
#: the samples with free bodies only (no ground, no statics, nothing that can touch)
FREE_SAMPLES = ("tumbling_box", "free_fall", "spinning_bodies")

#: two spheres; "spinner" turns at 100 rad/s about world z under the notes' scheme without
#: orthonormalization, at dt = 1 s: R is (1 + 100 i)^n in the xy block and diverges
SPINNER = """
[sim]
dt = 1.0
duration = 1000.0
gravity = [0.0, 0.0, 0.0]
integrator = "seed"
orthonormalize = "none"

[[body]]
name = "calm"
shape = "sphere"
radius = 0.1
mass = 1.0

[[body]]
name = "spinner"
shape = "sphere"
radius = 0.1
mass = 1.0
inertia_diag = [1.0, 1.0, 1.0]
position = [5.0, 0.0, 0.0]
angular_velocity = [0.0, 0.0, 100.0]
"""


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


#: the notes' scheme without orthonormalization at h w = 100: R's first column grows by
#: sqrt(1 + h^2 w^2) per step, so ortho_error overflows to inf within ~40 steps (a diverging run)
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
