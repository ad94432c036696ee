"""What a log holds for the audit to judge: its bodies by kind, joints, geoms by shape, which
per-interval impulses it carries and which it lacks, and its contact rows. ``rblog check``
prints it as one line per log, so that a verdict is read against what was there to judge."""

from __future__ import annotations

from collections import Counter

import numpy as np

from rblog.contract.model import (BODY_FREE, BODY_JOINTED, BODY_KIND_NAMES, GEOM_NAMES, IMPULSE_KINDS, JOINT_NAMES,
                                  SUPPLIED_LOGGED, SUPPLIED_MISSING, SUPPLIED_NONE)
from rblog.contract.trajectory import Trajectory


def log_contents(traj: Trajectory) -> dict:
    """JSON-able counts: ``bodies`` {kind: n}, ``joints`` {type: n}, ``geoms`` {shape: n} (on
    bodies), ``world_geoms`` {shape: n}, ``impulses`` {kind: {"logged": n, "none": n,
    "missing": n}} over bodies (missing: on bodies the dynamics move), ``impulse_gaps``
    {kind: {"intervals": n, "bodies": n}} for logged
    kinds left NaN in some intervals, ``contact_rows`` (int)."""
    m = traj.model
    n = m.n_bodies
    kinds = Counter(BODY_KIND_NAMES.get(int(k), str(k)) for k in np.asarray(m.body_kind).reshape(n))
    joints = Counter(JOINT_NAMES.get(int(j), str(j)) for j in np.asarray(m.joint_type))
    gb = np.asarray(m.geom_body)
    gt = np.asarray(m.geom_type)
    geoms = Counter(GEOM_NAMES.get(int(t), str(t)) for t in gt[gb >= 0])
    world = Counter(GEOM_NAMES.get(int(t), str(t)) for t in gt[gb < 0])
    sup = np.asarray(m.body_impulse_supplied).reshape(n, len(IMPULSE_KINDS))
    # a load of unknown size matters only on a body the dynamics move (not static, not kinematic)
    moving = np.isin(np.asarray(m.body_kind).reshape(n), (BODY_FREE, BODY_JOINTED))
    imp = {k: {"logged": int((sup[:, j] == SUPPLIED_LOGGED).sum()),
               "none": int((sup[:, j] == SUPPLIED_NONE).sum()),
               "missing": int(((sup[:, j] == SUPPLIED_MISSING) & moving).sum())}
           for j, k in enumerate(IMPULSE_KINDS)}
    # logged kinds the writer left NaN in some intervals (it did not know them there:
    # pybullet's joint limits): {kind: {"intervals": body-intervals, "bodies": n}}
    gaps = {}
    for j, k in enumerate(IMPULSE_KINDS):
        logged = sup[:, j] == SUPPLIED_LOGGED
        lin = getattr(traj, f"impulse_{k}_linear", None)
        if not logged.any() or lin is None or traj.n_samples < 2:
            continue
        ang = getattr(traj, f"impulse_{k}_angular")
        nan = (np.isnan(lin[1:]).any(axis=2) | np.isnan(ang[1:]).any(axis=2)) & logged[None]
        if nan.any():
            gaps[k] = {"intervals": int(nan.sum()), "bodies": int(nan.any(axis=0).sum())}
    return {"bodies": dict(kinds), "joints": dict(joints), "geoms": dict(geoms),
            "world_geoms": dict(world), "impulses": imp, "impulse_gaps": gaps,
            "contact_rows": len(traj.contacts)}


def _counts(c: dict) -> str:
    return ", ".join(f"{k} {v}" for k, v in sorted(c.items()))


def contents_line(c: dict) -> str:
    """``log_contents`` as one line: what there was to judge, and which loads the log lacks."""
    nb = sum(c["bodies"].values())
    parts = [f"{nb} bod{'y' if nb == 1 else 'ies'} ({_counts(c['bodies'])})"]
    nj = sum(c["joints"].values())
    if nj:
        parts.append(f"{nj} joint{'s' if nj != 1 else ''} ({_counts(c['joints'])})")
    ng = sum(c["geoms"].values())
    geo = f"{ng} geom{'s' if ng != 1 else ''}" + (f" ({_counts(c['geoms'])})" if ng else "")
    if c["world_geoms"]:
        geo += f" + static {_counts(c['world_geoms'])}"
    parts.append(geo)
    logged = [k for k, v in c["impulses"].items() if v["logged"]]
    missing = [f"{k} ({v['missing']} bod{'y' if v['missing'] == 1 else 'ies'})"
               for k, v in c["impulses"].items() if v["missing"] and k != "contact"]
    parts.append("impulses logged: " + (", ".join(logged) if logged else "none"))
    if missing:
        parts.append("loads of unknown size: " + ", ".join(missing))
    gaps = [f"{k} ({v['intervals']} interval{'s' if v['intervals'] != 1 else ''} of "
            f"{v['bodies']} bod{'y' if v['bodies'] == 1 else 'ies'})"
            for k, v in c.get("impulse_gaps", {}).items()]
    if gaps:
        parts.append("loads unknown in some intervals (NaN): " + ", ".join(gaps))
    parts.append(f"{c['contact_rows']} contact row{'s' if c['contact_rows'] != 1 else ''}")
    return "; ".join(parts)
