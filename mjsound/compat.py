"""Opt-in fixes for upstream releases that break on the MuJoCo version pip installs.

Nothing here runs unless you call it. Each function patches one third-party package in the
running process only (no file is changed), is idempotent, and does nothing when the package
is not installed or already works. Each returns what it patched (empty: nothing to do).

* :func:`patch_gymnasium_robotics` — gymnasium-robotics 1.4.2 with mujoco 4: Fetch and
  Shadow-hand envs fail in ``utils.mujoco_utils.set_joint_qpos`` with a bare
  ``AssertionError`` (``joint_type in (mjtJoint.mjJNT_HINGE, mjtJoint.mjJNT_SLIDE)`` is False
  for the ``np.int32`` that ``model.jnt_type[i]`` gives with mujoco 4's enums). The patch
  gives that module a view of ``mujoco`` whose ``mjtJoint`` members are plain ints.
* :func:`patch_dm_control` — dm_control 1.0.50 with mujoco 4.0.0: ``suite.load`` fails in
  ``Physics()`` with ``AttributeError: 'MjModel' object has no attribute 'flex_vertedge'``
  (its index lists fields mujoco 4 removed). The patch drops from dm_control's size table the
  fields this MuJoCo build does not have (dm_control 1.0.52 needs nothing).
* :func:`patch_metaworld` — Meta-World 3.0.0 with mujoco 4: every Sawyer env fails at
  construction in ``SawyerMocapBase.reset_mocap_welds`` with ``ValueError: could not
  broadcast input array from shape (11,) into shape (12,)``: a weld's ``eq_data`` row has 12
  numbers in mujoco 4 (``mjNEQDATA``), the 12th a flag that the relative pose (numbers 3-9) is
  recomputed from ``qpos0`` by ``mj_setConst`` (1) or given (0). The patched method writes
  Meta-World's 11 numbers (anchor 0, relative pose 0 with quaternion (-1, 0, 0, 0), torque
  scale 5) and the flag 0: the pose is given, as Meta-World means.
* :func:`patch_robosuite` — robosuite 1.5.2 with mujoco 4: ``suite.make`` fails in
  ``utils.binding_utils.MjModel.get_joint_qpos_addr`` with a bare ``AssertionError`` (the
  joint-enum comparison above), and every controller update then fails reading
  ``MjData.qM``: mujoco 4 stores the sparse inertia as ``MjData.M`` and ``mj_fullM`` takes
  ``(model, data, dst)`` instead of ``(model, dst, qM)``. The patch gives
  ``binding_utils`` the int-joint view, gives robosuite's ``MjData`` wrapper a ``qM`` that
  stands for its ``mujoco.MjData``, and gives ``controllers.parts.controller`` an
  ``mj_fullM`` that accepts the old argument order.

The tests of the env wrappers run the upstream envs through these patches
(``tests/conftest.py``); ``docs/envs.md`` gives each family's route.

Example
-------
>>> from mjsound.compat import patch_metaworld                      # doctest: +SKIP
>>> patch_metaworld()     # ['metaworld.sawyer_xyz_env.SawyerMocapBase.reset_mocap_welds']  # doctest: +SKIP
>>> env = gym.make("Meta-World/MT1", env_name="pick-place-v3")     # doctest: +SKIP
"""

from __future__ import annotations

import types

__all__ = ["patch_gymnasium_robotics", "patch_dm_control", "patch_metaworld", "patch_robosuite"]


class _IntJointTypes:
    """``mujoco.mjtJoint`` with plain-int members (compare equal to ``np.int32``)."""

    def __init__(self, enum):
        for name in ("mjJNT_FREE", "mjJNT_BALL", "mjJNT_SLIDE", "mjJNT_HINGE"):
            setattr(self, name, int(getattr(enum, name)))


def _joint_enum_works() -> bool:
    """Whether ``np.int32(jnt_type) in (mjtJoint.mjJNT_HINGE, mjtJoint.mjJNT_SLIDE)`` holds
    with this MuJoCo build (False with mujoco 4's enums)."""
    import mujoco
    import numpy as np

    return np.int32(int(mujoco.mjtJoint.mjJNT_HINGE)) in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE)


def _mujoco_view(**replaced) -> types.SimpleNamespace:
    """A stand-in for the ``mujoco`` module (every public name) with ``replaced`` names and
    plain-int ``mjtJoint`` members, for one patched module's global ``mujoco``."""
    import mujoco

    view = types.SimpleNamespace(**{k: getattr(mujoco, k) for k in dir(mujoco) if not k.startswith("__")})
    view.mjtJoint = _IntJointTypes(mujoco.mjtJoint)
    for name, value in replaced.items():
        setattr(view, name, value)
    return view


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
    if _joint_enum_works():
        return []  # this combination works as it is
    if not isinstance(getattr(mujoco_utils, "mujoco", None), types.SimpleNamespace):
        mujoco_utils.mujoco = _mujoco_view()
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


# Meta-World 3.0.0's weld data (sawyer_xyz_env.SawyerMocapBase.reset_mocap_welds): anchor (3),
# relative position (3), relative quaternion (4), torque scale (1)
_METAWORLD_WELD = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 5.0)


def _reset_mocap_welds(self) -> None:
    """Meta-World's ``reset_mocap_welds`` for any ``eq_data`` row length: its 11 numbers,
    then zeros (mujoco 4's 12th number 0: the relative pose is given, not recomputed)."""
    import mujoco
    import numpy as np

    model = self.model
    if model.nmocap > 0 and model.eq_data is not None:
        row = np.zeros(model.eq_data.shape[1])
        row[:len(_METAWORLD_WELD)] = _METAWORLD_WELD
        for i in range(model.eq_data.shape[0]):
            if model.eq_type[i] == mujoco.mjtEq.mjEQ_WELD:
                model.eq_data[i] = row


def patch_metaworld() -> list:
    """Make Meta-World's Sawyer envs construct with mujoco 4 (module docstring).

    Returns
    -------
    list[str]
        The patched method (empty when Meta-World is not installed or this MuJoCo build has
        Meta-World's 11 weld numbers).
    """
    try:
        from metaworld.sawyer_xyz_env import SawyerMocapBase
    except ImportError:
        return []
    import mujoco

    if getattr(mujoco, "mjNEQDATA", 11) == len(_METAWORLD_WELD):
        return []  # eq_data rows of 11: Meta-World's own method works
    SawyerMocapBase.reset_mocap_welds = _reset_mocap_welds
    return ["metaworld.sawyer_xyz_env.SawyerMocapBase.reset_mocap_welds"]


def _full_inertia(model, dst_or_data, qm_or_dst):
    """``mujoco.mj_fullM`` taking robosuite's mujoco-3 order ``(model, dst, qM)`` (``qM``
    being the ``mujoco.MjData`` that robosuite's patched ``MjData.qM`` gives) as well as
    mujoco 4's ``(model, data, dst)``."""
    import mujoco

    if isinstance(qm_or_dst, mujoco.MjData):
        return mujoco.mj_fullM(model, qm_or_dst, dst_or_data)
    return mujoco.mj_fullM(model, dst_or_data, qm_or_dst)


def patch_robosuite() -> list:
    """Make robosuite 1.5's environments and controllers run with mujoco 4 (module docstring).

    Returns
    -------
    list[str]
        The patched names (empty when robosuite is not installed or this MuJoCo build has the
        joint enums and ``MjData.qM`` robosuite expects).
    """
    try:
        from robosuite.controllers.parts import controller
        from robosuite.utils import binding_utils
    except ImportError:
        return []
    import mujoco

    patched = []
    if not _joint_enum_works():
        if not isinstance(getattr(binding_utils, "mujoco", None), types.SimpleNamespace):
            binding_utils.mujoco = _mujoco_view()
        patched.append("robosuite.utils.binding_utils")
    if not hasattr(mujoco.MjData, "qM"):
        if not isinstance(getattr(controller, "mujoco", None), types.SimpleNamespace):
            controller.mujoco = _mujoco_view(mj_fullM=_full_inertia)
        # (a class attribute: the wrapper's metaclass made one property per mujoco.MjData field)
        binding_utils.MjData.qM = property(lambda self: self._data, doc="The mujoco.MjData, for mj_fullM (mjsound.compat)")
        patched += ["robosuite.controllers.parts.controller.mujoco.mj_fullM", "robosuite.utils.binding_utils.MjData.qM"]
    return patched
