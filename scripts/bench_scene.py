#!/usr/bin/env python
"""Benchmark the demo scene (or any MJCF): real-time factor with audio and per-step overheads.

Measures, single thread, after a warm-up (numba compile, model cache), in CPU time
(``time.process_time``: the machine is shared; another process cannot inflate it), the medians
over ``--rounds`` interleaved rounds (physics only, reading only, with audio, with audio and no
clicks) of each round's own ratios and differences:

* ``realtime_factor``: simulated seconds per CPU second with audio (mj_step + contacts +
  synthesis, ``AudioSimulator.run`` with its default ``render_block_s`` = 10 ms), analysis
  excluded; ``realtime_factor_physics_only`` is the same simulation without audio, the bound
  no audio pipeline can beat;
* ``step_ratio``: time per step with audio / without audio (plain mj_step);
* ``contact_us_per_step``: reading the contacts (pair states, impact impulses and records)
  per step [us]: a third pass, the step kernel stepping and reading with nothing sounding
  (the same fused substeps, one numba call per ``render_block_s`` as in the audio run), minus
  physics only;
* ``synth_us_per_step``: the rest of the audio pipeline per step [us] (queueing impacts,
  sliding noise, clicks, rendering): with audio minus that third pass;
* ``step_ratio_pulses_off`` and ``pulses_us_per_step``: the same audio run with clicks and
  contact microphones off (``clicks=False, contact_mics=[]``), interleaved in the same rounds,
  and what turning them on costs per step [us] (the demo scene has a contact microphone);
* ``step_ratio_reflections_off`` and ``reflections_us_per_step``: the same audio run in free
  field (``reflections=False``: the floor does not reflect, docs/rooms.md), in the same rounds,
  and what the floor's image microphones cost per step [us];
* with ``--room SPEC`` (an ``mjsound-room`` text, docs/rooms.md), ``step_ratio_room`` and
  ``room_us_per_step``: the same audio run in that room (its images and late tail) against
  the default run, and ``tail_us_per_step``: the room with its tail against the room without
  (``tail=off``), in the same rounds.

Usage: python scripts/bench_scene.py [SCENE.xml] [--duration 3] [--rounds 3] [--room SPEC] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))


def main(argv=None) -> int:
    import mujoco
    import numpy as np

    from mjsound.sim import AudioSimulator, SoundScene
    from mjsound.sim.demo import find_demo_scene

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scene", nargs="?", default=None, help="MJCF (default: the demo scene)")
    p.add_argument("--duration", type=float, default=3.0, help="simulated seconds (default 3)")
    p.add_argument("--sample-rate", type=int, default=48000)
    p.add_argument("--quality", default="default")
    p.add_argument("--rounds", type=int, default=7, help="interleaved rounds (medians over rounds reported)")
    p.add_argument("--room", default=None, help="also run in this room (an mjsound-room text, e.g. "
                   "\"lo=-2 -2 0; hi=2 2 2.5; walls=plaster; floor=wood\"), with and without its tail")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    args = p.parse_args(argv)
    path = args.scene or find_demo_scene()
    model = mujoco.MjModel.from_xml_path(path)
    data = mujoco.MjData(model)

    def reset():
        if model.nkey:
            mujoco.mj_resetDataKeyframe(model, data, 0)
        else:
            mujoco.mj_resetData(model, data)

    t0 = time.perf_counter()
    scene = SoundScene.from_model(model, sample_rate=args.sample_rate, quality=args.quality, progress=not args.json)
    t_scene = time.perf_counter() - t0
    nsteps = int(round(args.duration / model.opt.timestep))

    # warm-up (numba compile / caches)
    reset()
    sim = AudioSimulator(model, data, scene=scene, sample_rate=args.sample_rate)
    sim.run(0.05)
    reset()
    sim_off = AudioSimulator(model, data, scene=scene, sample_rate=args.sample_rate, clicks=False, contact_mics=[])
    sim_off.run(0.05)
    reset()
    sim_free = AudioSimulator(model, data, scene=scene, sample_rate=args.sample_rate, reflections=False)
    sim_free.run(0.05)
    rooms = []  # (the room with its tail, without)
    if args.room:
        from mjsound.sim.rooms import room_from_text

        for spec in (args.room, args.room + "; tail=off"):
            reset()
            rooms.append(AudioSimulator(model, data, scene=scene, sample_rate=args.sample_rate,
                                        room=room_from_text(spec)))
            rooms[-1].run(0.05)
    from mjsound.sim.contacts import ContactReader
    from mjsound.sim.driver import StepDriver

    # reading alone: the step kernel with nothing sounding (no synthesizer, no pulses)
    reader = ContactReader(model)
    reading = StepDriver(model, data, reader, args.sample_rate)
    if not reading.fused:
        raise SystemExit("bench_scene: the step kernel cannot call mj_step here (MuJoCo's C functions not found)")
    every = sim.steps_per_render
    t_phys_all, t_audio_all, t_read_all, t_off_all, t_free_all = [], [], [], [], []
    t_rooms = [[] for _ in rooms]
    for _ in range(args.rounds):
        reset()
        t0 = time.process_time()
        for _ in range(nsteps):
            mujoco.mj_step(model, data)
        t_phys_all.append(time.process_time() - t0)
        # contact reading alone: the step kernel with nothing sounding (impulses of impacts included)
        reset()
        reading.reset()
        t0 = time.process_time()
        for k in range(0, nsteps, every):
            reading.substeps(min(every, nsteps - k), False)
        t_read_all.append(time.process_time() - t0)
        reset()
        sim.reset()
        t0 = time.process_time()
        audio = sim.run(args.duration)
        t_audio_all.append(time.process_time() - t0)
        reset()
        sim_off.reset()
        t0 = time.process_time()
        sim_off.run(args.duration)
        t_off_all.append(time.process_time() - t0)
        reset()
        sim_free.reset()
        t0 = time.process_time()
        sim_free.run(args.duration)
        t_free_all.append(time.process_time() - t0)
        for sim_room, times in zip(rooms, t_rooms):
            reset()
            sim_room.reset()
            t0 = time.process_time()
            sim_room.run(args.duration)
            times.append(time.process_time() - t0)
    # per-round differences and ratios, then their medians: a round's passes run back to back,
    # so the machine's drifting load hits them alike (a median of each pass apart does not pair them)
    t_phys_all, t_audio_all, t_read_all, t_off_all, t_free_all = map(
        np.array, (t_phys_all, t_audio_all, t_read_all, t_off_all, t_free_all))
    t_phys = float(np.median(t_phys_all))
    t_audio = float(np.median(t_audio_all))
    ratio = float(np.median(t_audio_all / t_phys_all))
    ratio_off = float(np.median(t_off_all / t_phys_all))
    per_step = lambda x: 1e6 * float(np.median(x)) / nsteps
    st = sim.stats()
    out = {
        "scene": os.path.basename(path),
        "duration_s": args.duration,
        "timestep_s": float(model.opt.timestep),
        "steps": nsteps,
        "sounding_geoms": len(scene.sounding),
        "modes": scene.n_modes,
        "scene_seconds": t_scene,
        "realtime_factor": args.duration / t_audio,
        "realtime_factor_physics_only": args.duration / t_phys,
        "step_ratio": ratio,
        "step_ratio_pulses_off": ratio_off,
        "pulses_us_per_step": per_step(t_audio_all - t_off_all),
        "step_ratio_reflections_off": float(np.median(t_free_all / t_phys_all)),
        "reflections_us_per_step": per_step(t_audio_all - t_free_all),
        "images": len(sim.images),
        "channels": list(sim.channel_names),
        "us_per_step_physics": 1e6 * t_phys / nsteps,
        "us_per_step_audio": 1e6 * t_audio / nsteps,
        "contact_us_per_step": per_step(t_read_all - t_phys_all),
        "synth_us_per_step": per_step(t_audio_all - t_read_all),
        "events": st["events"],
        "peak_pa": float(np.abs(audio[: sim.n_air]).max()) if audio.size else 0.0,  # (air channels)
    }
    if rooms:
        t_room, t_room_off = map(np.array, t_rooms)
        out.update({"room": args.room, "room_images": len(rooms[0].images),
                    "step_ratio_room": float(np.median(t_room / t_phys_all)),
                    "step_ratio_room_tail_off": float(np.median(t_room_off / t_phys_all)),
                    "room_us_per_step": per_step(t_room - t_audio_all),
                    "tail_us_per_step": per_step(t_room - t_room_off)})
    if args.json:
        print(json.dumps(out))
    else:
        for k, v in out.items():
            print(f"{k:28s} {v:.4g}" if isinstance(v, float) else f"{k:28s} {v}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
