"""Live playback, for real: a PortAudio stream into a private PulseAudio null sink through an
ALSA file tap that records what was played (tests/live_audio.py), and MuJoCo's viewer under
Xvfb. The played samples must be the simulated ones, at their times, paced to the wall clock;
a simulation that stalls must leave one clean gap and no drift."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from mjsound.live_tap import PulseTap, align, read_tap

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEMO = os.path.join(ROOT, "assets", "demo_scene.xml")
FS = 48000


@pytest.fixture(scope="module")
def tap(tmp_path_factory):
    """A running tap; its ``env`` runs a client with the shared model cache of this module
    (the demo scene is analysed once for all its tests)."""
    from mjsound.sim.warmup import warmup

    warmup(verbose=False, once=True)  # (a cold numba cache compiles here, not in the timed subprocesses)
    t = PulseTap(tmp_path_factory.mktemp("pulse"), names=("livetap", "livetap_dmc")).start()
    t.env.update(MJSOUND_CACHE_DIR=str(tmp_path_factory.mktemp("live_cache")), PYTHONPATH=ROOT, MUJOCO_GL="glfw")
    t.env.pop("DISPLAY", None)
    yield t
    t.stop()


def _play(tap, lead_s, stall_at, stall_s, out):
    """The demo scene for 2 s without the viewer (tests/live_audio.py), stalled once."""
    r = subprocess.run([sys.executable, os.path.join(ROOT, "tests", "live_audio.py"), "view", DEMO, out, "livetap", "2",
                        str(lead_s), "0.1", str(stall_at), str(stall_s)], env=tap.env, capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    z = np.load(out)
    return (read_tap(tap.wav), np.clip(z["sent"], -1.0, 1.0), json.loads(str(z["stats"])), json.loads(str(z["log"])),
            z["callbacks"], z["pushes"])


def _timing_faults(stats, callbacks, pushes, lead) -> list[str]:
    """What is wrong with the timing of a run that had one gap: PortAudio's DAC time of each
    played block (``CLOCK_MONOTONIC``) against its first simulated sample must be one line of
    slope 1 once the gap is added (at its time, paced to the wall clock, no drift), and the
    simulation must never run ahead of what is heard by more than the lead and the device."""
    (s0, gap), = stats["gaps"]
    first, n, dac, _ = callbacks.T
    m = n > 0
    heard = (first[m] + np.where(first[m] >= s0, gap, 0)) / FS
    slope, at0 = np.polyfit(heard, dac[m], 1)
    late = np.abs(np.polyval((slope, at0), heard) - dac[m]).max()
    faults = []
    if abs(slope - 1.0) > 0.02:
        faults.append(f"played at {slope:.4f} s of wall time per simulated s")
    if late > 0.02:
        faults.append(f"a block played {1000 * late:.0f} ms off the line")
    wall, pushed = pushes.T
    # (the stall and the re-priming aside: the ring refills to the lead while the device still plays silence)
    steady = (pushed < s0 - 0.02 * FS) | (pushed > s0 + (2 * lead + stats["latency_s"] + 0.05) * FS)
    ahead = (np.interp(pushed, first[m], dac[m]) - wall)[steady][5:]
    if ahead.max() > lead + stats["latency_s"] + 0.1:  # (a block, and PortAudio's DAC-time estimate)
        faults.append(f"the simulation ran {1000 * ahead.max():.0f} ms ahead of what was heard")
    if ahead.min() < 0.0:
        faults.append("a block was heard before it was simulated")
    return faults


def test_played_samples_are_the_simulated_ones_at_their_times_and_a_stall_leaves_one_clean_gap(tap, tmp_path):
    lead, stall_at, stall_s = 0.2, 1.0, 0.6  # (a lead that rides out a busy machine; a stall longer)
    for attempt in range(3):  # (a busy machine may underflow besides the stall or jitter: run again)
        (played, rate), sent, stats, logged, callbacks, pushes = _play(tap, lead, stall_at, stall_s,
                                                                       str(tmp_path / f"run{attempt}.npz"))
        # (PortAudio's flags: the callback thread itself came late and the device lost samples)
        clean = stats["underflows"] == 1 and stats["portaudio_underflows"] == 0
        faults = _timing_faults(stats, callbacks, pushes, lead) if clean else []
        if clean and not faults:
            break
    assert rate == FS and stats["underflows"] == 1 and stats["portaudio_underflows"] == 0, stats
    assert faults == []
    assert stats["frames_pushed"] == stats["frames_played"] == len(sent) == 2 * FS
    (s0, gap), = stats["gaps"]
    assert abs(s0 - stall_at * FS) <= 0.02 * FS  # (the ring ran dry one block or two after the stall began)
    assert 0.1 * FS < gap < stall_s * FS + lead * FS
    # the gap is said once, with how far behind
    assert [name for name, _ in logged] == ["mjsound.live"]
    assert f"fell {1000 * gap / FS:.0f} ms behind real time" in logged[0][1]

    # before the stall: every sample as simulated, none missing, none repeated
    before, after = sent[:s0], sent[s0:]
    k1, rho = align(played, before)
    assert rho > 0.999999
    np.testing.assert_array_equal(played[k1:k1 + s0], before)
    # the gap: the last sample ramps to zero over FADE_S (no step), then exact silence
    from mjsound.live import FADE_S

    fade = int(round(FADE_S * FS))
    end = k1 + s0
    last = np.abs(before[-1]).max()
    assert np.abs(np.diff(played[end - 1:end + fade + 1], axis=0)).max() <= last / fade * 1.001 + 1e-9
    k2 = end + gap  # after it: the rest, at the offset moved by exactly the gap (no drift)
    assert np.all(played[end + fade:k2] == 0.0)
    ramp = (np.arange(1, fade + 1, dtype=np.float32) / fade)[:, None]
    np.testing.assert_allclose(played[k2:k2 + fade], after[:fade] * ramp, atol=1e-7)
    np.testing.assert_array_equal(played[k2 + fade:k2 + len(after)], after[fade:])
    assert align(played, after)[0] == k2


def test_view_opens_the_viewer_and_plays_the_scene_live(tap, tmp_path, monkeypatch):
    """``mjsound view`` end to end under Xvfb: the window, then the stream; what the device
    played is the scene's simulation (run here again, no viewer), sample for sample, paced."""
    assert shutil.which("xvfb-run"), "xvfb-run missing: apt-get install xvfb xauth (.ci/run does)"
    for attempt in range(3):  # (a busy machine may underflow: run again)
        r = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 640x480x24", sys.executable, "-m", "mjsound.cli",
                            "view", DEMO, "--duration", "2", "--audio-device", "livetap", "--json", "--lead", "0.5",
                            "--device-latency", "0.1"],  # (software GL under Xvfb takes CPU: a small screen, more slack)
                           env=tap.env, capture_output=True, text=True, timeout=600, cwd=str(tmp_path))
        assert r.returncode == 0, r.stderr[-3000:]
        s = json.loads(r.stdout.strip().splitlines()[-1])
        if s["underflows"] == 0 and s["portaudio_underflows"] == 0:
            break
    assert s["underflows"] == 0 and s["portaudio_underflows"] == 0, s
    assert s["sim_seconds"] == pytest.approx(2.0) and s["frames_played"] == 2 * FS
    assert s["channels"] == ["mic_left", "mic_right"] and s["pace"] == pytest.approx(1.0, abs=0.05)
    played, rate = read_tap(tap.wav)
    assert rate == FS and 2 * FS <= len(played) < 4 * FS
    # the same simulation without the viewer (models from the run's cache): what view() sends
    from mjsound.live_view import open_scene

    monkeypatch.setenv("MJSOUND_CACHE_DIR", tap.env["MJSOUND_CACHE_DIR"])
    sim, heard = open_scene(DEMO, progress=False)
    blocks = [sim.advance(sim.steps_per_render)[heard] * np.float32(1.0 / 20.0) for _ in range(200)]
    sent = np.clip(np.concatenate(blocks, axis=1).T, -1.0, 1.0)
    assert np.sqrt(np.mean(sent.astype(np.float64) ** 2)) > 0.01  # (the demo's impacts)
    k, rho = align(played, sent)
    assert rho > 0.999999
    np.testing.assert_array_equal(played[k:k + len(sent)], sent)


def test_closing_the_viewer_waits_for_its_thread(tmp_path):
    """The viewer's thread is joined before the process goes on to exit (exiting while it
    tore down crashed 2 runs in 3 here): it is named ``Thread-N (_launch_internal)``."""
    code = ("import threading, mujoco\n"
            "from mjsound.live_view import launch_viewer, close_viewer\n"
            f"m = mujoco.MjModel.from_xml_path({DEMO!r}); d = mujoco.MjData(m)\n"
            "h = launch_viewer(m, d)\n"
            "for _ in range(50):\n    mujoco.mj_step(m, d); h.sync()\n"
            "assert any('(_launch_internal)' in t.name for t in threading.enumerate())\n"
            "close_viewer(h)\n"
            "print('alive', [t.name for t in threading.enumerate() if t.is_alive() and t is not threading.main_thread()])\n")
    env = dict(os.environ, PYTHONPATH=ROOT, MUJOCO_GL="glfw")
    r = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1280x1024x24", sys.executable, "-c", code], env=env,
                       capture_output=True, text=True, timeout=300, cwd=str(tmp_path))
    assert r.returncode == 0, r.stderr[-3000:]
    assert "alive []" in r.stdout  # (right after close(), an unjoined thread is still tearing down)


def test_the_gymnasium_and_dm_control_wrappers_play_their_observations_live(tap, tmp_path):
    """``AudioObservation(play=...)`` and ``AudioEnvironment(play=...)``: the device plays
    exactly the audio observations, one after the other, and the env steps in real time."""
    for attempt in range(3):  # (a busy machine may underflow: run again)
        out = str(tmp_path / f"envs{attempt}.npz")
        r = subprocess.run([sys.executable, os.path.join(ROOT, "tests", "live_audio.py"), "envs", out, "livetap",
                            "livetap_dmc", "1.0"], env=tap.env, capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, r.stderr[-3000:]
        z = np.load(out)
        if z["gym_underflows"] == 0 and z["dmc_underflows"] == 0:
            break
    for key, name in (("gym", "livetap"), ("dmc", "livetap_dmc")):
        assert z[f"{key}_underflows"] == 0
        sent, wall, dt = z[key], z[f"{key}_wall"], float(z[f"{key}_dt"])
        played, rate = read_tap(tap.wav_of(name))
        assert rate == 16000 and played.shape[1] == sent.shape[1] == 1
        assert np.abs(sent).max() > 0.001, key  # (heard: Ant's feet, the ball in the cup)
        k, rho = align(played, sent)
        assert rho > 0.999999, key
        np.testing.assert_array_equal(played[k:k + len(sent)], sent)
        # real time: after the first steps (the ring's lead fills at once) one step per dt
        pace = (wall[-1] - wall[5]) / ((len(wall) - 6) * dt)
        assert 0.9 < pace < 1.1, (key, pace)


def test_view_names_the_fix_for_a_device_that_is_not_there(tap):
    r = subprocess.run([sys.executable, "-m", "mjsound.cli", "view", DEMO, "--no-viewer", "--duration", "1",
                        "--audio-device", "no-such-device"], env=tap.env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    assert "no-such-device" in r.stderr and "'livetap'" in r.stderr and "--audio-device" in r.stderr
    assert "Traceback" not in r.stderr


def test_view_without_a_display_names_xvfb_run(monkeypatch, capsys):
    from mjsound.cli import main

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["view", DEMO, "--duration", "1"]) == 2
    err = capsys.readouterr().err
    assert "xvfb-run" in err and "--no-viewer" in err


def test_view_without_sounddevice_names_the_extra(monkeypatch, capsys):
    from mjsound.cli import main

    monkeypatch.setitem(sys.modules, "sounddevice", None)  # (what Python does for a module not installed)
    assert main(["view", DEMO, "--no-viewer", "--duration", "1"]) == 2
    err = capsys.readouterr().err
    assert "mjsound[live]" in err and "libportaudio2" in err


def test_audio_only_needs_an_end(capsys):
    from mjsound.cli import main

    assert main(["view", DEMO, "--no-viewer"]) == 2
    assert "--duration" in capsys.readouterr().err


def test_player_checks_its_input_before_opening_a_device():
    from mjsound.live import LivePlayer, output_channels

    with pytest.raises(ValueError, match="channels=3"):
        LivePlayer(FS, channels=3)
    with pytest.raises(ValueError, match="lead_s"):
        LivePlayer(FS, lead_s=float("nan"))
    with pytest.raises(ValueError, match=r"expected \(2, n\)"):
        LivePlayer(FS, channels=2).push(np.zeros((3, 10)))
    assert output_channels(3, [2]) == [0, 1] and output_channels(4, [0]) == [1, 2] and output_channels(1) == [0]
    with pytest.raises(ValueError, match="no air microphone"):
        output_channels(1, [0])


def test_the_ramps_to_silence_and_back_span_callbacks_of_any_size():
    """The ring's logic driven as PortAudio drives it (its callback with odd block sizes), no
    device: a dry ring ramps the last sample to zero over FADE_S even when the callbacks are
    shorter than the ramp, waits for ``lead`` frames, then resumes with the fade-in; every
    frame is played once, in order."""
    from types import SimpleNamespace

    from mjsound.live import FADE_S, LivePlayer

    p = LivePlayer(FS, channels=1, lead_s=0.002, block_s=0.001)
    fade = int(round(FADE_S * FS))
    x = np.full((2 * fade, 1), 0.5, np.float32)
    status, when = SimpleNamespace(output_underflow=False), SimpleNamespace(outputBufferDacTime=0.0, currentTime=0.0)
    out, pieces = [], [7, 50, 33, 1, 90, 64, 13, 5, 40, 30, 200, 40]

    def play(k):
        buf = np.full((k, 1), np.nan, np.float32)
        p._callback(buf, k, when, status)
        out.append(buf[:, 0].copy())

    assert p._write(x) == len(x)  # (192 frames >= lead = 96: playing starts)
    for k in pieces[:10]:  # runs dry at 192: the ramp (96 frames) over several callbacks, silence
        play(k)
    assert p._write(x) == len(x)
    for k in pieces[10:]:
        play(k)
    y = np.concatenate(out)
    assert not np.isnan(y).any()
    np.testing.assert_array_equal(y[:len(x)], 0.5)
    down = y[len(x):len(x) + fade]
    np.testing.assert_allclose(down, 0.5 * (1 - np.arange(1, fade + 1) / fade), atol=1e-7)
    start = sum(pieces[:10])  # (the resume: the first callback after the second write)
    assert np.all(y[len(x) + fade:start] == 0.0)
    np.testing.assert_allclose(y[start:start + fade], 0.5 * np.arange(1, fade + 1) / fade, atol=1e-7)
    np.testing.assert_array_equal(y[start + fade:start + len(x)], 0.5)
    s = p.stats()
    assert s["frames_played"] == 2 * len(x) and s["underflows"] == 2  # (the second: still dry at the end)
    assert s["gaps"][0] == (len(x), start - len(x))
