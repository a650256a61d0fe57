"""``mjsound/MaterialDrop-v0``: name the material of a dropped bar from its sound.

Task
----
At every reset a bar (0.2 x 0.03 x 0.02 m) is given one of ``materials`` (default steel,
brass, oak, ABS, uniformly at random) and released at rest from a random height (bottom
0.08-0.30 m above the floor) and orientation (any yaw, roll and pitch within +-20 degrees). Its
mass and inertia are fixed in the MJCF (0.3 kg), and the contact parameters do not depend on
the material, so the motion - and the whole state vector - is the same for every material:
only the sound (modal frequencies and damping of the bar, from ``mjsound.analyze``) tells
them apart. One microphone (site ``mic0``) 0.5 m from the drop point.

Spaces
------
action : ``Discrete(1 + K)``. ``0`` listens for one step (``dt = 0.02 s`` = 20 physics steps of
    1 ms); ``k >= 1`` answers material ``k - 1`` (``env.unwrapped.materials[k - 1]``) and ends
    the episode.
observation : ``Dict``
    ``"audio"``: float32 ``(1, window)`` waveform in full-scale units (20 Pa -> 1), default
    window one step (320 samples at 16 kHz), or ``(1, freq, time)`` ``log1p(|STFT|)`` with
    ``mode="spectrogram"`` (see :class:`mjsound.wrappers.AudioObservation`);
    ``"state"``: float64 ``(13,)``, the bar's free-joint ``qpos`` (7) and ``qvel`` (6).

Reward
------
``+1`` for the right material, ``0`` for a wrong one or for listening. Episodes are truncated
after 40 steps (0.8 s) by the registration's ``max_episode_steps``. Chance: ``1 / K``.

Info
----
``material`` (the true name, for evaluation only: a policy must not read it), and the audio
keys of :class:`mjsound.wrappers.AudioObservation` (``audio_clipped``, ``audio_peak_pa``,
``audio_samples``, ``audio_impacts``).

Options
-------
``reset(options={"material": name_or_index})`` fixes the material (calibration, tests).
"""

from __future__ import annotations

import numpy as np

from .assets import asset_path
from .base import NameTheMaterialEnv, modal_model

__all__ = ["MaterialDropEnv", "DEFAULT_MATERIALS", "BAR_SPEC"]

DEFAULT_MATERIALS = ("steel", "brass", "oak", "abs")
#: Built-in spec of the bar geom (what SoundScene would analyse for it).
BAR_SPEC = "box:0.2,0.03,0.02"


class MaterialDropEnv(NameTheMaterialEnv):
    metadata = {"render_modes": ["human", "rgb_array", "depth_array"], "render_fps": 50}

    def __init__(self, materials=DEFAULT_MATERIALS, sample_rate: int = 16000, window_s: float | None = None,
                 mode: str = "waveform", n_fft: int = 256, hop: int | None = None, full_scale_pa: float = 20.0,
                 quality: str = "draft", render_mode=None, **kw):
        self.quality = quality
        super().__init__(asset_path("material_drop.xml"), materials, "MaterialDrop", sample_rate=sample_rate,
                         window_s=window_s, mode=mode, n_fft=n_fft, hop=hop, full_scale_pa=full_scale_pa,
                         render_mode=render_mode, **kw)

    def _variant_scene(self, k):
        mat = self.materials[k]
        mm = modal_model(BAR_SPEC, mat, self.sample_rate, quality=self.quality, error_estimate=False)
        return {"bar": mat}, {"bar": mm}

    def reset_model(self):
        k = self._pick_material()
        rng = self.np_random
        yaw = rng.uniform(-np.pi, np.pi)
        roll, pitch = np.radians(rng.uniform(-20, 20, size=2))
        quat = _euler_quat(roll, pitch, yaw)
        qpos = self.init_qpos.copy()
        qpos[:3] = [0.0, 0.0, 0.10 + rng.uniform(0.08, 0.30)]  # half-diagonal ~0.1 m: clear of the floor
        qpos[3:7] = quat
        self.set_state(qpos, np.zeros(self.model.nv))
        self._use_variant(k)
        return self._obs()


def _euler_quat(roll, pitch, yaw) -> np.ndarray:
    cr, sr = np.cos(roll / 2), np.sin(roll / 2)
    cp, sp = np.cos(pitch / 2), np.sin(pitch / 2)
    cy, sy = np.cos(yaw / 2), np.sin(yaw / 2)
    return np.array([cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                     cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy])
