"""rblog.adapters: record a run of another engine's own model into the log contract, in two lines.

* ``mujoco``: :func:`~rblog.adapters.mujoco.recorder` (a
  :class:`~rblog.adapters.mujoco.MujocoRecorder`) takes an ``MjModel`` as shipped (and the
  ``MjData`` the user steps) and writes contract v3: every body (free, on joints, mocap, static)
  in its inertial frame, its joints, every geom (meshes with their vertices); called after each
  ``mj_step`` it accumulates the step's impulses per body (contact, applied, passive, actuator,
  joint: ``mj_rnePostConstraint``) and every ``every``-th step logs a sample with the contacts.
  :func:`~rblog.adapters.mujoco.record_rollout` records the output of ``mujoco.rollout`` (no
  contacts, impulses marked missing).
* ``pybullet``: :class:`~rblog.adapters.pybullet.PybulletRecorder` records every base and link of
  a client's bodies (multibodies on their joints; maximal coordinates as far as pybullet shows
  them), every collision shape, and per step the contact, damping, applied and joint impulses;
  ``rec()`` after each ``stepSimulation``, a sample every ``every`` steps.

Geoms the contract has no shape for (capsules, cylinders, meshes, several geoms on one body) are
recorded with ``body_shape = SHAPE_NONE`` (-1) and their inertia; restitution the engine does not
state (MuJoCo has none: its bounce comes from solref) is recorded as NaN, "unknown".

The engines stay optional: each module imports its engine inside its functions and raises
:class:`AdapterError` (one line, exit code 2) when it is missing.

May import: ``contract`` and ``record`` (and numpy); ``rblog.study.engines`` (``rblog run --engine``)
uses these adapters for its translation of the engines' conventions.
"""

from __future__ import annotations

from rblog.errors import RblogError, AdapterError


def require(module: str, extra: str = "engines"):
    """Import ``module`` or raise a one-line AdapterError saying how to install it."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as e:
        raise AdapterError(f"rblog.adapters.{module} needs the {module} package, which is not "
                           f"installed ({e}): pip install {module} (in a checkout: pip install -e "
                           f"\".[{extra}]\")") from None


__all__ = ["AdapterError", "require"]
