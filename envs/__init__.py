"""Gymnasium environments in which sound carries information the state vector does not.

Importing this package registers them::

    import gymnasium as gym
    import envs  # noqa: F401  (or gym.make("envs:mjsound/MaterialDrop-v0"))
    env = gym.make("mjsound/MaterialDrop-v0")

- ``mjsound/MaterialDrop-v0`` (:mod:`envs.material_drop`): name the material of a dropped bar.
- ``mjsound/TapContainers-v0`` (:mod:`envs.tap_containers`): tap three identical sealed
  containers and find the one holding a heavy block.
- ``mjsound/PalmDrop-v0`` (:mod:`envs.palm_drop`): name the material of a ball dropped on a
  plate from the plate's contact microphone alone.

All take ``sample_rate`` (16 kHz), ``window_s``, ``mode`` (``"waveform"`` |
``"spectrogram"``), ``n_fft``, ``hop`` and ``full_scale_pa`` (PalmDrop: ``full_scale`` [m/s^2]) like
:class:`mjsound.wrappers.AudioObservation`. MJCF: ``assets/envs/`` (scripts/make_env_assets.py).
"""

from gymnasium.envs.registration import register, registry

__all__ = ["ENV_IDS"]

ENV_IDS = ("mjsound/MaterialDrop-v0", "mjsound/TapContainers-v0", "mjsound/PalmDrop-v0")

_ENTRIES = {
    "mjsound/MaterialDrop-v0": ("envs.material_drop:MaterialDropEnv", 40),
    "mjsound/TapContainers-v0": ("envs.tap_containers:TapContainersEnv", 12),
    "mjsound/PalmDrop-v0": ("envs.palm_drop:PalmDropEnv", 30),
}

for _id, (_entry, _steps) in _ENTRIES.items():
    if _id not in registry:
        register(id=_id, entry_point=_entry, max_episode_steps=_steps)
