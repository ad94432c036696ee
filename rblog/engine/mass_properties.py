"""Mass properties of the scene's shapes: volume and principal moments, closed forms.

Every shape is in its own frame, centred on its centre of mass with its principal axes along the
frame's (the contract's geom conventions, rblog.contract.model GEOM_*); ``inertia_diag`` returns
the moments (I_xx, I_yy, I_zz) about the centre of mass for a mass ``m`` spread uniformly.

Derivations (uniform density rho, ``r`` radius, ``h`` half length along z, ``e`` half extents):

* sphere: V = 4/3 pi r^3, I = 2/5 m r^2 about every axis.
* box: V = 8 e_x e_y e_z, I_xx = m (e_y^2 + e_z^2) / 3 (and cyclic).
* cylinder (|z| <= h, x^2 + y^2 <= r^2): V = 2 pi r^2 h; I_zz = m r^2 / 2 (discs m r^2 / 2);
  I_xx = m (r^2 / 4 + h^2 / 3) (each disc of mass dm at height z contributes dm (r^2 / 4 + z^2);
  the mean of z^2 over [-h, h] is h^2 / 3).
* capsule (the segment |z| <= h grown by r): a cylinder of mass m_c = rho 2 pi r^2 h and two
  hemispheres, together a sphere of mass m_s = rho 4/3 pi r^3. I_zz = m_c r^2 / 2 + 2/5 m_s r^2.
  About x through the centre: each hemisphere has I = 2/5 (m_s / 2) r^2 about its flat face's
  diameter and its centre of mass at 3 r / 8 from the face; moving that axis to the capsule's
  centre (the face at distance h) by the parallel-axis theorem twice gives, for both,
  m_s (2/5 r^2 + h^2 + 3/4 h r); with the cylinder's m_c (r^2 / 4 + h^2 / 3).
"""

from __future__ import annotations

import math

import numpy as np


# Volumes in m^3, written as products so that a value past 1e308 is inf (the scene's mass check
# names it) instead of an OverflowError.

def sphere_volume(r: float) -> float:
    return 4.0 / 3.0 * math.pi * (r * r * r)


def box_volume(e) -> float:
    return 8.0 * math.prod(float(x) for x in e)  # inf past 1e308


def cylinder_volume(r: float, h: float) -> float:
    return 2.0 * math.pi * r * r * h


def capsule_volume(r: float, h: float) -> float:
    return cylinder_volume(r, h) + sphere_volume(r)


def sphere_inertia(m: float, r: float) -> np.ndarray:
    return np.full(3, 0.4 * m * r ** 2)


def box_inertia(m: float, e) -> np.ndarray:
    a, b, c = np.asarray(e, float) ** 2
    return m / 3.0 * np.array([b + c, a + c, a + b])


def cylinder_inertia(m: float, r: float, h: float) -> np.ndarray:
    ix = m * (r * r / 4.0 + h * h / 3.0)
    return np.array([ix, ix, 0.5 * m * r * r])


def capsule_inertia(m: float, r: float, h: float) -> np.ndarray:
    v_c, v_s = cylinder_volume(r, h), sphere_volume(r)
    m_c = m * v_c / (v_c + v_s)
    m_s = m * v_s / (v_c + v_s)
    ix = m_c * (r * r / 4.0 + h * h / 3.0) + m_s * (0.4 * r * r + h * h + 0.75 * h * r)
    return np.array([ix, ix, 0.5 * m_c * r * r + 0.4 * m_s * r * r])
