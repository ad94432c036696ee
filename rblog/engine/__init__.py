"""The simulator: a scene in, states out.

Data flow: ``scene`` (TOML -> validated Model + State) -> ``plan`` (the stages the scene needs,
chosen once) -> ``runner`` (blocks of compiled steps, samples handed to recorders) -> either
``free`` (the free-body kernel) or ``contact.world`` (the contact step), both stepping bodies
with the integrators of ``integrators``.

* ``constants``: every tolerance and setting of the engine, with its unit (incl. ContactParams).
* ``state``: :class:`State`, the changing arrays (position, momenta, q, R).
* ``rotation``: quaternion/matrix math shared by every kernel.
* ``integrators``: the integrator registry; each integrator's step is C++ (csrc/engine/).
* ``free``: the compiled free-body kernel (no contacts).
* ``contact/``: broadphase, narrowphase, solver, islands and the compiled contact step.
* ``plan``, ``scene``, ``runner``: see above.

May import: rblog.contract, rblog.errors, rblog._threads, numpy, and its compiled core
``rblog.engine._core`` (csrc/engine/). Never rblog.record (recorders are handed
in through the ``Recorder`` protocol), rblog.analyze or rblog.study.
"""
