"""Mass properties of the scene's shapes against an independent integration.

A solid of revolution about z with radius R(z) has, per unit density, the volume int pi R^2 dz,
I_zz = int pi R^4 / 2 dz (discs), I_xx = int (pi R^4 / 4 + pi R^2 z^2) dz (a disc's moment about
its diameter plus the parallel-axis term); scipy's adaptive quadrature evaluates them piece by
piece (breaks where R(z) changes formula), to round-off.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from rblog.engine import mass_properties as mp
from rblog.engine.scene import parse_scene


def _revolution(radius_of_z, breaks):
    """(volume, I_xx, I_zz) per unit density of the solid with radius R(z), z over breaks."""
    def integral(f):
        return sum(quad(f, a, b, epsabs=0, epsrel=2e-14, limit=200)[0]
                   for a, b in zip(breaks[:-1], breaks[1:]))
    vol = integral(lambda z: math.pi * radius_of_z(z) ** 2)
    ixx = integral(lambda z: math.pi * radius_of_z(z) ** 4 / 4 + math.pi * radius_of_z(z) ** 2 * z * z)
    izz = integral(lambda z: math.pi * radius_of_z(z) ** 4 / 2)
    return vol, ixx, izz


@pytest.mark.parametrize("r,h", [(0.05, 0.2), (0.3, 0.01), (1.0, 2.5)])
def test_capsule_against_quadrature(r, h):
    def R(z):
        return r if abs(z) <= h else math.sqrt(max(0.0, r * r - (abs(z) - h) ** 2))
    vol, ixx, izz = _revolution(R, [-h - r, -h, h, h + r])
    m = 2.7
    inertia = mp.capsule_inertia(m, r, h)
    # measured: relative differences <= 3e-16
    assert mp.capsule_volume(r, h) == pytest.approx(vol, rel=1e-12)
    assert inertia == pytest.approx(m / vol * np.array([ixx, ixx, izz]), rel=1e-12)


@pytest.mark.parametrize("r,h", [(0.05, 0.2), (0.3, 0.01), (1.0, 2.5)])
def test_cylinder_against_quadrature(r, h):
    vol, ixx, izz = _revolution(lambda z: r, [-h, h])
    m = 0.8
    assert mp.cylinder_volume(r, h) == pytest.approx(vol, rel=1e-12)
    assert mp.cylinder_inertia(m, r, h) == pytest.approx(m / vol * np.array([ixx, ixx, izz]),
                                                         rel=1e-12)


def test_scene_uses_them_with_density():
    sc = parse_scene("""
[sim]
dt = 1e-3
duration = 1
[[body]]
shape = "capsule"
radius = 0.1
half_length = 0.3
density = 500
""")
    vol = math.pi * 0.1 ** 2 * 0.6 + 4 / 3 * math.pi * 0.1 ** 3
    assert sc.model.body_mass[0] == pytest.approx(500 * vol, rel=1e-15)
    assert sc.model.body_inertia_diag[0] == pytest.approx(
        mp.capsule_inertia(500 * vol, 0.1, 0.3), rel=1e-15)
