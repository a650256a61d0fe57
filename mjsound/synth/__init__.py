"""Modal synthesis: resonator-bank kernels (numba), excitation, microphones and audio output.

* :class:`~mjsound.synth.synthesizer.Synthesizer`: objects + microphones -> pressure blocks [Pa]
* :mod:`~mjsound.synth.pulse`: Hertz contact time and the half-sine pulse spectrum
* :mod:`~mjsound.synth.output`: pressure -> full scale, streaming atomic WAV/FLAC writer
* :mod:`~mjsound.synth.events`: ``mjsound render-events EVENTS.json`` (offline rendering)

Attributes are imported lazily so that ``import mjsound.synth.output`` does not load numba.
"""

__all__ = ["Synthesizer", "hertz_contact_time", "half_sine_spectrum", "to_full_scale", "AudioWriter",
           "write_audio", "render_events"]

_WHERE = {
    "Synthesizer": "synthesizer",
    "hertz_contact_time": "pulse",
    "half_sine_spectrum": "pulse",
    "to_full_scale": "output",
    "AudioWriter": "output",
    "write_audio": "output",
    "render_events": "events",
}


def __getattr__(name):
    if name in _WHERE:
        import importlib

        return getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)
    raise AttributeError(f"module 'mjsound.synth' has no attribute {name!r}")
