"""Box-box contact: follows the separating-axis test of Gottschalk et al. (15 axes) with the face/edge
preference tolerances of Gregorius (GDC 2013, 2015): a face axis is kept unless an edge axis is
clearly better, so manifolds stay coherent from step to step. A face contact clips the incident
face against the side planes of the reference face (Sutherland-Hodgman) and reduces the clipped
polygon to four points (deepest point, farthest point, largest triangle, largest quad).

Tolerances (EDGE_REL_TOL, FACE_REL_TOL, AXIS_ABS_TOL, EDGE_PARALLEL_TOL) are in
rblog.engine.constants. The collider is C++: csrc/engine/box_box.cpp (its header comment holds the
derivation, the clipping and the feature ids); ``narrowphase.collide_np`` runs it from Python.
"""

from __future__ import annotations
