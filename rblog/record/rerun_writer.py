"""Write a run to a Rerun recording (.rrd file, live viewer, or both). See docs/log-format.md.

Everything goes through a dedicated ``rr.RecordingStream`` (never the global one), one
``send_columns`` call per entity per block: the float64 canonical channels under ``rblog/...`` and
the float32 view entities under ``world/...`` and ``plots/...``. Arrow arrays are built straight
from the block's numpy buffers (no per-sample Python).

Why this module is long: it is the one place that knows Rerun's side of the contract: the
streams and sinks (file, live viewer, spawned viewer) and their failure modes, the column
encoding of every entity, and the default viewer layout (the blueprint, which
rblog.record.findings reuses with a findings table added).
"""

from __future__ import annotations

import math
import time
import uuid

import numpy as np
import pyarrow as pa
import rerun as rr
import rerun.blueprint as rrb

from rblog.errors import LogWriteError
from rblog.contract.model import (GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER, GEOM_ELLIPSOID,
                                  GEOM_MESH, GEOM_PLANE, GEOM_SPHERE, Model)
from rblog.contract.orientation import quat_mul
from rblog.contract.trajectory import Contacts, RunInfo, Trajectory
from rblog.record import _common as C

#: the file sink is flushed (blocking) at most this often (wall s); the SDK also flushes on its
#: own every 200 ms or 1 MiB
FLUSH_EVERY_S = 0.5
#: The .rrd footer (a manifest of every chunk, for random access) is held in memory until the
#: file is closed: ~7 KB per chunk, and a block costs at most chunks_per_block(model). A run expected
#: to log more chunks than this is written without footer (still a valid .rrd; the viewer and
#: rblog.load read it; ``rerun rrd optimize`` can add one), so that memory stays bounded.
RRD_FOOTER_MAX_CHUNKS = 8192
#: chunks sent per block besides the geoms' entities: state, nine plots, contacts (data and
#: view), and one per body of a small scene (its body-frame angular velocity plot; at most
#: OMEGA_PLOT_MAX_BODIES)
CHUNKS_PER_BLOCK = 16
#: bodies' names are drawn in the 3D view for scenes of at most this many bodies (else on hover)
LABELS_MAX_BODIES = 12
#: scenes of at most this many bodies get a plot of each body's angular velocity in its own frame
#: (3 lines a body), where a flip about the intermediate axis shows as a component changing sign
OMEGA_PLOT_MAX_BODIES = 4
#: view entities of the bodies' geoms: every box geom is an instance of one Boxes3D, every
#: sphere of one Ellipsoids3D, ... (one entity per geom type, instances in geom order), posed per
#: sample by the instances' centers (capsules: translations, one end) and quaternions; a mesh
#: geom is a Mesh3D entity of its own (its convex hull) under MESHES_ENTITY, posed by a
#: Transform3D per sample
BOXES_ENTITY = "world/bodies/boxes"
SPHERES_ENTITY = "world/bodies/spheres"
ELLIPSOIDS_ENTITY = "world/bodies/ellipsoids"
CAPSULES_ENTITY = "world/bodies/capsules"
CYLINDERS_ENTITY = "world/bodies/cylinders"
MESHES_ENTITY = "world/bodies/meshes"
#: default gRPC address of a viewer started with ``spawn=True``
SPAWN_PORT = 9876

_PALETTE = np.array([[31, 119, 180], [255, 127, 14], [44, 160, 44], [214, 39, 40], [148, 103, 189],
                     [140, 86, 75], [227, 119, 194], [188, 189, 34], [23, 190, 207]], np.uint8)


class _Column:
    """A ready-made component column (``rr.ComponentColumn`` protocol) over an Arrow array."""

    __slots__ = ("_desc", "_arr")

    def __init__(self, desc: rr.ComponentDescriptor, values: pa.Array, offsets):
        self._desc = desc
        # from the buffers: ListArray.from_arrays validates the offsets, ~16x the cost
        off = np.ascontiguousarray(offsets, np.int32)
        if len(off) < 1 or off[0] != 0 or off[-1] != len(values) or np.any(np.diff(off) < 0):
            raise ValueError("offsets must rise from 0 to the number of values")
        self._arr = pa.ListArray.from_buffers(pa.list_(values.type), len(off) - 1,
                                              [None, pa.py_buffer(off)], children=[values])

    def component_descriptor(self) -> rr.ComponentDescriptor:
        return self._desc

    def as_arrow_array(self) -> pa.Array:
        return self._arr


def _fixed(values: np.ndarray, width: int, dtype=np.float32) -> pa.Array:
    """(k, width) values as Arrow ``fixed_size_list<item: float not null>[width]``: the exact
    type the SDK's own columns have (the viewer does not visualize a nullable item field)."""
    flat = pa.array(np.ascontiguousarray(values, dtype).reshape(-1))
    return pa.FixedSizeListArray.from_arrays(
        flat, type=pa.list_(pa.field("item", flat.type, nullable=False), width))


def _descriptors(columns) -> dict[str, rr.ComponentDescriptor]:
    out = {}
    for c in columns:
        d = c.component_descriptor()
        out[d.component.rsplit(":", 1)[-1]] = d
    return out


class RerunRecorder:
    """Records a run to ``path`` (.rrd), and/or to a live viewer (``spawn`` / ``connect_url``).

    ``findings_panel``: the layout has the findings table (rblog.record.findings logs the findings
    into :attr:`streams` before :meth:`close`). ``before_close``: callables ``f(streams)`` run
    first thing in :meth:`close`, while the streams are open (the live audit logs its final
    findings there: rblog.record.live_audit)."""

    def __init__(self, path: str | None, *, spawn: bool = False, connect_url: str | None = None,
                 findings_panel: bool = False):
        self.path = None if path is None else str(path)
        self.findings_panel = findings_panel
        self.spawn = spawn
        self.connect_url = connect_url
        self._rec: rr.RecordingStream | None = None  # the file's stream
        self._live: rr.RecordingStream | None = None  # the viewer's stream
        self._streams: list[rr.RecordingStream] = []
        self._closed = False
        self._last_flush = 0.0
        self.samples_written = 0
        self.before_close: list = []

    # --- lifecycle ------------------------------------------------------------------------------

    def open(self, model: Model, info: RunInfo) -> None:
        """Create the recording and its sinks, then log the static data and the blueprint."""
        where = self.path or self.connect_url or "rerun viewer"
        if self.path is None and not self.spawn and not self.connect_url:
            raise LogWriteError(where, "no output: give a file path, spawn=True or connect_url")
        if self.path is not None:
            try:  # fail early, with the OS's words, before the SDK gets the path
                with open(self.path, "wb"):
                    pass
            except OSError as e:
                raise LogWriteError(self.path, e.strerror or str(e)) from None
        self._model = model
        self._info = info
        self._bounds = None  # the last sample's finite positions (k, 3), for the closing blueprint
        self._t_end = None  # the last sample's time (s), for the closing blueprint
        self._n = model.n_bodies
        self._dt = float(info.dt) if info.dt else 1.0
        self.write_footer = _expected_chunks(model, info) <= RRD_FOOTER_MAX_CHUNKS
        # The file and the live viewer get separate streams (same recording id), so a viewer
        # that is missing or goes away never blocks or breaks the file: the live stream is
        # best-effort and never flushed with a wait.
        rid = str(uuid.uuid4())
        try:
            if self.path is not None:
                self._rec = rr.RecordingStream(C.APPLICATION_ID, recording_id=rid)
                self._rec.set_sinks(rr.FileSink(self.path, write_footer=self.write_footer),
                                    default_blueprint=self._layout())
                self._streams.append(self._rec)
            url = self.connect_url
            if url:
                check_viewer_reachable(url)
            if self.spawn:
                # spawn through a stream of ours: rr.spawn() without one is silently ignored
                # ("Rerun is disabled") because rblog never creates the global recording
                self._spawner = rr.RecordingStream(C.APPLICATION_ID, recording_id=rid)
                rr.spawn(port=SPAWN_PORT, connect=False, recording=self._spawner,
                         executable_path=_viewer_executable())
                spawned = f"rerun+http://127.0.0.1:{SPAWN_PORT}/proxy"
                try:
                    check_viewer_reachable(spawned, wait_s=VIEWER_SPAWN_WAIT_S)
                except LogWriteError:
                    raise LogWriteError("--spawn", "the Rerun viewer did not start (is a display "
                                        f"available?); nothing listens on 127.0.0.1:{SPAWN_PORT} "
                                        f"after {VIEWER_SPAWN_WAIT_S:g} s") from None
                url = url or spawned
            if url:
                self._live = rr.RecordingStream(C.APPLICATION_ID, recording_id=rid)
                self._live.set_sinks(rr.GrpcSink(url), default_blueprint=self._layout())
                self._streams.append(self._live)
        except (RuntimeError, ValueError, OSError) as e:
            self._disconnect_all()
            raise LogWriteError(where, str(e).splitlines()[0] if str(e) else type(e).__name__) from None
        self._init_descriptors()
        self._log_static(model, info)
        self._flush(force=True)

    def write(self, block: Trajectory) -> None:
        """Append a block of samples (and its contacts): a few send_columns calls, no per-sample
        Python."""
        if not self._streams or self._closed:
            raise LogWriteError(self.path or "rerun", "recorder is not open")
        T = len(block.t)
        if T:
            self._write_samples(block)
        self._write_contacts(block)
        self._flush()

    def close(self, truncated: bool = False, reason: str | None = None) -> None:
        """Log the status record, flush, and finalize the file (footer). Idempotent."""
        if self._closed:
            return
        self._closed = True
        if not self._streams:
            return
        try:
            for hook in self.before_close:
                hook(list(self._streams))
            if self._bounds is not None:  # frame the bodies where they end
                bp = self._layout(bounds=self._bounds, t_end=self._t_end)
                for rec in self._streams:
                    rec.send_blueprint(bp, make_active=True, make_default=True)
            status = rr.AnyValues(complete=np.array([not truncated]),
                                  truncated=np.array([bool(truncated)]), reason=reason or "")
            for rec in self._streams:
                rec.log("rblog/status", status, static=True)
            if self._rec is not None:
                self._rec.flush()
        except RuntimeError as e:
            raise LogWriteError(self.path or "rerun", str(e).splitlines()[0]) from None
        finally:
            self._disconnect_all()

    @property
    def streams(self) -> list[rr.RecordingStream]:
        """The open recording streams (file and viewer), for more entities of the same recording."""
        return list(self._streams)

    def _layout(self, bounds=None, t_end=None) -> rrb.Blueprint:
        return _blueprint(self._model, self._info, findings=self.findings_panel, bounds=bounds,
                          t_end=t_end)

    def _disconnect_all(self):
        for rec in self._streams:
            try:
                rec.disconnect()  # closes the file sink, writing its footer
            except RuntimeError:  # a viewer that went away
                pass
        self._streams = []
        self._rec = self._live = None

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        self.close(truncated=exc_type is not None, reason=None if exc is None else str(exc))

    # --- internals ------------------------------------------------------------------------------

    def _init_descriptors(self):
        z3, z4 = np.zeros((1, 3)), np.array([[0.0, 0.0, 0.0, 1.0]])
        # the bodies' geoms are drawn as instances of one entity per geom type (one send per
        # block, not one per body): entity -> (geoms, archetype, position and quaternion
        # descriptors, offsets (k, 3) and quaternions (k, 4) of the drawn primitive in its
        # body's frame); meshes: an entity each
        m = self._model
        gb, gt = np.asarray(m.geom_body), np.asarray(m.geom_type)
        self._body_groups = {}
        on_body = gb >= 0
        for ent, arch, types, pos_name in (
                (BOXES_ENTITY, rr.Boxes3D, (GEOM_BOX, GEOM_PLANE), "centers"),
                (SPHERES_ENTITY, rr.Ellipsoids3D, (GEOM_SPHERE,), "centers"),
                (ELLIPSOIDS_ENTITY, rr.Ellipsoids3D, (GEOM_ELLIPSOID,), "centers"),
                (CAPSULES_ENTITY, rr.Capsules3D, (GEOM_CAPSULE,), "translations"),
                (CYLINDERS_ENTITY, rr.Cylinders3D, (GEOM_CYLINDER,), "centers")):
            members = np.flatnonzero(on_body & np.isin(gt, types))
            if not len(members):
                continue
            d = _descriptors(arch.columns(**{pos_name: z3}, quaternions=z4))
            off, quat = _drawn_poses(m, members)
            self._body_groups[ent] = (members, arch, d[pos_name], d["quaternions"], off, quat)
        self._meshes = {}
        names = C.geom_view_names(m)
        for g in np.flatnonzero(on_body & (gt == GEOM_MESH)):
            d = _descriptors(rr.Transform3D.columns(translation=z3, quaternion=z4))
            self._meshes[f"{MESHES_ENTITY}/{names[g]}"] = (int(g), d["translation"],
                                                           d["quaternion"])
        self._d_scalar = _descriptors(rr.Scalars.columns(scalars=[0.0]))["scalars"]
        self._omega_bodies = list(range(self._n)) if self._n <= OMEGA_PLOT_MAX_BODIES else []
        self._d_pts = _descriptors(rr.Points3D.columns(positions=z3))["positions"]
        self._d_arrows = _descriptors(rr.Arrows3D.columns(vectors=z3, origins=z3))
        self._d_any = {}
        self._interval = C.run_interval_channels(m)

    def _any(self, name: str) -> rr.ComponentDescriptor:
        d = self._d_any.get(name)
        if d is None:
            d = self._d_any[name] = rr.ComponentDescriptor(name)
        return d

    def _log_static(self, model: Model, info: RunInfo):
        for rec in self._streams:
            self._log_static_to(rec, model, info)

    def _log_static_to(self, rec: rr.RecordingStream, model: Model, info: RunInfo):
        run = {k: (np.array([v], np.int64) if isinstance(v, int) else v)
               for k, v in C.info_to_fields(info).items()}
        run["rblog_log_format"] = np.array([C.LOG_FORMAT_VERSION], np.int64)
        rec.log("rblog/run", rr.AnyValues(**run), static=True)
        rec.log("rblog/model", rr.AnyValues(**C.model_to_arrays(model)), static=True)

        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        for ent, geom in _world_geoms(model):
            rec.log(ent, geom, static=True)
        show_labels = self._n <= LABELS_MAX_BODIES
        for ent, (members, arch, _, _, _, _) in self._body_groups.items():
            bodies = np.asarray(model.geom_body)[members]
            kw = dict(colors=_PALETTE[bodies % len(_PALETTE)],
                      labels=[str(model.body_name[i]) for i in bodies], show_labels=show_labels,
                      fill_mode="solid")
            rec.log(ent, _primitives(model, members, arch, kw), static=True)
        for ent, (g, _, _) in self._meshes.items():
            b = int(model.geom_body[g])
            rec.log(ent, _mesh(model, g, _PALETTE[b % len(_PALETTE)]), static=True)
        for ent, names in (("plots/momentum/linear", ["P_x (N s)", "P_y (N s)", "P_z (N s)"]),
                           ("plots/momentum/angular", ["L_x (N m s)", "L_y (N m s)", "L_z (N m s)"])):
            rec.log(ent, rr.SeriesLines(names=names, colors=SERIES_COLOURS[ent]), static=True)
        for ent, name in (("plots/energy/total", "total"),
                          ("plots/energy/translational", "translational"),
                          ("plots/energy/rotational", "rotational"),
                          ("plots/energy/potential", "potential"),
                          ):
            rec.log(ent, rr.SeriesLines(names=[name], colors=SERIES_COLOURS[ent]), static=True)
        for ent, name, colour in ((DRIFT_ENTITY + "/ortho_max", "max |R^T R - I|",
                                   (31, 119, 180)),
                                  (DRIFT_ENTITY + "/quat_norm_max", "max ||q| - 1|",
                                   (255, 127, 14))):
            rec.log(ent, rr.SeriesLines(names=[name], colors=[colour], widths=[2.0]),
                    static=True)
        rec.log(DRIFT_ENTITY + "/tolerance", rr.SeriesLines(
            names=[f"tolerance {DRIFT_TOLERANCE:g}"],
            colors=[[230, 30, 30]], widths=[2.0]), static=True)
        names = C.view_names(model.body_name)
        for i in self._omega_bodies:
            label = str(model.body_name[i])
            rec.log(f"{OMEGA_ENTITY}/{names[i]}", rr.SeriesLines(
                names=[f"{label} w_x", f"{label} w_y", f"{label} w_z"],
                colors=OMEGA_COLOURS[i % len(OMEGA_COLOURS)]), static=True)
        rec.log("world/contacts", rr.Points3D.from_fields(radii=[0.02], colors=[[230, 30, 30]]),
                static=True)
        rec.log("world/contacts/impulses", rr.Arrows3D.from_fields(colors=[[230, 120, 30]]),
                static=True)

    def _send(self, entity: str, indexes, columns):
        for rec in self._streams:
            rec.send_columns(entity, indexes=indexes, columns=columns)

    def _write_samples(self, block: Trajectory):
        T, n = len(block.t), self._n
        a = C.block_arrays(block, n, self._interval)
        step = np.asarray(block.step, np.int64)
        t = np.ascontiguousarray(block.t, np.float64)
        idx = [rr.TimeColumn("step", sequence=step),
               rr.TimeColumn("sim_time", duration=C.time_ns(t).astype("timedelta64[ns]"))]
        rows = np.arange(T + 1)
        # canonical float64 state: one row per sample
        cols = [_Column(self._any("t"), pa.array(t), rows)]
        for name, arr in a.items():
            cols.append(_Column(self._any(name), pa.array(arr.reshape(-1)), rows * arr.shape[1]))
        self._send("rblog/state", idx, cols)

        if np.isfinite(t[-1]):
            self._t_end = float(t[-1]) if self._t_end is None else max(self._t_end, float(t[-1]))
        # body poses (float32; view only): one row of instances per sample and shape kind
        pos = a["position"].reshape(T, n, 3)
        last = pos[-1][np.all(np.isfinite(pos[-1]), axis=1)]
        if len(last):  # the closing blueprint frames where the bodies end
            self._bounds = last.copy()
        q = a["quat_wxyz"].reshape(T, n, 4)
        rot = a["rotation"].reshape(T, n, 3, 3)
        gb = np.asarray(self._model.geom_body)
        for ent, (members, _, d_c, d_q, off, gq) in self._body_groups.items():
            k = len(members)
            b = gb[members]
            # the primitive's world pose: x + R off, q_body * q_geom
            p_e = pos[:, b] + np.einsum("tkij,kj->tki", rot[:, b], off)
            q_e = quat_mul(q[:, b], gq[None])
            xyzw = np.empty((T, k, 4), np.float32)
            xyzw[..., :3] = q_e[..., 1:]
            xyzw[..., 3] = q_e[..., 0]
            self._send(ent, idx, [_Column(d_c, _fixed(p_e, 3), rows * k),
                                  _Column(d_q, _fixed(xyzw, 4), rows * k)])
        m = self._model
        for ent, (g, d_t, d_q) in self._meshes.items():
            b = int(gb[g])
            p_e = pos[:, b] + rot[:, b] @ np.asarray(m.geom_pos_body[g], np.float64)
            q_e = quat_mul(q[:, b], np.asarray(m.geom_quat_wxyz_body[g], np.float64))
            xyzw = np.concatenate([q_e[:, 1:], q_e[:, :1]], axis=1)
            self._send(ent, idx, [_Column(d_t, _fixed(p_e, 3), rows),
                                  _Column(d_q, _fixed(xyzw, 4), rows)])

        # plots
        def scalars(entity, values):
            v = np.ascontiguousarray(values, np.float64).reshape(T, -1)
            self._send(entity, idx, [_Column(self._d_scalar, pa.array(v.reshape(-1)),
                                             rows * v.shape[1])])

        scalars("plots/energy/total", a["total_energy"])
        scalars("plots/energy/translational", a["energy_translational"].sum(axis=1))
        scalars("plots/energy/rotational", a["energy_rotational"].sum(axis=1))
        scalars("plots/energy/potential", a["energy_potential"].sum(axis=1))
        scalars("plots/momentum/linear", a["total_linear_momentum"])
        scalars("plots/momentum/angular", a["total_angular_momentum"])
        scalars(DRIFT_ENTITY + "/ortho_max",
                drift_log10(a["ortho_error"].max(axis=1) if n else np.zeros(T)))
        scalars(DRIFT_ENTITY + "/quat_norm_max",
                drift_log10(np.abs(a["quat_norm_error"]).max(axis=1) if n else np.zeros(T)))
        scalars(DRIFT_ENTITY + "/tolerance", np.full(T, math.log10(DRIFT_TOLERANCE)))
        if self._omega_bodies:
            names = C.view_names(self._model.body_name)
            rot = a["rotation"].reshape(T, n, 3, 3)
            w = a["angular_velocity"].reshape(T, n, 3)
            w_body = np.einsum("tnij,tni->tnj", rot, w)  # R^T w: the body frame's components
            for i in self._omega_bodies:
                scalars(f"{OMEGA_ENTITY}/{names[i]}", w_body[:, i])
        self.samples_written += T

    def _write_contacts(self, block: Trajectory):
        c: Contacts = block.contacts
        T = len(block.t)
        if len(c):
            step = np.asarray(c.step, np.int64)
            t = np.asarray(c.t, np.float64)
            cut = np.flatnonzero((step[1:] != step[:-1]) | (t[1:] != t[:-1])) + 1
            bounds = np.concatenate([[0], cut, [len(step)]])
            first = bounds[:-1]
            idx = [rr.TimeColumn("step", sequence=step[first]),
                   rr.TimeColumn("sim_time", duration=C.time_ns(t[first]).astype("timedelta64[ns]"))]
            cols = []
            for name in ("step", "body_a", "body_b", "kind"):
                cols.append(_Column(self._any(name), pa.array(np.asarray(getattr(c, name), np.int64)),
                                    bounds))
            for name in ("t", "separation", "normal_impulse"):
                cols.append(_Column(self._any(name),
                                    pa.array(np.asarray(getattr(c, name), np.float64)), bounds))
            for name in ("point", "normal", "friction_impulse"):
                v = np.ascontiguousarray(getattr(c, name), np.float64).reshape(-1)
                cols.append(_Column(self._any(name), pa.array(v), bounds * 3))
            self._send("rblog/contacts", idx, cols)
        if not T:
            return
        # view: the contacts of each sample's step (an empty row clears the previous ones)
        bstep = np.asarray(block.step, np.int64)
        if len(c):
            cstep = np.asarray(c.step, np.int64)
            keep = np.isin(cstep, bstep)
            order = np.flatnonzero(keep)
            if np.any(cstep[1:] < cstep[:-1]):  # the simulator writes them in step order
                order = order[np.argsort(cstep[keep], kind="stable")]
            sorted_steps = cstep[order]
            lo = np.searchsorted(sorted_steps, bstep, "left")
            hi = np.searchsorted(sorted_steps, bstep, "right")
            counts = hi - lo
            # the contacts of each sample's step, samples in order (a step logged twice gets its
            # contacts twice): positions lo[s]..hi[s] of ``order``, concatenated
            starts = np.repeat(lo - np.concatenate([[0], np.cumsum(counts)[:-1]]), counts)
            sel = order[starts + np.arange(int(counts.sum()))]
        else:
            counts = np.zeros(T, np.int64)
            sel = np.zeros(0, np.int64)
        if not counts.any() and not getattr(self, "_had_contacts", False):
            return  # nothing to show and nothing to clear
        self._had_contacts = bool(counts[-1]) if T else False
        offsets = np.concatenate([[0], np.cumsum(counts)])
        idx = [rr.TimeColumn("step", sequence=bstep),
               rr.TimeColumn("sim_time", duration=C.time_ns(block.t).astype("timedelta64[ns]"))]
        if len(sel) == len(c) and np.array_equal(sel, np.arange(len(c))):
            sel = slice(None)  # every contact, in order (the usual case): no gathers
        pts = c.point[sel]
        imp = c.normal_impulse[sel, None] * c.normal[sel] + c.friction_impulse[sel]
        vec = imp / self._dt * C.CONTACT_ARROW_M_PER_N
        self._send("world/contacts", idx, [_Column(self._d_pts, _fixed(pts, 3), offsets)])
        self._send("world/contacts/impulses", idx, [
            _Column(self._d_arrows["vectors"], _fixed(vec, 3), offsets),
            _Column(self._d_arrows["origins"], _fixed(pts, 3), offsets)])

    def _flush(self, force: bool = False):
        now = time.monotonic()
        if self._rec is not None and (force or now - self._last_flush >= FLUSH_EVERY_S):
            self._rec.flush()
            self._last_flush = now


def _expected_chunks(model: Model, info: RunInfo) -> float:
    """Chunks the run will log, from its duration and the simulator's block sizes."""
    from rblog.engine.runner import samples_per_block

    try:
        samples = float(info.duration_s) / (float(info.dt) * max(int(info.log_every), 1)) + 1
    except (ZeroDivisionError, ValueError, TypeError):
        return math.inf
    if not math.isfinite(samples):
        return math.inf
    per_block = samples_per_block(model.n_bodies, int(info.log_every))
    return math.ceil(samples / per_block) * chunks_per_block(model)


def chunks_per_block(model: Model) -> int:
    """Chunks one block sends at most: CHUNKS_PER_BLOCK, one per geom type the bodies have (one
    entity each) and one per mesh geom (an entity each)."""
    gb, gt = np.asarray(model.geom_body), np.asarray(model.geom_type)
    on_body = gt[gb >= 0]
    types = {GEOM_PLANE: GEOM_BOX}  # a body's planes are drawn with its boxes
    entities = {types.get(int(t), int(t)) for t in on_body if t != GEOM_MESH}
    return CHUNKS_PER_BLOCK + len(entities) + int(np.sum(on_body == GEOM_MESH))


#: the drift plot: log10 of the largest rigidity errors over the bodies, beside the tolerance
#: rblog check judges them by (a line), so that round-off (1e-16 .. 1e-12), the tolerance and a
#: body stretched to an error of 1 all read on one axis (DRIFT_AXIS_LOG10)
DRIFT_ENTITY = "plots/drift"
#: the rigidity tolerance drawn as a line: rblog.analyze.tolerances.DRIFT_ORTHO_ERROR (the record
#: room does not import the audit; tests/record/test_record.py checks the two agree)
DRIFT_TOLERANCE = 1e-6
#: an error of exactly 0 is drawn at this floor (log10 of it: -17), below float64 round-off
DRIFT_FLOOR = 1e-17
#: the drift plot's y range (log10 of the error): from below the floor to above an error of 10, so that
#: round-off, the tolerance (-6) and a stretched body (0) stand at their own heights with a tick
#: every few decades, whatever the run (scaled to the data, a clean run's axis spanned a
#: fraction of a decade and showed one tick label); the viewer still zooms
#: the floor a decade above the bottom edge; above an error of 10 the axis keeps 8 decades of
#: headroom, where the legend (three rows, ~30 % of the plot's height) stands off every trace
DRIFT_AXIS_LOG10 = (math.log10(DRIFT_FLOOR) - 1.0, 9.0)
#: the line colours of the energy and momentum plots (RGB): hues far apart on the colour wheel,
#: so that no two series of one plot look alike (the viewer's own picks were blues and purples);
#: total energy white, x/y/z as red/green/blue for P and orange/white/magenta for L; each
#: at a contrast of 3 or more to the viewer's dark plot background (13, 13, 13)
SERIES_COLOURS = {
    "plots/energy/total": [(235, 235, 235)],
    "plots/energy/translational": [(31, 119, 180)],
    "plots/energy/rotational": [(255, 127, 14)],
    "plots/energy/potential": [(44, 160, 44)],
    "plots/momentum/linear": [(214, 39, 40), (44, 160, 44), (31, 119, 180)],
    "plots/momentum/angular": [(255, 160, 0), (235, 235, 235), (227, 119, 194)],
}
#: per-body angular velocity (body frame) of small scenes: OMEGA_ENTITY/<body view name>
OMEGA_ENTITY = "plots/omega_body"
#: x, y, z line colours of each body's angular velocity (reds, greens, blues; lighter per body)
OMEGA_COLOURS = [[(235, 80, 80), (80, 200, 80), (90, 150, 250)],
                 [(250, 160, 150), (160, 230, 150), (160, 200, 255)],
                 [(170, 40, 40), (30, 130, 30), (40, 80, 190)],
                 [(250, 200, 120), (200, 240, 120), (120, 220, 240)]]


def drift_log10(err) -> np.ndarray:
    """log10 of rigidity errors for the drift plot, floored at DRIFT_FLOOR (NaN stays NaN)."""
    return np.log10(np.maximum(np.abs(np.asarray(err, np.float64)), DRIFT_FLOOR))  # NaN stays


def position_bounds(position) -> tuple[np.ndarray, np.ndarray] | None:
    """(lo, hi) corners (m, world) of the finite positions in ``position`` (..., 3), or None."""
    p = np.asarray(position, np.float64).reshape(-1, 3)
    if len(p):
        lo, hi = p.min(axis=0), p.max(axis=0)
        if np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)):
            return lo, hi
    p = p[np.all(np.isfinite(p), axis=1)]
    if not len(p):
        return None
    return p.min(axis=0), p.max(axis=0)


def _start_bounds(resolved: dict) -> tuple[np.ndarray, np.ndarray] | None:
    """(lo, hi) corners of the starting positions in a resolved scene: its [[body]] tables'
    positions and its generators' ``position_bounds``; None if a body has no position."""
    bodies = resolved.get("body") or []
    gens = resolved.get("generator") or []
    if not all(isinstance(b, dict) and "position" in b for b in bodies) or \
            not all(isinstance(g, dict) and "position_bounds" in g for g in gens):
        return None
    points = [b["position"] for b in bodies]
    for g in gens:
        points.extend(g["position_bounds"])
    return position_bounds(points) if points else None


#: the 3D view's vertical field of view (Rerun's default eye, degrees) and the width / height of
#: that view in the default layout at 1600 x 900 (the camera is placed to fit both)
VIEW_FOV_Y_DEG = 55.0
VIEW_ASPECT = 0.95
VIEW_ASPECT_FINDINGS = 1.3
#: fraction of the view's half height / half width the framed bodies may take
FRAME_FILL = 0.8
#: the camera looks from this direction (from above one corner)
EYE_DIRECTION = np.array([1.2, -1.8, 1.0])


#: with at least FRAME_TRIM_MIN_BODIES bodies, the camera frames this quantile of them (the
#: few that bounced far from a pile may be cut, the pile itself fills the view)
FRAME_QUANTILE = 0.98
FRAME_TRIM_MIN_BODIES = 50


def frame_camera(points, radius: float = 0.0, direction=EYE_DIRECTION,
                 fov_y_deg: float = VIEW_FOV_Y_DEG, aspect: float = VIEW_ASPECT,
                 fill: float = FRAME_FILL):
    """(eye position, look target) of a camera looking along ``-direction`` at ``points`` (k, 3),
    spheres of ``radius``, from the nearest distance at which they are inside the view with
    ``fill`` of its half extents used (a FRAME_QUANTILE of them when there are many). Fitting the
    points, not their bounding box, lets a wide flat pile fill the view."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    p = p[np.all(np.isfinite(p), axis=1)]
    q = FRAME_QUANTILE if len(p) >= FRAME_TRIM_MIN_BODIES else 1.0
    lo, hi = np.quantile(p, 1 - q, axis=0), np.quantile(p, q, axis=0)
    centre = 0.5 * (lo + hi)
    d = np.asarray(direction, np.float64)
    d = d / np.linalg.norm(d)
    fwd = -d
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right = right / (np.linalg.norm(right) or 1.0)
    up = np.cross(right, fwd)
    rel = p - centre
    tan_y = math.tan(math.radians(fov_y_deg) / 2) * fill
    tan_x = tan_y * aspect
    # a point at distance D - p.fwd from the eye (D: the eye's distance from the centre) is in
    # view when |p.up| + r <= tan_y (D + p.fwd) and |p.right| + r <= tan_x (D + p.fwd)
    need = np.maximum((np.abs(rel @ up) + radius) / tan_y,
                      (np.abs(rel @ right) + radius) / tan_x) - rel @ fwd
    dist = float(np.quantile(need, q)) if len(need) else 1.0
    dist = max(dist, 2.0 * radius, 1e-3)
    return centre + dist * d, centre


#: the plots' time axis reaches this fraction of the run past either end, so that the first and
#: last tick labels (+0 s, +20 s) are drawn whole rather than cut at the plot's edge
TIME_AXIS_MARGIN = 0.07


def _time_axis(t_end: float | None):
    if not t_end or not math.isfinite(t_end) or t_end <= 0:
        return None
    pad = TIME_AXIS_MARGIN * t_end
    return rrb.TimeAxis(view_range=rr.TimeRange(
        start=rrb.TimeRangeBoundary.absolute(seconds=-pad),
        end=rrb.TimeRangeBoundary.absolute(seconds=t_end + pad)))


def _blueprint(model: Model, info: RunInfo, findings: bool = False,
               bounds=None, t_end: float | None = None) -> rrb.Blueprint:
    """The default layout, made for a 1600 x 900 window: the 3D view beside a 2 x 2 grid of
    plots (energy, momentum, drift, and for small scenes each body's angular velocity in its own
    frame, else linear and angular momentum apart), each plot with its legend and a time axis a
    little wider than the run (``t_end``, else the scene's duration) so that its end labels are
    whole; the drift plot spans DRIFT_AXIS_LOG10 and draws the tolerance as a line. With
    ``findings``, the findings table (the ``findings`` text log of rblog.record.findings) spans
    the width below, and the time panel is expanded so that its ``findings`` row marks when
    they are. The camera frames ``bounds``: the bodies' positions (k, 3) at the end of the run,
    where the viewer opens (a recorder sends that blueprint when it closes, so a pile fills the
    view and a body that flew off is in it), or the (lo, hi) corners of a box; by default the
    bodies' starting positions (from the resolved scene, when the log has one)."""
    eye = None
    if bounds is None:
        bounds = _start_bounds(info.scene_resolved or {})
    if bounds is not None and model.n_bodies:
        # bounds: the bodies' positions (k, 3), or the (lo, hi) corners of a box around them
        pts = np.asarray(bounds, np.float64).reshape(-1, 3)
        if len(pts) == 2:
            pts = np.array([[x, y, z] for x in pts[:, 0] for y in pts[:, 1] for z in pts[:, 2]])
        radius = float(np.max(model.body_bounding_radius))
        position, target = frame_camera(pts, radius, aspect=VIEW_ASPECT_FINDINGS if findings
                                        else VIEW_ASPECT)
        eye = rrb.EyeControls3D(position=position, look_target=target)
    legend = rrb.PlotLegend(corner="LeftTop", visible=True)
    # the drift plot (DRIFT_AXIS_LOG10): its top keeps headroom above every trace for the legend
    drift_legend = rrb.PlotLegend(corner="LeftTop", visible=True)
    axis = _time_axis(t_end if t_end is not None else info.duration_s)
    kw = dict(plot_legend=legend, axis_x=axis) if axis is not None else dict(plot_legend=legend)
    world = rrb.Spatial3DView(origin="world", name="bodies", eye_controls=eye)
    drift = rrb.TimeSeriesView(origin=DRIFT_ENTITY, name="rigidity drift (log10 of the error)",
                               axis_y=rrb.ScalarAxis(range=DRIFT_AXIS_LOG10),
                               **{**kw, "plot_legend": drift_legend})
    if 0 < model.n_bodies <= OMEGA_PLOT_MAX_BODIES:
        plots = [rrb.TimeSeriesView(origin="plots/energy", name="energy (J)", **kw),
                 rrb.TimeSeriesView(origin="plots/momentum", name="total momentum", **kw),
                 drift,
                 rrb.TimeSeriesView(origin=OMEGA_ENTITY,
                                    name="angular velocity, body frame (rad/s)", **kw)]
    else:  # no per-body plot: the fourth cell splits linear and angular momentum
        plots = [rrb.TimeSeriesView(origin="plots/energy", name="energy (J)", **kw),
                 rrb.TimeSeriesView(origin="plots/momentum/linear",
                                    name="total linear momentum (N s)", **kw),
                 drift,
                 rrb.TimeSeriesView(origin="plots/momentum/angular",
                                    name="total angular momentum (N m s)", **kw)]
    top = rrb.Horizontal(world, rrb.Grid(*plots, grid_columns=2), column_shares=[1, 1])
    if findings:
        table = rrb.TextLogView(
            origin="findings", name="findings of rblog check (one row per finding)",
            columns=rrb.TextLogColumns(timeline_columns=["sim_time"],
                                       text_log_columns=["Body"]))
        top = rrb.Vertical(top, table, row_shares=[5, 2])
    return rrb.Blueprint(
        top,
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="expanded" if findings else "collapsed"),
    )


#: how long --spawn waits for the new viewer to listen (s)
VIEWER_SPAWN_WAIT_S = 5.0
#: how long a --connect check waits for the viewer's TCP port (s)
VIEWER_CONNECT_TIMEOUT_S = 1.0


def check_viewer_reachable(url: str, wait_s: float = 0.0) -> None:
    """Raise LogWriteError unless something accepts TCP connections at ``url``'s host:port
    (``rerun+http://host:port/proxy``). The SDK's gRPC sink connects lazily and never reports a
    dead address, so a typo'd port would otherwise stream into the void and exit 0."""
    import socket
    import time
    from urllib.parse import urlparse

    u = urlparse(url.replace("rerun+", "", 1))
    if not u.hostname or not u.port:
        raise LogWriteError(url, "expected a viewer URL like rerun+http://127.0.0.1:9876/proxy")
    deadline = time.monotonic() + wait_s
    while True:
        try:
            with socket.create_connection((u.hostname, u.port), timeout=VIEWER_CONNECT_TIMEOUT_S):
                return
        except OSError as e:
            if time.monotonic() >= deadline:
                raise LogWriteError(url, f"no Rerun viewer listens at {u.hostname}:{u.port} "
                                    f"({e.strerror or e})") from None
            time.sleep(0.1)


def _viewer_executable() -> str | None:
    """The ``rerun`` viewer on PATH, else the one installed beside this Python (a venv used
    without activating it), else None (the SDK then reports it missing)."""
    import shutil
    import sys
    from pathlib import Path

    found = shutil.which("rerun")
    if found:
        return found
    beside = Path(sys.executable).with_name("rerun")
    return str(beside) if beside.exists() else None


def _drawn_poses(model: Model, members: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(k, 3) offsets and (k, 4) quaternions (wxyz), in their bodies' frames, of the primitives
    drawing geoms ``members``: the geom's pose, a capsule's moved to its lower end (Rerun's
    Capsules3D starts at its translation and runs along +z), a plane's to its thin box."""
    from rblog.contract.orientation import quat_wxyz_to_matrix

    off = np.asarray(model.geom_pos_body, np.float64)[members].copy()
    quat = np.asarray(model.geom_quat_wxyz_body, np.float64)[members].copy()
    for j, g in enumerate(members):
        t = int(model.geom_type[g])
        if t == GEOM_CAPSULE:
            off[j] -= quat_wxyz_to_matrix(quat[j])[:, 2] * float(model.geom_size[g, 1])
        elif t == GEOM_PLANE:
            off[j], quat[j], _ = C.plane_box(model, int(g))
    return off, quat


def _primitives(model: Model, members: np.ndarray, arch, kw: dict):
    """The static part (sizes, colours, labels) of the instances drawing geoms ``members``."""
    size = np.asarray(model.geom_size, np.float64)[members]
    types = np.asarray(model.geom_type)[members]
    if arch is rr.Boxes3D:
        half = size.copy()
        for j, g in enumerate(members):
            if types[j] == GEOM_PLANE:
                half[j] = C.plane_box(model, int(g))[2]
        return rr.Boxes3D(half_sizes=half, **kw)
    if arch is rr.Ellipsoids3D:
        half = np.where((types == GEOM_SPHERE)[:, None], size[:, :1], size)
        return rr.Ellipsoids3D(half_sizes=half, **kw)
    if arch is rr.Capsules3D:
        return rr.Capsules3D(lengths=2.0 * size[:, 1], radii=size[:, 0], **kw)
    return rr.Cylinders3D(lengths=2.0 * size[:, 1], radii=size[:, 0], **kw)


def _mesh(model: Model, g: int, colour) -> rr.Mesh3D | rr.Points3D:
    """Mesh geom ``g`` in its own frame: the convex hull of its vertices (its points alone when
    the hull cannot be built)."""
    vert = model.geom_vertices(g)
    tri = C.hull_triangles(vert)
    if tri is None:
        return rr.Points3D(vert, colors=[colour], radii=[0.005])
    return rr.Mesh3D(vertex_positions=vert, triangle_indices=tri, albedo_factor=[*colour, 255])


def _world_geoms(model: Model) -> list:
    """(entity, archetype) of every world geom (static): the ground plane at ``world/ground``,
    other planes at ``world/planes/<name>`` (thin boxes), every other geom at
    ``world/statics/<j>`` (j counting them in geom order) as what it is."""
    out = []
    gb, gt = np.asarray(model.geom_body), np.asarray(model.geom_type)
    names = C.geom_view_names(model)
    ground_seen = False
    j = 0
    for g in np.flatnonzero(gb < 0):
        g = int(g)
        t = int(gt[g])
        q = np.asarray(model.geom_quat_wxyz_body[g], np.float64)
        p = np.asarray(model.geom_pos_body[g], np.float64)
        size = np.asarray(model.geom_size[g], np.float64)
        xyzw = [rr.Quaternion(xyzw=[*q[1:], q[0]])]
        solid = dict(colors=[[150, 150, 165, 200]], fill_mode="solid")
        if t == GEOM_PLANE:
            center, qp, half = C.plane_box(model, g)
            nrm = _normal(q)
            is_ground = (not ground_seen and model.ground
                         and np.allclose(nrm, model.ground_normal, rtol=0.0, atol=1e-12)
                         and abs(float(nrm @ p) - float(model.ground_offset)) <= 1e-12)
            ent = "world/ground" if is_ground else f"world/planes/{names[g]}"
            ground_seen = ground_seen or is_ground
            out.append((ent, rr.Boxes3D(centers=[center], half_sizes=[half],
                                        quaternions=[rr.Quaternion(xyzw=[*qp[1:], qp[0]])],
                                        colors=[[128, 128, 128, 160]], fill_mode="solid")))
            continue
        ent = f"world/statics/{j}"
        j += 1
        if t == GEOM_BOX:
            arch = rr.Boxes3D(centers=[p], half_sizes=[size], quaternions=xyzw, **solid)
        elif t in (GEOM_SPHERE, GEOM_ELLIPSOID):
            half = [size[0]] * 3 if t == GEOM_SPHERE else size
            arch = rr.Ellipsoids3D(centers=[p], half_sizes=[half], quaternions=xyzw, **solid)
        elif t == GEOM_CAPSULE:
            from rblog.contract.orientation import quat_wxyz_to_matrix

            end = p - quat_wxyz_to_matrix(q)[:, 2] * size[1]
            arch = rr.Capsules3D(translations=[end], lengths=[2 * size[1]], radii=[size[0]],
                                 quaternions=xyzw, **solid)
        elif t == GEOM_CYLINDER:
            arch = rr.Cylinders3D(centers=[p], lengths=[2 * size[1]], radii=[size[0]],
                                  quaternions=xyzw, **solid)
        else:  # a mesh: its hull placed by its own transform
            out.append((ent, rr.Transform3D(translation=p, quaternion=xyzw[0])))
            out.append((ent + "/mesh", _mesh(model, g, [150, 150, 165])))
            continue
        out.append((ent, arch))
    return out


def _normal(quat_wxyz) -> np.ndarray:
    from rblog.contract.orientation import quat_wxyz_to_matrix

    return quat_wxyz_to_matrix(np.asarray(quat_wxyz, np.float64))[:, 2]
