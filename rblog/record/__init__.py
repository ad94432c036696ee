"""rblog.record: write runs to Rerun (.rrd) and MCAP (.mcap) logs and read them back.

The layout of both formats is the contract in docs/log-format.md.

* :class:`RerunRecorder` (``rerun_writer``) and :class:`McapRecorder` (``mcap_writer``) share one
  interface: ``open(model, info)``, ``write(block)`` for each block of samples, and
  ``close(truncated=False, reason=None)``.
* :class:`Recorder` (``recorder``): the public writer API for any engine (body table + state
  blocks in, every derived channel and the files out, through the two writers above).
* :func:`load` (``reader``) reads either format back into one Trajectory.
"""

#: public name -> module, imported on first use: a writer's module pulls in its SDK (Rerun,
#: pyarrow: ~0.3 s; mcap, protobuf), which a run that writes only the other format, or no log,
#: and the submodules' own ``from rblog.record import _common`` should not pay for
_API = {
    "McapRecorder": "rblog.record.mcap_writer",
    "Recorder": "rblog.record.recorder",
    "RecordError": "rblog.record.recorder",
    "RerunRecorder": "rblog.record.rerun_writer",
    "body_table": "rblog.record.recorder",
    "load": "rblog.record.reader",
    "rewritten": "rblog.record.recorder",
    "trajectory_from_arrays": "rblog.record.recorder",
}

__all__ = sorted(_API)


def __getattr__(name):
    if name in _API:
        import importlib

        value = getattr(importlib.import_module(_API[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'rblog.record' has no attribute {name!r}")
