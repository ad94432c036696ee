"""Exact flight and bounces in contact scenes (issue 17): the figures of benchmarks/RESULTS.md.

Prints, for the scenes of tests/engine/contact/test_flight.py and test_contact.py: how far bodies
over a ground are from their parabola before a contact first pushes them, how often a ball
dropped from 2 cm bounces and how close its apexes are to e^(2n) h0, and the 1 m drop's apexes.
To compare with another version of rblog, run it with PYTHONPATH pointing at that tree:

    python benchmarks/flight_figures.py
    PYTHONPATH=/path/to/other/checkout python benchmarks/flight_figures.py
"""
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "engine" / "contact"))
import test_flight as T
import rblog
from rblog.engine import integrators as rot
from rblog.engine.contact import ContactParams, ContactWorld
from rblog.study.scenes import make_model, make_state
from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE
from rblog.contract.trajectory import CONTACT_IMPACT
print("rblog from", rblog.__file__)
G = 9.81
for dt in (1e-3, 1e-2):
    h = 0.1
    model = make_model([SHAPE_SPHERE, SHAPE_BOX, SHAPE_BOX, SHAPE_BOX],
                       [0.1, [0.2, 0.1, 0.05], [h] * 3, [h] * 3], [1.0, 2.0, 1.0, 1.0], restitution=0.5)
    x0 = np.array([[0.0, 0.0, 1.1], [2.0, 0.0, 1.5], [-2.0, 0.0, h], [-2.0, 0.0, 3 * h]])
    v0 = np.array([[0.3, -0.2, 1.0], [0.0, 0.4, 0.5], [0.0] * 3, [0.0] * 3])
    state = make_state(model, x0, v0, omega=[[0, 0, 0], [3.0, -1.0, 7.0], [0] * 3, [0] * 3])
    world = ContactWorld(model, ContactParams(sleep=False), rot.METHOD_RK4, rot.ORTHO_NORMALIZE)
    out, contacts = T.simulate(world, state, dt, int(round(0.8 / dt)))
    g = np.array([0.0, 0.0, -G])
    for body in (0, 1):
        first = T.first_push_step(contacts, body)
        k = np.arange(1, first); t = k * dt
        xe = x0[body] + v0[body] * t[:, None] + 0.5 * g * t[:, None] ** 2
        print(f"free fall dt={dt:g} body {body}: {first - 1} steps before the first push, "
              f"max |x - parabola| = {np.abs(out['position'][k - 1, body] - xe).max():.3g} m")
for dt in (1e-3, 1e-2):
    r, h0, e = 0.1, 0.02, 0.6
    model = make_model([SHAPE_SPHERE], [r], [1.0], restitution=e, ground_restitution=0.0)
    world = ContactWorld(model, ContactParams(sleep=False), *T.SPLIT)
    state = make_state(model, [[0.0, 0.0, r + h0]])
    n_steps = int(round(1.0 / dt))
    out, contacts = T.simulate(world, state, dt, n_steps)
    z = out["position"][:, 0, 2] - r; vz = out["linear_momentum"][:, 0, 2]
    pushed = np.unique(contacts.step[contacts.normal_impulse > 0])
    fl = [f for f in T.flights(pushed, n_steps) if vz[f].max() > 0.0]
    errs = [np.abs((z[f] + vz[f] ** 2 / (2 * G)) / (e ** (2 * n) * h0) - 1).max() for n, f in enumerate(fl, 1)]
    print(f"2 cm drop dt={dt:g}: {int((contacts.kind == CONTACT_IMPACT).sum())} bounces, "
          f"apex energy-height rel errors {['%.2g' % x for x in errs]}")
r, h0, e = 0.1, 1.0, 0.8
model = make_model([SHAPE_SPHERE], [r], [1.0], restitution=e, ground_restitution=0.0)
world = ContactWorld(model, ContactParams(), *T.SPLIT)
state = make_state(model, [[0.0, 0.0, r + h0]])
out, contacts = T.simulate(world, state, 1e-3, 4000)
z = out["position"][:, 0, 2] - r; vz = out["linear_momentum"][:, 0, 2]
turn = [k for k in range(1, len(z)) if vz[k - 1] > 0.0 >= vz[k]]
print("1 m drop e=0.8 dt=1e-3: flights", len(turn), "energy-height rel errors n=1..4",
      ['%.2g' % abs((z[k] + vz[k]**2/(2*G)) / (e ** (2 * n) * h0) - 1) for n, k in enumerate(turn[:4], 1)],
      "sampled", ['%.2g' % abs(z[k] / (e ** (2 * n) * h0) - 1) for n, k in enumerate(turn[:4], 1)])
