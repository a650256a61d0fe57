"""``mjsound/PalmDrop-v0``: feel what fell into the palm, through a contact microphone.

Task
----
A robot's palm, an aluminium plate (0.16 x 0.12 x 0.004 m) held still, carries a contact
microphone on its underside (site ``contact_mic_plate``). At every reset a ball (r = 1 cm) is
given one of ``materials`` (default steel, ABS, rubber, uniformly at random) and released at
rest 2-6 cm above a random point of the plate. Its mass and inertia are fixed in the MJCF
(30 g) and the contact parameters do not depend on the material, so the motion - and the whole
state vector - is the same for every material. What differs is how the impact drives the plate:
the Hertz contact time (about 20 us for steel, 0.2 ms for ABS, 15 ms for rubber on aluminium)
and the restitution. The observation is the contact microphone alone: the plate's surface
acceleration, which hears nothing through the air.

Spaces
------
action : ``Discrete(1 + K)``. ``0`` listens for one step (``dt = 0.02 s`` = 20 physics steps of
    1 ms); ``k >= 1`` answers material ``k - 1`` (``env.unwrapped.materials[k - 1]``) and ends
    the episode.
observation : ``Dict``
    ``"audio"``: float32 ``(1, window)`` waveform of the contact microphone in full-scale units
    (``full_scale`` m/s^2 -> 1, default 50 000: a steel ball makes the plate peak near
    30 000), default window one step (320 samples at 16 kHz), or ``log1p(|STFT|)`` with
    ``mode="spectrogram"``; ``"state"``: float64 ``(13,)``, the
    ball's free-joint ``qpos`` (7) and ``qvel`` (6).

Reward
------
``+1`` for the right material, ``0`` for a wrong one or for listening. Truncated after 30
steps by the registration. Chance: ``1 / K``.

Info
----
``material`` (the true name, for evaluation only) and the audio keys (``audio_clipped``,
``audio_peak_pa`` (here the peak acceleration [m/s^2]), ``audio_samples``, ``audio_impacts``).

Options
-------
``reset(options={"material": name_or_index})`` fixes the material.
"""

from __future__ import annotations

import numpy as np

from mjsound.modal.model import ModalModel
from mjsound.materials import get_material

from .assets import asset_path
from .base import NameTheMaterialEnv, modal_model

__all__ = ["PalmDropEnv", "PALM_MATERIALS", "PLATE_SPEC", "PLATE_ANALYSIS"]

PALM_MATERIALS = ("steel", "abs", "rubber")
#: Built-in spec of the plate geom and its analysis (quadratic hex cells, draft).
PLATE_SPEC = "box:0.16,0.12,0.004"
PLATE_ANALYSIS = {"quality": "draft", "error_estimate": False}
PLATE_TOP = 0.2 + 0.002


def _silent_ball(material: str) -> ModalModel:
    """The ball sounds through the plate only: a model without modes that carries its
    material (for the Hertz contact time and the restitution) and its mass."""
    return ModalModel(np.zeros(0), np.zeros(0), np.zeros((1, 3)), [[0.0, 0.0, 1.0]], np.zeros((1, 3, 0)), np.zeros(0),
                      get_material(material), method="none", mass_kg=0.03)


class PalmDropEnv(NameTheMaterialEnv):
    metadata = {"render_modes": ["human", "rgb_array", "depth_array"], "render_fps": 50}
    listen_to = "contact"

    def __init__(self, materials=PALM_MATERIALS, sample_rate: int = 16000, window_s: float | None = None,
                 mode: str = "waveform", n_fft: int = 256, hop: int | None = None, full_scale: float = 50000.0,
                 render_mode=None, **kw):
        for m in materials:
            get_material(m)  # (names the bad one)
        super().__init__(asset_path("palm_drop.xml"), materials, "PalmDrop", sample_rate=sample_rate,
                         window_s=window_s, mode=mode, n_fft=n_fft, hop=hop, full_scale_pa=full_scale,
                         render_mode=render_mode, **kw)

    def _variant_scene(self, k):
        plate = modal_model(PLATE_SPEC, "aluminium", self.sample_rate, **PLATE_ANALYSIS)
        return {"ball": self.materials[k]}, {"plate": plate, "ball": _silent_ball(self.materials[k])}

    def reset_model(self):
        k = self._pick_material()
        rng = self.np_random
        qpos = self.init_qpos.copy()
        qpos[:3] = [rng.uniform(-0.05, 0.05), rng.uniform(-0.035, 0.035), PLATE_TOP + 0.01 + rng.uniform(0.02, 0.06)]
        qpos[3:7] = [1.0, 0.0, 0.0, 0.0]
        self.set_state(qpos, np.zeros(self.model.nv))
        self._use_variant(k)
        return self._obs()
