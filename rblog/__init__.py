"""rblog: simulate rigid bodies, record what happened, and audit the recording.

The public API, imported lazily so that ``import rblog`` stays cheap::

    scene = rblog.load_scene("samples/tumbling_box.toml")
    traj, summary = rblog.simulate(scene)          # in memory
    summary = rblog.run(scene, recorders=[...])    # streamed to log writers
    traj = rblog.load("run.mcap")                  # read a log back (.rrd or .mcap)
    results = rblog.check(traj)                    # physics analyzers
"""

__version__ = "0.1.0"

_API = {
    "load_scene": ("rblog.scene", "load_scene"),
    "parse_scene": ("rblog.scene", "parse_scene"),
    "simulate": ("rblog.simulate", "simulate"),
    "run": ("rblog.simulate", "run"),
    "load": ("rblog.record.reader", "load"),
    "check": ("rblog.analyze", "check"),
    "Trajectory": ("rblog.trajectory", "Trajectory"),
}

__all__ = ["__version__", *_API]


def __getattr__(name):
    if name in _API:
        import importlib

        mod, attr = _API[name]
        return getattr(importlib.import_module(mod), attr)
    raise AttributeError(f"module 'rblog' has no attribute {name!r}")
