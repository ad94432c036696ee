"""rblog.record: write runs to Rerun (.rrd) and MCAP (.mcap) logs and read them back.

The layout of both formats is the contract in docs/log-format.md.

* :class:`RerunRecorder` (``rerun_writer``) and :class:`McapRecorder` (``mcap_writer``) share one
  interface: ``open(model, info)``, ``write(block)`` for each block of samples, and
  ``close(truncated=False, reason=None)``.
* :class:`Recorder` (``recorder``): the public writer API for any engine (body table + state
  blocks in, every derived channel and the files out, through the two writers above).
* :func:`load` (``reader``) reads either format back into one Trajectory.
"""

from rblog.record.mcap_writer import McapRecorder
from rblog.record.recorder import Recorder, body_table, trajectory_from_arrays
from rblog.record.reader import load
from rblog.record.rerun_writer import RerunRecorder

__all__ = ["McapRecorder", "Recorder", "RerunRecorder", "body_table", "load",
           "trajectory_from_arrays"]
