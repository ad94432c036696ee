"""The log contract in memory: what the engine produces, the recorders write and read back, and
the analyzers judge (docs/log-format.md is the same contract on disk).

* ``model``: :class:`Model`, the body table and the world (masses, body-frame inertia,
  materials, gravity, applied loads; bodies' kinds and parents, joints, geoms of every shape
  with the world's, which per-interval impulses the writer supplies; the v2 summaries
  body_shape, ground, static boxes).
* ``trajectory``: :class:`Trajectory` (samples x bodies, time first, with the optional
  per-interval impulses and works), :class:`Contacts` (contact rows), :class:`RunInfo` (run
  metadata), and :func:`derive` (state -> every derived channel).
* ``orientation``: quaternion <-> matrix <-> rotation vector conversions (numpy).
* ``derive``: the compiled kernel that defines the derived channels (momenta, energies, rigidity
  errors, totals) once for every writer and reader (C++: its own module ``rblog.contract._derive``,
  csrc/contract/).

May import: numpy, rblog.errors, its own compiled module ``_derive``. Nothing else of rblog: the engine, the recorders and the
analyzers all import this room, never the other way round.
"""
