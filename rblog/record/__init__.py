"""rblog.record: write runs to Rerun (.rrd) and MCAP (.mcap) logs and read them back.

The layout of both formats is the contract in docs/log-format.md.

* :class:`RerunRecorder` (``rerun_writer``) and :class:`McapRecorder` (``mcap_writer``) share one
  interface: ``open(model, info)``, ``write(block)`` for each block of samples, and
  ``close(truncated=False, reason=None)``.
* :func:`load` (``reader``) reads either format back into one Trajectory.
"""

from rblog.record.mcap_writer import McapRecorder
from rblog.record.reader import load
from rblog.record.rerun_writer import RerunRecorder

__all__ = ["McapRecorder", "RerunRecorder", "load"]
