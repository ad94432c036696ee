"""``record_rollout`` of :mod:`rblog.adapters.mujoco`: a ``mujoco.rollout`` output as a log
(no contacts, no impulses: the log says they are missing)."""

from __future__ import annotations

import numpy as np

from rblog.adapters import AdapterError
from rblog.adapters._mujoco_model import _mj, inspect, settings, state_offsets
from rblog.adapters._mujoco_step import Kinematics, momenta


def record_rollout(m, initial_state, state, *, d=None, rrd=None, mcap=None, batch: int = 0,
                   spec=None, restitution=None, writer: str | None = None,
                   keep: bool | None = None, **recorder_options):
    """Record the output of ``mujoco.rollout.rollout(m, d, initial_state, ...)``: ``state``
    (nbatch, nstep, nstate) or (nstep, nstate), the state after each step, and the
    ``initial_state`` it started from (sample 0). A rollout returns neither contacts nor forces:
    the log has no contact rows, and its model says that every body's impulses and work are
    missing (``body_impulse_supplied`` all False). ``batch`` picks one rollout of a batch.

    Returns the Trajectory when kept (default: when there is no output path), else None."""
    from dataclasses import replace

    from rblog.record.recorder import Recorder

    mj = _mj()
    state = np.asarray(state, np.float64)
    x0 = np.asarray(initial_state, np.float64)
    if state.ndim == 3:
        state = state[batch]
    if x0.ndim == 2:
        x0 = x0[batch if len(x0) > 1 else 0]
    nstate = int(mj.mj_stateSize(m, int(mj.mjtState.mjSTATE_FULLPHYSICS if spec is None else spec)))
    if state.ndim != 2 or state.shape[1] != nstate or x0.shape != (nstate,):
        raise AdapterError(f"record_rollout: state has shape {state.shape} and initial_state "
                           f"{x0.shape}, expected (nstep, {nstate}) and ({nstate},) (mj_stateSize)")
    it, iq, iv = state_offsets(m, spec)
    rows = np.concatenate([x0[None], state])
    model, layout, notes = inspect(m, d, restitution=restitution)
    model = replace(model, body_impulse_supplied=np.zeros_like(model.body_impulse_supplied),
                    body_work_supplied=np.zeros_like(model.body_work_supplied))
    dt = float(m.opt.timestep)
    engine = {**settings(m), **notes, "contact_rows": {"separation": "before the step (none logged: "
                                                       "mujoco.rollout returns no contacts)"},
              "impulses": "none (mujoco.rollout returns no forces)"}
    kin = Kinematics(m, layout)
    T, n = len(rows), len(layout)
    x, r, v, w = np.empty((T, n, 3)), np.empty((T, n, 3, 3)), np.empty((T, n, 3)), np.empty((T, n, 3))
    q = np.empty((T, n, 4))
    for i in range(T):
        kin(rows[i, iq:iq + m.nq], rows[i, iv:iv + m.nv], out=(x[i], r[i], v[i], w[i]))
        q[i] = kin.quat_wxyz()
    step = np.rint(rows[:, it] / dt).astype(np.int64)
    # the momenta as MujocoRecorder logs them (the states as MuJoCo gives them)
    p, L = momenta(np.asarray(model.body_mass, np.float64),
                   np.asarray(model.body_inertia_diag, np.float64), r, v, w)
    rec = Recorder(model, rrd=rrd, mcap=mcap, dt=dt, writer=writer or f"mujoco {mj.__version__} "
                   "rollout via rblog.adapters", integrator=engine["integrator"],
                   combine_friction="max", combine_restitution="max", engine_settings=engine,
                   keep=keep, **recorder_options)
    with rec:
        rec.write(t=step * dt, step=step, position=x, rotation=r, quat_wxyz=q, velocity=v,
                  angular_velocity=w, linear_momentum=p, angular_momentum=L)
    return rec.trajectory if rec.keep else None
