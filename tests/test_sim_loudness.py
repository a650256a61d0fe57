"""Loudness sanity: a simple drop scene must give a plausible peak sound pressure level.

Uses the real modal analysis (draft quality, cached on disk after the first run).
"""

from __future__ import annotations

import mujoco
import numpy as np

from mjsound.sim.scene import SoundScene
from mjsound.sim.simulator import AudioSimulator

FS = 48000

DROP_XML = """
<mujoco>
  <option timestep="0.001"/>
  <custom><text name="mjsound:ball" data="steel"/><text name="mjsound:plate" data="steel"/></custom>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 .1"/>
    <geom name="plate" type="box" size="0.15 0.15 0.003" pos="0 0 0.003" solref="-1e5 -120"/>
    <site name="mic0" pos="0 0 1.006"/>
    <body name="ball" pos="0 0 0.116">
      <freejoint/>
      <geom name="ball" type="sphere" size="0.01" solref="-1e5 -120"/>
    </body>
  </worldbody>
</mujoco>"""


def test_ball_drop_on_plate_peak_spl_is_plausible():
    """A 33 g steel ball (R = 1 cm) dropped 10 cm onto a 30 x 30 x 0.6 cm steel plate, heard
    1 m above the impact, must peak between 0.1 and 5 Pa (74-108 dB SPL).

    Why this range: measured ball-on-plate impacts of this size (Akay 1978, "A review of impact
    noise"; Troccaz et al. 2000) peak around 80-100 dB SPL at 1 m, i.e. 0.2-2 Pa; an energy
    bound agrees: the ball brings m g h = 0.03 J, of which an impact radiates at most ~1e-3
    (acoustic efficiency of ball/plate impacts 1e-5..1e-3). The range leaves ~6 dB each side
    for the model's approximations (compact radiation estimate, Hertz pulse, restitution) and
    still catches the errors it is meant to catch: a missing or doubled 1/(4 pi), a radiation
    estimate used far outside its compact (k a << 1) range (+24 dB here before the
    radiation-efficiency cap), an impulse train instead of one impact, or an impulse in the
    wrong units, all of which move the level by 20 dB or more.
    """
    model = mujoco.MjModel.from_xml_string(DROP_XML)
    data = mujoco.MjData(model)
    scene = SoundScene.from_model(model, sample_rate=FS, progress=False, quality="draft")
    assert [s.name for s in scene.sounding] == ["plate"]
    sim = AudioSimulator(model, data, scene=scene, sample_rate=FS)
    audio = sim.run(0.3)
    assert sim.events["impact"] >= 1
    first = sim.impacts[0]
    # the impact itself is right (m (1 + e) sqrt(2 g h), e = 0.6 for steel): 0.0084-0.0094 N s
    assert 0.007 < first.impulse_pred < 0.011
    peak = float(np.abs(audio).max())
    assert 0.1 < peak < 5.0, f"peak {peak:.3g} Pa = {20 * np.log10(peak / 2e-5):.1f} dB SPL"
