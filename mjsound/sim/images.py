"""Image microphones: the scene's planes (and a room's walls) reflect the sound.

A source ``S`` heard at microphone ``M`` after a reflection off the plane ``n . x = d`` (unit
normal ``n``) travels as far as the direct path from ``S`` to the mirror image of ``M``,

.. math::

    M' = H M + 2 d n, \\qquad H = I - 2 n n^T,

and arrives from the direction of ``M'`` as seen from ``S``. So each reflecting plane adds an
*image microphone* at ``M'``: one more air channel of the synthesizer, rendered as every air
microphone is (delay ``|S - M'| / c``, ``1 / |S - M'|``, the object's radiation toward it, the
click's dipole toward it), times the surface's reflection factor (:mod:`.surfaces`), and
added into ``M``'s channel (:func:`fold`). Above a rigid plane this is
exactly the two-source field ``p = p(S -> M) + p(S' -> M)`` of a source and its mirror image.
A room (:mod:`.rooms`) adds the images of higher order the same way: the composition of
mirrors is the affine map ``x -> A x + b`` each image row carries.

The reflection factor depends on frequency: the synthesizer multiplies every mode it renders
at an image microphone by ``R(f_mode)``
(:meth:`mjsound.synth.synthesizer.Synthesizer.set_channel_response`) and :func:`fold` adds
the image rows as they are (a click's image is not in them: it joins its microphone's pulse
with its factor ``R_click``, :func:`.clicks.click_rows`).

Synthesizer rows (microphones): the air microphones ``0 .. A-1``, their images ``A .. A+I-1``,
then the contact microphones. Output channels: the air microphones, then the contact
microphones, as without reflections.
"""

from __future__ import annotations

import warnings
from typing import NamedTuple

import numpy as np

from ..jit import njit
from .surfaces import BANDS_HZ, get_surface, surface_for_material

__all__ = ["ImageSet", "no_images", "mirror_affine", "apply_affine", "plane_images", "scene_surfaces", "fold",
           "fold_rows", "SURFACE_TEXT_PREFIX"]

#: MJCF custom texts ``<text name="mjsound-surface:PLANE" data="carpet"/>`` name a plane's surface.
SURFACE_TEXT_PREFIX = "mjsound-surface:"

_PLANE = 0  # mjGEOM_PLANE
_PLAIN = np.zeros(0)  # (fold_rows' gains: none)


class ImageSet(NamedTuple):
    """The image microphones of a scene (``I`` of them).

    Attributes
    ----------
    parent : (I,) int64
        The air microphone (channel) each image belongs to.
    affine : (I, 3, 4) float64
        Its position from the parent's: ``x' = affine[:, :3] @ x + affine[:, 3]``.
    reflection : (I, 6) float64
        The product of the reflection factors of the surfaces on its path, per octave band
        (:data:`.surfaces.BANDS_HZ`).
    click : (I,) float64
        The same for a click (each surface's :attr:`.surfaces.Surface.click_reflection`).
    labels : list[str]
        What each image is behind (a plane's name, a room's walls).
    """

    parent: np.ndarray
    affine: np.ndarray
    reflection: np.ndarray
    click: np.ndarray
    labels: list

    def __len__(self) -> int:
        return len(self.parent)

    def positions(self, mics) -> np.ndarray:
        """``(I, 3)`` image positions for the air microphones ``mics`` (A, 3) [m]."""
        mics = np.asarray(mics, np.float64).reshape(-1, 3)
        return apply_affine(self.affine, mics[self.parent])

    def rows(self, n_air: int, n_channels: int) -> tuple[np.ndarray, np.ndarray]:
        """The synthesizer's rows (air microphones, these images, contact microphones) for
        ``n_air`` air and ``n_channels`` channels in all: ``(channel (rows,) int64, affine
        (rows, 3, 4))``, the channel whose position each row follows and the map from it
        (identity but for the images)."""
        channel = np.concatenate([np.arange(n_air), self.parent, np.arange(n_air, n_channels)]).astype(np.int64)
        affine = np.tile(np.hstack([np.eye(3), np.zeros((3, 1))]), (len(channel), 1, 1))
        affine[n_air:n_air + len(self)] = self.affine
        return channel, affine

    def mode_gains(self) -> np.ndarray:
        """``(I, 6)`` per band what the synthesizer multiplies a mode by: ``R`` (all of it;
        :func:`fold` adds the rows as they are)."""
        return self.reflection


def no_images() -> ImageSet:
    """An empty :class:`ImageSet` (free field)."""
    return ImageSet(np.zeros(0, np.int64), np.zeros((0, 3, 4)), np.zeros((0, len(BANDS_HZ))), np.zeros(0), [])


def mirror_affine(normal, point) -> np.ndarray:
    """The mirror across the plane through ``point`` with normal ``normal`` as a (3, 4) affine
    map ``[H | 2 d n]`` (module docstring)."""
    n = np.asarray(normal, np.float64).reshape(3)
    nn = float(np.linalg.norm(n))
    if not nn > 0:
        raise ValueError(f"mirror_affine: the plane's normal {normal!r} must be a non-zero vector")
    n = n / nn
    d = float(n @ np.asarray(point, np.float64).reshape(3))
    out = np.zeros((3, 4))
    out[:, :3] = np.eye(3) - 2.0 * np.outer(n, n)
    out[:, 3] = 2.0 * d * n
    return out


def apply_affine(affine, x) -> np.ndarray:
    """``affine[k, :, :3] @ x[k] + affine[k, :, 3]`` for (k, 3, 4) maps and (k, 3) points."""
    a = np.asarray(affine, np.float64).reshape(-1, 3, 4)
    return np.einsum("kij,kj->ki", a[:, :, :3], np.asarray(x, np.float64).reshape(-1, 3)) + a[:, :, 3]


def scene_surfaces(model, geom_material, reflections=True) -> dict:
    """``{plane geom id: Surface}`` of the planes that reflect.

    Parameters
    ----------
    model : mujoco.MjModel
    geom_material : list
        The scene's acoustic material per geom (a plane's surface follows its material,
        :func:`.surfaces.surface_for_material`).
    reflections : bool | dict
        True: every plane welded to the world reflects (its surface: an MJCF custom text
        ``mjsound-surface:PLANE``, else its material's, else a concrete floor). False: none.
        A dict ``{plane name or id: surface or None}`` sets (None: turns off) the named planes'
        surfaces; the others reflect as with True.

    Raises
    ------
    ValueError
        For a key that is not a plane of the model, or a bad surface.
    """
    from .objects import custom_texts, geom_name

    if reflections is False or reflections is None:
        return {}
    planes = [g for g in range(model.ngeom) if int(model.geom_type[g]) == _PLANE]
    by_name = {geom_name(model, g): g for g in planes}
    given = {}
    if isinstance(reflections, dict):
        for key, spec in reflections.items():
            g = key if isinstance(key, (int, np.integer)) and int(key) in planes else by_name.get(str(key))
            if g is None:
                raise ValueError(f"reflections: {key!r} is not a plane of this model (planes: "
                                 f"{', '.join(by_name) or 'none'})")
            given[int(g)] = None if spec is None else get_surface(spec)
    elif reflections is not True:
        raise ValueError(f"reflections={reflections!r}: give True (the scene's planes reflect), False (free field) "
                         "or {plane name: surface or None}")
    texts = custom_texts(model, SURFACE_TEXT_PREFIX)
    for key in texts:
        if key not in by_name:
            warnings.warn(f"mjsound: MJCF custom text '{SURFACE_TEXT_PREFIX}{key}' names no plane of this model "
                          "(it is ignored)", UserWarning, stacklevel=3)
    out = {}
    for g in planes:
        body = int(model.geom_bodyid[g])
        if int(model.body_weldid[body]) != 0 or int(model.body_mocapid[body]) >= 0:
            continue  # (a moving plane: its images would have to move too; not modelled)
        if g in given:
            if given[g] is not None:
                out[g] = given[g]
            continue
        name = geom_name(model, g)
        out[g] = get_surface(texts[name]) if name in texts else surface_for_material(geom_material[g])
    return out


def plane_images(model, data, surfaces: dict, mics) -> ImageSet:
    """The first-order images of the air microphones ``mics`` (A, 3) [m] in the planes
    ``surfaces`` (:func:`scene_surfaces`; poses from ``data.geom_xpos`` / ``geom_xmat``).
    A microphone behind a plane (or on it) has no image in it."""
    from .objects import geom_name

    mics = np.asarray(mics, np.float64).reshape(-1, 3)
    parent, affine, refl, click, labels = [], [], [], [], []
    for g, surf in surfaces.items():
        n = np.asarray(data.geom_xmat[g], np.float64).reshape(3, 3)[:, 2]
        p = np.asarray(data.geom_xpos[g], np.float64)
        A = mirror_affine(n, p)
        for m in range(len(mics)):
            if not float(n @ (mics[m] - p)) > 0:
                continue
            parent.append(m)
            affine.append(A)
            refl.append(surf.reflection)
            click.append(surf.click_reflection)
            labels.append(geom_name(model, g))
    if not parent:
        return no_images()
    return ImageSet(np.asarray(parent, np.int64), np.asarray(affine), np.asarray(refl), np.asarray(click), labels)


def fold(block: np.ndarray, n_air: int, images: ImageSet, gains: np.ndarray | None = None) -> np.ndarray:
    """The output channels of a synthesizer block (rows: air microphones, images, contact
    microphones; module docstring): each image row (times ``gains`` where given) added into
    its parent's row, the image rows dropped.

    Parameters
    ----------
    block : (A + I + C, n) array
        Overwritten: the air rows receive their images.
    n_air : int
        ``A``.
    images : ImageSet
    gains : (I,) float, optional
        Factors of the image rows (default none: their modes carry the reflection already).

    Returns
    -------
    (A + C, n) array of the block's dtype: a view of ``block`` (its first rows; the contact
    rows moved up over the images), ``block`` itself when ``I = 0``.

    Examples
    --------
    >>> im = ImageSet(np.array([0]), np.zeros((1, 3, 4)), np.ones((1, 6)), np.array([0.5]), ["floor"])
    >>> fold(np.array([[1.0, 2.0], [4.0, 4.0]]), 1, im)
    array([[5., 6.]])
    """
    k = len(images)
    if k == 0:
        return block
    g = _PLAIN if gains is None else np.asarray(gains, np.float64)
    return block[:fold_rows(block, n_air, images.parent, g)]


@njit(cache=True)
def fold_rows(block, n_air, parent, gain):
    """:func:`fold` in place, in one call (per block: the numpy version's few operations per
    image cost more than the sums themselves at a step's 48 samples).

    Parameters
    ----------
    block : (A + I + C, n) float32 or float64
        Synthesizer rows: ``A`` air microphones, ``I`` images, ``C`` contact microphones.
        Overwritten: ``block[parent[i]] += gain[i] block[A + i]`` for ``i = 0 .. I-1`` in this
        order (the product rounded to the block's dtype, then the sum; the plain sum for an
        empty ``gain``), then the contact rows moved to rows ``A .. A+C-1``.
    n_air : int
        ``A``.
    parent : (I,) int64
        The air row each image is added into.
    gain : (I,) or (0,) float64
        Each image's factor, rounded to the block's dtype first; empty: none.

    Returns
    -------
    int
        ``A + C``: the output channels are ``block[:A + C]``.
    """
    k = parent.shape[0]
    rows, n = block.shape
    g = np.empty(1, block.dtype)
    for i in range(k):
        p = parent[i]
        if gain.shape[0] == 0:
            for s in range(n):
                block[p, s] += block[n_air + i, s]
            continue
        g[0] = gain[i]
        gi = g[0]
        for s in range(n):
            block[p, s] += block[n_air + i, s] * gi
    for r in range(n_air + k, rows):
        for s in range(n):
            block[r - k, s] = block[r, s]
    return rows - k
