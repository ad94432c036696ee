"""dm_control's suite models as shipped, as ``mujoco.MjModel`` (the MJCF files and assets inside
the dm_control package; the ``models`` extra)."""

from __future__ import annotations

from rblog.adapters import AdapterError, require
from rblog.adapters._mujoco_model import _mj


#: dm_control suite models whose XML needs its module's own builder (as its tasks load them)
_SUITE_BUILDERS = {"stacker": ("stacker", dict(n_boxes=4)),
                   "manipulator": ("manipulator", dict(use_peg=False, insert=False)),
                   "quadruped": ("quadruped", dict(floor_size=10))}


def suite_model(name: str):
    """The ``mujoco.MjModel`` of dm_control's suite model ``name`` as shipped (the MJCF files and
    assets inside the dm_control package: ``humanoid``, ``cartpole``, ``walker``, ...;
    ``stacker`` with its 4 boxes, ``manipulator`` as in ``bring_ball``); needs the ``models``
    extra (dm-control)."""
    import importlib
    import warnings

    mj = _mj()
    require("dm_control", extra="models")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # GLFW: no display
        module, kwargs = _SUITE_BUILDERS.get(name, (name, None))
        try:
            mod = importlib.import_module(f"dm_control.suite.{module}")
        except ImportError:
            raise AdapterError(f"suite_model: dm_control.suite has no model {name!r}") from None
        got = mod.make_model(**kwargs) if kwargs is not None else mod.get_model_and_assets()
    if isinstance(got, (str, bytes)):  # quadruped's builder returns the XML alone
        from dm_control.suite import common

        got = (got, common.ASSETS)
    return mj.MjModel.from_xml_string(*got)
