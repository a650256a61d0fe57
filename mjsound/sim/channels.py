"""The output channels of a scene: its air microphones, then its contact microphones.

A contact microphone is a site (named ``contact_mic*``, or named by the caller) glued to its
body; its channel reads the body's surface acceleration along the site's z axis [m/s^2]
(:mod:`mjsound.synth.contact_mic`). Its modal part comes from the synthesizer
(:meth:`mjsound.synth.synthesizer.Synthesizer.add_contact_microphone`) and listens to the
sounding object of the site's body whose surface is nearest the site; a site on a body without
one hears only the body's rigid-body pulses (:mod:`.clicks`).

Channel order everywhere (simulator blocks, observations, files, rerun): the air microphones
in the scene's order, then the contact microphones in site order (or the order named).
"""

from __future__ import annotations

import numpy as np

from .clicks import ImpactPulses  # (the channels' pulses; the simulator imports both from here)

__all__ = ["ImpactPulses", "CONTACT_MIC_PREFIX", "contact_mic_sites", "channel_layout", "needs_pulses", "attach_contact_mics",
           "site_in_object_frame", "nearest_object"]

#: Sites whose name starts with this are contact microphones.
CONTACT_MIC_PREFIX = "contact_mic"


def contact_mic_sites(model, names=None) -> list[int]:
    """Site ids of the contact microphones: the sites named in ``names`` (in that order), or
    every site whose name starts with ``contact_mic`` (in model order).

    Raises
    ------
    ValueError
        For a name that is not a site of the model.
    """
    import mujoco

    if names is None:
        return [s for s in range(model.nsite)
                if (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, s) or "").startswith(CONTACT_MIC_PREFIX)]
    ids = []
    for name in ([names] if isinstance(names, str) else list(names)):
        sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, str(name))
        if sid < 0:
            raise ValueError(f"contact microphone site {name!r} is not in the model; add "
                             f"<site name=\"{name}\"/> to the body it is glued to")
        ids.append(sid)
    return ids


def site_in_object_frame(data, site: int, position, rotation) -> tuple[np.ndarray, np.ndarray]:
    """A contact microphone's point and sensing axis (its site's z axis) in the frame of an
    object at ``position`` / ``rotation`` (object to world) [m]: ``(point (3,), axis (3,))``."""
    R = np.asarray(rotation, dtype=np.float64).reshape(3, 3)
    p = np.asarray(data.site_xpos[site], dtype=np.float64) - np.asarray(position, dtype=np.float64)
    axis = np.asarray(data.site_xmat[site], dtype=np.float64).reshape(3, 3)[:, 2]
    return R.T @ p, R.T @ axis


def nearest_object(points_world: list, site_position) -> int:
    """Index of the surface sample set (each (p, 3) world points) nearest to a site; -1 if none."""
    best, which = np.inf, -1
    x = np.asarray(site_position, dtype=np.float64)
    for i, pts in enumerate(points_world):
        pts = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
        if len(pts):
            d = float(np.min(np.sum((pts - x) ** 2, axis=1)))
            if d < best:
                best, which = d, i
    return which


def channel_layout(model, scene, contact_mics=None) -> tuple[list[int], int, list[str], np.ndarray]:
    """``(contact sites, number of air channels, channel names, contact channels)`` of a
    scene: the air microphones (at least the default listener), then the contact microphones
    (:func:`contact_mic_sites` of ``contact_mics``)."""
    import mujoco

    sites = contact_mic_sites(model, contact_mics)
    n_air = max(1, len(scene.mic_positions))
    names = list(scene.mic_names)[:n_air] + [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, s) for s in sites]
    return sites, n_air, names, np.arange(n_air, len(names))


def needs_pulses(model, contact_sites, clicks: bool) -> bool:
    """Whether a scene's impacts make pulses: it has contact microphones, or clicks are on and
    some body can move."""
    return bool(contact_sites) or (bool(clicks) and bool(np.any(np.asarray(model.body_weldid)[1:] != 0)))


def attach_contact_mics(synth, scene, model, data, sites) -> None:
    """One synthesizer channel per contact microphone site (after the air ones), listening to
    the sounding object of the site's body nearest the site (none: a channel without modes)."""
    for s in sites:
        body = int(model.site_bodyid[s])
        cands = [o for o in scene.sounding if synth.n_modes(o.name) and int(o.body_id) == body]
        k = nearest_object([synth.object_points_world(o.name) for o in cands], data.site_xpos[s])
        if k < 0:
            synth.add_contact_microphone(None, np.zeros(3), [0.0, 0.0, 1.0])
            continue
        pos, R = synth.object_pose(cands[k].name)
        point, axis = site_in_object_frame(data, s, pos, R)
        synth.add_contact_microphone(cands[k].name, point, axis)
