import math

import pytest

from mjsound.materials import MATERIALS, Material, get_material, parse_material


def test_table_has_common_materials_with_plausible_values():
    for name in ["steel", "stainless_steel", "aluminium", "brass", "copper", "glass", "porcelain",
                 "ceramic", "oak", "pine", "abs", "polycarbonate", "rubber", "concrete"]:
        m = get_material(name)
        assert 1e6 <= m.E <= 2e12 and 300 <= m.rho <= 20000 and -1 < m.nu < 0.5
    assert len(MATERIALS) >= 12
    # wave speeds within textbook ranges: steel ~3.2 km/s shear, rubber far slower
    cs = lambda m: math.sqrt(m.shear_modulus / m.rho)
    assert 3000 < cs(get_material("steel")) < 3400
    assert cs(get_material("rubber")) < 50


def test_aliases_and_case():
    assert get_material("Aluminum") is get_material("aluminium")
    assert get_material("STAINLESS-steel").name == "stainless_steel"


def test_unknown_material_lists_known_ones():
    with pytest.raises(KeyError) as e:
        get_material("unobtainium")
    assert "steel" in str(e.value) and "E=70e9" in str(e.value)


def test_inline_spec_and_override():
    m = parse_material("E=70e9,nu=0.33,rho=2700,alpha=2,beta=1e-7")
    assert (m.E, m.nu, m.rho, m.alpha, m.beta) == (70e9, 0.33, 2700, 2, 1e-7)
    s = parse_material("steel,alpha=0")
    assert s.alpha == 0 and s.E == get_material("steel").E


@pytest.mark.parametrize(
    "spec, word",
    [("E=70e9,nu=0.5,rho=2700", "nu"), ("E=70e9,nu=-1,rho=2700", "nu"), ("E=0,nu=0.3,rho=2700", "E"),
     ("E=70e9,nu=0.3,rho=-1", "rho"), ("E=nan,nu=0.3,rho=1", "E"), ("E=70e9,nu=0.3", "rho"),
     ("E=70e9,nu=0.3,rho=1,alpha=-1", "alpha"), ("E=1e9,nu=0.3,rho=1,colour=3", "colour")],
)
def test_impossible_values_rejected(spec, word):
    with pytest.raises(ValueError) as e:
        parse_material(spec)
    assert word in str(e.value)


def test_material_is_hashable_key_stable():
    a = Material(E=1e9, nu=0.3, rho=1000)
    assert a.key() == Material(E=1e9, nu=0.3, rho=1000).key()
    assert a.key() != Material(E=1e9, nu=0.3, rho=1001).key()


@pytest.mark.parametrize("text, metres", [("0.12mm", 0.12e-3), ("4 mm", 4e-3), ("0.4cm", 4e-3), ("120um", 120e-6),
                                          ("0.002", 0.002), ("2e-3m", 2e-3)])
def test_wall_in_inline_spec_with_units(text, metres):
    m = parse_material(f"aluminium,wall={text}")
    assert m.wall == pytest.approx(metres, rel=1e-12)
    assert m.E == get_material("aluminium").E and m.name == "aluminium"
    assert m.key() != get_material("aluminium").key()  # hollow objects are cached apart


@pytest.mark.parametrize("text", ["-1mm", "0mm", "2 furlongs", "mm", "nan", "inf m"])
def test_bad_wall_named(text):
    with pytest.raises(ValueError, match="wall|length"):
        parse_material(f"aluminium,wall={text}")


def test_solid_material_key_unchanged_by_wall_field():
    assert "wall" not in get_material("steel").key()
    assert Material(E=1e9, nu=0.3, rho=1000, wall=0.001).wall == 0.001
    with pytest.raises(ValueError, match="wall"):
        Material(E=1e9, nu=0.3, rho=1000, wall=-0.001)


def test_two_base_materials_refused():
    with pytest.raises(ValueError, match="two base materials.*'steel'.*'glass'"):
        parse_material("steel,glass,alpha=0")
    with pytest.raises(ValueError, match="given twice"):
        parse_material("steel,alpha=0,alpha=1")
