"""A room around the scene: a box whose six walls reflect, as image microphones (:mod:`.images`).

A shoebox ``lo <= x <= hi`` (side lengths ``L``) mirrors a microphone at ``x`` along each
axis into the lattice of images

.. math::

    x_n = \\begin{cases} x + n L & n \\text{ even} \\\\ 2\\,lo + (n + 1) L - x & n \\text{ odd}
    \\end{cases}

whose path crosses the wall at ``hi`` ``ceil(n / 2)`` times and the wall at ``lo``
``floor(n / 2)`` times for ``n > 0`` (the other way round for ``n < 0``). The images with
``1 <= |n_x| + |n_y| + |n_z| <= order`` are kept (6 for order 1, 24 for 2, 62 for 3); each is
heard through the product of the reflection factors of the walls it crosses (per octave
band). The early reflections are exact (up to the surfaces' model); the late reverberation
the kept order leaves out is the room's tail (:mod:`.room_tail`, ``tail=True``).

Reverberation time of the box (``V`` volume, ``S_i`` wall areas, ``alpha_i`` absorption,
``S`` total area, ``alpha_bar = sum S_i alpha_i / S``): Sabine ``T = 0.161 V / sum S_i
alpha_i``, Eyring ``T = 0.161 V / (-S ln(1 - alpha_bar))`` (:meth:`Room.rt60`). A room given
by its ``rt60`` gets the uniform absorption whose Eyring time it is.

MJCF: ``<custom><text name="mjsound-room" data="lo=-3 -3 0; hi=3 3 2.5; walls=plaster;
floor=carpet; order=2"/></custom>`` (keys: ``lo``, ``hi``, ``walls``, one per wall name of
:data:`WALLS`, ``rt60``, ``order``, ``tail`` = on / off).
"""

from __future__ import annotations

import itertools
import math
import numpy as np

from .images import ImageSet, no_images, plane_images, scene_surfaces
from .surfaces import BANDS_HZ, get_surface

__all__ = ["Room", "WALLS", "ROOM_TEXT", "room_from_text", "scene_room", "scene_images", "set_image_responses"]

#: Wall names, in the order of the walls' arrays: the low and high wall along x, y, z.
WALLS = ("x-", "x+", "y-", "y+", "floor", "ceiling")
#: MJCF custom text holding a room (module docstring).
ROOM_TEXT = "mjsound-room"
#: Sabine's constant 24 ln(10) / c at c = 343 m/s [s/m].
SABINE = 24.0 * math.log(10.0) / 343.0


class Room:
    """A shoebox room around the scene.

    Parameters
    ----------
    lo, hi : (3,) array_like
        Opposite corners [m] (world frame; ``lo < hi``).
    walls : surface or dict
        Every wall's surface (:func:`.surfaces.get_surface`: a name, one absorption
        coefficient or six per octave band), or ``{wall: surface}`` over :data:`WALLS`
        (walls not named: ``"plaster"``; the key ``"walls"`` sets the default).
    rt60 : float, optional
        Instead of ``walls``: the reverberation time [s]; every wall gets the absorption
        whose Eyring time it is (the same in every band).
    order : int
        Highest image order kept (>= 1; images per microphone: 6, 24, 62, 128 for 1 .. 4).
    tail : bool
        Add the late reverberant tail (default True): a feedback delay network decaying at
        the room's Eyring time per band, fed by the images (:mod:`.room_tail`). False: the
        images only.

    Examples
    --------
    >>> room = Room(lo=(-2, -2, 0), hi=(2, 2, 2.5), walls={"walls": "plaster", "floor": "carpet"})
    >>> round(float(room.rt60("sabine")[3]), 2)   # 1 kHz band [s]
    0.85
    """

    def __init__(self, lo, hi, walls="plaster", rt60: float | None = None, order: int = 1, tail: bool = True):
        lo = np.asarray(lo, np.float64).reshape(-1)
        hi = np.asarray(hi, np.float64).reshape(-1)
        if lo.shape != (3,) or hi.shape != (3,) or not np.all(np.isfinite(lo)) or not np.all(np.isfinite(hi)) \
                or not np.all(hi > lo):
            raise ValueError(f"Room: give corners lo={lo.tolist()} < hi={hi.tolist()} as finite (x, y, z) in metres")
        if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or not 1 <= int(order) <= 8:
            raise ValueError(f"Room: order={order!r} must be an integer image order from 1 to 8")
        if not isinstance(tail, (bool, np.bool_)):
            raise ValueError(f"Room: tail={tail!r} must be True (the late reverberant tail) or False")
        self.lo, self.hi, self.order, self.rt60_s, self.tail = lo, hi, int(order), None, bool(tail)
        if rt60 is not None:
            try:
                t = float(rt60)
            except (TypeError, ValueError):
                t = float("nan")
            V, S = self.volume, float(self.areas.sum())
            a = 1.0 - math.exp(-SABINE * V / (S * t)) if math.isfinite(t) and t > 0 else float("nan")
            if not 0 < a < 1:
                raise ValueError(f"Room: rt60={rt60!r} s is not a reverberation time this box can have "
                                 f"(give a positive time in seconds, e.g. 0.5)")
            self.rt60_s = t
            walls = a
        if isinstance(walls, dict):
            bad = [k for k in walls if k not in WALLS and k != "walls"]
            if bad:
                raise ValueError(f"Room: unknown wall(s) {bad}; the walls are {', '.join(WALLS)} (or 'walls' for all)")
            default = walls.get("walls", "plaster")
            self.surfaces = [get_surface(walls.get(w, default)) for w in WALLS]
        else:
            self.surfaces = [get_surface(walls)] * 6
        self.walls = walls

    def __repr__(self) -> str:
        walls = f"rt60={self.rt60_s!r}" if self.rt60_s is not None else f"walls={self.walls!r}"
        return f"Room(lo={self.lo.tolist()}, hi={self.hi.tolist()}, {walls}, order={self.order}, tail={self.tail})"

    @property
    def size(self) -> np.ndarray:
        return self.hi - self.lo

    @property
    def volume(self) -> float:
        return float(np.prod(self.size))

    @property
    def areas(self) -> np.ndarray:
        """Area of each wall (:data:`WALLS` order) [m^2]."""
        Lx, Ly, Lz = self.size
        return np.array([Ly * Lz, Ly * Lz, Lx * Lz, Lx * Lz, Lx * Ly, Lx * Ly])

    def rt60(self, formula: str = "sabine") -> np.ndarray:
        """Reverberation time per octave band [s] (6,), by ``"sabine"`` or ``"eyring"``."""
        alpha = np.array([s.absorption for s in self.surfaces])  # (6 walls, 6 bands)
        S = self.areas
        if formula == "sabine":
            return SABINE * self.volume / (S @ alpha)
        if formula == "eyring":
            abar = (S @ alpha) / S.sum()
            return SABINE * self.volume / (-S.sum() * np.log1p(-abar))
        raise ValueError(f"rt60: formula={formula!r}; choose 'sabine' or 'eyring'")

    def contains(self, x) -> bool:
        x = np.asarray(x, np.float64).reshape(3)
        return bool(np.all(x > self.lo) and np.all(x < self.hi))

    def late_tail(self, images: ImageSet, mics, sample_rate: float, source=None):
        """The room's late tail (:func:`.room_tail.room_tail`) for the air microphones ``mics``
        (A, 3) [m] and their images, sources at ``source`` (3,) [m]; None when :attr:`tail`
        is False."""
        from .room_tail import room_tail

        return room_tail(self, images, mics, sample_rate, source) if self.tail else None

    def images(self, mics) -> ImageSet:
        """The images of the air microphones ``mics`` (A, 3) [m] up to :attr:`order`.

        Raises
        ------
        ValueError
            For a microphone outside the room.
        """
        mics = np.asarray(mics, np.float64).reshape(-1, 3)
        for m, x in enumerate(mics):
            if not self.contains(x):
                raise ValueError(f"Room: microphone {m} at {x.tolist()} is outside the room "
                                 f"{self.lo.tolist()} .. {self.hi.tolist()}; enlarge the room or move the microphone")
        R = np.array([s.reflection for s in self.surfaces])  # (6 walls, 6 bands)
        Rc = np.array([s.click_reflection for s in self.surfaces])
        L, lo = self.size, self.lo
        cells = [n for n in itertools.product(range(-self.order, self.order + 1), repeat=3)
                 if 1 <= sum(abs(k) for k in n) <= self.order]
        parent, affine, refl, click, labels = [], [], [], [], []
        for m in range(len(mics)):
            for n in cells:
                A = np.zeros((3, 4))
                hits = np.zeros(6)
                for ax, k in enumerate(n):
                    if k % 2 == 0:
                        A[ax, ax], A[ax, 3] = 1.0, k * L[ax]
                    else:
                        A[ax, ax], A[ax, 3] = -1.0, 2 * lo[ax] + (k + 1) * L[ax]
                    up, down = (k + 1) // 2, k // 2  # crossings of the high and the low wall, k > 0
                    if k < 0:
                        up, down = (-k) // 2, (-k + 1) // 2
                    hits[2 * ax] += down
                    hits[2 * ax + 1] += up
                parent.append(m)
                affine.append(A)
                refl.append(np.prod(R ** hits[:, None], axis=0))
                click.append(float(np.prod(Rc ** hits)))
                labels.append(f"room{n}")
        return ImageSet(np.asarray(parent, np.int64), np.asarray(affine), np.asarray(refl), np.asarray(click), labels)


def room_from_text(text: str) -> Room:
    """A :class:`Room` from MJCF custom text ``"lo=-3 -3 0; hi=3 3 2.5; walls=plaster;
    floor=carpet; order=2"`` (or ``rt60=0.4`` in place of walls; ``tail=off`` leaves out the
    late tail).

    Raises
    ------
    ValueError
        Naming the key that is missing or malformed.
    """
    kv = {}
    for part in str(text).split(";"):
        if part.strip():
            key, sep, val = part.partition("=")
            if not sep:
                raise ValueError(f"MJCF text '{ROOM_TEXT}': {part.strip()!r} is not key=value "
                                 f"(e.g. \"lo=-3 -3 0; hi=3 3 2.5; walls=plaster\")")
            kv[key.strip().lower()] = val.strip()
    for key in ("lo", "hi"):
        if key not in kv:
            raise ValueError(f"MJCF text '{ROOM_TEXT}' needs {key}=x y z (the room's corners in metres)")

    def vec(s):
        try:
            return [float(x) for x in s.replace(",", " ").split()]
        except ValueError:
            raise ValueError(f"MJCF text '{ROOM_TEXT}': {s!r} is not three numbers") from None

    def surf(s):
        parts = s.replace(",", " ").split()
        try:
            return [float(x) for x in parts] if len(parts) > 1 else float(parts[0])
        except (ValueError, IndexError):
            return s

    walls = {k: surf(v) for k, v in kv.items() if k in WALLS or k == "walls"}
    tail = kv.get("tail", "on").lower()
    if tail not in ("on", "off", "true", "false", "1", "0"):
        raise ValueError(f"MJCF text '{ROOM_TEXT}': tail={tail!r}; give tail=on or tail=off")
    return Room(vec(kv["lo"]), vec(kv["hi"]), walls=walls or "plaster",
                rt60=float(kv["rt60"]) if "rt60" in kv else None, order=int(kv.get("order", 1)),
                tail=tail in ("on", "true", "1"))


def scene_room(model, reflections=True, room=None) -> Room | None:
    """The scene's room: ``room``, or the model's ``mjsound-room`` text when ``room`` is None
    and ``reflections`` is not False; None for none."""
    from .objects import custom_texts

    if reflections is False:
        return None
    if room is None:
        text = custom_texts(model, "").get(ROOM_TEXT)
        room = room_from_text(text) if text is not None else None
    if room is not None and not isinstance(room, Room):
        raise ValueError(f"room={room!r}: give a mjsound Room (mjsound.sim.rooms.Room) or None")
    return room


def scene_images(model, data, scene, mics, reflections=True, room=None) -> ImageSet:
    """The image microphones of a scene: a room's (:func:`scene_room`), else those of the
    planes that reflect (:func:`.images.scene_surfaces`)."""
    if reflections is False:
        return no_images()
    room = scene_room(model, reflections, room)
    if room is not None:
        return room.images(mics)
    return plane_images(model, data, scene_surfaces(model, scene.geom_material, reflections), mics)


def set_image_responses(synth, n_air: int, images: ImageSet) -> None:
    """Give each image row of ``synth`` (rows ``n_air ..``) its per-mode gain ``R(f)``
    (:mod:`.images`; none where that is 1 in every band)."""
    for k, g in enumerate(images.mode_gains()):
        if not np.all(g == 1.0):
            synth.set_channel_response(n_air + k, BANDS_HZ, g)

