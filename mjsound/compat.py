"""Opt-in fixes for upstream releases that break on the MuJoCo version pip installs.

Nothing here runs unless you call it. Each function patches one third-party package in the
running process only (no file is changed), is idempotent, and does nothing when the package
already works.

* :func:`patch_gymnasium_robotics` — gymnasium-robotics 1.4.2 with mujoco 4.0.0: Fetch and
  Shadow-hand envs fail in ``utils.mujoco_utils.set_joint_qpos`` with a bare
  ``AssertionError`` (``joint_type in (mjtJoint.mjJNT_HINGE, mjtJoint.mjJNT_SLIDE)`` is False
  for the ``np.int32`` that ``model.jnt_type[i]`` gives with mujoco 4's enums). The patch
  gives that module a view of ``mujoco`` whose ``mjtJoint`` members are plain ints.
* :func:`patch_dm_control` — dm_control 1.0.50 with mujoco 4.0.0: ``suite.load`` fails in
  ``Physics()`` with ``AttributeError: 'MjModel' object has no attribute 'flex_vertedge'``
  (its index lists fields mujoco 4 removed). The patch drops from dm_control's size table the
  fields this MuJoCo build does not have.

The tests of :mod:`mjsound.wrappers` and :mod:`mjsound.dmc` run the upstream envs through
these patches (``tests/conftest.py``).
"""

from __future__ import annotations

import types

__all__ = ["patch_gymnasium_robotics", "patch_dm_control"]


class _IntJointTypes:
    """``mujoco.mjtJoint`` with plain-int members (compare equal to ``np.int32``)."""

    def __init__(self, enum):
        for name in ("mjJNT_FREE", "mjJNT_BALL", "mjJNT_SLIDE", "mjJNT_HINGE"):
            setattr(self, name, int(getattr(enum, name)))


def patch_gymnasium_robotics() -> list:
    """Make gymnasium-robotics' joint helpers work with mujoco 4 (module docstring).

    Returns
    -------
    list[str]
        The patched module names (empty when gymnasium-robotics is not installed or already
        works).
    """
    try:
        from gymnasium_robotics.utils import mujoco_utils
    except ImportError:
        return []
    import mujoco
    import numpy as np

    if np.int32(int(mujoco.mjtJoint.mjJNT_HINGE)) in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
        return []  # this combination works as it is
    if isinstance(getattr(mujoco_utils, "mujoco", None), types.SimpleNamespace):
        return ["gymnasium_robotics.utils.mujoco_utils"]  # patched before
    view = types.SimpleNamespace(**{k: getattr(mujoco, k) for k in dir(mujoco) if not k.startswith("__")})
    view.mjtJoint = _IntJointTypes(mujoco.mjtJoint)
    mujoco_utils.mujoco = view
    return ["gymnasium_robotics.utils.mujoco_utils"]


def patch_dm_control() -> list:
    """Make ``dm_control.suite.load`` work with mujoco 4 (module docstring).

    Returns
    -------
    list[str]
        The ``struct.field`` names dropped from dm_control's index (empty when dm_control is
        not installed or already matches this MuJoCo build).
    """
    try:
        from dm_control.mujoco.wrapper.mjbindings import sizes
    except ImportError:
        return []
    import mujoco

    dropped = []
    for struct, cls in (("mjmodel", mujoco.MjModel), ("mjdata", mujoco.MjData)):
        table = sizes.array_sizes.get(struct, {})
        for field in list(table):
            if not hasattr(cls, field):
                del table[field]
                dropped.append(f"{struct}.{field}")
    return dropped
