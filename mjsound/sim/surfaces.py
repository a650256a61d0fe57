"""How much of the sound a surface reflects: absorption coefficients per octave band.

A surface absorbs the fraction ``alpha(f)`` of the sound energy that reaches it and reflects
the rest; its pressure reflection factor is taken real and independent of the angle of
incidence (a locally reacting surface described by its random-incidence absorption, the
usual image-source model of room acoustics):

.. math::

    R(f) = \\sqrt{1 - \\alpha(f)}

so an image source behind it is heard ``20 log10 R`` dB below a rigid surface's (``R = 1``).
``alpha`` is tabulated in the octave bands 125 Hz ... 4 kHz; between band centres ``R`` is
interpolated linearly in log frequency and outside them it is the nearest band's
(:func:`reflection_at`). Modal synthesis applies it per mode (the mode's frequency picks the
value). A click (an impact's acceleration pulse, :mod:`mjsound.sim.clicks`) is a pulse of
tens of microseconds whose spectrum is flat up to about ``1 / (2 tau)`` (above 4 kHz for every
contact mjsound makes); with equal energy per hertz, the highest octaves hold most of it, so a
click is reflected with the 4 kHz band's ``R`` (:attr:`Surface.click_reflection`).

Source of the coefficients
--------------------------
M. D. Egan, *Architectural Acoustics*, McGraw-Hill 1988, appendix table of sound absorption
coefficients of common building materials (also reproduced in F. A. Everest, *Master
Handbook of Acoustics*, and on HyperPhysics, "Sound absorption coefficients"). The rows kept
here are the surfaces a robot scene has under and around it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["BANDS_HZ", "SURFACES", "MATERIAL_SURFACES", "DEFAULT_SURFACE", "Surface", "get_surface",
           "surface_for_material", "reflection_at"]

#: Octave band centres of the absorption coefficients [Hz].
BANDS_HZ = (125.0, 250.0, 500.0, 1000.0, 2000.0, 4000.0)

#: Absorption coefficients per octave band (:data:`BANDS_HZ`), Egan 1988 (module docstring).
SURFACES: dict[str, tuple] = {
    "rigid": (0.0, 0.0, 0.0, 0.0, 0.0, 0.0),  # an ideal reflector (closed forms, tests)
    "concrete": (0.01, 0.01, 0.015, 0.02, 0.02, 0.02),  # floors: concrete or terrazzo
    "marble": (0.01, 0.01, 0.01, 0.01, 0.02, 0.02),  # marble or glazed tile
    "brick": (0.03, 0.03, 0.03, 0.04, 0.05, 0.07),  # brick, unglazed
    "plaster": (0.013, 0.015, 0.02, 0.03, 0.04, 0.05),  # gypsum or lime plaster on brick
    "gypsum_board": (0.29, 0.10, 0.05, 0.04, 0.07, 0.09),  # 1/2 in board nailed to studs
    "wood": (0.15, 0.11, 0.10, 0.07, 0.06, 0.07),  # wood floor (boards on joists)
    "parquet": (0.04, 0.04, 0.07, 0.06, 0.06, 0.07),  # wood parquet in asphalt on concrete
    "plywood": (0.28, 0.22, 0.17, 0.09, 0.10, 0.11),  # plywood panelling, 3/8 in
    "linoleum": (0.02, 0.03, 0.03, 0.03, 0.03, 0.02),  # linoleum, rubber or cork tile on concrete
    "glass": (0.18, 0.06, 0.04, 0.03, 0.02, 0.02),  # large panes of heavy plate glass
    "window": (0.35, 0.25, 0.18, 0.12, 0.07, 0.04),  # ordinary window glass
    "carpet": (0.02, 0.06, 0.14, 0.37, 0.60, 0.65),  # heavy carpet on concrete
    "carpet_on_pad": (0.08, 0.24, 0.57, 0.69, 0.71, 0.73),  # heavy carpet on foam rubber
    "water": (0.008, 0.008, 0.013, 0.015, 0.020, 0.025),  # water surface (swimming pool)
}

#: The surface a plane of an acoustic material (:mod:`mjsound.materials`) is: metals, stone and
#: ceramics are hard and smooth (the table's marble / glazed tile row), woods a wood floor,
#: plastics and rubber a resilient tile on concrete.
MATERIAL_SURFACES = {
    "concrete": "concrete", "oak": "wood", "pine": "wood", "glass": "glass", "porcelain": "marble",
    "ceramic": "marble", "steel": "marble", "stainless_steel": "marble", "aluminium": "marble", "brass": "marble",
    "copper": "marble", "iron": "marble", "titanium": "marble", "tungsten_carbide": "marble", "diamond": "marble",
    "abs": "linoleum", "polycarbonate": "linoleum", "acrylic": "linoleum", "rubber": "linoleum",
}

#: A plane without a surface or an acoustic material: a concrete floor.
DEFAULT_SURFACE = "concrete"


@dataclass(frozen=True)
class Surface:
    """A reflecting surface: its absorption coefficient per octave band.

    Parameters
    ----------
    name : str
    absorption : tuple of 6 floats
        ``alpha`` in each band of :data:`BANDS_HZ`, each in [0, 1).

    Examples
    --------
    >>> round(get_surface("carpet").click_reflection, 3)
    0.592
    """

    name: str
    absorption: tuple

    def __post_init__(self):
        a = tuple(float(x) for x in self.absorption)
        if len(a) != len(BANDS_HZ) or not all(0.0 <= x < 1.0 for x in a):
            raise ValueError(f"surface {self.name!r}: give {len(BANDS_HZ)} absorption coefficients in [0, 1) "
                             f"(octave bands {', '.join(f'{b:g}' for b in BANDS_HZ)} Hz), got {self.absorption!r}; "
                             f"a surface that absorbs everything reflects nothing: turn its reflection off instead")
        object.__setattr__(self, "absorption", a)

    @property
    def reflection(self) -> np.ndarray:
        """Pressure reflection factor per band, ``sqrt(1 - alpha)`` (6,)."""
        return np.sqrt(1.0 - np.asarray(self.absorption))

    @property
    def click_reflection(self) -> float:
        """The reflection factor a click gets: the 4 kHz band's (module docstring)."""
        return float(self.reflection[-1])

    @property
    def rigid(self) -> bool:
        return not any(self.absorption)


def get_surface(spec) -> Surface:
    """A surface from a name in :data:`SURFACES` (or an acoustic material's name, through
    :data:`MATERIAL_SURFACES`), one absorption coefficient for every band, six (one per band
    of :data:`BANDS_HZ`) or a :class:`Surface`.

    Raises
    ------
    ValueError
        For an unknown name or coefficients outside [0, 1).
    """
    if isinstance(spec, Surface):
        return spec
    if isinstance(spec, str):
        key = spec.strip().lower().replace("-", "_").replace(" ", "_")
        key = MATERIAL_SURFACES.get(key, key)
        if key not in SURFACES:
            raise ValueError(f"unknown surface {spec!r}: use one of {', '.join(SURFACES)}, an absorption "
                             f"coefficient in [0, 1) or {len(BANDS_HZ)} of them (octave bands 125 Hz .. 4 kHz)")
        return Surface(key, SURFACES[key])
    try:
        a = np.asarray(spec, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"surface {spec!r}: give a name, an absorption coefficient or {len(BANDS_HZ)}") from None
    if a.size == 1:
        a = np.repeat(a, len(BANDS_HZ))
    if not np.all(np.isfinite(a)):
        raise ValueError(f"surface {spec!r}: absorption coefficients must be finite numbers in [0, 1)")
    return Surface("alpha=" + ",".join(f"{x:g}" for x in a), tuple(a.tolist()))


def surface_for_material(material) -> Surface:
    """The surface a plane made of an acoustic ``material`` (a :class:`mjsound.materials.Material`
    or None) is: :data:`MATERIAL_SURFACES` of its name, else :data:`DEFAULT_SURFACE`."""
    name = getattr(material, "name", None) or ""
    return get_surface(MATERIAL_SURFACES.get(name, DEFAULT_SURFACE))


def reflection_at(gains, f) -> np.ndarray:
    """A per-band quantity ``gains`` (6,) at frequencies ``f`` [Hz]: linear in log frequency
    between band centres, the nearest band's outside (as
    :meth:`mjsound.synth.synthesizer.Synthesizer.response_at`)."""
    f = np.maximum(np.asarray(f, np.float64), 1e-30)
    return np.interp(np.log(f), np.log(BANDS_HZ), np.asarray(gains, np.float64))

