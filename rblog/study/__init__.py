"""Studies around the engine: accuracy against cost, stress, peers.

* ``reference``: closed-form and high-accuracy reference solutions (the exact answers tests and
  benchmarks measure against).
* ``bench``: ``rblog bench``, error against run time per integrator and dt, peers side by side.
* ``stress``: ``rblog stress``, numerical stability at extreme inputs.
* ``peers``: the same problems run in MuJoCo and pybullet (optional extras).
* ``scenes``: reference contact scenes built in code (stacks, piles) for tests and benchmarks.
* ``cluster``: the executor every bulk job runs on (serial, local Dask cluster, running scheduler).
* ``bulk_check``: ``rblog check`` on many logs.  ``sweep`` (+ ``variants``): ``rblog sweep``.

May import anything in rblog; nothing in rblog imports this room except the CLI.
"""
