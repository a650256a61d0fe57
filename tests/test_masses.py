"""The sound's objects weigh what MuJoCo says (mjsound.sim.scene_masses): a light body becomes a
hollow wall or a lighter material with the same wave speeds, a heavy one a denser and stiffer
material; the report says which; ``masses="material"`` keeps the materials' densities and warns
only of what the user named."""

import math
import pickle
import warnings

import mujoco
import numpy as np
import pytest

from mjsound.materials import get_material
from mjsound.sim import SoundScene
from mjsound.sim.scene_masses import decide, masses_option

XML = """<mujoco><custom>{custom}</custom><worldbody>
  <body name="can" pos="0 0 0.5"><freejoint/><geom name="can" type="capsule" size="0.02 0.05" mass="{can}"/></body>
  <body name="brick" pos="0.3 0 0.5"><freejoint/><geom name="brick" type="box" size="0.1 0.05 0.005" density="{brick}"/></body>
  <body name="pair" pos="0.6 0 0.5"><freejoint/>
    <geom name="knob" type="sphere" size="0.01" pos="0 0 0.05" density="1000"/>
    <geom name="rod" type="cylinder" size="0.01 0.04" density="1000"/></body>
</worldbody></mujoco>"""

AL = get_material("aluminium")
CAN_V = math.pi * 0.02**2 * (0.1 + 4 / 3 * 0.02)
CAN_A = 2 * math.pi * 0.02 * (0.1 + 0.04)


def _model(can=0.0285, brick=5400, custom=""):
    return mujoco.MjModel.from_xml_string(XML.format(can=can, brick=brick, custom=custom))


def _gid(m, name):
    return m.geom(name).id


def test_the_rule_by_hand():
    """A 28.5 g aluminium capsule of 159 cm^3 (a solid would weigh 429 g) is a wall of
    ``m / (rho A)`` = 0.6 mm, 3 % of its radius: hollow; the same capsule at 8.5 g (a
    0.18 mm foil, under 1 % of the radius) and at 300 g (thick) keep the solid shape with
    density and stiffness scaled (the wave speeds the material's); a brick of density 5400 in
    aluminium is twice as dense and stiff; geoms of one body share its mass by volume."""
    m = _model()
    mat, rule, note = decide(m, [_gid(m, "can")], AL)
    assert rule == "hollow" and mat.wall == pytest.approx(0.0285 / (2700 * CAN_A), rel=1e-9)
    assert mat.E == AL.E and mat.rho == AL.rho and "hollow, a wall of 0.6 mm" in note
    m = _model(can=0.3)
    mat, rule, note = decide(m, [_gid(m, "can")], AL)
    r = 0.3 / (2700 * CAN_V)
    assert rule == "scaled" and mat.wall is None
    assert mat.rho == pytest.approx(2700 * r) and mat.E == pytest.approx(AL.E * r)
    assert math.sqrt(mat.E / mat.rho) == pytest.approx(math.sqrt(AL.E / AL.rho), rel=1e-12)
    m = _model(can=0.0085)  # a foil: the material stays, the report says why
    mat, rule, note = decide(m, [_gid(m, "can")], AL)
    assert rule == "foil" and mat is AL and "foil of 179 um" in note
    mat, rule, _ = decide(m, [_gid(m, "brick")], AL)
    assert rule == "scaled" and mat.rho == pytest.approx(5400) and mat.E == pytest.approx(2 * AL.E)
    mat, rule, _ = decide(m, [_gid(m, "brick")], AL.scaled(2.0, 2.0))
    assert rule == "solid"
    # the knob's share of its body: its volume over the body's (MuJoCo: density 1000 for both)
    v_knob, v_rod = 4 / 3 * math.pi * 0.01**3, math.pi * 0.01**2 * 0.08
    mat, rule, note = decide(m, [_gid(m, "knob")], get_material("steel"))
    assert m.body("pair").mass[0] == pytest.approx(1000 * (v_knob + v_rod))
    # its share, 1000 v_knob, over a steel surface: a wall of 0.42 mm (4 % of its radius)
    assert rule == "hollow" and mat.wall == pytest.approx(1000 * v_knob / (7850 * 4 * math.pi * 0.01**2), rel=1e-9)
    world = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom name="g" type="box" size=".1 .1 .1"/>'
                                           "</worldbody></mujoco>")
    assert decide(world, [0], AL)[1] == "none"  # the world's geoms have no MuJoCo mass


def test_scene_objects_get_mujocos_masses_and_the_report_says_how():
    m = _model()
    scene = SoundScene.from_model(m, materials={"*": "aluminium"}, sample_rate=16000, quality="draft", progress=False,
                                  error_estimate=False)
    obj = {s.name: s for s in scene.sounding}
    can, brick = obj["can"], obj["brick"]
    assert can.mass_rule == "hollow" and can.material.wall == pytest.approx(0.0285 / (2700 * CAN_A), rel=1e-9)
    assert can.model.mass_kg == pytest.approx(0.0285, rel=0.15)  # (the wall inside a voxelised surface)
    assert brick.mass_rule == "scaled" and brick.model.mass_kg == pytest.approx(m.body("brick").mass[0], rel=1e-3)
    rep = scene.report()
    assert "hollow, a wall of 0.6 mm" in rep and "density and stiffness x2" in rep
    kept = SoundScene.from_model(m, materials={"*": "aluminium"}, sample_rate=16000, quality="draft",
                                 progress=False, error_estimate=False, masses="material")
    ref = {s.name: s for s in kept.sounding}["brick"]
    assert ref.mass_rule == "kept" and ref.model.mass_kg == pytest.approx(brick.model.mass_kg / 2, rel=1e-3)
    np.testing.assert_allclose(brick.model.frequencies_hz, ref.model.frequencies_hz, rtol=1e-6)


def test_masses_option_and_warnings_only_for_named_materials():
    m = _model(can=0.3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the default material, the default rule: nothing to warn of
        SoundScene.from_model(m, materials={"*": "aluminium"}, sample_rate=16000, quality="draft", progress=False,
                              error_estimate=False, masses="material")
        SoundScene.from_model(m, materials={"brick": "aluminium"}, sample_rate=16000, quality="draft",
                              progress=False, error_estimate=False)
    with pytest.warns(UserWarning, match=r"whose material you named differ in mass.*brick"):
        SoundScene.from_model(m, materials={"brick": "aluminium"}, sample_rate=16000, quality="draft",
                              progress=False, error_estimate=False, masses="material")
    texted = _model(can=0.3, custom='<text name="mjsound-masses" data="material"/>')
    assert masses_option(texted, None) == "material" and masses_option(texted, "mujoco") == "mujoco"
    assert masses_option(m, None) == "mujoco"
    with pytest.raises(ValueError, match=r"masses='solid'.*'mujoco'.*'material'"):
        masses_option(m, "solid")
    bad = _model(custom='<text name="mjsound-masses" data="heavy"/>')
    with pytest.raises(ValueError, match="MJCF custom text 'mjsound-masses'"):
        masses_option(bad, None)


_STUB = dict(materials={"*": "aluminium"}, sample_rate=16000, quality="draft", progress=False, error_estimate=False)


def _rules(scene):
    return {s.name: (s.mass_rule, s.material, s.notes) for s in scene.sounding}


def test_a_scenes_models_given_back_keep_its_mass_rules(fake_analyze):
    """A batch worker builds its scene from the driver's models (pickled): each keeps the mass
    rule, the analysed material and the note it was analysed under (a hollow wall that lost
    its rule took Hertz's contact time instead of the shell's: tests/test_batch.py's audio
    differed by 10 % of the peak); a model of another material keeps its own, rule "kept"."""
    from mjsound.sim.stub import stub_model

    m = _model()
    ref = SoundScene.from_model(m, **_STUB)
    n = len(fake_analyze)
    assert {k: v[0] for k, v in _rules(ref).items()} == {"can": "hollow", "brick": "scaled", "pair": "scaled"}
    models = pickle.loads(pickle.dumps({s.name: s.model for s in ref.sounding}))
    got = SoundScene.from_model(m, models=models, **_STUB)
    assert len(fake_analyze) == n  # nothing analysed again
    assert _rules(got) == _rules(ref)
    assert all(g.model is models[g.name] for g in got.sounding)
    foreign = SoundScene.from_model(m, models={"brick": stub_model("box:0.2,0.1,0.01", AL, 8, 430.0)}, **_STUB)
    rule, mat, notes = _rules(foreign)["brick"]
    assert (rule, mat) == ("kept", AL) and notes[0].startswith("mass 0.54 kg (aluminium) against MuJoCo's 1.08 kg")
    assert _rules(foreign)["can"] == _rules(ref)["can"]


def test_a_hollow_fallbacks_model_given_back_keeps_the_fallback(monkeypatch):
    """A hollow wall the analysis cannot resolve is analysed scaled (``_object_model``); that
    model given back is recognised as the fallback's, with its rule and note."""
    import mjsound.modal.analyze as an
    from mjsound.sim.stub import stub_model

    def no_walls(mesh, material, **kw):
        if material.wall is not None:
            raise RuntimeError("wall too thin")
        return stub_model(mesh, material, 8, 430.0)

    monkeypatch.setattr(an, "analyze", no_walls)
    m = _model()
    ref = SoundScene.from_model(m, **_STUB)
    rule, mat, notes = _rules(ref)["can"]
    assert rule == "scaled" and mat.wall is None and "as a hollow wall of 0.6 mm it could not be analysed" in notes[0]
    models = pickle.loads(pickle.dumps({s.name: s.model for s in ref.sounding}))
    assert _rules(SoundScene.from_model(m, models=models, **_STUB)) == _rules(ref)
