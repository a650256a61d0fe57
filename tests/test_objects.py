"""Sounding objects as users have them (issue 15): bodies of several geoms, named sound meshes,
checked material keys, masses against MuJoCo's, what the report says, budgets of large solids.

Modal models are seeded stubs or a recording fake ``analyze`` wherever the analysis itself is
not the point, so the file runs in seconds."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pytest

from mjsound.geometry import load_mesh
from mjsound.materials import get_material
from mjsound.sim.objects import PART_GAP, object_surface
from mjsound.sim.scene import AUTO_MAX_MODES, SoundScene
from mjsound.sim.scene_analysis import BAND_MARGIN
from mjsound.sim.simulator import AudioSimulator
from mjsound.sim.stub import stub_model
from tests.scenes import TABLE_XML, table_model


def gid(model, name):
    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)


def world_vertices(model, data, g, V):
    """Vertices ``V`` of geom ``g``'s frame in the world."""
    return V @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g]


def sorted_rows(a):
    a = np.round(np.asarray(a), 9)
    return a[np.lexsort(a.T[::-1])]


@pytest.fixture
def recorded(monkeypatch):
    """A fake ``analyze`` that records its calls and returns stubs."""
    import mjsound.modal.analyze as an

    calls = []

    def fake(mesh, material, **kw):
        calls.append({"mesh": mesh, "material": material.name, "wall": material.wall, **kw})
        return stub_model(mesh, material, 4, 900.0)

    monkeypatch.setattr(an, "analyze", fake)
    return calls


def test_a_body_of_several_geoms_is_one_object_in_its_anchor_frame(recorded):
    model = table_model()
    scene = SoundScene.from_model(model, materials={"table": "steel"}, progress=False)
    (obj,) = scene.sounding
    leg, top = gid(model, "leg"), gid(model, "top")
    assert obj.name == "table" and obj.geom_ids == (leg, top) and obj.geom_id == leg
    assert scene.by_geom() == {leg: obj, top: obj}
    # the analysed surface, put into the world by the anchor's pose, is both geoms where they are
    (call,) = recorded
    V, F = call["mesh"]
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    union_world = world_vertices(model, data, leg, V)
    expected = []
    for g in (leg, top):
        corners = np.array(np.meshgrid(*[[-1, 1]] * 3)).reshape(3, -1).T * model.geom_size[g]
        expected.append(world_vertices(model, data, g, corners))
    # (each part shrunk by PART_GAP about its centre, so that touching parts stay two closed surfaces)
    np.testing.assert_allclose(sorted_rows(union_world), sorted_rows(np.vstack(expected)), atol=PART_GAP * 0.4)
    assert not np.allclose(sorted_rows(union_world), sorted_rows(np.vstack(expected)), atol=1e-12, rtol=0)
    assert len(F) == 24
    # per-geom stays an option
    per_geom = SoundScene.from_model(model, materials={"table": "steel"}, progress=False, objects="geom")
    assert [s.name for s in per_geom.sounding] == ["leg", "top"]
    with pytest.raises(ValueError, match="objects="):
        SoundScene.from_model(model, materials={"table": "steel"}, progress=False, objects="bodies")


def test_a_hit_on_any_geom_of_the_body_rings_the_one_object():
    model = table_model()
    leg, top = gid(model, "leg"), gid(model, "top")
    V, F = object_surface(model, [leg, top])[0]
    models = {"table": stub_model((V, F), "steel", 6, 700.0)}
    scene = SoundScene.from_model(model, materials={"table": "steel"}, models=models, progress=False)
    sim = AudioSimulator(model, scene=scene, sample_rate=16000)
    assert sim.geom_objects[leg] == sim.geom_objects[top] >= 0  # both geoms excite the same object
    y = sim.run(0.4)
    hits = [r for r in sim.impacts if top in (r.geom1, r.geom2)]
    assert hits and not any(leg in (r.geom1, r.geom2) for r in sim.impacts)
    assert np.max(np.abs(y)) > 0  # the top was hit, the table (anchored at the leg) rang


def test_sound_mesh_named_in_mjcf_or_python(recorded):
    model = table_model(custom='<text name="mjsound-mesh:table" data="look"/>')
    scene = SoundScene.from_model(model, materials={"table": "steel"}, progress=False)
    (obj,) = scene.sounding
    assert obj.mesh == "sound mesh: geom look"
    V, _ = recorded[-1]["mesh"]
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    look = gid(model, "look")
    spec, _ = object_surface(model, [look])  # the cylinder's built-in spec, in its own frame
    Vl = np.asarray(load_mesh(spec).vertices)
    np.testing.assert_allclose(sorted_rows(world_vertices(model, data, obj.geom_id, V)),
                               sorted_rows(world_vertices(model, data, look, Vl)), atol=1e-9)
    # in Python, in the body frame: a box of the top's size at the body origin
    model = table_model()
    SoundScene.from_model(model, materials={"table": "steel"}, progress=False,
                          sound_meshes={"table": "box:0.4,0.2,0.02"})
    V, _ = recorded[-1]["mesh"]
    top = gid(model, "top")
    body_to_world = world_vertices(model, data, obj.geom_id, V)
    np.testing.assert_allclose(np.sort(np.unique(np.round(body_to_world[:, 2], 9))),
                               sorted({round(float(data.geom_xpos[top][2]) + s * 0.01, 9) for s in (-1, 1)}), atol=1e-9)
    with pytest.raises(ValueError, match="not a geom, mesh asset"):
        SoundScene.from_model(model, materials={"table": "steel"}, progress=False, sound_meshes={"table": "lok"})
    with pytest.raises(ValueError, match="closest: 'table'"):
        SoundScene.from_model(model, materials={"table": "steel"}, progress=False, sound_meshes={"tabel": "look"})
    with pytest.raises(ValueError, match="sound mesh for 'ball': no sounding object"):  # the ball has no material
        SoundScene.from_model(model, materials={"table": "steel"}, progress=False, sound_meshes={"ball": "look"})
    typo = table_model(custom='<text name="mjsound-mesh:tabel" data="look"/>')  # a typo in the MJCF
    with pytest.warns(UserWarning, match="'mjsound-mesh:tabel' names nothing.*closest: 'table'"):
        scene = SoundScene.from_model(typo, materials={"table": "steel"}, progress=False)
    assert scene.sounding[0].mesh.startswith("union")  # (ignored)


def test_material_keys_are_checked_and_every_form_works(recorded):
    xml = """<mujoco><worldbody>
      <body name="b1" pos="0 0 1"><freejoint/><geom type="box" size=".05 .05 .05"/></body>
      <body name="b2" pos="0 0 2"><freejoint/><geom type="box" size=".05 .05 .05"/></body>
      <body name="b3" pos="0 0 3"><freejoint/><geom name="named" type="box" size=".05 .05 .05"/></body>
    </worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    scene = SoundScene.from_model(model, materials={"geom0": "steel", 1: "glass", "*": "oak"}, progress=False)
    got = {s.name: (s.material.name, s.source) for s in scene.sounding}
    # (an unnamed geom alone in a named body is named like the body)
    assert got == {"b1": ("steel", "mapping"), "b2": ("glass", "mapping"), "named": ("oak", "default")}
    with pytest.raises(ValueError, match=r"no geom or body named 'nmaed'.*closest: 'named'"):
        SoundScene.from_model(model, materials={"nmaed": "steel"}, progress=False)
    with pytest.raises(ValueError, match="geom id 7 out of range"):
        SoundScene.from_model(model, materials={7: "steel"}, progress=False)
    with pytest.raises(ValueError, match="unknown material"):
        SoundScene.from_model(model, materials={"*": "stele"}, progress=False)
    typo = mujoco.MjModel.from_xml_string(xml.replace("<worldbody>", '<custom><text name="mjsound:nmaed" '
                                                                      'data="steel"/></custom><worldbody>'))
    with pytest.warns(UserWarning, match="custom text 'mjsound:nmaed' names nothing in this model.*closest: 'named'"):
        SoundScene.from_model(typo, progress=False)
    with pytest.raises(ValueError, match="models: no sounding object named 'nam'"):
        SoundScene.from_model(model, materials={"*": "oak"}, progress=False, models={"nam": stub_model()})


def test_a_named_object_that_cannot_ring_says_so():
    xml = """<mujoco><worldbody>
      <body name="A" pos="0 0 1"><freejoint/><geom name="pebble" type="sphere" size=".005"/></body>
      <body name="B" pos="0 0 2"><freejoint/><geom name="grit" type="sphere" size=".005"/></body>
    </worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    with pytest.warns(UserWarning, match=r"'pebble' \(steel.*will not ring: no audible modes.*higher sample_rate"):
        scene = SoundScene.from_model(model, materials={"pebble": "steel", "*": "steel"}, progress=False)
    assert "no audible modes" in scene.silent["grit"]
    with warnings.catch_warnings(record=True) as caught:  # given by "*" only: one warning for the scene
        warnings.simplefilter("always")
        SoundScene.from_model(model, materials={"*": "steel"}, progress=False)
    (w,) = caught
    assert "nothing in this scene rings: 2 object(s)" in str(w.message) and "will not ring" not in str(w.message)


def test_masses_are_compared_with_mujocos():
    model = table_model(density=1000)  # steel is 7850 kg/m^3
    V, F = object_surface(model, [gid(model, "leg"), gid(model, "top")])[0]
    models = {"table": stub_model((V, F), "steel", 4, 900.0)}
    with pytest.warns(UserWarning, match=r"differ in mass from MuJoCo's.*table"):
        scene = SoundScene.from_model(model, materials={"table": "steel"}, models=models, progress=False)
    (obj,) = scene.sounding
    vol = 0.4 * 0.2 * 0.02 + 0.02 * 0.04 * 0.28
    assert obj.model.mass_kg == pytest.approx(7850 * vol, rel=1e-5)
    ref = float(model.body_mass[obj.body_id])  # MuJoCo: density 1000, the visual cylinder included
    assert ref == pytest.approx(1000 * (vol + np.pi * 0.12**2 * 0.04), rel=1e-6)
    assert any(f"{100 * (7850 * vol / ref - 1):+.0f} %" in n for n in obj.notes) and "against MuJoCo's" in scene.report()
    # the visual cylinder has density too (MuJoCo counts it): the body is heavier than the boxes,
    # so give it no mass for an exact match
    xml = TABLE_XML.format(custom="", density=7850).replace('group="1"', 'group="1" mass="0"')
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scene = SoundScene.from_model(mujoco.MjModel.from_xml_string(xml), materials={"table": "steel"},
                                      models=models, progress=False)
    assert not scene.sounding[0].notes


def test_report_shows_error_estimates_and_open_surfaces():
    model = table_model()
    mm = stub_model("box:0.4,0.2,0.02", "steel", 4, 900.0)
    mm.error_estimate_cents = 80.0
    mm.info = {"watertight": False, "h": [0.01, 0.01, 0.01], "refine": 2}
    scene = SoundScene.from_model(model, materials={"table": "steel"}, models={"table": mm}, progress=False,
                                  objects="body")
    rep = scene.report()
    assert "+-80 c (!)" in rep and "estimated frequency error above 50 cents" in rep
    assert "not a closed surface" in rep and "analysed as a wall 5 mm thick" in rep
    summary = scene.summary()["sounding"][0]
    assert summary["error_estimate_cents"] == 80.0 and summary["geoms"] == ["leg", "top"]


def test_large_solids_get_a_mode_budget(recorded):
    xml = """<mujoco><worldbody>
      <body name="slab" pos="0 0 0.5"><geom name="slab" type="box" size="0.5 0.4 0.2"/></body>
      <body name="cube" pos="2 0 0.5"><freejoint/><geom name="cube" type="box" size="0.02 0.02 0.02"/></body>
    </worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    scene = SoundScene.from_model(model, materials={"*": "aluminium"}, sample_rate=48000, progress=False)
    caps = {c["mesh"]: (c["max_modes"], c["f_max"]) for c in recorded}
    assert caps["box:0.04,0.04,0.04"] == (None, None)
    n, f_band = caps["box:1,0.8,0.4"]
    # Weyl: N(f) = 2 (4 pi / 3) V f^3 (1/cL^3 + 2/cT^3); the band ends BAND_MARGIN above the
    # estimated frequency of the 64th mode
    al = get_material("aluminium")
    cT = np.sqrt(al.shear_modulus / al.rho)
    cL = cT * np.sqrt(2 * (1 - al.nu) / (1 - 2 * al.nu))
    f64 = (AUTO_MAX_MODES / (2 * 4 * np.pi / 3 * 0.32 * (1 / cL**3 + 2 / cT**3))) ** (1 / 3)
    assert n == AUTO_MAX_MODES and f_band == pytest.approx(BAND_MARGIN * f64, rel=1e-9) and f_band < 0.45 * 48000
    slab = [s for s in scene.sounding if s.name == "slab"][0]
    assert any("large solid" in n and f"lowest {AUTO_MAX_MODES}, analysed to {f_band / 1000:.1f} kHz" in n
               for n in slab.notes)
    recorded.clear()
    SoundScene.from_model(model, materials={"*": "aluminium"}, sample_rate=48000, progress=False,
                          max_modes_per_object=None)
    assert {(c["max_modes"], c["f_max"]) for c in recorded} == {(None, None)}


def test_touching_geoms_of_a_body_analyse_as_one_solid():
    """Two 20 x 20 x 1 cm aluminium plates edge to edge (sharing a face) and a third overlapping
    both: the union is a solid plate of their combined volume, not the hollow shell that welding
    the shared face would make of it."""
    xml = """<mujoco><worldbody><body name="plate" pos="0 0 1"><freejoint/>
      <geom type="box" size=".1 .1 .005"/><geom type="box" size=".1 .1 .005" pos=".2 0 0"/>
      <geom type="box" size=".05 .05 .005" pos=".1 0 0"/></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (MuJoCo counts the overlap twice in its mass)
        scene = SoundScene.from_model(model, materials={"*": "aluminium"}, sample_rate=16000, quality="draft",
                                      progress=False, error_estimate=False, masses="material")
    (plate,) = scene.sounding
    assert len(plate.geom_ids) == 3 and plate.model.info["watertight"] and plate.model.n_modes > 3
    assert plate.model.mass_kg == pytest.approx(2700 * 0.4 * 0.2 * 0.01, rel=1e-3)
    assert not any("closed" in n for n in plate.notes)
    # MuJoCo's masses (the default): density 1000 (scaled with the stiffness: the same modes)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        light = SoundScene.from_model(model, materials={"*": "aluminium"}, sample_rate=16000, quality="draft",
                                      progress=False, error_estimate=False).sounding[0]
    assert light.mass_rule == "scaled" and light.model.mass_kg == pytest.approx(1000 * 0.4 * 0.2 * 0.01, rel=1e-3)
    np.testing.assert_allclose(light.model.frequencies_hz, plate.model.frequencies_hz, rtol=1e-6)


def test_cli_materials_take_the_star_and_report_objects(tmp_path, capsys):
    """``mjsound sonify --materials '{"*": ...}'``: the default reaches every geom without one,
    and the printed report names the object (here a body of two plates) with its notes."""
    import json

    from mjsound.cli import main

    xml = tmp_path / "scene.xml"
    xml.write_text("""<mujoco><option timestep="0.002"/><worldbody><geom name="floor" type="plane" size="1 1 .1"/>
      <body name="tray" pos="0 0 0.05"><freejoint/><geom type="box" size=".1 .1 .005"/>
      <geom type="box" size=".1 .1 .005" pos=".2 0 0"/></body></worldbody></mujoco>""")
    rc = main(["sonify", str(xml), "-o", str(tmp_path / "out.wav"), "--duration", "0.1", "--sample-rate", "16000",
               "--quality", "draft", "--materials", json.dumps({"*": "aluminium"})])
    out = capsys.readouterr().out
    assert rc == 0 and "sounding   1 object(s)" in out and "tray" in out and "aluminium" in out
    # density 1000 in the MJCF, aluminium in the sound: the sound takes MuJoCo's mass
    assert "mass: density and stiffness x0.37" in out and "MuJoCo's 0.8 kg" in out
    rc = main(["sonify", str(xml), "-o", str(tmp_path / "out.wav"), "--duration", "0.1", "--materials",
               json.dumps({"tary": "aluminium"})])
    assert rc == 2 and "no geom or body named 'tary'; closest: 'tray'" in capsys.readouterr().err


def test_a_wall_in_the_material_reaches_the_analysis(recorded):
    """``wall=`` (hollow objects given by their outer surface) passes through to ``analyze``, and a
    hollow object gets no large-solid mode budget (it is not a solid)."""
    xml = """<mujoco><worldbody><body name="tank" pos="0 0 1"><freejoint/>
      <geom type="cylinder" size=".4 .5"/><geom type="box" size=".1 .1 .1" pos="0 0 .6"/></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    SoundScene.from_model(model, materials={"tank": "steel,wall=2mm"}, sample_rate=48000, progress=False)
    (call,) = recorded
    assert call["wall"] == pytest.approx(0.002) and call["material"] == "steel"
    assert call["max_modes"] is None and call["f_max"] is None
    recorded.clear()
    SoundScene.from_model(model, materials={"tank": "steel"}, sample_rate=48000, progress=False)
    assert recorded[0]["wall"] is None and recorded[0]["max_modes"] == AUTO_MAX_MODES
