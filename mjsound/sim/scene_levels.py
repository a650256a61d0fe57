r"""How loud each sounding object is at the scene's microphones: its loudest mode for a
reference tap (``SoundScene.report``, ``SoundScene.summary``).

The reference tap: a 10 g steel ball arriving at 1 m/s on a flat of the object and stopping,
``J = 0.01`` N s, its force a half sine lasting Hertz's contact time ``tau``
(:func:`mjsound.synth.pulse.hertz_contact_time`, the object's mass and material). A normal
impulse at a surface point ``x`` with normal ``n`` sets each mode (mass-normalised shape
``phi_i``) moving at ``dq_i/dt = J phi_i(x).n``; the pulse's spectrum ``S(omega tau)``
(:func:`mjsound.synth.pulse.half_sine_spectrum`, 1 for a short pulse) scales what each mode
takes, so that it rings as

.. math::

    q_i(t) = \frac{J\, |S(\omega_i \tau)|\, \phi_i(x) \cdot n}{\omega_i} e^{-d_i t} \sin \omega_i t ,

and a microphone at distance ``r`` in direction ``u`` (the object's frame, from its
radiation centre) hears, in the far field, the amplitude

.. math::

    p_i = \frac{|F_i(u)|\, J\, |S(\omega_i \tau)|\, |\phi_i(x) \cdot n|}{\omega_i\, r},

``F_i`` the mode's far-field pattern (:meth:`mjsound.modal.ModalModel.radiation_pattern`, Pa m
per unit modal coordinate). Tapped where it rings most (its largest ``|phi_i . n|`` over the
surface samples), the loudest mode of each object at each microphone is what a listener
balances objects by: a table that drowns a cup, a bar that is 30 dB under everything else.
Free field, the initial pose (``qpos0``), no floor or room: a level to compare objects by, not
a prediction of a run (the impacts' own strengths, contact durations and the coupling to
the contact decide those).
"""

from __future__ import annotations

import math

import numpy as np

from ..synth.constants import P_REF_PA, R_MIN_M  # (R_MIN_M: the synthesizer's least distance for 1/r)

__all__ = ["REFERENCE_TAP_NS", "P_REF_PA", "loudest_modes"]

#: The reference tap [N s]: a 10 g steel ball arriving at 1 m/s and stopping.
REFERENCE_TAP_NS = 0.01
TAP_MASS_KG, TAP_SPEED_M_S = 0.01, 1.0



def loudest_modes(scene) -> list[list[dict]]:
    """Each sounding object's loudest mode at each microphone for the reference tap.

    Parameters
    ----------
    scene : mjsound.sim.SoundScene

    Returns
    -------
    list (one per ``scene.sounding``) of lists (one per microphone) of dicts:
    ``mic`` (name), ``distance_m``, ``frequency_hz``, ``pressure_pa`` (the mode's amplitude
    [Pa]), ``spl_db`` (its RMS, ``p / sqrt 2``, in dB re 20 uPa; None when it is silent there), ``contact_s`` (the tap's
    ``tau``); an empty list for an object with no mode or no surface samples.

    Examples
    --------
    >>> scene = SoundScene.from_model("assets/demo_scene.xml")     # doctest: +SKIP
    >>> loudest_modes(scene)[0][0]["spl_db"]   # the table at the first microphone  # doctest: +SKIP
    """
    import mujoco

    from ..materials import get_material
    from ..synth.pulse import half_sine_spectrum, hertz_contact_time

    steel = get_material("steel")
    ball_radius = (3 * TAP_MASS_KG / (4 * np.pi * steel.rho)) ** (1 / 3)
    model = scene.model
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)  # (the pose the microphones were placed at)
    mics = np.asarray(scene.mic_positions, np.float64).reshape(-1, 3)
    out = []
    for s in scene.sounding:
        mm = s.model
        if mm.n_modes == 0 or len(mm.points) == 0:
            out.append([])
            continue
        R = np.asarray(data.geom_xmat[s.geom_id], np.float64).reshape(3, 3)
        centre = np.zeros(3) if mm.radiation_centre is None else np.asarray(mm.radiation_centre, np.float64)
        world_centre = np.asarray(data.geom_xpos[s.geom_id], np.float64) + R @ centre
        to_mic = (mics - world_centre) @ R  # (m, 3) in the object's frame
        norm = np.linalg.norm(to_mic, axis=1)
        dist = np.maximum(norm, R_MIN_M)
        away = np.where(norm[:, None] > 0, to_mic, [0.0, 0.0, 1.0])  # (a microphone at the centre: any)
        F = np.abs(mm.radiation_pattern(away))  # (m, n)
        phi_n = np.einsum("pcn,pc->pn", mm.shapes.astype(np.float64), mm.normals.astype(np.float64))
        antinode = np.abs(phi_n).max(axis=0)  # (n,)
        omega = 2 * np.pi * np.asarray(mm.frequencies_hz, np.float64)
        mass = float(mm.mass_kg) if mm.mass_kg > 0 else np.inf
        tau = hertz_contact_time(TAP_MASS_KG, mass, ball_radius, np.inf, steel, s.material, TAP_SPEED_M_S)
        taken = REFERENCE_TAP_NS * np.abs(half_sine_spectrum(omega, tau)) * antinode  # (n,) [m/s sqrt(kg)]
        with np.errstate(divide="ignore", invalid="ignore"):
            p = np.where(omega > 0, F * taken / (omega * dist[:, None]), 0.0)  # (m, n)
        rows = []
        for k, name in enumerate(scene.mic_names):
            i = int(np.argmax(p[k]))
            amp = float(p[k, i])
            rows.append(dict(mic=name, distance_m=float(dist[k]), frequency_hz=float(mm.frequencies_hz[i]),
                             pressure_pa=amp, contact_s=float(tau),
                             spl_db=20 * math.log10(amp / math.sqrt(2) / P_REF_PA) if amp > 0 else None))
        out.append(rows)
    return out
