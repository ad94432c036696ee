"""Penetration during resting contact, with jitter and creep.

Separations are recomputed from the logged poses and the model's shapes (rblog.analyze.geometry
for boxes and spheres, rblog.analyze.shapes for every geom of the contract: rule
"geom_pair_support"), never taken from the contacts the simulator reported. Per sample, a body is
in contact when a separation to the ground, a static box, another world geom or another body is
within CONTACT_DISTANCE_M; its primary
support is the deepest of those, with a witness point at the centre of the patch where the two
touch (rblog.analyze.geometry: a corner, the crossing of two edges, the middle of an edge's part
on a face, the centroid of two faces' overlap), so that a body turning about its contact (a box
pivoting on a corner of another) has no slip there.

* Resting: in contact, and every point of the body slow relative to the partner: the contact
  point's velocity relative to the partner (``v + ω x r``, minus the partner's) plus the relative
  angular speed times twice the bounding radius below REST_SPEED_MPS, for at least
  REST_MIN_SAMPLES consecutive samples. A sphere rolling without slip and a box tipping over an
  edge have a resting contact point but are not at rest: the sphere rolls, the box pivots.
* Rolling and sliding: in contact, not at rest, the contact point's normal speed at most
  REST_SPEED_MPS: rolling where its tangential slip is at most REST_SPEED_MPS, else sliding;
  reported as events with their slip (:func:`_motion_stretches`), not judged as resting. A
  sphere's witness on the ground or a box is midway between the two surfaces (rule
  "sphere_midway"), where a rolling contact has no slip.
* Per resting interval: max and mean depth, duration; after SETTLE_S, the largest contact-point
  speed and jitter; creep over the whole interval less its settling slide. Jitter is the
  alternating part of the contact-point velocity,
  ``|v(k+1) - 2 v(k) + v(k-1)| / 4`` on one partner, kept only where it persists over
  JITTER_PERSIST_SAMPLES consecutive samples: exactly the amplitude of a velocity that flips
  between samples, and zero for any motion at constant acceleration (a body that slides off
  slowly, decelerates to a stop or tips over) and for a single kick (a resting box struck by
  another: an impact, not jitter). Creep is the net tangential slide at the contact while
  settled, taken from the poses (not the logged velocities): over each
  sample interval, each body's rigid displacement field ``d(y) = dx + theta x (y - x)`` (dx its
  centre's displacement, theta the rotation vector of R(k+1) R(k)^T) at the contact point, body
  minus partner, tangential part, summed; an interval counts in full when both its samples are
  slower than CREEP_SPEED_MPS and not sliding, half when one is, so that a body that starts to
  slide away is not creep; an interval over which a body's velocity (or angular velocity times
  twice its bounding radius) changes by more than CREEP_SPEED_MPS beyond the mean change of its
  neighbouring intervals held an impact and does not count (steady accelerations do); nor does
  an interval over which the contact slid faster than CREEP_SPEED_MPS on average (from the poses):
  a kick between two slow samples (a resting box struck and stopped by friction within the
  interval) is a slide, and the samples cannot tell it from a slip. A sphere rolling without
  slip and a box pivoting on its contact slide 0. Where the pair's logged rows carry load at one
  point at most (rows within WITNESS_BAND_M of each other are one point), a patch may turn about
  any of its points: an edge patch slides by its
  least-slipping point (a box swinging about one end of its edge slides 0), a face patch 0 when
  the pair turns about a point on both faces (a box pivoting on one corner of its face contact);
  where more points carry load, static friction holds them all, and the witness is judged (see
  contact_slide in csrc/audit/penetration.cpp). From the poses, motion the
  velocities do not show is creep too (an engine's position correction pushing a resting body
  along at a few mm/s, steps between samples at which a contact slipped slowly),
  and velocities that never move the body (spikes between steps) are not. Settled means after
  the settling slide: a stay begins with the body's arrival (it lands, slides to a stop, the
  solver settles it), so within its first SETTLE_S the intervals before the first of least slide
  do not count, and the others count at most at the stay's steady slip speed over the next
  SETTLE_S (:func:`_settling_slide`). A body at rest, or creeping at a steady rate from its first
  sample, is settled throughout (a 0.30 mm creep reads 0.30 mm wherever in the stay it begins;
  before, the first SETTLE_S never counted: 0.285 mm for a creep from the first sample); a box
  that lands or slides to a stop keeps none of its arrival (tests/analyze/test_creep.py). A
  contact two bodies both take as their support (each the other's deepest: boxes side by side in
  a pile) slides the same for both: it counts once, for the body it holds up (along -gravity;
  the lower index when level), and a finding names the partner its creep was measured against
  when that is not the stay's first (the 500-box pile once read the one slide between box315 and
  box317, 0.105 mm, as box315's "on the ground" and box317's "on box316").
* Sliding is not resting: at a sample where the support contact's logged rows (the pair's points
  at the sample's step) are at their Coulomb limit, ``|f| >= (1 - SLIDE_CONE_FRAC) mu J_n``, all
  but at most one (a rigid contact that slips, translating or twisting about its normal, slips
  at every point but the one it may pivot about, and a slipping point's friction is at the
  limit), or where the tangential load the support must hold (the body's other contact impulses
  plus (m g + F) dt) reaches that limit, or where none of the pair's rows carries load (its limit
  is mu x 0: a box chattering on another, loaded only between samples), or where the body has no
  row at all at a sample whose other rows show that the log carries contacts (it touches nothing:
  a ball struck by another, hopping 0.2 mm between two samples), the contact slides: the
  notes' resting-contact model (static friction holds the body, strictly inside the cone) does
  not cover it, so its slip is not creep and its velocity change is not jitter. Such samples stay
  in the resting interval (a box that sticks, is dragged by a neighbour and sticks again is one
  stay), so slip between them with the friction inside the cone is still creep: that is what
  static friction forbids, and an unconverged velocity solve produces. Without logged contact
  rows, a body touching nothing but its support is judged by its inferred impulse over the
  interval ending at the sample; a body with several contacts cannot be split, and counts as
  resting.
* Flags: resting depth beyond min(DEPTH_M, DEPTH_FRAC x the body's inner radius), any depth (an
  impact too) beyond min(TRANSIENT_DEPTH_M, TRANSIENT_FRAC x inner radius), jitter beyond
  JITTER_MPS, creep beyond CREEP_M.

The special cases above are the named rules of :data:`RULES` (one table: each rule's case, what
the analyzer does, its constants, the measurement that justifies it and the tests that hold it
both ways).

Why this module is long: depth, jitter, creep and the sliding test are judged over the same
resting intervals, from the same per-sample supports, witness points, contact velocities and
poses;
splitting them would pass those arrays and the interval bookkeeping between modules.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from rblog.analyze import _audit
from rblog.analyze import geometry, shapes
from rblog.analyze import tolerances as T
from rblog.analyze.base import (Analyzer, Context, Finding, Result, Worst, body_label,
                                combine_friction, shapeless, shapeless_note, static_material)
from rblog.analyze.momentum import static_feature_of_points
from rblog.contract.model import (GEOM_CAPSULE, GEOM_CYLINDER, GEOM_ELLIPSOID, GEOM_SPHERE,
                                  SHAPE_BOX, SHAPE_SPHERE)
from rblog.contract.trajectory import STATIC_BODY


class Rule(NamedTuple):
    """One special case of the penetration analyzer."""

    name: str
    case: str  # when it applies
    then: str  # what the analyzer does
    constants: tuple[str, ...]  # names in rblog.analyze.tolerances (or this module)
    measured: str  # the measurement that justifies it
    tests: tuple[str, ...]  # "file::test" holding it (the case passes, its fault is flagged)


#: The penetration analyzer's special cases, each with its justifying measurement.
RULES: tuple[Rule, ...] = (
    Rule("resting", "in contact, every point of the body (the contact point's speed plus the "
         "relative angular speed times 2 bounding radii) slower than REST_SPEED relative to the "
         "partner for REST_MIN_SAMPLES samples, whatever the shape",
         "the pair rests: resting depth, jitter and creep are judged",
         ("PENETRATION_REST_SPEED_MPS", "PENETRATION_REST_MIN_SAMPLES"),
         "a box at rest moves < 1e-5 m/s (MuJoCo, rblog); a sphere rolling without slip at 1.09 "
         "m/s has its contact point at rest but not its top (2.2 m/s), and its 'creep' was the "
         "witness's omega d/2 (MuJoCo 3.95 mm over 2 s, rblog's mixed.toml at dt 1e-2 0.36 mm)",
         ("tests/analyze/test_analyze.py::test_resting_box_reports_its_rest",
          "tests/analyze/test_rolling.py::"
          "test_a_resting_mujoco_box_with_a_planted_03_mm_creep_is_still_flagged")),
    Rule("rolling_sliding", "in contact and not at rest, the contact point's normal speed "
         "relative to the partner at most REST_SPEED (neither landing nor leaving)",
         "rolling where its tangential slip is at most REST_SPEED (rolling, pivoting or spinning "
         "on the point), else sliding: runs of REST_MIN_SAMPLES samples on one partner are "
         "events with their slip (mean, largest, first and last, deceleration, distance), "
         "never findings; only the transient depth is judged there",
         ("PENETRATION_REST_SPEED_MPS", "PENETRATION_REST_MIN_SAMPLES"),
         "a MuJoCo ball rolling at 1.09 m/s slips 1e-5 m/s at contact.pos (from qvel), the "
         "audit's slip equals it to 1e-3; a box sliding to a stop reads v0 .. v(t), mu g, "
         "v0 t - mu g t^2/2 exactly; a ball launched without spin decelerates its slip at 7/2 mu "
         "g (MuJoCo 2.6 % below) and rolls on at 5/7 v0",
         ("tests/analyze/test_analyze.py::test_rolling_is_not_creep",
          "tests/analyze/test_rolling.py::"
          "test_a_box_sliding_to_a_stop_slides_with_the_closed_form_slip",
          "tests/analyze/test_rolling.py::"
          "test_a_mujoco_ball_rolling_without_slip_reads_rolling_with_mujocos_own_slip",
          "tests/analyze/test_rolling.py::"
          "test_the_issues_ball_with_a_steady_071_mm_s_slip_reads_rolling_with_that_slip",
          "tests/analyze/test_rolling.py::"
          "test_a_mujoco_ball_launched_without_spin_slides_then_rolls_at_five_sevenths")),
    Rule("sphere_midway", "a sphere's support on the ground or a box (the witness kernel's "
         "point lies on one surface)", "the witness moves midway between the two surfaces "
         "along the normal, as for box-box and sphere-sphere pairs and MuJoCo's contact.pos", (),
         "a ball sunk d = 0.365 mm into MuJoCo's floor rolling at 10.9 rad/s slips omega d/2 "
         "= 2.0 mm/s at its lowest point and 1e-5 m/s midway, MuJoCo's own",
         ("tests/analyze/test_rolling.py::"
          "test_a_mujoco_ball_rolling_without_slip_reads_rolling_with_mujocos_own_slip",)),
    Rule("settling", "the first SETTLE_S of a stay", "jitter is not judged; creep keeps none of "
         "the arrival's slide and at most the stay's steady slip speed",
         ("PENETRATION_SETTLE_S", "_STEADY_FRAC"),
         "a body sliding to a stop from REST_SPEED under mu >= 0.05 takes < 0.1 s; a box swinging "
         "at 0.05 rad/s changes its slip speed by 5e-5 of itself over two SETTLE_S",
         ("tests/analyze/test_creep.py::test_a_box_sliding_to_a_stop_does_not_creep",
          "tests/analyze/test_creep.py::test_a_box_creeping_0_3_mm_reads_0_3_mm")),
    Rule("jitter_persists", "the alternating part of the contact-point velocity",
         "is jitter only where it persists over JITTER_PERSIST_SAMPLES samples",
         ("PENETRATION_JITTER_PERSIST_SAMPLES", "PENETRATION_JITTER_MPS"),
         "a step change of velocity (a kick) makes two alternating second differences, a "
         "one-sample spike three; a good engine jitters ~1e-6 m/s",
         ("tests/analyze/test_analyze.py::test_penetration_single_kick_is_not_jitter",
          "tests/analyze/test_analyze.py::test_penetration_flags_jitter_and_creep")),
    Rule("creep_slow_samples", "a sample interval with a sample faster than CREEP_SPEED or "
         "sliding", "counts half (one such sample) or not at all (both)",
         ("PENETRATION_CREEP_SPEED_MPS",),
         "a body that starts to slide away (a ramp steeper than its friction) is not creep",
         ("tests/analyze/test_engine_creep.py::test_mujoco_creep_down_a_ramp_is_flagged",
          "tests/analyze/test_engine_creep.py::test_rblog_holds_a_box_on_a_ramp")),
    Rule("creep_kick_is_a_slide", "an interval that slid faster than CREEP_SPEED on average "
         "(from the poses), or whose velocity changed by more than CREEP_SPEED beyond its "
         "neighbours' mean change", "holds a slide or an impact: no creep",
         ("PENETRATION_CREEP_SPEED_MPS",),
         "0.2 mm within one 10 ms interval (20 mm/s) is a kick; the same shift over ten "
         "intervals (2 mm/s) is creep 0.2 mm",
         ("tests/analyze/test_sliding.py::test_a_kick_between_two_samples_is_a_slide_not_creep",
          "tests/analyze/test_sliding.py::test_the_same_shift_over_ten_intervals_is_creep")),
    Rule("witness_band", "logged rows of a pair within WITNESS_BAND_M of each other",
         "are one loaded point for the patch rules", ("WITNESS_BAND_M",),
         "a box-box manifold clips two rows to one corner 2.3 nm apart (28,772 of 441,399 rows "
         "of samples/pile.toml at seed 12); pile seed 12's 0.126 mm 'creep' was box406 "
         "swinging about that corner",
         ("tests/analyze/test_witness.py::test_two_rows_at_the_pivot_are_one_loaded_point",
          "tests/analyze/test_witness.py::"
          "test_the_same_swing_with_both_ends_of_the_edge_loaded_creeps")),
    Rule("patch_pivot", "a pair whose logged rows carry load at one point at most",
         "an edge patch slides by its least-slipping point, a face patch 0 when the pair turns "
         "about a point on both faces; with more loaded points the witness is judged", (),
         "a box swinging about one end of its edge, or pivoting on one corner of its face, "
         "slips 0 there (an every-step log: 0.2 um per 10 ms at the corner)",
         ("tests/analyze/test_witness.py::"
          "test_a_box_swinging_about_an_end_of_its_edge_does_not_creep",
          "tests/analyze/test_witness.py::test_the_same_box_sliding_03_mm_along_its_edge_creeps")),
    Rule("mutual_support", "a contact two bodies both take as their support",
         "slides the same for both: counted once, for the body it holds up", (),
         "the 500-box pile once read one slide between box315 and box317 (0.105 mm) twice",
         ("tests/analyze/test_creep.py::"
          "test_a_slide_between_two_bodies_that_support_each_other_is_reported_once",)),
    Rule("sliding_at_the_cone", "the support's logged rows at their Coulomb limit, all but at "
         "most one, or its tangential load at that limit",
         "the contact slides: its slip is not creep, its velocity change not jitter",
         ("PENETRATION_SLIDE_CONE_FRAC",),
         "points at the limit are there to round-off (within 1e-9: 62,016 of rblog's 438,425 "
         "pile rows, 8,769 of MuJoCo's 42,112, 25,824 of pybullet's 60,737); 0.99 .. 1 - 1e-9 "
         "holds 0.46-4.4 % of rows, so 1 % moves few samples",
         ("tests/analyze/test_sliding.py::"
          "test_box_pushed_at_the_friction_limit_slides_and_is_not_creep",
          "tests/analyze/test_sliding.py::"
          "test_planted_creep_of_a_box_held_by_static_friction_is_flagged")),
    Rule("unloaded_support", "no row of the pair carries more than MOMENTUM_CONE_FLOOR_NS (or "
         "the body has no row while the log carries contacts)", "slides (limit mu x 0)",
         ("MOMENTUM_CONE_FLOOR_NS",),
         "rblog's pile at seed 2: box 177 chattering on box 130, loaded between samples; a ball "
         "struck by another hops 0.2 mm between two samples",
         ("tests/analyze/test_sliding.py::"
          "test_a_box_on_an_unloaded_support_slides_and_is_not_creep",
          "tests/analyze/test_sliding.py::test_the_same_slide_on_a_loaded_support_is_creep")),
    Rule("geom_pair_support", "a body without a v2 shape (capsule, cylinder, ellipsoid, mesh, "
         "several geoms), or a contact with a world geom that is neither the ground nor a static "
         "box (a wall plane: partner N + M + w)",
         "its supports are its geom pairs within CONTACT_DISTANCE (rblog.analyze.shapes, the "
         "log's collision filter): the deepest per sample, witness at the midpoint of the two "
         "witness points, no edge or face patch (span 0: the witness slides as it is), reach for "
         "the rest test from its geoms, resting depth tol from the pair's thinner geom; its "
         "any-time depth is judged per geom pair (geom_depths); logged static rows go to the "
         "nearest world geom",
         ("CONTACT_DISTANCE_M", "PENETRATION_REST_SPEED_MPS"),
         "a MuJoCo capsule and cylinder resting on a floor slide < 1e-5 m over 0.6 s; a capsule "
         "rolling without slip at 0.05 rad/s slides 0 to round-off (closed form: x = r theta); "
         "0.3 mm written into either log reads 0.3 mm",
         ("tests/analyze/test_geom_rest.py::"
          "test_a_mujoco_capsule_and_cylinder_resting_on_a_floor_are_clean",
          "tests/analyze/test_geom_rest.py::"
          "test_a_creep_of_03_mm_written_into_the_log_is_flagged_on_the_capsule",
          "tests/analyze/test_geom_rest.py::test_a_capsule_rolling_without_slip_does_not_creep",
          "tests/analyze/test_geom_rest.py::test_the_same_roll_slipping_03_mm_creeps_03_mm")),
    Rule("depth_limits", "a pair's depth", "resting beyond min(DEPTH_M, DEPTH_FRAC x the inner "
         "radius), at any sample beyond min(TRANSIENT_DEPTH_M, TRANSIENT_FRAC x it)",
         ("PENETRATION_DEPTH_M", "PENETRATION_DEPTH_FRAC", "PENETRATION_TRANSIENT_DEPTH_M",
          "PENETRATION_TRANSIENT_FRAC"),
         "the audit's depth equals MuJoCo's contact.dist to round-off (a capsule limb resting "
         "in MuJoCo's soft floor < 5 mm; sunk 20 mm it is flagged with MuJoCo's own depth)",
         ("tests/analyze/test_geometry_penetration.py::"
          "test_clean_mujoco_log_passes_with_mujocos_depth",
          "tests/analyze/test_geometry_penetration.py::test_capsule_sunk_20mm_is_flagged")),
)


def _world_geoms(model) -> np.ndarray:
    """(W,) the world geoms that are neither the ground nor a static box, in the order of their
    partner codes N + M + w (rblog.analyze.shapes.partner_codes)."""
    if not getattr(model, "n_geoms", 0):
        return np.zeros(0, np.int64)
    codes = shapes.partner_codes(model)
    first = model.n_bodies + len(model.static_box_position)
    return np.flatnonzero(codes >= first)[np.argsort(codes[codes >= first])]


def _partner_label(model, b: int) -> str:
    n = model.n_bodies
    m = len(model.static_box_position)
    if b == -1:
        return "the ground"
    if b >= n + m:
        g = int(_world_geoms(model)[b - n - m])
        name = model.geom_name[g] if model.geom_name is not None else ""
        return f"world geom {g} ({name!r})"
    if b >= n:
        return f"static box {b - n}"
    return body_label(model, b)


def _static_friction(model, sid: np.ndarray) -> np.ndarray:
    """Friction of static partners ``sid`` (-1 ground, m < M static box m, M + w the w-th other
    world geom (its geom_friction, the static boxes' worst case where NaN), < -1 unknown: the worst
    case, rblog.analyze.base.static_material)."""
    sid = np.asarray(sid, np.int64)
    m = len(model.static_box_position)
    _, mu = static_material(model, np.where(sid >= m, -2, sid))
    far = sid >= m
    if far.any():
        gf = np.asarray(model.geom_friction, float)[_world_geoms(model)[sid[far] - m]]
        mu = np.asarray(mu, float).copy()
        mu[far] = np.where(np.isnan(gf), mu[far], gf)
    return mu


def _sphere_midway(model, i, b, sep, normal, point) -> None:
    """Move, in place, the witness ``point`` (R, 3) of support rows (body i, partner b; sep (R,),
    normal (R, 3) partner -> body) that lie on one surface only to the point midway between the
    two surfaces along the normal (rule "sphere_midway"): a sphere on the ground (the witness
    kernel gives the sphere's lowest point, sep above the plane: midway is ``point - sep/2 n``),
    a sphere on a box (the box's surface point: ``point + sep/2 n``), a box on a sphere
    (``point - sep/2 n``). Box-box and sphere-sphere points are midway already."""
    shape = np.asarray(model.body_shape)
    n = len(shape)
    sph_body = shape == SHAPE_SPHERE
    if not len(i) or not sph_body.any():
        return
    dyn = (b >= 0) & (b < n)
    rows = np.flatnonzero(sph_body[i] | (dyn & sph_body[np.where(dyn, b, 0)]))
    if not len(rows):
        return
    i, b = i[rows], b[rows]
    part = np.where((b >= 0) & (b < n), shape[np.clip(b, 0, n - 1)], -2)
    sph = shape[i] == SHAPE_SPHERE
    boxlike = (part == SHAPE_BOX) | ((b >= n) & (b < n + len(model.static_box_position)))
    half = np.where(sph & (b == -1), -0.5, 0.0)
    half = np.where(sph & boxlike, 0.5, half)
    half = np.where((shape[i] == SHAPE_BOX) & (part == SHAPE_SPHERE), -0.5, half)
    m = rows[half != 0]
    if len(m):
        point[m] += (half[half != 0] * sep[m])[:, None] * normal[m]


def _mutual_lower(pk, pi_, pb, normal, model, n: int, t_n: int) -> np.ndarray:
    """(R,) True at the support rows of a body whose partner (a body) takes it as its own support
    at the same sample, for the one of the two that lies below: normal (partner -> body) less
    along -gravity than its partner's (the lower body index when level or without gravity)."""
    r_n = len(pk)
    out = np.zeros(r_n, bool)
    dyn = (pb >= 0) & (pb < n)
    if not dyn.any():
        return out
    row_of = np.full((n, t_n), -1, np.int64)
    row_of[pi_, pk] = np.arange(r_n)
    rows = np.nonzero(dyn)[0]
    other = row_of[pb[rows], pk[rows]]
    mutual = (other >= 0) & (pb[np.maximum(other, 0)] == pi_[rows])
    rows, other = rows[mutual], other[mutual]
    g = np.asarray(model.gravity, float)
    gn = np.linalg.norm(g)
    up = -g / gn if gn > 0 else np.zeros(3)
    mine, theirs = normal[rows] @ up, normal[other] @ up
    out[rows] = (mine < theirs) | ((mine == theirs) & (pi_[rows] > pi_[other]))
    return out


def _main_partner(contrib, run_of, pb, in_run, nr: int, partner_default) -> np.ndarray:
    """(runs,) the partner of each run whose intervals slide the most in net (|sum|), or
    ``partner_default`` where nothing slid."""
    out = np.asarray(partner_default).copy()
    rows = np.nonzero(in_run & (np.abs(contrib).sum(axis=1) > 0))[0]
    if not len(rows):
        return out
    key = run_of[rows].astype(np.int64) * (int(pb.max()) + 2) + (pb[rows] + 1)
    uk, inv = np.unique(key, return_inverse=True)
    tot = np.stack([np.bincount(inv, contrib[rows, d], len(uk)) for d in range(3)], 1)
    mag = np.linalg.norm(tot, axis=1)
    run_k = uk // (int(pb.max()) + 2)
    order = np.lexsort((-mag, run_k))
    first = np.r_[True, run_k[order][1:] != run_k[order][:-1]]
    best = order[first]
    out[run_k[best]] = (uk[best] % (int(pb.max()) + 2)) - 1
    return out


def _geom_candidates(gp: dict, model, cd: float) -> dict:
    """Support candidates from geom pairs (:meth:`PenetrationAnalyzer.geom_pairs`): each pair
    within ``cd`` counts for each of its geoms' bodies, with the other geom's partner code
    (rblog.analyze.shapes.partner_codes), the normal from the partner into the body, the witness
    at the midpoint of the two surfaces' witness points (one point for both bodies), no edge
    patch (span 0) and the pair's thinner geom's smallest half-extent as the inner radius."""
    code = shapes.partner_codes(model)
    body = gp["geoms"].body
    gi, gj = gp["i"], gp["j"]
    keep = gp["sep"] <= cd
    gi, gj = gi[keep], gj[keep]
    mid = 0.5 * (gp["pa"][keep] + gp["pb"][keep])
    nrm = gp["normal"][keep]
    inner = np.minimum(gp["inner"][gi], gp["inner"][gj])
    parts = []
    for me, other, sign in ((gi, gj, 1.0), (gj, gi, -1.0)):
        m = body[me] >= 0
        parts.append(dict(k=gp["k"][keep][m], i=body[me][m], b=code[other][m],
                          sep=gp["sep"][keep][m], normal=sign * nrm[m], point=mid[m],
                          inner=inner[m]))
    out = {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
    out["span"] = np.zeros((len(out["k"]), 3))
    out["geom"] = np.ones(len(out["k"]), bool)
    return out


def _merge_supports(a: dict, b: dict) -> dict:
    """The deepest candidate per (body, sample) of two sets of support rows (``a`` first on a
    tie), in body-major order (body, then sample)."""
    both = {key: np.concatenate([a[key], b[key]]) for key in a}
    r_a = len(a["k"])
    order = np.lexsort((np.arange(len(both["k"])) >= r_a, both["sep"], both["k"], both["i"]))
    ik = both["i"][order] * (int(both["k"].max(initial=0)) + 1) + both["k"][order]
    first = np.r_[True, ik[1:] != ik[:-1]] if len(ik) else np.zeros(0, bool)
    sel = order[first]
    return {key: v[sel] for key, v in both.items()}


def _distinct_points(inv, point, carry, n_keys: int, band: float) -> np.ndarray:
    """(n_keys,) how many distinct points carry load per key: a carrying row (``carry``, R bool)
    of key ``inv`` (R,) whose ``point`` (R, 3) lies within ``band`` (m, along each axis) of
    another carrying row of the same key is the same point. A box-box manifold can clip two rows to one corner (2 nm apart,
    normals 8e-4 apart: 28,772 of the 441,399 rows of samples/pile.toml at seed 12), and a patch
    pivoting on that corner carries load at one point, not two (contact_slide's patch rules)."""
    rows = np.nonzero(carry)[0]
    out = np.bincount(inv[rows], minlength=n_keys)
    if len(rows) < 2:
        return out
    o = rows[np.lexsort((point[rows, 0], inv[rows]))]
    key, p = inv[o], point[o]
    dup = np.zeros(len(o), bool)
    longest = int(out.max())
    for lag in range(1, longest):
        near = (key[lag:] == key[:-lag]) & (np.abs(p[lag:] - p[:-lag]) <= band).all(axis=1)
        dup[lag:] |= near
    return out - np.bincount(key[dup], minlength=n_keys)


#: per-interval slides closer than this fraction of the creep tolerance are equal (1e-10 m at the
#: default: four orders above the round-off of a pose difference, six below the tolerance)
_EQUAL_SLIDE_FRAC = 1e-6
#: an early interval slipping within this fraction of the stay's steady slip speed counts in full
#: (a box swinging at 0.05 rad/s as it creeps along its edge, tests/analyze/test_witness.py,
#: changes its slip speed by up to 1 - cos(0.05 x 0.2) = 5e-5 of itself over two SETTLE_S)
_STEADY_FRAC = 1e-2


def _settling_slide(contrib: np.ndarray, early: np.ndarray, ref: np.ndarray,
                    run_of: np.ndarray, dt_w: np.ndarray, nr: int, equal_m: float) -> np.ndarray:
    """The slide of each interval (R, 3) (row r: the interval from row r to r + 1, already
    weighted), with the settling slide of each stay taken out of its first SETTLE_S.

    Of the ``early`` intervals (R bool: those starting within the stay's first SETTLE_S), the ones
    before the first of least slide count 0 (the body slowing to its least: arriving, landing,
    sliding to a stop, the solver settling), and the others count at most the stay's steady slip
    speed, ``sum of |slide| / sum of dt_w`` over its ``ref`` intervals (the next SETTLE_S; dt_w
    (R,) the interval's weighted duration, s), times their own dt_w, within _STEADY_FRAC (a steady
    slip whose speed drifts slowly, a box swinging as it creeps, changes by far less per
    SETTLE_S). Slides within ``equal_m`` (m) of the least count as equal to it (the round-off of
    a difference of poses is ~1e-14 m). So a body at rest, or creeping at a steady
    rate from its first sample, keeps all of its slide, and a box that lands or slides to a stop
    keeps none of its arrival.
    """
    out = contrib.copy()
    rows = np.nonzero(early)[0]
    if not len(rows):
        return out
    ref_rows = np.nonzero(ref)[0]
    tot = np.bincount(run_of[ref_rows], weights=np.linalg.norm(contrib[ref_rows], axis=1),
                      minlength=nr)
    dur = np.bincount(run_of[ref_rows], weights=dt_w[ref_rows], minlength=nr)
    with np.errstate(invalid="ignore", divide="ignore"):
        rate = np.where(dur > 0, tot / dur, 0.0)
    mag = np.linalg.norm(contrib[rows], axis=1)
    run = run_of[rows]
    least = np.full(nr, np.inf)
    np.minimum.at(least, run, mag)
    at = rows[mag <= least[run] + equal_m]
    first = np.full(nr, np.iinfo(np.int64).max)
    np.minimum.at(first, run_of[at], at)
    with np.errstate(invalid="ignore", divide="ignore"):
        keep = np.where(rows >= first[run],
                        np.minimum(1.0, np.where(mag > 0, (1.0 + _STEADY_FRAC) * rate[run]
                                                 * dt_w[rows] / mag, 1.0)), 0.0)
    out[rows] *= keep[:, None]
    return out


def _motion_stretches(an, ctx: Context, sup: dict, rest: np.ndarray, cv: np.ndarray,
                      slip: np.ndarray, wspeed: np.ndarray, depth: np.ndarray,
                      stats: dict) -> list[dict]:
    """Rolling and sliding stretches of the support rows ``sup`` (R rows, body-major) as events
    (rule "rolling_sliding"), counts and totals into ``stats``.

    A row moves where the pair is not at rest (``rest`` (R,) False) but stays in contact: the
    contact point's normal speed relative to the partner, ``|cv . n|`` (cv (R, 3) m/s), at most
    REST_SPEED. It rolls where the point's tangential slip ``|slip|`` ((R, 3) m/s) is at most
    REST_SPEED (the contact point at rest: rolling, pivoting or spinning on it), else slides. A
    stretch is a run of REST_MIN_SAMPLES or more consecutive samples of one body on one partner in
    one class. Per stretch, over its samples by the trapezoid rule: ``slid_m`` = the integral of
    |slip| dt, ``slip_mps`` its mean (slid_m / duration), the slip at its first and last sample
    and its largest, ``slip_decel_mps2`` = (first - last) / duration (mu |g| for a box sliding to a
    stop on a level floor), ``speed_mps`` the mean speed of the body's centre relative to the
    partner's velocity field there, ``spin_radps`` the mean relative angular speed (wspeed (R,)
    rad/s), ``depth_max_m``."""
    tr = ctx.traj
    model = tr.model
    n = tr.n_bodies
    t, step = tr.t, tr.step
    tol = an.tol
    stats["rolling_stretches"] = stats["sliding_stretches"] = 0.0
    mv = np.flatnonzero(~rest)  # only the rows that move (still body-major)
    r_n = len(mv)
    if r_n < 2:
        return []
    pk, pi_, pb, pnorm = sup["k"][mv], sup["i"][mv], sup["b"][mv], sup["normal"][mv]
    cv, slip, wspeed, depth = cv[mv], slip[mv], wspeed[mv], depth[mv]
    vs = tol["rest_speed_mps"]
    vn = np.abs(np.einsum("ij,ij->i", cv, pnorm))
    s_speed = np.sqrt(np.einsum("ij,ij->i", slip, slip))
    cls = np.where(vn > vs, 0, np.where(s_speed <= vs, 1, 2)).astype(np.int8)
    # runs: consecutive samples of one body on one partner in one class
    same = np.zeros(r_n, bool)
    same[:-1] = ((pi_[1:] == pi_[:-1]) & (pk[1:] == pk[:-1] + 1) & (pb[1:] == pb[:-1])
                 & (cls[1:] == cls[:-1]))
    on = cls > 0
    starts = np.nonzero(on & ~np.r_[False, same[:-1]])[0]
    ends = np.nonzero(on & ~same)[0]
    long_ = (ends - starts + 1) >= tol["rest_min_samples"]
    starts, ends = starts[long_], ends[long_]
    if not len(starts):
        return []
    kind = cls[starts]
    # the centre's velocity relative to the partner's velocity field there (a static partner: 0)
    vc = tr.velocity[pk, pi_].astype(float)
    dyn = (pb >= 0) & (pb < n)
    if dyn.any():
        kb, bb = pk[dyn], pb[dyn]
        vc[dyn] -= tr.velocity[kb, bb] + np.cross(tr.angular_velocity[kb, bb],
                                                  tr.position[kb, pi_[dyn]] - tr.position[kb, bb])
    c_speed = np.linalg.norm(vc, axis=1)
    # trapezoid sums over each stretch's intervals (row r to r + 1 inside the stretch)
    dt = np.zeros(r_n)
    dt[:-1] = np.where(same[:-1], t[np.minimum(pk[:-1] + 1, len(t) - 1)] - t[pk[:-1]], 0.0)
    in_run = np.zeros(r_n + 1, np.int64)
    np.add.at(in_run, starts, 1)
    np.add.at(in_run, ends, -1)  # the last row's interval leaves the stretch
    inner = np.cumsum(in_run)[:-1] > 0
    dt = np.where(inner, dt, 0.0)
    idx = np.empty(2 * len(starts), np.int64)
    idx[0::2], idx[1::2] = starts, ends + 1

    def total(x):  # sum over each stretch's intervals of dt (x(r) + x(r + 1)) / 2
        x_next = np.r_[x[1:], 0.0]
        return np.add.reduceat(np.r_[dt * 0.5 * (x + x_next), 0.0], idx)[0::2]

    def most(x):
        return np.maximum.reduceat(np.r_[x, 0.0], idx)[0::2]

    dur = t[pk[ends]] - t[pk[starts]]
    slid = total(s_speed)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(dur > 0, slid / dur, s_speed[starts])
        speed = np.where(dur > 0, total(c_speed) / dur, c_speed[starts])
        spin = np.where(dur > 0, total(wspeed) / dur, wspeed[starts])
        decel = np.where(dur > 0, (s_speed[starts] - s_speed[ends]) / dur, 0.0)
    s_max, d_max = most(s_speed), most(depth)
    for c_, word in ((1, "rolling"), (2, "sliding")):
        m = kind == c_
        stats[f"{word}_stretches"] = float(m.sum())
        if m.any():
            stats[f"{word}_duration_total_s"] = float(dur[m].sum())
            stats[f"{word}_slip_max_mps"] = float(s_max[m].max())
    round_ = _round_bodies(model)
    out = []
    for r in np.argsort(pk[starts], kind="stable")[: T.MAX_EVENTS]:
        a, e = int(starts[r]), int(ends[r])
        word = "rolling" if kind[r] == 1 else "sliding"
        verb = ("slides" if kind[r] == 2 else "rolls" if round_[int(pi_[a])] else "pivots")
        text = (f"{body_label(model, int(pi_[a]))} {verb} on "
                f"{_partner_label(model, int(pb[a]))} from t = {t[pk[a]]:.6g} s for "
                f"{dur[r]:.3g} s at {speed[r]:.3g} m/s, slip {_speed_text(mean[r])}")
        text += (f" (max {_speed_text(s_max[r])})" if kind[r] == 1 else
                 f" ({_speed_text(s_speed[a])} -> {_speed_text(s_speed[e])}, slid "
                 f"{slid[r]:.3g} m)")
        out.append({
            "kind": word, "body": int(pi_[a]), "partner": int(pb[a]),
            "t_start": float(t[pk[a]]), "t_end": float(t[pk[e]]),
            "step_start": int(step[pk[a]]), "step_end": int(step[pk[e]]),
            "duration_s": float(dur[r]), "samples": e - a + 1,
            "speed_mps": float(speed[r]), "spin_radps": float(spin[r]),
            "slip_mps": float(mean[r]), "slip_max_mps": float(s_max[r]),
            "slip_start_mps": float(s_speed[a]), "slip_end_mps": float(s_speed[e]),
            "slip_decel_mps2": float(decel[r]), "slid_m": float(slid[r]),
            "depth_max_m": float(d_max[r]), "text": text,
        })
    return out


#: the geoms a body rolls on; a rolling contact of a body with none of them (a box tipping over
#: its edge, a hull on a vertex) is the body pivoting on that point
ROUND_GEOMS = (GEOM_SPHERE, GEOM_CAPSULE, GEOM_CYLINDER, GEOM_ELLIPSOID)


def _round_bodies(model) -> np.ndarray:
    """(N,) bool: the body is a sphere (contract v2) or has a round geom (ROUND_GEOMS)."""
    out = np.asarray(model.body_shape) == SHAPE_SPHERE
    if getattr(model, "n_geoms", 0):
        gb = np.asarray(model.geom_body, np.int64)
        rnd = np.isin(np.asarray(model.geom_type), ROUND_GEOMS) & (gb >= 0)
        out[gb[rnd]] = True
    return out


def _speed_text(v: float) -> str:
    """A speed for a report: mm/s below 0.1 m/s (a slip of 0.71 mm/s), else m/s."""
    return f"{v * 1e3:.3g} mm/s" if v < 0.1 else f"{v:.3g} m/s"


class PenetrationAnalyzer(Analyzer):
    name = "penetration"
    description = ("resting contact: depth recomputed from the poses, duration, jitter and creep; "
                   "and the deepest penetration at any time")
    defaults = T.options("penetration", "depth_m", "depth_frac", "transient_depth_m",
                         "transient_frac", "rest_speed_mps", "rest_min_samples", "settle_s",
                         "jitter_mps", "jitter_persist_samples", "creep_m", "creep_speed_mps",
                         "slide_cone_frac", slide_floor_ns=T.MOMENTUM_CONE_FLOOR_NS,
                         contact_distance_m=T.CONTACT_DISTANCE_M)

    def supports(self, ctx: Context):
        """The primary support of each body at each sample where it touches something (within
        the contact distance): the deepest of its contacts with the ground, static boxes and
        other bodies (pairs count for both bodies).

        Returns dict of (R,) arrays in body-major order (body, then sample): k, i (body), b
        (partner: -1 ground, N+m static box m, or a body), sep, normal (partner -> body), point,
        span (R, 3): an edge patch's half-span (the patch is point +- span), else 0.
        """
        tr = ctx.traj
        model = tr.model
        n, t_n = tr.n_bodies, tr.n_samples
        cd = self.tol["contact_distance_m"]
        prox = ctx.proximity(cd)
        near = prox.near_pairs(cd)
        ground = prox.ground_sep if prox.ground_sep is not None else np.zeros((0, 0))
        none = shapeless(model)
        if none.any():  # no separations for bodies without a shape: left out (not_judged)
            keep = ~none[near["a"]] & ~((near["b"] < n) & none[np.minimum(near["b"], n - 1)])
            near = {key: v[keep] for key, v in near.items()}
            if ground.size:
                ground = np.where(none[None, :], np.inf, ground)
        pk, pa, pb, ps = near["k"], near["a"], near["b"], near["sep"]
        kind = np.full((n, t_n), -1, np.int8)  # -1 none, 0 ground, 1 pair as a, 2 pair as b
        ref = np.zeros((n, t_n), np.int64)
        c = np.ascontiguousarray
        _audit.deepest(c(ground, dtype=np.float64), float(cd), c(pk, dtype=np.int64),
                       c(pa, dtype=np.int64), c(pb, dtype=np.int64), c(ps, dtype=np.float64), n,
                       kind, ref)
        i, k = np.nonzero(kind >= 0)  # body-major
        src = kind[i, k]
        ref = ref[i, k]
        r = len(k)
        b = np.full(r, -1, np.int64)
        sep_out = np.empty(r)
        normal = np.empty((r, 3))
        point = np.empty((r, 3))
        span = np.zeros((r, 3))
        g = src == 0
        if g.any():
            sep_out[g] = prox.ground_sep[k[g], i[g]]
            normal[g] = np.asarray(model.ground_normal, float)
            point[g], span[g] = geometry.plane_witness_at(model, k[g], i[g], i[g], tr.position,
                                                          tr.rotation, with_span=True)
        for which, sign in ((1, 1.0), (2, -1.0)):
            m = src == which
            if m.any():
                rr = ref[m]
                b[m] = pb[rr] if which == 1 else pa[rr]
                sep_out[m], nn, pp, ss = prox.iv_geometry(near["row"][rr], near["end"][rr],
                                                          with_span=True)
                normal[m] = sign * nn
                point[m] = pp
                span[m] = ss
        _sphere_midway(model, i, b, sep_out, normal, point)
        out = dict(k=k, i=i, b=b, sep=sep_out, normal=normal, point=point, span=span,
                   inner=geometry.inner_radius(model)[i], geom=np.zeros(r, bool))
        gp = self.geom_pairs(ctx)
        if gp is None:
            return out
        return _merge_supports(out, _geom_candidates(gp, model, cd))

    def geom_pairs(self, ctx: Context):
        """The geom pairs (contract v3 geoms, rblog.analyze.shapes) within the contact distance at
        each sample that involve a body without a v2 shape or a world geom that is neither the
        ground nor a static box (a wall plane), by the log's collision filter, with
        their witness points: dict of k, i, j (geoms), sep, normal (j into i), pa, pb, and
        ``inner`` (G,) each geom's smallest half-extent; None when there are none to test.
        Computed once per context."""
        tr = ctx.traj
        model = tr.model
        cd = self.tol["contact_distance_m"]

        def compute():
            if not getattr(model, "n_geoms", 0) or shapes.contacts_disabled(tr.info):
                return None
            none = shapeless(model)
            geoms = shapes.model_geoms(model)
            body = geoms.body
            # world geoms the v2 fields do not describe (a wall plane, a world capsule)
            unseen = shapes.partner_codes(model) >= model.n_bodies + len(model.static_box_position)
            if not none[body[body >= 0]].any() and not unseen.any():
                return None
            pos, rot = ctx.geom_poses()
            k, i, j = shapes.broadphase(geoms, pos, rot, cd)
            mine = (none[np.maximum(body[i], 0)] & (body[i] >= 0)) | \
                (none[np.maximum(body[j], 0)] & (body[j] >= 0)) | unseen[i] | unseen[j]
            keep = mine & shapes.collide_mask(model, i, j)
            k, i, j = k[keep], i[keep], j[keep]
            d = shapes.pair_distance(geoms, pos, rot, k, i, j, with_points=True)
            near = d["sep"] <= cd
            return dict(k=k[near], i=i[near], j=j[near], sep=d["sep"][near],
                        normal=d["normal"][near], pa=d["pa"][near], pb=d["pb"][near],
                        geoms=geoms, inner=shapes.inner_half_extent(geoms))

        return ctx.cached(("penetration.geom_pairs", cd), compute)

    def sliding(self, ctx: Context, sup: dict,
                cand: np.ndarray) -> tuple[np.ndarray, dict, np.ndarray]:
        """(R,) True where the support contact is sliding, not resting (see the module
        docstring), judged at the rows ``cand`` (R,) only (the slow ones: only they can rest),
        counts of why, and (R,) at how many distinct points the pair's logged rows at the step
        carry load (above the impulse floor; -1 where the log has none for the pair).

        With logged contact rows (the step that ends at the sample, rows of the support pair):
        the pair's points are at their Coulomb limit, ``|f| >= (1 - SLIDE_CONE_FRAC) mu J_n``,
        all but at most one (the point a slipping contact may pivot about), or the tangential
        load the support must hold (the body's other contacts' impulses plus (m g + F) dt) is at
        or beyond ``mu sum J_n``. Without contact rows in the log, a body touching nothing but its
        support is judged by its inferred impulse over the interval that ends at the sample
        (rblog.analyze.base.Context.impulse); a body with several contacts cannot be, and
        counts as resting.
        """
        tr = ctx.traj
        model = tr.model
        n = tr.n_bodies
        r_n = len(sup["k"])
        frac = self.tol["slide_cone_frac"]
        floor = self.tol["slide_floor_ns"]
        out = np.zeros(r_n, bool)
        nload = np.full(r_n, -1, np.int64)
        why = {"sliding_friction_at_limit": 0, "sliding_pushed": 0, "sliding_unloaded": 0,
               "sliding_inferred": 0}
        rows_c = np.nonzero(cand)[0]
        if not len(rows_c):
            return out, why, nload
        pk, pi_, pb = sup["k"][rows_c], sup["i"][rows_c], sup["b"][rows_c]
        pnorm = sup["normal"][rows_c]
        c = tr.contacts
        codes = shapes.partner_codes(model) if getattr(model, "n_geoms", 0) else np.zeros(0, int)
        e_n = max(n + len(model.static_box_position), int(codes.max(initial=-1)) + 1) + 1
        if len(c):
            # rows of logged steps that end at a sample, entered for body_a and (negated) body_b
            kr = np.searchsorted(tr.step, c.step)
            ok = kr < tr.n_samples
            ok[ok] = tr.step[kr[ok]] == c.step[ok]
            ca, cb = c.body_a.astype(np.int64), c.body_b.astype(np.int64)
            ok &= (ca >= 0) & (ca < n)
            part = cb.copy()
            st = ok & (cb == STATIC_BODY)
            if st.any():
                if (codes >= n + len(model.static_box_position)).any():
                    # world geoms the v2 fields do not describe (a wall plane): each row's
                    # partner is the world geom nearest its point (rule "geom_pair_support")
                    part[st] = codes[shapes.nearest_static_geom(
                        model, shapes.model_geoms(model), c.point[st])]
                else:
                    fid = static_feature_of_points(model, c.point[st], c.normal[st])
                    part[st] = np.where(fid >= 0, n + fid, -1)
            dyn = ok & (cb >= 0) & (cb < n)
            key = np.concatenate([(kr[ok] * n + ca[ok]) * e_n + part[ok] + 1,
                                  (kr[dyn] * n + cb[dyn]) * e_n + ca[dyn] + 1])
            uk, inv = np.unique(key, return_inverse=True)
            skey = (pk * n + pi_) * e_n + pb + 1
            ks = np.unique(kr[ok])
            # only rows at a sample with logged rows can have rows or be airborne: the searches
            # below go over those (the rest: not found, not airborne)
            at = np.zeros(tr.n_samples, bool)
            at[ks] = True
            q = np.flatnonzero(at[pk]) if len(uk) else np.arange(len(pk))
            pos = np.zeros(len(pk), np.int64)
            pos[q] = np.clip(np.searchsorted(uk, skey[q]), 0, len(uk) - 1)
            found = np.zeros(len(pk), bool)
            found[q] = uk[pos[q]] == skey[q]
            # a body the log gives no row at all at a sample that has rows (the engine logs
            # every point that pushes or touches): it touches nothing there, in the air between
            # two landings (a ball struck by another hops 0.2 mm and lands within 25 ms), so its
            # support carries no load, as a support whose rows all carry none (below): not at
            # rest, neither jitter nor creep. Only where the body has no row with any partner,
            # so that a partner the rows name differently (a static box's feature) is never
            # taken for one without rows.
            kb = np.unique(np.concatenate([kr[ok] * n + ca[ok], kr[dyn] * n + cb[dyn]]))
            airborne = np.zeros(len(pk), bool)
            if len(ks):
                kb_pos = np.clip(np.searchsorted(kb, pk[q] * n + pi_[q]), 0, len(kb) - 1)
                airborne[q] = ~found[q] & (kb[kb_pos] != pk[q] * n + pi_[q])
            out[rows_c[airborne]] = True
            why["sliding_unloaded"] += int(airborne.sum())
            if not found.any():
                return out, why, nload
            sel = np.nonzero(found)[0]
            pos, pk, pi_, pb, rows_c = pos[sel], pk[sel], pi_[sel], pb[sel], rows_c[sel]
            sgn = np.concatenate([np.ones(int(ok.sum())), -np.ones(int(dyn.sum()))])
            rows = np.concatenate([np.nonzero(ok)[0], np.nonzero(dyn)[0]])
            jn_row = c.normal_impulse
            nv = jn_row[:, None] * c.normal

            def per_key(v):
                return np.stack([np.bincount(inv, sgn * v[rows, d], len(uk)) for d in range(3)], 1)

            jn_k = np.bincount(inv, jn_row[rows], len(uk))
            f_k, n_k = per_key(c.friction_impulse), per_key(nv)
            # points at their Coulomb limit: a rigid contact that slips (translating or twisting
            # about its normal) slips at every point but the one it may pivot about, and a
            # slipping point's friction is at mu J_n; so the pair slides when at least one
            # load-carrying point is at its limit and at most one is inside the cone (a box
            # twisting on its support has every point at the limit, each in its own direction,
            # with their vector sum well inside; an edge pivoting about one end has one of two)
            bf = np.asarray(model.body_friction, float)
            smu = _static_friction(model, np.where(part >= n, part - n, -1))
            mu_row = np.where(cb == STATIC_BODY, smu, 0.0)
            mu_row[dyn] = combine_friction(bf[ca[dyn]], bf[cb[dyn]], tr.info.combine_friction)
            if st.any():
                mu_row[st] = combine_friction(bf[ca[st]], smu[st], tr.info.combine_friction)
            f_row = c.friction_impulse - np.einsum("ij,ij->i", c.friction_impulse,
                                                   c.normal)[:, None] * c.normal
            carry = jn_row > floor
            lim_row = carry & (np.linalg.norm(f_row, axis=1) >= (1.0 - frac) * mu_row * jn_row)
            n_at = np.bincount(inv, lim_row[rows], len(uk))
            n_in = np.bincount(inv, (carry & ~lim_row)[rows], len(uk))
            # every row's impulse on the body, per (sample, body)
            ub, inv_b = np.unique(key // e_n, return_inverse=True)
            imp = c.friction_impulse + nv
            tot_b = np.stack([np.bincount(inv_b, sgn * imp[rows, d], len(ub)) for d in range(3)],
                             1)
            pos_b = np.clip(np.searchsorted(ub, pk * n + pi_), 0, len(ub) - 1)
            jn_s = jn_k[pos]
            nvec = n_k[pos]
            # the support's mean normal (rows of an edge or a corner differ a little)
            nl = np.linalg.norm(nvec, axis=1)
            nrm = np.where((nl > 0)[:, None], nvec / np.where(nl > 0, nl, 1.0)[:, None],
                           pnorm[sel])
            # friction coefficient of each support pair, by the log's combine rule
            sid = np.where(pb == -1, -1, np.where(pb >= n, pb - n, -2))
            s_mu = _static_friction(model, sid)
            dynp = (pb >= 0) & (pb < n)
            mu = combine_friction(bf[pi_], np.where(dynp, bf[np.clip(pb, 0, n - 1)], s_mu),
                                  tr.info.combine_friction)
            limit = mu * jn_s
            held = jn_s > floor
            at_limit = held & (n_at[pos] >= 1) & (n_in[pos] <= 1)
            other = tot_b[pos_b] - f_k[pos] - nvec
            load = other + (ctx.mass[pi_] * ctx.dt_step)[:, None] * ctx.accel[pi_]
            load_t = load - np.einsum("ij,ij->i", load, nrm)[:, None] * nrm
            pushed = held & ~at_limit & (np.linalg.norm(load_t, axis=1) >= (1.0 - frac) * limit)
            # a support whose logged rows all carry no load (a box chattering on its partner,
            # loaded every other step) holds no friction at that step: mu x 0 is its limit
            unloaded = ~held
            why["sliding_friction_at_limit"] = int(at_limit.sum())
            why["sliding_pushed"] = int(pushed.sum())
            why["sliding_unloaded"] += int(unloaded.sum())
            out[rows_c] = at_limit | pushed | unloaded
            nload[rows_c] = _distinct_points(inv, c.point[rows], carry[rows], len(uk),
                                             T.WITNESS_BAND_M)[pos]
        elif tr.n_samples > 1:
            # how many things the body touches at the sample: the ground, static boxes, bodies
            cd = self.tol["contact_distance_m"]
            prox = ctx.proximity(cd)
            near = prox.near_pairs(cd)
            keys = np.concatenate([near["k"] * n + near["a"],
                                   (near["k"] * n + near["b"])[near["b"] < n]])
            uk, cnt = np.unique(keys, return_counts=True)
            want = pk * n + pi_
            pos = np.clip(np.searchsorted(uk, want), 0, max(len(uk) - 1, 0))
            n_cont = np.where(uk[pos] == want, cnt[pos], 0) if len(uk) else np.zeros(len(pk), int)
            if prox.ground_sep is not None:
                n_cont = n_cont + (prox.ground_sep[pk, pi_] <= cd)
            lone = n_cont == 1
            kk = np.maximum(pk, 1) - 1  # the interval that ends at the sample (the first: starts)
            jv = ctx.impulse(kk, pi_)
            jn = np.einsum("ij,ij->i", jv, pnorm)
            jt = np.linalg.norm(jv - jn[:, None] * pnorm, axis=1)
            sid = np.where(pb == -1, -1, np.where(pb >= n, pb - n, -2))
            s_mu = _static_friction(model, sid)
            bf = np.asarray(model.body_friction, float)
            dynp = (pb >= 0) & (pb < n)
            mu = combine_friction(bf[pi_], np.where(dynp, bf[np.clip(pb, 0, n - 1)], s_mu),
                                  tr.info.combine_friction)
            sl = lone & (jn > floor) & (jt >= (1.0 - frac) * mu * jn)
            out[rows_c] = sl
            why["sliding_inferred"] = int(sl.sum())
        return out, why, nload

    def analyze(self, ctx: Context) -> Result:
        tr = ctx.traj
        model = tr.model
        n, t_n = tr.n_bodies, tr.n_samples
        if not model.ground and not len(model.static_box_position) and n < 2:
            return self.skip("nothing to rest on: no ground, no static boxes, one body")
        t, step = tr.t, tr.step
        tol = self.tol
        ri = geometry.inner_radius(model)
        rest_tol = np.minimum(tol["depth_m"], tol["depth_frac"] * ri)
        trans_tol = np.minimum(tol["transient_depth_m"], tol["transient_frac"] * ri)
        worst = Worst("m", tol["depth_m"])
        findings: list[Finding] = []
        stats: dict[str, float] = {}
        n_found = 0
        events: list[dict] = []

        sup = self.supports(ctx)
        pk, pi_, pb = sup["k"], sup["i"], sup["b"]
        psep, pnorm, ppt = sup["sep"], sup["normal"], sup["point"]
        depth = np.maximum(-psep, 0.0)
        nrow = len(pk)
        stats["depth_max_m"] = float(depth.max()) if nrow else 0.0

        # per row, the resting depth tolerance: the body's inner radius on its v2 shape, the
        # thinner geom's smallest half-extent on a geom pair's row (rule "geom_pair_support")
        on_geoms = sup["geom"].any()
        row_rest_tol = np.where(sup["geom"], np.minimum(tol["depth_m"],
                                                        tol["depth_frac"] * sup["inner"]),
                                rest_tol[pi_]) if on_geoms else rest_tol[pi_]
        # ---- any-time depth (impacts included): the deepest sample of each body (a geom pair's
        # rows are judged per pair at every sample: geom_depths)
        v2_depth = np.where(sup["geom"], 0.0, depth) if on_geoms else depth
        if nrow:
            worst.offer_array(v2_depth, trans_tol[pi_], "m", step[pk], t[pk], pi_,
                              "penetration depth at any time")
            bstart = np.r_[0, np.nonzero(pi_[1:] != pi_[:-1])[0] + 1]
            bmax = np.maximum.reduceat(v2_depth, bstart)
            bodies = pi_[bstart]
            bad = np.nonzero(bmax > trans_tol[bodies])[0]
            n_found += len(bad)
            for j in bad:
                lo = bstart[j]
                hi = bstart[j + 1] if j + 1 < len(bstart) else nrow
                r = lo + int(np.argmax(v2_depth[lo:hi]))
                bj = int(bodies[j])
                findings.append(Finding(
                    self.name,
                    f"{body_label(model, bj)} sinks {depth[r] * 1e3:.3g} mm into "
                    f"{_partner_label(model, int(pb[r]))} at t = {t[pk[r]]:.6g} s (tol "
                    f"{trans_tol[bj] * 1e3:.3g} mm at any time)",
                    float(depth[r]), float(trans_tol[bj]), "m", int(step[pk[r]]), float(t[pk[r]]),
                    [bj]))

        # ---- contact-point velocity relative to the partner, at the primary support
        cv, slip = np.empty((nrow, 3)), np.empty((nrow, 3))
        cspeed, wspeed = np.empty(nrow), np.empty(nrow)
        c = np.ascontiguousarray
        _audit.contact_velocity(c(pk, dtype=np.int64), c(pi_, dtype=np.int64),
                                c(pb, dtype=np.int64), c(ppt, dtype=np.float64),
                                c(pnorm, dtype=np.float64), c(tr.position, dtype=np.float64),
                                c(tr.velocity, dtype=np.float64),
                                c(tr.angular_velocity, dtype=np.float64), n, cv, slip, cspeed,
                                wspeed)
        # The pair rests where every point of the body (within 2 bounding radii of the contact)
        # is slow relative to the partner: a box rocking on an edge has a resting pivot but is
        # not at rest, nor is a sphere rolling without slip (rule "resting"). A pair in contact
        # that moves is rolling or sliding (rule "rolling_sliding"): reported as events with its
        # slip, never judged as resting.
        reach = 2.0 * geometry.bounding_radius(model)[pi_]
        rest = cspeed + wspeed * reach <= tol["rest_speed_mps"]
        motion = _motion_stretches(self, ctx, sup, rest, cv, slip, wspeed, depth, stats)
        # a contact whose friction is at the Coulomb limit (or whose load reaches it) slides,
        # whatever its speed (a box dragged by a neighbour at a few mm/s): its slip is not creep
        # and its velocity change not jitter. It does not end the resting interval (a box that
        # sticks, is dragged, and sticks again stays on its partner), so sliding samples between
        # creeping ones cannot hide the creep: slip with friction inside the cone is what
        # static friction forbids.
        slides, why, nload = self.sliding(ctx, sup, rest)
        stats.update({k: float(v) for k, v in why.items()})

        # ---- resting intervals: runs of consecutive resting samples of one body (row space)
        nxt_same = np.zeros(nrow, bool)
        if nrow > 1:
            nxt_same[:-1] = (pi_[1:] == pi_[:-1]) & (pk[1:] == pk[:-1] + 1)
        link = rest & np.r_[nxt_same[:-1] & rest[1:], False] if nrow else rest
        prev_link = np.r_[False, link[:-1]] if nrow else link
        starts = np.nonzero(rest & ~prev_link)[0]
        ends = np.nonzero(rest & ~link)[0]
        long_ = (ends - starts + 1) >= tol["rest_min_samples"]
        starts, ends = starts[long_], ends[long_]
        nr = len(starts)
        stats["rest_intervals"] = float(nr)
        if nr:
            idx = np.empty(2 * nr, np.int64)
            idx[0::2] = starts
            idx[1::2] = ends + 1

            def red(ufunc, arr):
                return ufunc.reduceat(np.append(arr, np.zeros((1,) + arr.shape[1:]), axis=0),
                                      idx, axis=0)[0::2]

            bs, ks, ke = pi_[starts], pk[starts], pk[ends]
            r_max = red(np.maximum, depth)
            r_mean = red(np.add, depth) / (ends - starts + 1)
            dur = t[ke] - t[ks]
            # run of each row (only meaningful inside runs)
            marker = np.bincount(starts, minlength=nrow + 1) - np.bincount(ends + 1,
                                                                           minlength=nrow + 1)
            in_run = np.cumsum(marker)[:-1] > 0
            run_of = np.maximum(np.cumsum(np.bincount(starts, minlength=nrow)) - 1, 0)
            settled = in_run & (t[pk] >= t[ks][run_of] + tol["settle_s"])
            speed_settled = red(np.maximum, np.where(settled, cspeed, 0.0))
            # jitter: the alternating part of the contact-point velocity, |v+ - 2 v + v-| / 4,
            # at settled rows whose neighbours are settled rows of the same run on the same
            # partner (velocities relative to different partners are not comparable) ...
            osc = np.zeros(nrow)
            if nrow > 2:
                still = settled & ~slides
                mid = (still[1:-1] & still[:-2] & still[2:] & nxt_same[:-2] & nxt_same[1:-1]
                       & (pb[:-2] == pb[1:-1]) & (pb[2:] == pb[1:-1]))
                d2 = cv[2:] - 2.0 * cv[1:-1] + cv[:-2]
                osc[1:-1] = np.where(mid, 0.25 * np.sqrt(np.einsum("ij,ij->i", d2, d2)), 0.0)
            # ... that persists: the smallest of JITTER_PERSIST_SAMPLES consecutive values. A
            # velocity flipping every sample keeps its full amplitude; a single kick (a box
            # struck by another: a step change of velocity, or a one-sample spike) gives two or
            # three alternating values and then none, so it is an impact, not jitter.
            w = int(tol["jitter_persist_samples"])
            if w > 1 and nrow >= w:
                win = np.lib.stride_tricks.sliding_window_view(osc, w)
                eroded = np.zeros(nrow)
                h = w // 2
                eroded[h:nrow - (w - 1 - h)] = win.min(axis=1)
                osc = eroded
            jit = red(np.maximum, osc)
            has_settled = red(np.maximum, settled.astype(float)) > 0
            slow = in_run & ~slides & (np.sqrt(np.einsum("ij,ij->i", slip, slip))
                                       <= tol["creep_speed_mps"])
            # the contact's slide over each interval between consecutive rows of the same run on
            # the same partner, from the poses; an interval counts in full when both ends are
            # slow and not sliding, half when one is (a trapezoid of the slip); the intervals of
            # the first SETTLE_S only as far as the settling allows (_settling_slide)
            both = np.zeros(nrow, bool)
            both[:-1] = in_run[:-1] & in_run[1:] & nxt_same[:-1] & (pb[1:] == pb[:-1])
            # ... and no impact between the samples: an interval over which the body (or a body
            # partner) changes its velocity, or its angular velocity times its reach, by more than
            # the creep speed beyond what its neighbouring intervals change it (a steady
            # acceleration, a ball rolling down a ramp, changes every interval alike) was struck,
            # and a contact may slide at its cone unseen between the samples: not resting
            if nrow > 1 and t_n > 1:
                jump = _audit.impact_jump(c(tr.velocity, dtype=np.float64),
                                    c(tr.angular_velocity, dtype=np.float64),
                                    c(2.0 * geometry.bounding_radius(model), dtype=np.float64))
                k0 = np.minimum(pk[:-1], t_n - 2)
                bad = np.zeros(nrow - 1, bool)
                for who in (pi_[:-1], pb[:-1]):
                    dyn = (who >= 0) & (who < n)
                    bad |= dyn & (jump[k0, np.where(dyn, who, 0)] > tol["creep_speed_mps"])
                both[:-1] &= ~bad
            contrib = np.zeros((nrow, 3))
            s_pos, s_rot, s_half = geometry.static_boxes(model)
            _audit.contact_slide(c(pk, dtype=np.int64), c(pi_, dtype=np.int64),
                                 c(pb, dtype=np.int64), c(ppt, dtype=np.float64),
                                 c(sup["span"], dtype=np.float64), c(pnorm, dtype=np.float64),
                                 c(tr.position, dtype=np.float64),
                                 c(tr.rotation, dtype=np.float64), n, c(both), contrib,
                                 c(np.asarray(model.body_shape) == SHAPE_BOX),
                                 c(model.body_size, dtype=np.float64),
                                 c(s_pos, dtype=np.float64), c(s_rot, dtype=np.float64),
                                 c(s_half, dtype=np.float64), T.WITNESS_BAND_M,
                                 c(nload, dtype=np.int64))
            weight = np.zeros(nrow)
            weight[:-1] = 0.5 * (slow[:-1].astype(float) + slow[1:])
            # ... and an interval over which the contact slid faster than the creep speed on
            # average (from the poses) held a slide, not creep, though both its samples are slow:
            # the samples cannot tell a kick between them (a resting box struck and stopped by
            # friction within the interval) from a slip, and the speed rule is the samples' own
            if nrow > 1 and t_n > 1:
                span_t = t[np.minimum(pk[:-1] + 1, t_n - 1)] - t[pk[:-1]]
                fast = (np.linalg.norm(contrib[:-1], axis=1)
                        > tol["creep_speed_mps"] * np.where(span_t > 0, span_t, np.inf))
                weight[:-1] = np.where(fast, 0.0, weight[:-1])
                stats["creep_fast_intervals"] = float(fast.sum())
            contrib *= weight[:, None]
            if nrow > 1 and t_n > 1:
                t_run0 = t[ks][run_of]
                t_row = t[pk]
                dt_row = np.zeros(nrow)
                dt_row[:-1] = span_t
                contrib = _settling_slide(
                    contrib, both & (weight > 0) & in_run & ~settled,
                    both & (weight > 0) & settled & (t_row < t_run0 + 2.0 * tol["settle_s"]),
                    run_of, dt_row * weight, nr, _EQUAL_SLIDE_FRAC * tol["creep_m"])
            # a contact two bodies both take as their support (each the other's deepest: boxes
            # side by side in a pile) slides the same for both: it is counted once, for the body
            # it holds up (the one on top along gravity; the lower index when level)
            contrib[_mutual_lower(pk, pi_, pb, pnorm, model, n, t_n)] = 0.0
            creep = np.linalg.norm(red(np.add, contrib), axis=1)
            # the partner the creep was measured against (a stay may change its deepest contact):
            # the one whose intervals slide the most, named when it is not the stay's first
            creep_partner = _main_partner(contrib, run_of, pb, in_run, nr,
                                          partner_default=pb[starts])
            jit = np.where(has_settled, jit, np.nan)
            creep = np.where(has_settled, creep, np.nan)
            speed_settled = np.where(has_settled, speed_settled, np.nan)
            partner = pb[starts]
            stats["rest_depth_max_m"] = float(r_max.max())
            stats["rest_depth_mean_m"] = float(np.average(r_mean, weights=ends - starts + 1))
            stats["rest_duration_total_s"] = float(dur.sum())
            if np.isfinite(jit).any():
                stats["jitter_max_mps"] = float(np.nanmax(jit))
                stats["settled_speed_max_mps"] = float(np.nanmax(speed_settled))
                stats["creep_max_m"] = float(np.nanmax(creep))
            # where in each run the depth is largest
            at_max = np.nonzero(in_run & (depth == r_max[run_of]))[0]
            runs_hit, first_hit = np.unique(run_of[at_max], return_index=True)
            kdeep = ks.copy()
            kdeep[runs_hit] = pk[at_max[first_hit]]
            run_tol = red(np.minimum, row_rest_tol)
            worst.offer_array(r_max, run_tol, "m", step[kdeep], t[kdeep], bs,
                              "resting penetration depth")
            fin = np.isfinite(jit)
            if fin.any():
                worst.offer_array(jit[fin], tol["jitter_mps"], "m/s", step[ke[fin]], t[ke[fin]],
                                  bs[fin], "oscillating contact-point speed while resting (jitter)")
                worst.offer_array(creep[fin], tol["creep_m"], "m", step[ke[fin]], t[ke[fin]],
                                  bs[fin], "slip while resting (creep)")

            def what_rest(r):
                return (f"resting on {_partner_label(model, int(partner[r]))} from t = "
                        f"{t[ks[r]]:.6g} s for {dur[r]:.3g} s")

            checks = (
                (r_max > run_tol, lambda r: Finding(
                    self.name,
                    f"{body_label(model, int(bs[r]))} {what_rest(r)}: sinks "
                    f"{r_max[r] * 1e3:.3g} mm "
                    f"(mean {r_mean[r] * 1e3:.3g} mm; tol {run_tol[r] * 1e3:.3g} mm)",
                    float(r_max[r]), float(run_tol[r]), "m", int(step[kdeep[r]]),
                    float(t[kdeep[r]]), [int(bs[r])])),
                (fin & (np.nan_to_num(jit) > tol["jitter_mps"]), lambda r: Finding(
                    self.name,
                    f"{body_label(model, int(bs[r]))} jitters {what_rest(r)}: its contact point "
                    f"oscillates at up to {jit[r]:.3g} m/s after settling (tol "
                    f"{tol['jitter_mps']:.3g} m/s)",
                    float(jit[r]), tol["jitter_mps"], "m/s", int(step[ke[r]]), float(t[ke[r]]),
                    [int(bs[r])])),
                (fin & (np.nan_to_num(creep) > tol["creep_m"]), lambda r: Finding(
                    self.name,
                    f"{body_label(model, int(bs[r]))} creeps {what_rest(r)}: slides "
                    f"{creep[r] * 1e3:.3g} mm at the contact while settled"
                    + ("" if creep_partner[r] == partner[r] else
                       f", on {_partner_label(model, int(creep_partner[r]))}")
                    + f" (tol {tol['creep_m'] * 1e3:.3g} mm)",
                    float(creep[r]), tol["creep_m"], "m", int(step[ke[r]]), float(t[ke[r]]),
                    [int(bs[r])])),
            )
            for flag, make in checks:
                idx_f = np.nonzero(flag)[0]
                n_found += len(idx_f)
                for r in idx_f[: T.MAX_FINDINGS]:
                    findings.append(make(int(r)))
            # (a fifth of the events kept for rolling and sliding stretches, when there are any)
            for r in range(min(nr, T.MAX_EVENTS - min(len(motion), T.MAX_EVENTS // 5))):
                events.append({
                    "kind": "rest", "body": int(bs[r]), "partner": int(partner[r]),
                    "t_start": float(t[ks[r]]), "t_end": float(t[ke[r]]),
                    "step_start": int(step[ks[r]]), "duration_s": float(dur[r]),
                    "depth_max_m": float(r_max[r]), "depth_mean_m": float(r_mean[r]),
                    "jitter_mps": None if np.isnan(jit[r]) else float(jit[r]),
                    "settled_speed_max_mps": None if np.isnan(speed_settled[r])
                    else float(speed_settled[r]),
                    "creep_m": None if np.isnan(creep[r]) else float(creep[r]),
                })
        # ---- rolling and sliding stretches: events with their slip, after the rests
        events += motion[: max(T.MAX_EVENTS - len(events), 0)]
        # ---- bodies the v2 shapes leave out: depth per geom pair, at every sample
        g_find, g_rows = self.geom_depths(ctx, worst, stats)
        findings += g_find
        n_found += len(g_find)
        ok = "" if nr or nrow or g_rows else "no contacts found"
        res = self.result(worst, findings, stats, events, ok_reason=ok, n_findings=n_found)
        # a body without a v2 shape is judged on its geoms (rule "geom_pair_support"); one
        # without geoms either (a v2 log of another engine's capsule) is not
        has_geoms = np.zeros(n, bool)
        if getattr(model, "n_geoms", 0):
            gb = np.asarray(model.geom_body, np.int64)
            has_geoms[gb[gb >= 0]] = True
        off = shapes.contacts_disabled(tr.info)
        if off:
            has_geoms[:] = False
        return res.leave_out(shapeless_note(
            model, "depth, jitter and creep of their contacts"
            + (" (the engine's contacts are switched off: disableflags)" if off else ""),
            known=has_geoms))

    def geom_depths(self, ctx: Context, worst: Worst, stats: dict):
        """Penetration depth per geom pair at every sample for the bodies without a v2 shape
        (rblog.analyze.shapes: every shape of the contract, the log's collision filter,
        rblog.analyze.shapes.collide_mask). A pair deeper than min(transient_depth_m,
        transient_frac x the thinner geom's smallest half-extent) at some sample is a finding
        at its deepest sample. Returns (findings, number of pair-samples in contact, or None when
        no body needs it)."""
        tr = ctx.traj
        model = tr.model
        gp = self.geom_pairs(ctx)
        if gp is None:
            return [], None
        geoms, k, i, j, d = gp["geoms"], gp["k"], gp["i"], gp["j"], gp
        body = geoms.body
        depth = np.maximum(-d["sep"], 0.0)
        touching = depth > 0
        stats["geom_pairs_touching"] = float(len(np.unique(i[touching] * len(body) + j[touching])))
        stats["geom_depth_max_m"] = float(depth.max()) if len(depth) else 0.0
        if not len(depth):
            return [], 0
        inner = gp["inner"]
        tol_ = np.minimum(self.tol["transient_depth_m"],
                          self.tol["transient_frac"] * np.minimum(inner[i], inner[j]))
        bodies = np.stack([body[i], body[j]], 1)
        worst.offer_array(depth, tol_, "m", tr.step[k], tr.t[k], bodies,
                          "penetration depth of a geom pair")
        names = model.geom_name if model.geom_name is not None else [""] * len(body)
        findings = []
        over = np.nonzero(depth > tol_)[0]
        pair = i[over] * len(body) + j[over]
        for p_ in np.unique(pair):
            rows = over[pair == p_]
            r = rows[np.argmax(depth[rows])]
            ga, gb = int(i[r]), int(j[r])
            if body[ga] < 0:  # the moving geom first
                ga, gb = gb, ga
            label = lambda g: (f"geom {g} ({names[g]!r}) of "
                               f"{body_label(model, int(body[g])) if body[g] >= 0 else 'the world'}")
            findings.append(Finding(
                self.name,
                f"{label(ga)} is {depth[r] * 1e3:.3g} mm into {label(gb)} at t = "
                f"{tr.t[k[r]]:.6g} s (tol {tol_[r] * 1e3:.3g} mm; {len(rows)} samples past it)",
                float(depth[r]), float(tol_[r]), "m", int(tr.step[k[r]]), float(tr.t[k[r]]),
                [int(b) for b in (body[ga], body[gb]) if b >= 0]))
        return findings, int(touching.sum())
