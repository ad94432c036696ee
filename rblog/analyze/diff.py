"""``rblog diff A B``: how far apart are two logs of the same scene?

Two runs of one scene (another engine, integrator, dt or rblog version) are compared over their
common sample times (times equal to the nanosecond):

* per body: the distance between the centres of mass ``|x_A - x_B|`` (m) and the angle between the
  orientations ``2 acos |q_A . q_B|`` (rad), their maxima and final values, the first time either
  leaves its tolerance, and the growth rates: the least-squares slopes of ``ln |x_A - x_B|`` and of
  ``ln angle`` over time (1/s, e-folding rates; samples below DIFF_FLOOR_M / DIFF_FLOOR_RAD are
  round-off and left out);
* totals side by side: energy, linear and angular momentum of each log at the first and last
  common time, and their largest difference.

The logs must describe the same bodies (names, shapes, sizes, masses, inertia); otherwise
:class:`IncompatibleLogs` (exit 2) names the bodies that differ. Uses only logged channels.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from rblog.analyze import tolerances as T
from rblog.contract.trajectory import Trajectory
from rblog.errors import RblogError, IncompatibleLogs

#: relative difference of sizes, masses and inertias still counted as the same body table
SAME_BODY_REL = 1e-9


@dataclass
class BodyDiff:
    name: str
    position_max_m: float
    position_final_m: float
    angle_max_rad: float
    angle_final_rad: float
    #: first common time (s) where the position or the angle leaves its tolerance, or None
    first_exceed_t: float | None
    #: slope of ln |x_A - x_B| over time (1/s), or None when there are too few samples
    growth_rate_per_s: float | None
    #: slope of ln(angle) over time (1/s), or None
    angle_growth_rate_per_s: float | None = None


@dataclass
class DiffReport:
    a: str
    b: str
    writer_a: str
    writer_b: str
    integrator_a: str
    integrator_b: str
    dt_a: float
    dt_b: float
    t: np.ndarray
    position: np.ndarray  # (T, N) m
    angle: np.ndarray  # (T, N) rad
    bodies: list[BodyDiff]
    totals: dict = field(default_factory=dict)
    position_tol_m: float = T.DIFF_POSITION_M
    angle_tol_rad: float = T.DIFF_ANGLE_RAD

    @property
    def within(self) -> bool:
        return all(b.first_exceed_t is None for b in self.bodies)

    @property
    def n_exceed(self) -> int:
        return sum(b.first_exceed_t is not None for b in self.bodies)

    def to_dict(self) -> dict:
        d = {k: v for k, v in asdict(self).items() if k not in ("t", "position", "angle")}
        d["within"] = self.within
        d["common_samples"] = int(len(self.t))
        d["t_range"] = [float(self.t[0]), float(self.t[-1])] if len(self.t) else []
        d["position_max_m"] = float(self.position.max()) if self.position.size else 0.0
        d["angle_max_rad"] = float(self.angle.max()) if self.angle.size else 0.0
        return _finite(d)


def _finite(v):
    if isinstance(v, dict):
        return {k: _finite(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_finite(x) for x in v]
    if isinstance(v, (float, np.floating)):
        return float(v) if math.isfinite(v) else None
    if isinstance(v, np.integer):
        return int(v)
    return v


def compatible(a: Trajectory, b: Trajectory) -> list[str]:
    """Why the two body tables differ (empty when they describe the same bodies)."""
    ma, mb = a.model, b.model
    if ma.n_bodies != mb.n_bodies:
        return [f"{ma.n_bodies} bodies vs {mb.n_bodies}"]
    out = []
    for i in range(ma.n_bodies):
        what = []
        if ma.body_name[i] != mb.body_name[i]:
            what.append(f"name {ma.body_name[i]!r} vs {mb.body_name[i]!r}")
        if int(ma.body_shape[i]) != int(mb.body_shape[i]):
            what.append("shape")
        for name in ("body_size", "body_mass", "body_inertia_diag"):
            x, y = np.asarray(getattr(ma, name)[i], float), np.asarray(getattr(mb, name)[i], float)
            if np.any(np.abs(x - y) > SAME_BODY_REL * np.maximum(np.abs(x), np.abs(y))):
                what.append(name.removeprefix("body_"))
        if what:
            out.append(f"body {i} ({ma.body_name[i]!r}): {', '.join(what)}")
    return out


def diff(a: Trajectory, b: Trajectory, *, position_tol_m: float = T.DIFF_POSITION_M,
         angle_tol_rad: float = T.DIFF_ANGLE_RAD, label_a: str = "A", label_b: str = "B") -> DiffReport:
    """Compare two logs of one scene (see the module docstring)."""
    why = compatible(a, b)
    if why:
        more = f" (+{len(why) - 5} more)" if len(why) > 5 else ""
        raise IncompatibleLogs(f"{label_a} and {label_b} describe different bodies: "
                               + "; ".join(why[:5]) + more)
    ta = np.rint(np.asarray(a.t, float) * 1e9).astype(np.int64)
    tb = np.rint(np.asarray(b.t, float) * 1e9).astype(np.int64)
    common, ia, ib = np.intersect1d(ta, tb, assume_unique=False, return_indices=True)
    if len(common) == 0:
        raise IncompatibleLogs(f"{label_a} and {label_b} share no sample time (A: "
                               f"{a.t[0] if a.n_samples else 0:g}..{a.t[-1] if a.n_samples else 0:g} s "
                               f"every {a.info.log_every * a.info.dt:g} s; B: every "
                               f"{b.info.log_every * b.info.dt:g} s)")
    t = a.t[ia]
    pos = np.linalg.norm(a.position[ia] - b.position[ib], axis=-1)
    qa = a.quat_wxyz[ia] / np.linalg.norm(a.quat_wxyz[ia], axis=-1, keepdims=True)
    qb = b.quat_wxyz[ib] / np.linalg.norm(b.quat_wxyz[ib], axis=-1, keepdims=True)
    dot = np.clip(np.abs(np.einsum("tni,tni->tn", qa, qb)), 0.0, 1.0)
    ang = 2.0 * np.arccos(dot)
    bodies = []
    for i, name in enumerate(a.model.body_name):
        out = (pos[:, i] > position_tol_m) | (ang[:, i] > angle_tol_rad)
        first = float(t[int(np.argmax(out))]) if out.any() else None
        rate, arate = _log_slope(t, pos[:, i], T.DIFF_FLOOR_M), _log_slope(t, ang[:, i], T.DIFF_FLOOR_RAD)
        bodies.append(BodyDiff(str(name), float(pos[:, i].max()), float(pos[-1, i]),
                               float(ang[:, i].max()), float(ang[-1, i]), first, rate, arate))
    totals = {}
    for name in ("total_energy", "total_linear_momentum", "total_angular_momentum"):
        va, vb = np.asarray(getattr(a, name))[ia], np.asarray(getattr(b, name))[ib]
        va2, vb2 = va.reshape(len(t), -1), vb.reshape(len(t), -1)
        totals[name] = {
            "a_first": va2[0].tolist(), "a_last": va2[-1].tolist(),
            "b_first": vb2[0].tolist(), "b_last": vb2[-1].tolist(),
            "max_abs_difference": float(np.linalg.norm(va2 - vb2, axis=-1).max()),
        }
    return DiffReport(label_a, label_b, a.info.writer, b.info.writer, a.info.integrator,
                      b.info.integrator, float(a.info.dt), float(b.info.dt), t, pos, ang, bodies,
                      totals, position_tol_m, angle_tol_rad)


def _log_slope(t, d, floor):
    """Least-squares slope of ln d over t where d > floor (1/s), None with < 3 such samples."""
    use = d > floor
    if use.sum() < 3 or np.ptp(t[use]) <= 0:
        return None
    return float(np.polyfit(t[use], np.log(d[use]), 1)[0])


def format_table(r: DiffReport, max_rows: int = 20) -> str:
    """A text table: header, the bodies that diverge most, totals side by side."""
    lines = [f"A: {r.a} ({r.writer_a}, {r.integrator_a}, dt {r.dt_a:g} s)",
             f"B: {r.b} ({r.writer_b}, {r.integrator_b}, dt {r.dt_b:g} s)",
             f"{len(r.t)} common samples, t = {r.t[0]:g}..{r.t[-1]:g} s; tolerance "
             f"{r.position_tol_m:g} m, {r.angle_tol_rad:g} rad: "
             + ("within" if r.within else f"{r.n_exceed} of {len(r.bodies)} bodies leave it"),
             "",
             f"{'body':<16} {'max |dx| m':>11} {'final m':>10} {'max angle':>10} {'final rad':>10} "
             f"{'leaves at s':>11} {'growth 1/s':>10}"]
    order = sorted(range(len(r.bodies)), key=lambda i: -r.bodies[i].position_max_m)
    for i in order[:max_rows]:
        b = r.bodies[i]
        lines.append(f"{b.name[:16]:<16} {b.position_max_m:>11.3g} {b.position_final_m:>10.3g} "
                     f"{b.angle_max_rad:>10.3g} {b.angle_final_rad:>10.3g} "
                     f"{'-' if b.first_exceed_t is None else f'{b.first_exceed_t:.4g}':>11} "
                     f"{'-' if b.growth_rate_per_s is None else f'{b.growth_rate_per_s:.3g}':>10}")
    if len(order) > max_rows:
        lines.append(f"... {len(order) - max_rows} more bodies (--json lists all)")
    lines.append("")
    lines.append(f"{'total':<24} {'A first':>12} {'A last':>12} {'B first':>12} {'B last':>12} {'max |A-B|':>10}")
    for name, v in r.totals.items():
        fmt = lambda x: f"{np.linalg.norm(x):.6g}" if len(x) > 1 else f"{x[0]:.6g}"  # noqa: E731
        label = name.removeprefix("total_") + (" |.|" if len(v["a_first"]) > 1 else "")
        lines.append(f"{label:<24} {fmt(v['a_first']):>12} {fmt(v['a_last']):>12} "
                     f"{fmt(v['b_first']):>12} {fmt(v['b_last']):>12} {v['max_abs_difference']:>10.3g}")
    return "\n".join(lines)


def plot(r: DiffReport, path: str) -> None:
    """PNG: per-body position divergence (log scale) and orientation angle over time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    n = r.position.shape[1]
    floor = T.DIFF_FLOOR_M
    for ax, data, tol, unit in ((axes[0], r.position, r.position_tol_m, "m"),
                                (axes[1], r.angle, r.angle_tol_rad, "rad")):
        if n <= 10:
            for i in range(n):
                ax.semilogy(r.t, np.maximum(data[:, i], floor), lw=1, label=r.bodies[i].name)
            ax.legend(fontsize=7)
        else:
            ax.semilogy(r.t, np.maximum(data.max(axis=1), floor), lw=1.2, label="max over bodies")
            ax.semilogy(r.t, np.maximum(np.median(data, axis=1), floor), lw=1.2, label="median")
            ax.legend(fontsize=7)
        ax.axhline(tol, color="k", ls="--", lw=0.8)
        ax.set_xlabel("t (s)")
        ax.set_ylabel(f"|A - B| ({unit})")
    axes[0].set_title("position divergence")
    axes[1].set_title("orientation divergence")
    fig.suptitle(f"{r.a} vs {r.b}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


__all__ = ["BodyDiff", "DiffReport", "IncompatibleLogs", "compatible", "diff", "format_table", "plot"]
