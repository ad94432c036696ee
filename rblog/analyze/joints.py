"""Joints: do the logged poses keep every joint together?

For each joint of the log (``joint_*``, contract v3), from the logged poses of its child body c
and parent body p (the world for parent -1) at every sample:

* anchor separation (m): the anchor carried to the world by the child's pose,
  ``a_c = x_c + R_c anchor_body``, against the same point carried by the parent's,
  ``a_p = x_p + R_p anchor_parent``. What of ``e = a_c - a_p`` a joint forbids: all of it for
  hinge, ball and fixed joints; its part normal to the axis for a slide (which moves along it);
  its part along the axis for a planar joint (which moves in the plane normal to it). The axis is
  the parent's, ``u_p = R_p axis_parent``.
* axis misalignment (rad): the angle between ``u_c = R_c axis_body`` and ``u_p`` (hinge,
  slide, planar); for joints that allow no rotation (fixed, slide) the angle of the relative
  rotation ``R_p^T R_c`` against its value at the first sample (the contract carries no
  reference orientation, so the first logged sample is the reference). Ball joints: anchors only.

Tolerance, per joint and sample, from what a correct recording cannot avoid:

* round-off: JOINTS_ROUNDOFF_ULPS units of the log's float precision (eps of the position
  channel's dtype) times the size of the numbers that enter the transform
  (``|x_c| + |x_p| + |anchor_body| + |anchor_parent|`` for the anchors; 1 for angles);
* the step: an engine in maximal coordinates holds a joint at the velocity level, and a step of
  length dt (RunInfo.dt) then carries the anchor along the chord of its arc about the joint: it
  leaves ``r theta^2 / 2`` with ``theta = |w_c - w_p| dt`` (logged angular velocities), r the
  anchor's distance from the child's centre; the axes likewise ``theta^2 / 2`` rad. Less than
  that cannot be asked of one step; more is drift the engine let through.

A body with several joint rows (MuJoCo's humanoid hip: three hinges; a planar slide-slide-hinge
body; contract v3 lists them in the order the engine applies them, parent side first) is one
compound joint: each row's axis and anchor are fixed in the frame *between* its neighbours'
motions, which the log does not carry, so a row's own check would flag the others' motion. The
compound is judged for what all its rows together forbid, where that is known from the rows
alone (rule table ``_compound_rule``):

* rows that only turn (hinge, ball) about one anchor point keep that point together (its
  separation judged once, on the first row); their axes are not judged;
* slides first, then turns about one anchor point (none, or hinges and balls: dm_control's
  planar stacker boxes, slide x, slide z, hinge y): no rotation comes before the slides, so their
  axes stay fixed in the parent's frame (``u_p``), and the turns' anchor moves by the slides
  only: its separation ``e`` is judged for its part outside the span of the slides' ``u_p``
  (on the first turn row; on the first slide row, a body point, when there are no turns). A lone
  hinge after the slides keeps its axis aligned (its own angle check); slides alone allow no
  rotation (the first row's relative rotation against the first sample);

any other compound (a slide after a turn, or turns about different points) is not judged, and
the result says which bodies.

A joint past tolerance is reported with its onset (first sample past tolerance), its worst
value and its growth after the onset (the better of a line and an exponential, as the drift
analyzer describes it). A log whose bodies move on joints but that has no joint table is "not
judged"; a log of free, kinematic and static bodies only has nothing to check (skip).
"""

from __future__ import annotations

import numpy as np

from rblog.analyze import tolerances as T
from rblog.analyze.base import Analyzer, Context, Finding, Result, Worst, body_label
from rblog.analyze.drift import _fit, _growth, _residuals
from rblog.contract.model import (BODY_JOINTED, JOINT_BALL, JOINT_FIXED, JOINT_HINGE, JOINT_NAMES,
                                  JOINT_PLANAR, JOINT_SLIDE)

_AXIAL = (JOINT_HINGE, JOINT_SLIDE, JOINT_PLANAR)
_RIGID = (JOINT_FIXED, JOINT_SLIDE)
#: what the angle metric measures, per joint type (else the axis misalignment)
_ANGLE_LABEL = {JOINT_FIXED: "relative rotation",
                JOINT_SLIDE: "rotation (axis misalignment or relative turn)"}


def joint_label(model, j: int) -> str:
    name = model.joint_name[j] if model.joint_name is not None and j < len(model.joint_name) \
        else ""
    kind = JOINT_NAMES.get(int(model.joint_type[j]), "?")
    return f"joint {j} ({name!r}, {kind} of {body_label(model, int(model.joint_body[j]))})"


def _poses(tr, body: np.ndarray):
    """(T, J, 3) positions, (T, J, 3, 3) rotations, (T, J, 3) angular velocities of bodies
    ``body`` (J,); -1 is the world (origin, identity, at rest)."""
    t_n = tr.n_samples
    j_n = len(body)
    x = np.zeros((t_n, j_n, 3))
    r = np.broadcast_to(np.eye(3), (t_n, j_n, 3, 3)).copy()
    w = np.zeros((t_n, j_n, 3))
    m = body >= 0
    x[:, m] = tr.position[:, body[m]]
    r[:, m] = tr.rotation[:, body[m]]
    w[:, m] = tr.angular_velocity[:, body[m]]
    return x, r, w


#: rows of one body within this of each other (m, relative to 1 + |anchor|) name one point
_SAME_ANCHOR_REL = 1e-9


def _compound_rule(model) -> tuple[np.ndarray, np.ndarray, list[str], list[tuple[int, np.ndarray]]]:
    """Which rows keep their own checks, for bodies with several joint rows (module docstring).

    Returns (gap_judged (J,) bool, angle_judged (J,) bool, notes, planar): one note per
    compound body left out, naming it and why; ``planar`` the compounds of slides then turns:
    (the row whose anchor separation is judged outside the slides' span, the slide rows)."""
    jt = np.asarray(model.joint_type, np.int64)
    child = np.asarray(model.joint_body, np.int64)
    ab = np.asarray(model.joint_anchor_body, float).reshape(-1, 3)
    ap = np.asarray(model.joint_anchor_parent, float).reshape(-1, 3)
    gap_ok = np.ones(len(jt), bool)
    angle_ok = np.ones(len(jt), bool)
    left_out = []
    planar: list[tuple[int, np.ndarray]] = []

    def one_point(rows) -> bool:  # the rows' anchors one point, in both bodies
        return all(np.linalg.norm(a[rows] - a[rows[0]], axis=-1).max()
                   <= _SAME_ANCHOR_REL * (1.0 + np.linalg.norm(a[rows[0]])) for a in (ab, ap))

    for b in np.unique(child):
        rows = np.flatnonzero(child == b)
        if len(rows) < 2:
            continue
        angle_ok[rows] = False
        gap_ok[rows] = False
        turn = np.isin(jt[rows], (JOINT_HINGE, JOINT_BALL))
        n_slide = int(np.argmax(turn)) if turn.any() else len(rows)  # the leading slides
        slides, turns = rows[:n_slide], rows[n_slide:]
        if not ((jt[slides] == JOINT_SLIDE).all() and turn[n_slide:].all()
                and (len(turns) < 2 or one_point(turns))):
            left_out.append(body_label(model, int(b)))
            continue
        first = int(turns[0]) if len(turns) else int(slides[0])
        gap_ok[first] = True
        if len(turns) == 1 and jt[turns[0]] == JOINT_HINGE:
            angle_ok[turns[0]] = True  # its axis, fixed in both frames
        elif not len(turns):
            angle_ok[first] = True  # no rotation at all
        if len(slides):
            planar.append((first, slides))
    notes = []
    if left_out:
        more = f" +{len(left_out) - 3} more" if len(left_out) > 3 else ""
        notes.append(f"{len(left_out)} bodies on compound joints other than slides then turns "
                     f"about one point ({', '.join(left_out[:3])}{more}): not judged (their "
                     "rows' intermediate frames are not in the log)")
    return gap_ok, angle_ok, notes, planar


def joint_errors(tr) -> dict[str, np.ndarray]:
    """Per sample and joint (T, J): ``gap`` (m) and ``gap_tol``, ``angle`` (rad) and
    ``angle_tol`` (module docstring; angle 0 and its tolerance inf for ball joints and for the
    rows of a compound joint that are not judged), and ``notes``: the compound joints left out."""
    model = tr.model
    jt = np.asarray(model.joint_type, np.int64)
    child = np.asarray(model.joint_body, np.int64)
    parent = np.asarray(model.body_parent, np.int64)[child]
    ab = np.asarray(model.joint_anchor_body, float).reshape(-1, 3)
    ap = np.asarray(model.joint_anchor_parent, float).reshape(-1, 3)
    ub = np.asarray(model.joint_axis_body, float).reshape(-1, 3)
    up = np.asarray(model.joint_axis_parent, float).reshape(-1, 3)
    xc, rc, wc = _poses(tr, child)
    xp, rp, wp = _poses(tr, parent)
    a_c = xc + np.einsum("tjab,jb->tja", rc, ab)
    a_p = xp + np.einsum("tjab,jb->tja", rp, ap)
    e = a_c - a_p
    u_p = np.einsum("tjab,jb->tja", rp, up)
    u_c = np.einsum("tjab,jb->tja", rc, ub)
    along = (e * u_p).sum(-1)
    gap = np.linalg.norm(e, axis=-1)
    slide = jt == JOINT_SLIDE
    planar = jt == JOINT_PLANAR
    normal_part = np.linalg.norm(e - along[..., None] * u_p, axis=-1)
    gap = np.where(slide[None], normal_part, np.where(planar[None], np.abs(along), gap))

    # axis misalignment, and the relative rotation of joints that allow none
    angle = np.zeros_like(gap)
    axial = np.isin(jt, _AXIAL)
    cr = np.linalg.norm(np.cross(u_c, u_p), axis=-1)
    axis_angle = np.arctan2(cr, (u_c * u_p).sum(-1))
    angle = np.where(axial[None], axis_angle, angle)
    rigid = np.isin(jt, _RIGID)
    if rigid.any() and len(gap):
        rel = np.einsum("tjba,tjbc->tjac", rp, rc)  # R_p^T R_c
        d = np.einsum("jba,tjbc->tjac", rel[0], rel)  # rel(0)^T rel(t)
        vx = d[..., 2, 1] - d[..., 1, 2]
        vy = d[..., 0, 2] - d[..., 2, 0]
        vz = d[..., 1, 0] - d[..., 0, 1]
        sn = 0.5 * np.sqrt(vx * vx + vy * vy + vz * vz)
        rel_angle = np.arctan2(sn, 0.5 * (np.trace(d, axis1=-2, axis2=-1) - 1.0))
        angle = np.where(rigid[None], np.maximum(angle, rel_angle), angle)

    eps = np.finfo(np.asarray(tr.position).dtype).eps
    ulps = T.JOINTS_ROUNDOFF_ULPS
    size = (np.linalg.norm(xc, axis=-1) + np.linalg.norm(xp, axis=-1)
            + np.linalg.norm(ab, axis=-1)[None] + np.linalg.norm(ap, axis=-1)[None])
    dt = float(tr.info.dt) if tr.info.dt and np.isfinite(tr.info.dt) else 0.0
    theta = np.linalg.norm(wc - wp, axis=-1) * dt
    r_anchor = np.linalg.norm(ab, axis=-1)[None]
    gap_tol = ulps * eps * size + 0.5 * r_anchor * theta ** 2
    angle_tol = np.where((axial | rigid)[None], ulps * eps + 0.5 * theta ** 2, np.inf)
    gap_ok, angle_ok, notes, planar = _compound_rule(model)
    for row, slides in planar:
        # e of `row` less its part in the span of the slides' parent-frame axes (an orthonormal
        # basis per sample: QR of the (T, 3, k) axes)
        basis = np.linalg.qr(np.swapaxes(u_p[:, slides], -1, -2))[0]  # (T, 3, k)
        er = e[:, row]
        inside = np.einsum("tak,tk->ta", basis, np.einsum("tak,ta->tk", basis, er))
        gap[:, row] = np.linalg.norm(er - inside, axis=-1)
    gap_tol = np.where(gap_ok[None], gap_tol, np.inf)
    angle_tol = np.where(angle_ok[None], angle_tol, np.inf)
    return dict(gap=gap, gap_tol=gap_tol, angle=angle, angle_tol=angle_tol, notes=notes)


class JointsAnalyzer(Analyzer):
    name = "joints"
    description = ("joint anchors kept together and axes aligned by the logged poses; onset and "
                   "growth of any drift")
    #: the tolerances are derived per joint and sample (module docstring); these scale them
    defaults = {"tol_scale": 1.0}

    def analyze(self, ctx: Context) -> Result:
        tr = ctx.traj
        model = tr.model
        if model.n_joints == 0:
            jointed = np.flatnonzero(np.asarray(model.body_kind) == BODY_JOINTED)
            if len(jointed):
                names = ", ".join(repr(model.body_name[i]) for i in jointed[:3])
                more = f" +{len(jointed) - 3} more" if len(jointed) > 3 else ""
                return self.not_judged(
                    f"{len(jointed)} bodies move on joints ({names}{more}) but the log has no "
                    "joint table (joint_* of contract v3)")
            return self.skip("no joints: every body is free, kinematic or static")
        err = joint_errors(tr)
        s = self.tol["tol_scale"]
        t = tr.t
        findings: list[Finding] = []
        finite = err["gap_tol"][np.isfinite(err["gap_tol"])]
        if not finite.size and not np.isfinite(err["angle_tol"]).any():
            return self.not_judged("; ".join(err["notes"]))
        worst = Worst("m", float(s * finite.max()) if finite.size else np.inf)
        stats: dict[str, float] = {"joints": float(model.n_joints)}
        bodies = np.asarray(model.joint_body, np.int64)
        for key, tkey, unit, what in (("gap", "gap_tol", "m", "anchor separation"),
                                      ("angle", "angle_tol", "rad", "axis misalignment")):
            v, tol = err[key], s * err[tkey]
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(tol > 0, v / tol, np.where(v > 0, np.inf, 0.0))
            ratio = np.where(np.isfinite(tol), ratio, 0.0)
            stats[f"{key}_max"] = float(v.max()) if v.size else 0.0
            kmax = ratio.argmax(axis=0)
            jj = np.arange(v.shape[1])
            worst.offer_array(v[kmax, jj], tol[kmax, jj], unit, tr.step[kmax], t[kmax], bodies,
                              what)
            over = ratio > 1.0
            for j in np.nonzero(over.any(axis=0))[0]:
                k0 = int(over[:, j].argmax())
                kw = int(np.argmax(v[:, j]))
                w_ = (np.arange(len(t)) >= k0).astype(float)[:, None]
                y = v[:, j:j + 1]
                slope = _fit(t, y, w_)
                with np.errstate(divide="ignore", invalid="ignore"):
                    ly = np.log(np.where(y > 0, y, np.nan))
                lw = w_ * np.isfinite(ly) * np.nan_to_num(y / np.nanmax(y[k0:])) ** 2
                rate = _fit(t, np.nan_to_num(ly), lw)
                expo = (_residuals(t, np.nan_to_num(ly), lw, rate, y_exp=y, w_res=w_)
                        < _residuals(t, y, w_, slope)) & (rate > 0)
                growth = _growth(float(slope[0]), float(rate[0]), bool(expo[0])) \
                    if k0 < len(t) - 1 else "at the last sample"
                label = what if key == "gap" else _ANGLE_LABEL.get(int(model.joint_type[j]), what)
                findings.append(Finding(
                    self.name,
                    f"{joint_label(model, int(j))} comes apart: {label} reaches {v[kw, j]:.3g} "
                    f"{unit} (tol {tol[kw, j]:.3g} {unit}) at t = {t[kw]:.6g} s; past tolerance "
                    f"from t = {t[k0]:.6g} s, {growth}",
                    float(v[kw, j]), float(tol[kw, j]), unit, int(tr.step[kw]), float(t[kw]),
                    [int(bodies[j])]))
        stats["joints_flagged"] = float(len({f.bodies[0] for f in findings}))
        return self.result(worst, findings, stats).leave_out(err["notes"])
