"""`--engine mujoco`'s restitution: the damping ratio of MuJoCo's soft contact for a scene's e.

MuJoCo's contact is a spring-damper on the penetration r whose force cannot pull: it lets go when
m (k r + b r') reaches 0, still r > 0 deep, not when r returns to 0. The translation's zeta(e)
(rblog.study.engines.mujoco.zeta_of_restitution) is that contact's, checked here against an
independent integration of the ODE (scipy) and against MuJoCo's own rebound.
"""

import math

import numpy as np
import pytest

from rblog.engine.scene import parse_scene
from rblog.study.engines.mujoco import DEFAULT_OMEGA_DT, restitution_of_zeta, zeta_max, zeta_of_restitution


def _released_rebound(zeta: float) -> float:
    """r'' + 2 zeta r' + r = 0 from r = 0, r' = 1, integrated by scipy until r + 2 zeta r' = 0."""
    solve_ivp = pytest.importorskip("scipy.integrate").solve_ivp

    def force(t, y):
        return y[0] + 2.0 * zeta * y[1]

    force.terminal, force.direction = True, -1
    sol = solve_ivp(lambda t, y: [y[1], -y[0] - 2.0 * zeta * y[1]], (0.0, 100.0), [0.0, 1.0],
                    events=force, rtol=1e-12, atol=1e-14, method="DOP853")
    return -float(sol.y_events[0][0][1])


@pytest.mark.parametrize("zeta", [0.01, 0.1, 0.3, 0.7, 0.99, 1.01, 1.5, 2.5])
def test_closed_form_rebound_equals_the_integrated_contact(zeta):
    # measured: |closed form - DOP853 at rtol 1e-12| <= 3e-12 over these zetas
    assert restitution_of_zeta(zeta) == pytest.approx(_released_rebound(zeta), abs=1e-10)


@pytest.mark.parametrize("e", [0.05, 0.1, 0.3, 0.5, 0.8, 0.95, 0.999])
def test_zeta_of_restitution_inverts_the_rebound(e):
    z = zeta_of_restitution(e)
    assert z < zeta_max(DEFAULT_OMEGA_DT)
    assert restitution_of_zeta(z) == pytest.approx(e, rel=1e-12)


def test_below_the_stable_damping_the_cap_is_used():
    # b dt = 2 zeta omega_dt <= 1: at omega_dt 0.2, zeta 2.5 rebounds with e = 0.0327
    cap = zeta_max(0.2)
    assert cap == 2.5
    assert zeta_of_restitution(0.0, 0.2) == cap
    assert zeta_of_restitution(0.01, 0.2) == cap
    assert restitution_of_zeta(cap) == pytest.approx(_released_rebound(cap), abs=1e-10)
    assert zeta_of_restitution(1.0) == 0.0


def _mujoco_rebound(e: float, gap: float, dt: float = 1e-3) -> float:
    """A 1 kg ball of radius 0.1 m, no gravity, at 2 m/s towards the ground of restitution e from
    ``gap`` above it, in the translation's MuJoCo model: its velocity after the contact over the
    one before."""
    pytest.importorskip("mujoco")
    from rblog.study.engines.mujoco import MujocoRun

    scene = parse_scene(f"""
[sim]
dt = {dt!r}
duration = 0.5
gravity = [0.0, 0.0, 0.0]
[ground]
restitution = {e!r}
friction = 0.0
[[body]]
name = "ball"
shape = "sphere"
radius = 0.1
mass = 1.0
position = [0.0, 0.0, {0.1 + gap!r}]
velocity = [0.0, 0.0, -2.0]
restitution = {e!r}
friction = 0.0
""")
    run = MujocoRun(scene, dt)
    run.step(int(round(0.3 / dt)))
    _, _, v, _ = run.state()
    return float(v[0, 2]) / 2.0


@pytest.mark.parametrize("e", [0.1, 0.3, 0.5, 0.8])
def test_mujoco_rebounds_with_the_scene_restitution(e):
    """MuJoCo's rebound depends on how deep the ball is at the first step the contact acts (0 to
    v dt): over ten entry depths spread across one step the scene's e lies inside MuJoCo's rebounds
    and their mean is e to 0.025 (measured at dt 1e-3, omega dt 0.2: means 0.082, 0.287, 0.493,
    0.799, ranges [0.058, 0.107], [0.259, 0.316], [0.470, 0.518], [0.790, 0.810]; the figures
    are the same at dt 1e-2, omega dt fixing the contact's time in steps)."""
    dt, v0 = 1e-3, 2.0
    gaps = 3 * v0 * dt + (np.arange(10) + 0.5) / 10 * v0 * dt
    rebound = np.array([_mujoco_rebound(e, float(g), dt) for g in gaps])
    assert rebound.min() <= e <= rebound.max()
    assert rebound.mean() == pytest.approx(e, abs=0.025)
