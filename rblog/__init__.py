"""rblog: simulate rigid bodies, record what happened, and audit the recording.

Rooms (docs/architecture.md): ``contract`` (the log contract in memory: Model, Trajectory),
``engine`` (the simulator), ``record`` (Rerun and MCAP writers, the reader), ``analyze`` (the
audit), ``study`` (benchmarks, stress, references, peers); ``errors`` is shared by all.

The public API, imported lazily so that ``import rblog`` stays cheap::

    scene = rblog.load_scene("samples/tumbling_box.toml")
    traj, summary = rblog.simulate(scene)              # in memory
    summary = rblog.run(scene, recorders=[...])    # streamed to log writers
    traj = rblog.load("run.mcap")                  # read a log back (.rrd or .mcap)
    results = rblog.check(traj)                    # physics analyzers
    with rblog.Recorder(model, mcap="x.mcap") as rec:   # record another engine's run
        rec.write(t=t, position=x, quat_wxyz=q, velocity=v, angular_velocity=w)
"""

__version__ = "0.1.0"


_API = {
    "load_scene": ("rblog.engine.scene", "load_scene"),
    "parse_scene": ("rblog.engine.scene", "parse_scene"),
    "simulate": ("rblog.engine.runner", "simulate"),
    "run": ("rblog.engine.runner", "run"),
    "load": ("rblog.record.reader", "load"),
    "check": ("rblog.analyze", "check"),
    "Trajectory": ("rblog.contract.trajectory", "Trajectory"),
    "Model": ("rblog.contract.model", "Model"),
    "RunInfo": ("rblog.contract.trajectory", "RunInfo"),
    "Contacts": ("rblog.contract.trajectory", "Contacts"),
    "Recorder": ("rblog.record.recorder", "Recorder"),
    "body_table": ("rblog.record.recorder", "body_table"),
    "trajectory_from_arrays": ("rblog.record.recorder", "trajectory_from_arrays"),
    "RblogError": ("rblog.errors", "RblogError"),
    "SceneError": ("rblog.errors", "SceneError"),
    "LogReadError": ("rblog.errors", "LogReadError"),
    "LogWriteError": ("rblog.errors", "LogWriteError"),
    "RecordError": ("rblog.record.recorder", "RecordError"),
    "SimulationDiverged": ("rblog.errors", "SimulationDiverged"),
    "RunInterrupted": ("rblog.errors", "RunInterrupted"),
    "AuditFailed": ("rblog.analyze.live", "AuditFailed"),
}

__all__ = ["__version__", *_API]


def __getattr__(name):
    if name in _API:
        import importlib

        mod, attr = _API[name]
        value = getattr(importlib.import_module(mod), attr)
        globals()[name] = value  # bind once: no submodule of rblog can shadow a public name
        return value
    raise AttributeError(f"module 'rblog' has no attribute {name!r}")
