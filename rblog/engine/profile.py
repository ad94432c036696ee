"""Per-stage timing of a run (``rblog run --profile``), as Box2D's ``b2Profile``.

Inside the compiled step (csrc/engine/world_step.cpp) a stage is timed with the CPU's cycle
counter (rdtsc on x86-64, one instruction, ~20 ns, no call back into Python; a steady clock in
nanoseconds elsewhere; csrc/engine/profile.hpp). The counter's rate is measured once against
``time.perf_counter`` (:func:`ticks_per_second`). The step reads the counter only when its profile array is not empty,
so an unprofiled run pays one branch per stage.

Stages (``STAGES``, indices ``P_*``) follow contact/step.py; ``integrate`` also holds a free-body
scene's whole kernel. ``sample`` is the kernel's copy of states into the sample buffers (and the
contact rows); ``logging`` is measured in Python by the run loop: the time the simulation thread
waited for the writers (deriving channels and encoding overlap the next block on other threads,
so only what they could not hide is counted).
"""

from __future__ import annotations

import time

import numpy as np

from rblog.engine import _core

(P_KICK, P_BROADPHASE, P_WAKE, P_COLLIDE, P_COLOUR, P_SOLVE, P_RELAX, P_INTEGRATE,
 P_RESTITUTION, P_PROJECT, P_SLEEP, P_SAMPLE) = range(12)
N_PROF = 12
#: stage names in step order, matching the P_* indices
STAGES = ("kick", "broadphase", "wake", "collide", "colour", "solve", "relax", "integrate", "restitution",
          "project", "sleep", "sample")


# the C++ step indexes the profile by the same P_* (profile.hpp); they must agree
if _core.N_PROF != N_PROF:
    raise ImportError("rblog.engine._core is out of step with profile.py (N_PROF): rebuild it "
                      "(pip install -e .)")


def ticks() -> int:
    """The cycle counter the compiled step reads (int64 ticks)."""
    return _core.ticks()


_RATE: list[float] = []


def ticks_per_second() -> float:
    """The cycle counter's rate (ticks per second), measured once over ~20 ms of wall time."""
    if not _RATE:
        t0, c0 = time.perf_counter(), ticks()
        while time.perf_counter() - t0 < 0.02:
            pass
        t1, c1 = time.perf_counter(), ticks()
        _RATE.append(max(c1 - c0, 1) / (t1 - t0))
    return _RATE[0]


class Profile:
    """Seconds per stage, accumulated over a run.

    ``ticks`` is the (N_PROF,) int64 array the compiled step adds to; ``extra`` holds stages
    timed in Python (``logging``, ``python``: the run loop's own work between blocks)."""

    def __init__(self):
        self.ticks = np.zeros(N_PROF, np.int64)
        self.extra: dict[str, float] = {}
        self.wall = 0.0

    def add(self, stage: str, seconds: float) -> None:
        self.extra[stage] = self.extra.get(stage, 0.0) + seconds

    def seconds(self) -> dict[str, float]:
        """{stage: seconds} in step order, Python-timed stages last."""
        rate = ticks_per_second()
        out = {name: float(self.ticks[k]) / rate for k, name in enumerate(STAGES)}
        out.update(self.extra)
        return out

    def table(self) -> list[tuple[str, float, float]]:
        """(stage, seconds, share of the run's wall time) for every stage that took time, the
        rest of the wall time (``other``), and the run's wall time."""
        sec = self.seconds()
        rows = [(k, v, v / self.wall if self.wall > 0 else 0.0) for k, v in sec.items() if v > 0.0]
        other = self.wall - sum(sec.values())
        rows.append(("other (run loop, step bookkeeping)", other,
                     other / self.wall if self.wall > 0 else 0.0))
        rows.append(("total (wall)", self.wall, 1.0))
        return rows
