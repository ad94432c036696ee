"""Zero false alarms on every sample under MuJoCo and pybullet (issue 16's Done-when), behind
``-m slow``: every samples/*.toml is run through ``rblog run --engine mujoco`` and ``--engine
pybullet`` and ``rblog check`` must flag exactly the engine's real faults enumerated below, each
with its measured worst value (so the list is itself a check: a fault that goes away, a new kind
of finding, or a value that moves by more than a factor 2 fails the test).

Why each is real (not a false alarm of the check), from the traces in benchmarks/RESULTS.md
(issue 16):

* ``flight angular``: both engines step a free body's rotation with explicit Euler (the same
  numbers to 6e-14 in both: the gyroscopic term integrated explicitly), so L = R I w drifts in free
  flight (tumbling_box 0.26% of |L| in 20 s; rblog's integrators keep it to round-off).
* ``flight energy``: the same step gains energy (tumbling_box +0.48%, spinning_bodies +7.9% in 5 s).
* ``collision angular``: the same explicit rotation step while bodies touch: their L about the
  common centre of mass is not conserved (MuJoCo 4.4e-4, pybullet 3.6e-4 of the scale in mixed;
  one finding per contact event).
* ``sink`` (any time) and ``resting sink``: MuJoCo's soft contacts (omega dt = 0.2 here) let a
  ball sink 19 mm at a 4.4 m/s bounce, a 10-box stack at dt = 10 ms 6.1 mm at rest, the
  pile 18 mm; pybullet's stack at dt = 10 ms sinks 6 mm, its pile 4.8-5.7 mm (tol 5 mm: marginal, see
  MARGINAL).
* ``creep``: with the friction inside the Coulomb cone, on pairs at rest (rolling and sliding
  pairs are events, not judged for creep): MuJoCo's pile (2.8 mm); pybullet's resting cube slips
  0.22 mm in 5 s, its stack at dt = 10 ms 8 mm, boxes in its pile 0.62 mm. mixed's balls roll on
  the ramp in both engines: their contact point (midway between the surfaces) slips ~1e-6 m/s in
  MuJoCo's own qvel (tests/analyze/test_rolling.py), so no creep there.
* ``jitter``: MuJoCo's soft resting contacts oscillate at 2.0-8.5 mm/s (tol 2 mm/s).
* ``restitution``, ``bounce lost``, ``elastic loss``: Bullet rebounds the bouncing ball at e = 0.21
  instead of 0.8 on its later bounces, three balls at 0.45 instead of 0.5, stops a ball dead on the
  ramp (arrives at 2.43 m/s normal, e = 0.5) and loses 0.64% of the head-on pair's kinetic energy
  at e = 1; MuJoCo's elastic pair gains 0.93% (an explicitly stepped stiff spring).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from rblog_cli.main import main

REPO = Path(__file__).resolve().parents[2]
ENGINES = ("mujoco", "pybullet")


def kind(analyzer: str, message: str) -> str:
    """A finding's kind, from its analyzer and message."""
    m = message
    if analyzer == "momentum":
        if "in free flight" in m:
            return "flight " + ("angular" if m.split(":")[1].strip().startswith("angular") else "linear")
        if "in the collision of" in m:
            return "collision " + ("angular" if m.startswith("angular") else "linear")
        for key, name in (("friction cone", "cone"), ("bounce lost", "bounce lost"),
                          ("elastic impact", "elastic loss"), ("energy grows", "impact energy"),
                          ("restitution", "restitution")):
            if key in m:
                return name
    if analyzer == "penetration":
        for key, name in (("creeps", "creep"), ("jitters", "jitter"), ("resting on", "resting sink"),
                          ("sinks", "sink")):
            if key in m:
                return name
    if analyzer == "energy":
        return "flight energy" if "in free flight" in m else "contact energy"
    return analyzer


#: (sample, engine) -> {kind: worst measured value (the finding's value, in its unit)}.
#: Measured 2026-11-26 (MuJoCo 4.0.0, pybullet 3.2.7), samples at their own durations (the
#: whole set: ~4 min on a loaded 2-core machine, the pile 115 s (MuJoCo) and 50 s (pybullet)).
KNOWN: dict[tuple[str, str], dict[str, float]] = {
    ("bouncing_ball", "mujoco"): {"penetration: sink": 0.0191},
    ("bouncing_ball", "pybullet"): {"momentum: restitution": 0.59},
    # measured 2026-12-03 with zeta(e) of the force-released contact (e = 0: zeta 2.5): the stack's
    # 24 mm landing sink is gone, its resting sink 6.1 mm
    ("box_stack", "mujoco"): {"penetration: resting sink": 0.00606},
    ("box_stack", "pybullet"): {
        "penetration: creep": 0.00815,
        "penetration: resting sink": 0.0056,
        "penetration: sink": 0.00621,
    },
    ("free_fall", "mujoco"): {"momentum: flight angular": 0.00148},
    ("free_fall", "pybullet"): {"momentum: flight angular": 0.00148},
    ("mixed", "mujoco"): {
        "momentum: collision angular": 0.000442,
        "momentum: flight angular": 0.00486,
        "penetration: jitter": 0.00382,
        "penetration: sink": 0.0236,
    },
    ("mixed", "pybullet"): {
        "momentum: bounce lost": 1.22,
        "momentum: collision angular": 0.000359,
        "momentum: flight angular": 0.0065,
        "momentum: restitution": 0.0483,
    },
    ("newton_pair", "mujoco"): {
        "energy: contact energy": 0.00922,
        "momentum: impact energy": 0.0093,
        "penetration: sink": 0.0136,
    },
    ("newton_pair", "pybullet"): {"momentum: elastic loss": 0.00642},
    ("pile", "mujoco"): {
        # creep from the poses since 7a2eb36 (the velocity trapezoid read 2.81 mm)
        "penetration: creep": 0.00043,
        "penetration: jitter": 0.00847,
        "penetration: sink": 0.0178,
    },
    ("pile", "pybullet"): {
        "momentum: collision angular": 0.000109,
        "penetration: creep": 0.000621,
        # pybullet's own deepest contact (contactDistance in its rows, rblog.adapters.pybullet):
        # 7.09 mm on 2026-12-01, past the 5 mm tolerance
        "penetration: sink": 0.00709,
    },
    ("resting_box", "pybullet"): {"penetration: creep": 0.000218},
    # measured 2026-12-03 with zeta(e) of the force-released contact (rblog/study/engines/
    # mujoco.py; tests/study/test_mujoco_restitution.py: MuJoCo's balls rebound at the scene's e):
    # the restitution, sink and capsule penetration findings are gone; the explicit rotation
    # step's flight angular drift remains. A capsule's friction cone against the slope (a static
    # box) is not judged: its centre does not tell which face it touches (slider3 near the slope's
    # lower end read a normal 78 deg off the face it slides on, where Bullet's own rows sit on
    # the cone: |f| / J_n = 0.39, mu 0.387)
    # the largest flight angular drift: the dumbbell (a compound, spinning as it falls) since it
    # joined the sample, 8.84e-5 (box3's 7.25e-5 before)
    ("shapes", "mujoco"): {"momentum: flight angular": 8.84e-05},
    # re-measured 2026-12-03 with the hulls and cylinders in shapes.toml: MuJoCo's the same
    # kinds and values; pybullet's capsule "momentum: momentum" (at 1.004x the allowance's edge)
    # no longer appears
    ("shapes", "pybullet"): {
        "momentum: flight angular": 0.000461,
    },
    ("spinning_bodies", "mujoco"): {
        "energy: flight energy": 0.0789,
        "momentum: flight angular": 0.0534,
    },
    ("spinning_bodies", "pybullet"): {
        "energy: flight energy": 0.0789,
        "momentum: flight angular": 0.0534,
    },
    ("tumbling_box", "mujoco"): {
        "energy: flight energy": 0.00481,
        "momentum: flight angular": 0.0026,
    },
    ("tumbling_box", "pybullet"): {
        "energy: flight energy": 0.00481,
        "momentum: flight angular": 0.0026,
    },
}


#: (sample, engine) -> {kind: the analyzer's tolerance it is judged against}: faults whose true
#: size sits at the tolerance, so that whether they are flagged depends on the machine (the pile
#: is chaotic: libm and CPU differences move every box). pybullet's 500-box pile: its own deepest
#: contact (contactDistance, logged in its contact rows) 5.05 mm and the analyzer's depth from the
#: logged poses 4.78 mm on the 2026-11-28 machine (not flagged), 5.65 mm on the 2026-11-26 one
#: (flagged); tol 5 mm. The test checks that the engine's own depth really is within
#: MARGINAL_BAND of the tolerance (an independent measure: the engine's collision detection, not
#: the analyzer's), and then accepts the finding either way.
MARGINAL: dict[tuple[str, str], dict[str, float]] = {}
MARGINAL_BAND = 0.15


def engine_depth(log) -> float:
    """The engine's own deepest contact in ``log`` (m, >= 0): minus the least separation of its
    logged contact rows."""
    from rblog.record.reader import load

    sep = load(log).contacts.separation
    return float(max(0.0, -sep.min())) if len(sep) else 0.0


def findings_of(tmp_path, sample: str, engine: str) -> dict[str, float]:
    log = tmp_path / f"{sample}-{engine}.mcap"
    res = CliRunner().invoke(main, ["run", str(REPO / "samples" / f"{sample}.toml"), "--engine",
                                    engine, "--mcap", str(log)])
    assert res.exit_code == 0, res.output
    res = CliRunner().invoke(main, ["check", "--json", str(log)])
    assert res.exit_code in (0, 1), res.output
    (doc,) = json.loads(res.stdout)["logs"]
    worst: dict[str, float] = {}
    for r in doc["results"]:
        for f in r["findings"]:
            k = f"{r['analyzer']}: {kind(r['analyzer'], f['message'])}"
            worst[k] = max(worst.get(k, 0.0), f["value"])
    return worst


CASES = [(p.stem, e) for p in sorted((REPO / "samples").glob("*.toml")) for e in ENGINES]


@pytest.mark.slow
@pytest.mark.parametrize("sample,engine", CASES, ids=[f"{s}-{e}" for s, e in CASES])
def test_check_flags_only_the_engines_real_faults(tmp_path, sample, engine):
    pytest.importorskip(engine)
    got = findings_of(tmp_path, sample, engine)
    want = KNOWN.get((sample, engine), {})
    marginal = MARGINAL.get((sample, engine), {})
    if marginal:
        depth = engine_depth(tmp_path / f"{sample}-{engine}.mcap")
        for k, tol in marginal.items():
            assert abs(depth - tol) <= MARGINAL_BAND * tol, (k, depth, tol)
            if k in got:
                assert abs(got[k] - tol) <= MARGINAL_BAND * tol, (k, got[k], tol)
        got = {k: v for k, v in got.items() if k not in marginal}
    assert set(got) == set(want), {"unexpected": sorted(set(got) - set(want)),
                                   "gone": sorted(set(want) - set(got)), "got": got}
    for k, v in want.items():
        assert v / 2 <= got[k] <= 2 * v, (k, got[k], v)
