"""Hear a scene live: MuJoCo's viewer on it and its sound on an audio device (``mjsound view``).

:func:`view` simulates an MJCF scene in blocks of ``render_block_s`` (10 ms), sends each
block's air-microphone audio to a :class:`mjsound.live.LivePlayer` and shows the state in
``mujoco.viewer.launch_passive`` about 60 times a second; what the user does in the viewer
(dragging a body with Ctrl + right mouse) is applied at each sync and heard with the next
block. The player paces the loop: the simulation runs at most ``lead_s`` ahead of what the
device plays, so it keeps to the wall clock and each sound is heard ``lead_s`` plus the
device's latency after the simulation made it.

Order matters on start and end (measured, docs/live.md): the audio stream opens after the
viewer's window (opened before, its first block underran), and the viewer's thread is joined
before returning (a process that exits while it tears down may crash).
"""

from __future__ import annotations

import os
import sys
import threading
import time

import numpy as np

from .live import LiveAudioError, LivePlayer, check_output_device, open_sounddevice, output_channels

__all__ = ["view", "open_scene", "check_display", "launch_viewer", "close_viewer"]

SYNC_S = 1.0 / 60.0
"""How often the viewer is synced with the simulation [s]."""


def check_display() -> None:
    """Raise :class:`LiveAudioError` naming the fix when MuJoCo's viewer cannot open a window
    (no display, GLFW unusable); the viewer itself would wait forever on a failed start."""
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise LiveAudioError("no display for MuJoCo's viewer ($DISPLAY is not set): run under a virtual one "
                             "(xvfb-run -a mjsound view ...), or listen without the viewer (--no-viewer)")
    try:
        import glfw
    except ImportError as exc:  # (mujoco depends on glfw; a broken install)
        raise ImportError(f"MuJoCo's viewer needs the glfw package: pip install glfw ({exc})") from None
    if not glfw.init():
        raise LiveAudioError(f"MuJoCo's viewer cannot open a window on display {os.environ.get('DISPLAY', '')!r} "
                             "(GLFW failed to initialise): check the display, run under xvfb-run -a, or pass --no-viewer")
    glfw.terminate()


def launch_viewer(model, data):
    """``mujoco.viewer.launch_passive(model, data)`` after :func:`check_display`."""
    check_display()
    import mujoco.viewer

    try:
        return mujoco.viewer.launch_passive(model, data)
    except RuntimeError as exc:  # (macOS: needs mjpython)
        raise LiveAudioError(f"MuJoCo's viewer: {exc} (on macOS run `mjpython -m mjsound.cli view ...`)") from None


def close_viewer(handle) -> None:
    """Close the viewer and wait for its thread to end (Python names it after its target,
    ``Thread-N (_launch_internal)``)."""
    handle.close()
    for t in threading.enumerate():
        if t is not threading.current_thread() and "(_launch_internal)" in t.name:
            t.join(10.0)


def open_scene(scene_xml, *, sample_rate: int = 48000, quality: str = "default", materials=None,
               budget_modes: int | None = None, timestep: float | None = None, progress: bool = True):
    """The simulator :func:`view` runs: the scene at its first keyframe (when it has one), and
    the channels a listener hears (:func:`mjsound.live.output_channels`).

    Parameters are :func:`view`'s. Returns ``(sim, heard)``: the
    :class:`mjsound.sim.AudioSimulator` (``sim.model``, ``sim.data``) and the list of channels.

    Example
    -------
    >>> sim, heard = open_scene("assets/demo_scene.xml")              # doctest: +SKIP
    >>> frames = sim.advance(sim.steps_per_render)[heard] / 20.0      # doctest: +SKIP
    """
    import mujoco

    from .limits import check_timestep
    from .sim.rollout import load_materials
    from .sim.scene import SoundScene
    from .sim.simulator import AudioSimulator

    model = mujoco.MjModel.from_xml_path(os.fspath(scene_xml))
    if timestep is not None:
        model.opt.timestep = timestep
    check_timestep(model.opt.timestep, f"{os.fspath(scene_xml)}: <option timestep>")
    data = mujoco.MjData(model)
    if model.nkey > 0:
        mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    scene = SoundScene.from_model(model, materials=load_materials(materials), sample_rate=sample_rate,
                                  quality=quality, budget_modes=budget_modes, progress=progress)
    sim = AudioSimulator(model, data, scene=scene, sample_rate=sample_rate, keep_events=0)
    return sim, output_channels(sim.n_channels, sim.contact_channels)


def view(scene_xml, *, duration: float | None = None, device=None, viewer: bool = True, sample_rate: int = 48000,
         full_scale_pa: float = 20.0, lead_s: float = 0.05, device_latency_s: float | None = None,
         quality: str = "default", materials=None, budget_modes: int | None = None, timestep: float | None = None, progress: bool = True,
         on_block=None, on_timing=None) -> dict:
    """Simulate ``scene_xml`` in real time, shown in MuJoCo's viewer and heard on ``device``.

    Parameters
    ----------
    scene_xml : str | os.PathLike
        MJCF scene (its first keyframe, when it has one, is the start).
    duration : float, optional
        Simulated seconds to run; None: until the viewer is closed (or Ctrl-C).
    device : str | int | None
        Audio output device (None: the default).
    viewer : bool
        Open MuJoCo's viewer (False: audio only; needs ``duration`` or Ctrl-C to end).
    sample_rate : int
        Audio sample rate [Hz].
    full_scale_pa : float
        Pressure played at the device's full scale [Pa] (louder samples are clipped, counted).
    lead_s : float
        How far the simulation may run ahead of what is played [s] (:class:`LivePlayer`).
    device_latency_s : float, optional
        Latency asked of the audio device [s] (None: PortAudio's default).
    quality, materials, budget_modes, timestep
        As for ``mjsound sonify``.
    on_block : callable, optional
        ``on_block(frames)`` with each block sent to the device, ``(channels, n)`` float32 in
        full-scale units (e.g. to keep a copy).
    on_timing : callable, optional
        ``on_timing(timing)`` with the player's :meth:`LivePlayer.timing` at the end.

    Returns
    -------
    dict
        The player's :meth:`LivePlayer.stats` plus ``sim_seconds`` (simulated),
        ``wall_seconds`` (from the push of simulated time ``2 lead_s``, when the ring is full,
        to the last), ``pace`` (simulated seconds per wall second between them: 1 when paced
        to the wall clock),
        ``channels`` (the microphones heard).
    """
    from .limits import check_duration
    from .sim.warmup import warmup

    fsp = float(full_scale_pa)
    if not (np.isfinite(fsp) and fsp > 0):
        raise ValueError(f"full_scale_pa={full_scale_pa!r} must be a positive pressure in Pa (e.g. 20)")
    if duration is not None:
        duration = check_duration(duration, "--duration")
    elif not viewer:
        raise ValueError("without the viewer nothing ends the run: give --duration S")
    open_sounddevice()  # (errors before the analysis: sounddevice or PortAudio missing, no display, no device)
    if viewer:
        check_display()
    check_output_device(device, sample_rate)
    sim, heard = open_scene(scene_xml, sample_rate=sample_rate, quality=quality, materials=materials,
                            budget_modes=budget_modes, timestep=timestep, progress=progress)
    model, data = sim.model, sim.data
    warmup(verbose=False, once=True)  # (a cold numba cache compiles now, not while playing)
    every = sim.steps_per_render
    total = None if duration is None else int(round(duration / float(model.opt.timestep)))
    handle = launch_viewer(model, data) if viewer else None
    player = LivePlayer(sim.sample_rate, len(heard), device=device, lead_s=lead_s, device_latency_s=device_latency_s)
    steps = 0
    paced = []  # (wall time after a push [s], steps simulated by then)
    drain = False
    try:
        player.start()  # (after the viewer's window: opened before it, the first block underran)
        last_sync = time.monotonic()
        while (total is None or steps < total) and (handle is None or handle.is_running()):
            n = every if total is None else min(every, total - steps)
            if handle is not None:
                with handle.lock():
                    block = sim.advance(n)
            else:
                block = sim.advance(n)
            steps += n
            frames = block[heard] * np.float32(1.0 / fsp)
            if on_block is not None:
                on_block(frames)
            player.push(frames)
            paced.append((time.monotonic(), steps))
            if handle is not None and time.monotonic() - last_sync >= SYNC_S:
                handle.sync()
                last_sync = time.monotonic()
        drain = True
    finally:
        try:
            stats = player.close(drain=drain)
            if on_timing is not None:
                on_timing(player.timing())
        finally:
            if handle is not None:
                close_viewer(handle)
    dt = float(model.opt.timestep)
    # pace: from the first push that had to wait for the device (the ring holds lead_s), to the last
    steady = [p for p in paced if p[1] * dt >= 2 * lead_s] or paced
    wall = steady[-1][0] - steady[0][0] if len(steady) > 1 else 0.0
    sim_paced = (steady[-1][1] - steady[0][1]) * dt if len(steady) > 1 else 0.0
    return dict(stats, sim_seconds=steps * dt, channels=[sim.channel_names[c] for c in heard],
                wall_seconds=wall, pace=sim_paced / wall if wall > 0 else float("nan"))
