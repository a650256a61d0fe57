#!/usr/bin/env python
"""A driven arm (one hinge, ``harmonic`` preset by default) whose speed sweeps up and down:
writes the contact microphone on the link as a WAV and its spectrogram, on which the drive's
lines follow the speed (docs/actuators.md).

    python scripts/arm_demo.py --preset servo -o arm.wav --png docs/actuators_arm.png
"""

import argparse
import math

import mujoco
import numpy as np

from mjsound.sim.simulator import AudioSimulator

ARM = """<mujoco><option timestep="0.001" gravity="0 0 0"/>
<custom><text name="mjsound:base" data="steel"/><text name="mjsound:link" data="aluminium"/></custom>
<worldbody>
 <body name="base" pos="0 0 0.5"><geom name="base" type="box" size=".1 .1 .05"/>
  <body name="arm" pos="0 0 0.1"><joint name="shoulder" type="hinge" axis="0 0 1" damping="0.2"/>
   <geom name="link" type="box" size=".25 .025 .025" pos=".25 0 0"/><site name="s_link" pos=".4 0 .025"/></body></body>
</worldbody>
<actuator><velocity name="shoulder" joint="shoulder" kv="5"/></actuator></mujoco>"""


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="servo")
    ap.add_argument("--seconds", type=float, default=4.0)
    ap.add_argument("-o", "--output", default="arm.wav")
    ap.add_argument("--png", default="")
    args = ap.parse_args()
    m = mujoco.MjModel.from_xml_string(ARM)
    d = mujoco.MjData(m)
    sim = AudioSimulator(m, d, microphones=[[0.6, 0.6, 0.8]], contact_mics=["s_link"], progress=False,
                         actuators={"shoulder": args.preset})
    n = int(round(args.seconds / m.opt.timestep))
    out = []
    for i in range(n):
        d.ctrl[0] = 0.3 + 2.7 * math.sin(math.pi * i / n)  # speed up, then down [rad/s]
        mujoco.mj_step(m, d)
        out.append(sim.step())
    audio = np.concatenate(out, axis=1)
    from mjsound.synth.output import write_audio

    write_audio(args.output, audio[1:2], sim.sample_rate, normalize=True)
    print(f"wrote {args.output}: {audio.shape[1] / sim.sample_rate:.1f} s, contact mic peak {np.abs(audio[1]).max():.3g}")
    if args.png:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6, 3))
        ax.specgram(audio[1], NFFT=2048, Fs=sim.sample_rate, noverlap=1536, cmap="magma")
        ax.set_ylim(0, 6000)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("frequency [Hz]")
        ax.set_title(f"driven arm, preset {args.preset!r}: contact microphone on the link")
        fig.tight_layout()
        fig.savefig(args.png, dpi=60)
        print(f"wrote {args.png}")


if __name__ == "__main__":
    main()
