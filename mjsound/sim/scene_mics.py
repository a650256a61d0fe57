"""Where a scene's microphones are (``SoundScene.from_model(microphones=...)``).

Site names (the microphones follow their bodies), fixed world positions [m], or by default the
sites whose name starts with ``mic`` in model order, else one listener 1 m from the centre of
the sounding objects, 30 degrees above the horizon, towards -y (:func:`default_listener`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["place_microphones", "default_listener"]


def place_microphones(model, sounding: list, microphones=None) -> tuple[list, np.ndarray, list]:
    """The microphones of a scene: ``(site ids, positions (m, 3) at the initial state [m], names)``.

    Parameters
    ----------
    model : mujoco.MjModel
    sounding : list[SoundingGeom]
        The scene's sounding objects (the default listener looks at their centre).
    microphones : list[str] | (m, 3) array, optional
        Site names or fixed world positions [m]; None: the ``mic*`` sites, else the default
        listener. Site ids are empty for fixed positions.

    Raises
    ------
    ValueError
        A site name not in the model, or a position that is not finite.
    """
    import mujoco

    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    if microphones is None:
        ids = [s for s in range(model.nsite)
               if (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, s) or "").lower().startswith("mic")]
        if not ids:
            return [], np.asarray([default_listener(model, data, sounding)]), ["listener"]
    elif len(microphones) and isinstance(microphones[0], str):
        ids = []
        for name in microphones:
            sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
            if sid < 0:
                raise ValueError(f"microphone site {name!r} not in the model")
            ids.append(sid)
    else:
        pos = np.asarray(microphones, dtype=np.float64).reshape(-1, 3)
        if not np.isfinite(pos).all():
            raise ValueError("microphone positions must be finite")
        return [], pos, [f"mic{i}" for i in range(len(pos))]
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, s) for s in ids]
    return ids, np.array(data.site_xpos[ids], dtype=np.float64), names


def default_listener(model, data, sounding: list) -> np.ndarray:
    """1 m from the centre of the sounding objects (of the moving bodies when none sounds),
    30 degrees above the horizon, towards -y [m]."""
    if sounding:
        pts = np.array([data.geom_xpos[s.geom_id] for s in sounding])
    else:
        dyn = [b for b in range(1, model.nbody)]
        pts = np.array(data.xpos[dyn]) if dyn else np.zeros((1, 3))
    centre = pts.mean(axis=0) if len(pts) else np.zeros(3)
    return centre + np.array([0.0, -np.cos(np.pi / 6), np.sin(np.pi / 6)])
