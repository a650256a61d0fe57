"""What mjsound says (issue 36 item 5, issue 40 items 5-6): one impact per contact pair in the
counts and the event log, silent geoms of no interest counted in one line, a warning when
nothing has a material, hints that propose something new, warnings pointing at the user's line."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest

from mjsound.sim.scene import SoundScene, _finer_quality_hint
from mjsound.sim.simulator import AudioSimulator

BOX = """<mujoco><option timestep="0.001"/><worldbody>
  <geom name="floor" type="plane" size="1 1 .1"/>
  <body name="box" pos="0 0 .0301"><freejoint/><geom name="box" type="box" size=".1 .1 .03"/></body>
  %s
</worldbody></mujoco>"""


def test_a_box_landing_flat_is_one_impact():
    model = mujoco.MjModel.from_xml_string(BOX % "")
    data = mujoco.MjData(model)
    data.qvel[2] = -0.5  # flat onto its four corners
    sim = AudioSimulator(model, data, materials={"box": "steel"}, sample_rate=16000, quality="draft", progress=False)
    for _ in range(20):
        mujoco.mj_step(model, data)
        sim.step()
        if sim.n_impacts:
            break
    assert data.ncon == 4  # four contact points...
    assert sim.events["impact"] == 1 == sim.reader.n_impacts_made  # ... one impact
    (entry,) = [e for e in sim.event_log if e[1] == "impact"]
    (record,) = sim.reader.impacts
    assert entry[2:4] == (record.geom1, record.geom2)
    np.testing.assert_allclose(entry[4], record.impulse_pred, rtol=1e-12)  # the four corners' impulses summed


def test_the_report_counts_visual_geoms_in_one_line():
    visual = "".join(f'<geom name="deco{i}" type="sphere" size=".01" pos="0 0 {i}" contype="0" conaffinity="0"/>'
                     for i in range(40))
    model = mujoco.MjModel.from_xml_string(BOX % visual)
    scene = SoundScene.from_model(model, materials={"box": "steel"}, sample_rate=16000, quality="draft",
                                  progress=False)
    report = scene.report()
    line = [l for l in report.splitlines() if "cannot collide" in l]
    assert line == ["  silent: 40 geoms cannot collide (contype = conaffinity = 0) (deco0, deco1, deco2, ...; "
                    "report(details=True) lists them)"]
    detailed = scene.report(details=True)
    assert sum("cannot collide" in l for l in detailed.splitlines()) == 40 and "silent deco39:" in detailed


def test_a_scene_without_materials_warns_and_points_at_the_caller():
    model = mujoco.MjModel.from_xml_string(BOX % "")
    with pytest.warns(UserWarning, match=r"nothing in this scene rings: no colliding geom has an acoustic material") as rec:
        scene = SoundScene.from_model(model, sample_rate=16000, progress=False)
    assert not scene.sounding
    assert [w.filename for w in rec] == [__file__]  # the line above, not mjsound's


def test_a_wrapper_warning_points_at_the_users_line():
    import gymnasium as gym

    from mjsound.wrappers import AudioObservation

    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        AudioObservation(gym.make("HalfCheetah-v5"), default_material=None, progress=False)
    mine = [w for w in rec if "nothing in this scene rings" in str(w.message)]
    assert len(mine) == 1 and mine[0].filename == __file__


def test_a_hint_proposes_only_finer_qualities():
    assert "'default', 'high'" in _finer_quality_hint("draft")
    assert "('high'; now 'default')" in _finer_quality_hint("default")
    assert "finest preset" in _finer_quality_hint("high")


def test_will_not_ring_says_it_once():
    xml = ('<mujoco><worldbody><body name="A" pos="0 0 1"><freejoint/><geom name="pebble" type="sphere" '
           'size=".005"/></body></worldbody></mujoco>')
    with pytest.warns(UserWarning, match="will not ring") as rec:
        SoundScene.from_model(mujoco.MjModel.from_xml_string(xml), materials={"pebble": "steel"}, progress=False)
    (w,) = [w for w in rec if "will not ring" in str(w.message)]
    assert str(w.message).lower().count("still excites what it hits") == 1
