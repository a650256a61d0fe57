"""Acoustic materials: elastic constants, density and Rayleigh damping.

A :class:`Material` holds what modal analysis and contact need:

* ``E``   Young's modulus [Pa]
* ``nu``  Poisson's ratio [-], in (-1, 0.5)
* ``rho`` density [kg/m^3]
* ``alpha``, ``beta`` Rayleigh damping, ``C = alpha*M + beta*K`` [1/s] and [s];
  mode i decays at ``d_i = (alpha + beta*omega_i**2) / 2`` [1/s]
* ``restitution`` coefficient of restitution against a hard surface [-], in [0, 1]
* ``wall`` wall thickness [m] of a hollow object made of it, or None (solid); inline
  specs accept units: ``"aluminium,wall=0.12mm"`` (see :func:`parse_length`)

Sources of the table values
---------------------------
Elastic constants and densities are typical room-temperature handbook values:
[C] Callister & Rethwisch, *Materials Science and Engineering*, 10th ed., Appendix B;
[A] ASM Handbook vol. 2 (non-ferrous) and vol. 1 (steels);
[W] US Forest Products Laboratory, *Wood Handbook* FPL-GTR-282 (2021), tables 5-3a / 4-3a
(longitudinal modulus, 12 % moisture; wood is treated as isotropic, which it is not);
[P] manufacturer datasheets summarised in Callister App. B for ABS / polycarbonate;
[R] Gent, *Engineering with Rubber*, 3rd ed. (small-strain modulus of a 60 Shore A rubber);
[K] Neville, *Properties of Concrete*, 5th ed. (normal-strength concrete, 30 MPa).
[H] tungsten carbide and diamond: ASM *Engineered Materials Handbook* / Field,
*The Properties of Natural and Synthetic Diamond* (1992).

Rayleigh damping is perceptual rather than measured: the values follow the per-class
fits of Ren, Yeh and Lin, *Example-guided physically based modal sound synthesis*,
ACM TOG 32(1), 2013, table 2 (ceramic, glass, wood, plastic, iron/steel,
polycarbonate), with the metals scaled among themselves by their loss factors in
[A]; rubber and concrete are damped heavily by choice (they thud). Restitution
coefficients are typical ball-drop values ([C], and Cross, *Am. J. Phys.* 67, 1999).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

__all__ = ["Material", "MATERIALS", "get_material", "parse_material", "parse_length"]


@dataclass(frozen=True)
class Material:
    """An isotropic linear-elastic material with Rayleigh damping.

    Parameters
    ----------
    E : float
        Young's modulus in Pa (> 0).
    nu : float
        Poisson's ratio, strictly inside (-1, 0.5).
    rho : float
        Density in kg/m^3 (> 0).
    alpha : float
        Mass-proportional Rayleigh damping in 1/s (>= 0).
    beta : float
        Stiffness-proportional Rayleigh damping in s (>= 0).
    restitution : float
        Coefficient of restitution in [0, 1].
    name : str
        Label used in reports and cache keys.
    wall : float or None
        Wall thickness in m (> 0) when the object is hollow: modal analysis turns a
        closed outer surface into a wall of this thickness inside it and gives an open
        surface exactly this thickness. None: solid (closed meshes) or the analysis'
        own ``thickness`` (open meshes).

    Examples
    --------
    >>> steel = Material(E=200e9, nu=0.29, rho=7850, alpha=5.0, beta=3e-8, name="steel")
    >>> round(steel.shear_modulus / 1e9, 1)
    77.5
    """

    E: float
    nu: float
    rho: float
    alpha: float = 0.0
    beta: float = 0.0
    restitution: float = 0.5
    name: str = "custom"
    wall: float | None = None

    def __post_init__(self):
        def bad(field, value, why):
            raise ValueError(
                f"material {self.name!r}: {field}={value!r} is {why}. "
                "Give E>0 [Pa], -1<nu<0.5, rho>0 [kg/m^3], alpha>=0 [1/s], beta>=0 [s], "
                "0<=restitution<=1, e.g. 'E=70e9,nu=0.33,rho=2700'."
            )

        for field in ("E", "nu", "rho", "alpha", "beta", "restitution"):
            value = getattr(self, field)
            try:
                value = float(value)
            except (TypeError, ValueError):
                bad(field, value, "not a number")
            if not math.isfinite(value):
                bad(field, value, "not finite")
            object.__setattr__(self, field, value)
        if self.E <= 0:
            bad("E", self.E, "not positive")
        if self.rho <= 0:
            bad("rho", self.rho, "not positive")
        if not -1.0 < self.nu < 0.5:
            bad("nu", self.nu, "outside (-1, 0.5) (0.5 is incompressible: no finite bulk modulus)")
        if self.alpha < 0:
            bad("alpha", self.alpha, "negative (negative damping makes modes grow)")
        if self.beta < 0:
            bad("beta", self.beta, "negative (negative damping makes modes grow)")
        if not 0.0 <= self.restitution <= 1.0:
            bad("restitution", self.restitution, "outside [0, 1]")
        if self.wall is not None:
            try:
                wall = float(self.wall)
            except (TypeError, ValueError):
                bad("wall", self.wall, "not a length in metres")
            if not (math.isfinite(wall) and wall > 0):
                bad("wall", self.wall, "not a positive finite length in metres")
            object.__setattr__(self, "wall", wall)

    @property
    def shear_modulus(self) -> float:
        """G = E / (2 (1 + nu)) in Pa."""
        return self.E / (2.0 * (1.0 + self.nu))

    @property
    def lame(self) -> tuple[float, float]:
        """Lamé parameters (lambda, mu) in Pa."""
        lam = self.E * self.nu / ((1.0 + self.nu) * (1.0 - 2.0 * self.nu))
        return lam, self.shear_modulus

    def scaled(self, stiffness: float = 1.0, density: float = 1.0) -> "Material":
        """A copy with E multiplied by ``stiffness`` and rho by ``density``."""
        d = asdict(self)
        d["E"] *= stiffness
        d["rho"] *= density
        return Material(**d)

    def to_dict(self) -> dict:
        return asdict(self)

    def key(self) -> str:
        """Stable text for cache keys (full float precision); a solid material's key
        does not mention ``wall``."""
        items = {k: v for k, v in asdict(self).items() if not (k == "wall" and v is None)}
        return ",".join(f"{k}={v!r}" for k, v in sorted(items.items()))


def _m(name, E, nu, rho, alpha, beta, e):
    return name, Material(E=E, nu=nu, rho=rho, alpha=alpha, beta=beta, restitution=e, name=name)


#: Named materials. Source letters refer to the module docstring.
MATERIALS: dict[str, Material] = dict(
    [
        _m("steel", 200e9, 0.29, 7850, 5.0, 3e-8, 0.6),  # [C] plain carbon steel
        _m("stainless_steel", 193e9, 0.30, 8000, 5.0, 4e-8, 0.6),  # [A] AISI 304
        _m("aluminium", 70e9, 0.33, 2700, 5.0, 5e-8, 0.55),  # [C] (design reference values)
        _m("brass", 100e9, 0.34, 8500, 4.0, 4e-8, 0.55),  # [A] C26000 cartridge brass
        _m("copper", 117e9, 0.34, 8940, 5.0, 6e-8, 0.5),  # [C] annealed copper
        _m("iron", 170e9, 0.27, 7200, 5.0, 1e-7, 0.5),  # [A] grey cast iron, Ren et al. 'iron'
        _m("titanium", 110e9, 0.34, 4500, 4.0, 5e-8, 0.55),  # [C] commercially pure Ti
        _m("glass", 70e9, 0.22, 2500, 1.0, 1e-7, 0.7),  # [C] soda-lime glass
        _m("porcelain", 70e9, 0.17, 2400, 6.0, 1e-7, 0.6),  # [C] vitrified porcelain
        _m("ceramic", 100e9, 0.22, 2600, 6.0, 1e-7, 0.6),  # [C] alumina-rich stoneware
        _m("oak", 12.3e9, 0.35, 750, 60.0, 2e-6, 0.5),  # [W] red oak, along the grain
        _m("pine", 9.0e9, 0.35, 500, 60.0, 2e-6, 0.5),  # [W] eastern white pine / Picard's pine ~12 GPa
        _m("abs", 2.3e9, 0.35, 1050, 30.0, 1e-6, 0.6),  # [P] ABS
        _m("polycarbonate", 2.4e9, 0.37, 1200, 0.5, 4e-7, 0.65),  # [P] PC, Ren et al. 'polycarbonate'
        _m("acrylic", 3.2e9, 0.37, 1180, 20.0, 8e-7, 0.6),  # [P] PMMA
        _m("rubber", 3.6e6, 0.49, 1100, 200.0, 1e-4, 0.8),  # [R] 60 Shore A, nearly incompressible
        _m("concrete", 30e9, 0.20, 2400, 100.0, 2e-6, 0.3),  # [K] normal-strength concrete
        _m("tungsten_carbide", 600e9, 0.24, 15600, 2.0, 1e-8, 0.7),  # [H] cemented WC
        _m("diamond", 1050e9, 0.10, 3510, 1.0, 1e-9, 0.7),  # [H] single crystal, averaged
    ]
)

_ALIASES = {
    "aluminum": "aluminium",
    "stainless": "stainless_steel",
    "stainless-steel": "stainless_steel",
    "wood": "oak",
    "plastic": "abs",
    "pc": "polycarbonate",
    "pmma": "acrylic",
    "metal": "steel",
    "stoneware": "ceramic",
    "wc": "tungsten_carbide",
}


def get_material(name: str) -> Material:
    """Look up a named material (case-insensitive; ``-``/space count as ``_``).

    Raises
    ------
    KeyError
        With the list of known names when ``name`` is unknown.
    """
    key = str(name).strip().lower().replace("-", "_").replace(" ", "_")
    key = _ALIASES.get(key, key)
    if key not in MATERIALS:
        raise KeyError(
            f"unknown material {name!r}. Known: {', '.join(sorted(MATERIALS))}; "
            "or give one inline as 'E=70e9,nu=0.33,rho=2700[,alpha=..,beta=..,restitution=..]'."
        )
    return MATERIALS[key]


def parse_material(spec: "str | Material | dict") -> Material:
    """A material from a name, an inline spec ``"E=70e9,nu=0.33,rho=2700"``, a dict or a Material.

    Inline specs may start from one named material and override fields:
    ``"steel,alpha=0"``; ``wall=`` makes the object hollow with that wall thickness
    (units m, cm, mm, um; a bare number is metres): ``"aluminium,wall=0.12mm"``.

    Raises
    ------
    ValueError
        An unknown or repeated field, a value that is not a number (or length), two base
        materials (``"steel,glass"``), missing E/nu/rho, or an impossible value.
    KeyError
        An unknown material name.
    """
    if isinstance(spec, Material):
        return spec
    if isinstance(spec, dict):
        return Material(**spec)
    text = str(spec).strip()
    if "=" not in text:
        return get_material(text)
    base: dict = {}
    base_name = None
    fields: dict = {}
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        if "=" not in part:
            if base_name is not None:
                raise ValueError(
                    f"material spec {spec!r} names two base materials ({base_name!r} and {part!r}); "
                    f"give one, then the fields to override, e.g. '{base_name},alpha=0'"
                )
            base_name = part
            base = get_material(part).to_dict()
            continue
        k, v = (s.strip() for s in part.split("=", 1))
        if k not in _SPEC_FIELDS:
            raise ValueError(
                f"material spec {spec!r}: unknown field {k!r}; fields are {', '.join(_SPEC_FIELDS)}"
            )
        if k in fields:
            raise ValueError(f"material spec {spec!r}: {k} is given twice")
        if k == "wall":
            try:
                v = parse_length(v)
            except ValueError as exc:
                raise ValueError(f"material spec {spec!r}: {exc}") from None
        elif k != "name":
            try:
                v = float(v)
            except ValueError:
                raise ValueError(f"material spec {spec!r}: {k}={v!r} is not a number") from None
        fields[k] = v
    merged = {**base, **fields}
    missing = {"E", "nu", "rho"} - merged.keys()
    if missing:
        raise ValueError(
            f"material spec {spec!r} lacks {', '.join(sorted(missing))}; "
            "an inline material needs E, nu and rho, e.g. 'E=70e9,nu=0.33,rho=2700'"
        )
    if "name" not in fields and not base:
        merged["name"] = "custom"
    return Material(**merged)


_SPEC_FIELDS = ("E", "nu", "rho", "alpha", "beta", "restitution", "name", "wall")
_LENGTH_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6, "\u00b5m": 1e-6, "\u03bcm": 1e-6}


def parse_length(text) -> float:
    """A length in metres from ``"0.12mm"``, ``"4 mm"``, ``"0.4cm"``, ``"120um"`` or a bare
    number (metres).

    Raises
    ------
    ValueError
        Not a number with one of the units m, cm, mm, um (or µm), or not positive and finite.
    """
    import re

    raw = str(text).strip()
    m = re.fullmatch(r"([-+0-9.eE]+)\s*([a-zA-Z\u00b5\u03bc]*)", raw)
    unit = m.group(2).lower() if m else ""
    if m is None or unit not in ("",) + tuple(_LENGTH_UNITS):
        raise ValueError(f"length {raw!r} is not a number with a unit m, cm, mm or um (e.g. '0.12mm')")
    try:
        value = float(m.group(1)) * _LENGTH_UNITS.get(unit, 1.0)
    except ValueError:
        raise ValueError(f"length {raw!r} is not a number with a unit m, cm, mm or um (e.g. '0.12mm')") from None
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"length {raw!r} must be positive and finite")
    return value
