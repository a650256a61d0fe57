"""The scene report's levels: each object's loudest mode at each microphone for the reference
tap (mjsound.sim.scene_levels), against the far field's 1/r, a rigid turn of the whole scene
and the pulse's spectrum."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from mjsound.sim import SoundScene
from mjsound.sim.scene_levels import P_REF_PA, REFERENCE_TAP_NS, loudest_modes

BAR = """
<mujoco>
  <custom><text name="mjsound:bar" data="aluminium"/></custom>
  <worldbody>
    <body name="b" pos="0 0 0.5" euler="{euler}">
      <freejoint/>
      <geom name="bar" type="box" size="0.08 0.0075 0.005"/>
    </body>
    <site name="mic_a" pos="{mic}"/>
  </worldbody>
</mujoco>
"""


def bar_scene(mic, euler="0 0 0"):
    xml = BAR.format(mic=" ".join(f"{x:.9g}" for x in mic), euler=euler)
    m = mujoco.MjModel.from_xml_string(xml)
    return SoundScene.from_model(m, sample_rate=16000, quality="draft", progress=False)


def test_level_falls_6_db_per_doubling_and_follows_the_pattern():
    centre = np.array([0, 0, 0.5]) + bar_scene([0, 0, 1]).sounding[0].model.radiation_centre
    u = np.array([0.6, 0.0, 0.8])
    near = loudest_modes(bar_scene(centre + 0.5 * u))[0][0]
    far = loudest_modes(bar_scene(centre + 1.0 * u))[0][0]  # (the same direction, twice as far)
    assert near["distance_m"] == pytest.approx(0.5, rel=1e-9) and far["distance_m"] == pytest.approx(1.0, rel=1e-9)
    assert far["frequency_hz"] == near["frequency_hz"]
    assert near["spl_db"] - far["spl_db"] == pytest.approx(20 * math.log10(2), abs=1e-6)
    assert near["spl_db"] == pytest.approx(20 * math.log10(near["pressure_pa"] / math.sqrt(2) / P_REF_PA))


def test_reference_computation_and_a_rigid_turn_of_the_whole_scene():
    """The level against a plain computation (world direction turned into the bar's frame, the
    antinode's |phi . n|, the half-sine's spectrum), and unchanged when bar and microphone turn
    together; turning the bar alone changes it (directivity)."""
    from mjsound.synth.pulse import half_sine_spectrum

    mic = np.array([0.35, -0.1, 0.8])
    scene = bar_scene(mic)
    got = loudest_modes(scene)[0][0]
    mm = scene.sounding[0].model
    d = mic - (np.array([0, 0, 0.5]) + mm.radiation_centre)  # (the bar is not turned)
    r = np.linalg.norm(d)
    F = np.abs(mm.radiation_pattern(d[None]))[0]
    phi_n = np.abs(np.einsum("pcn,pc->pn", mm.shapes, mm.normals)).max(axis=0)
    w = 2 * np.pi * mm.frequencies_hz
    p = F * REFERENCE_TAP_NS * np.abs(half_sine_spectrum(w, got["contact_s"])) * phi_n / (w * r)
    i = int(np.argmax(p))
    assert got["frequency_hz"] == mm.frequencies_hz[i]
    assert got["pressure_pa"] == pytest.approx(p[i], rel=1e-9)
    assert 20e-6 < got["contact_s"] < 200e-6  # (steel on aluminium at 1 m/s: tens of microseconds)

    turn = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]], float)  # 90 degrees about z
    mic_turned = np.array([0, 0, 0.5]) + turn @ (mic - np.array([0, 0, 0.5]))
    both = loudest_modes(bar_scene(mic_turned, euler="0 0 90"))[0][0]
    assert both["pressure_pa"] == pytest.approx(got["pressure_pa"], rel=1e-6)
    bar_alone = loudest_modes(bar_scene(mic, euler="0 0 90"))[0][0]
    assert abs(bar_alone["spl_db"] - got["spl_db"]) > 0.5


def test_report_and_summary_show_the_levels():
    scene = bar_scene([0.3, 0.2, 0.9])
    lv = loudest_modes(scene)[0][0]
    assert f"{lv['frequency_hz']:.0f} Hz {lv['spl_db']:.0f} dB at mic_a" in scene.report()
    assert scene.summary()["sounding"][0]["loudest_mode"][0]["spl_db"] == pytest.approx(lv["spl_db"])
