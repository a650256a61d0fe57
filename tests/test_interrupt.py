"""Ctrl-C while stepping reaches the caller as KeyboardInterrupt (never SystemError from numba)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

import mjsound

CHILD = r'''
import sys
import mujoco
import numpy as np
from mjsound.sim.scene import SoundScene
from mjsound.sim.simulator import AudioSimulator
from mjsound.sim.stub import stub_model

XML = """<mujoco><option timestep="0.002"/>
  <custom><text name="mjsound:ball" data="steel"/><text name="mjsound:box" data="oak"/></custom>
  <worldbody><geom name="floor" type="plane" size="2 2 .1"/>
    <body name="ball" pos="0 0 0.2"><freejoint/><geom name="ball" type="sphere" size="0.02"/></body>
    <body name="box" pos="0.5 0 0.03"><freejoint/><geom name="box" type="box" size="0.04 0.03 0.03"/></body>
  </worldbody></mujoco>"""
models = {"ball": stub_model("sphere:0.02", "steel", 4, 9000.0), "box": stub_model("box:0.08,0.06,0.06", "oak", 6, 700.0)}
model = mujoco.MjModel.from_xml_string(XML)
data = mujoco.MjData(model)
sim = AudioSimulator(model, data, scene=SoundScene.from_model(model, models=models, progress=False), sample_rate=16000)

def restart():
    mujoco.mj_resetData(model, data)
    data.qvel[0] = 0.4
    sim.reset()

restart()
for _ in range(60):  # every path of the loop below runs (and is compiled) before the interrupts:
    data.xfrc_applied[2, 0] = 3.0  # (the box slides: streams) an interrupt inside numba's compiler
    sim.advance(5, render=False)  # is beyond this test (and numba's control)
    sim.flush()
    mujoco.mj_step(model, data)
    sim.step()
restart()
print("ready", flush=True)
caught = 0
while caught < int(sys.argv[1]):
    try:
        for i in range(10**9):
            if data.time > 1.5:
                restart()
            data.xfrc_applied[2, 0] = 3.0
            if i % 2:
                sim.advance(5, render=False)
                sim.flush()
            else:
                mujoco.mj_step(model, data)
                sim.step()
    except KeyboardInterrupt:
        caught += 1
        print("KeyboardInterrupt", flush=True)
        # the interrupt may fall between mj_step and sim.step(): that step's contacts were
        # never read, which the simulator rightly refuses to skip over; start clean
        restart()
    except BaseException as e:
        print("ERROR", type(e).__name__, e, flush=True)
        sys.exit(4)
'''


def _sigint_default():
    """Default Ctrl-C disposition in the child: a suite started in the background by a
    non-interactive shell (``cmd &``) ignores SIGINT, and children would inherit that."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT to a child process")
def test_ctrl_c_while_stepping_is_a_keyboard_interrupt():
    """A child process steps a scene in a loop (fused substeps and single steps, with
    rendering); each SIGINT sent to it must arrive as KeyboardInterrupt."""
    n = 12
    env = dict(os.environ, PYTHONPATH=os.path.dirname(os.path.dirname(os.path.abspath(mjsound.__file__))))
    p = subprocess.Popen([sys.executable, "-c", CHILD, str(n)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True, env=env, preexec_fn=_sigint_default)
    try:
        assert p.stdout.readline().strip() == "ready", p.stderr.read()
        lines = []
        for k in range(n):
            time.sleep(0.05 + 0.03 * (k % 5))
            p.send_signal(signal.SIGINT)
            lines.append(p.stdout.readline().strip())
            if lines[-1] != "KeyboardInterrupt":
                break
        p.wait(timeout=60)
    finally:
        p.kill()
    assert lines == ["KeyboardInterrupt"] * n, lines + [p.stderr.read()[-2000:]]
    assert p.returncode == 0


def test_interrupt_several_system_errors_deep_is_a_keyboard_interrupt():
    """numba may wrap the interrupt in more than one SystemError (boxing a returned array
    calls ``_numba_unpickle`` repeatedly); ``interruptible`` finds it anywhere in the chain."""
    from mjsound.synth.interrupt import caused_by_interrupt, interruptible

    def nested(depth):
        try:
            if depth == 0:
                raise KeyboardInterrupt
            nested(depth - 1)
        except BaseException as e:
            raise SystemError("returned a result with an exception set") from e

    with pytest.raises(KeyboardInterrupt):
        interruptible(nested)(3)
    with pytest.raises(SystemError):  # a SystemError without an interrupt stays what it is
        interruptible(lambda: (_ for _ in ()).throw(SystemError("other")))()
    assert not caused_by_interrupt(SystemError("x"))
