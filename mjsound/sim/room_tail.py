r"""A room's late reverberant tail: the feedback delay network (:mod:`mjsound.synth.reverb`)
tuned to the room and fed by its rendered early reflections.

Decay: every octave band decays at the room's Eyring time ``T_b`` (:meth:`.rooms.Room.rt60`;
the given time for a room made with ``rt60=``), ``tau_b = T_b / (6 ln 10)``.

Level: the image sources of a room (one per volume ``V``, at distance ``c t`` at time ``t``
after the emission, their energy ``exp(-t / tau_b)`` of the source's after the reflections
on their way) give the statistical late energy response (H. Kuttruff, *Room Acoustics*, 5th
ed., 2009, sec. 4.1 and 5.1; J.-D. Polack's model of the late impulse response)

.. math::

    \frac{\langle p^2(t) \rangle}{E_1} = \frac{4 \pi c}{V} e^{-t / \tau_b}
    \quad \text{per second,}

``E_1`` the energy of the direct sound at 1 m. Its integral from the emission on,
``4 pi c tau_b / V = 16 pi / A_b`` with Eyring's absorption area ``A_b = -S ln(1 - alpha_b)``,
is the classic ratio of the reverberant to the direct energy at 1 m, ``16 pi / R`` with the
room constant ``R = S alpha / (1 - alpha)`` (equal to first order in ``alpha``).

Which part is the tail's: the images up to the room's ``order`` are rendered (image
microphones); the tail supplies, from the arrival of the first image left out
(``t_mix``), the share of that energy the rendered images do not hold, found by counting the
image lattice's points per time bin (rendered against all): a few input taps make the
tail's onset that staircase.

Input: the network is fed with what each air microphone hears directly and early, every
path through its own input (:class:`.LateTail`: orthogonal input vectors, so the copies'
tails add incoherently instead of comb-filtering each other): microphone ``a``'s own row
(the direct sound, and every click with its images: the clicks' images go straight to
their microphone, :mod:`.clicks`) and each of its image rows (whose modes carry their
reflection ``R_i,b``, :mod:`.images`), all weighted by ``w_a``. For a source at ``S``
(distance ``r_a`` to the microphone, ``r_i`` to image ``i``) whose direct sound has the
energy ``E_1`` at 1 m, the input then has the energy ``E_1 q_b``,

.. math::

    q_b = \sum_a w_a^2 P_{a,b}, \qquad P_{a,b} = \frac{1}{r_a^2} + \sum_{i \in a}
    \frac{R_{i,b}^2}{r_i^2},

arriving at ``t = r / c`` after the emission (``w_a = (A P_{a,1k})^{-1/2}``: ``q_b`` is about
1). ``S`` is where the scene's sounding objects are when the simulator is made (their
centroid): a source that moves toward a microphone raises its tail with its direct sound
(by up to ``r_a^2 / r^2``), and a microphone that moves keeps the calibration of its start.

With the network's impulse energy ``Phi`` (:meth:`.LateTail.impulse_energy`), the taps
``(d_k, a_k)`` and the images' arrivals, the input's gain per band is

.. math::

    G_b^2 = \frac{4 \pi c}{V f_s\, \Phi\, q_b \sum_k a_k^2 e^{d_k / (f_s \tau_b)}\,
    M_b}, \qquad M_b = \frac{1}{q_b} \sum_a w_a^2 \Big(\frac{e^{r_a / (c \tau_b)}}{r_a^2} +
    \sum_{i \in a} \frac{R_{i,b}^2\, e^{r_i / (c \tau_b)}}{r_i^2}\Big).

One network serves every air microphone of the room (its late field is one diffuse field):
each microphone hears it through its own output vector (rows of a Hadamard matrix:
uncorrelated outputs).
"""

from __future__ import annotations

import math

import numpy as np

from ..synth.accel_noise import SPEED_OF_SOUND
from ..synth.reverb import N_LINES, LateTail, prime_delays
from .surfaces import BANDS_HZ

__all__ = ["room_tail", "tail_onset", "late_energy_rate"]

#: Time bins of the tail's onset staircase (taps: one more).
ONSET_BINS = 4


def late_energy_rate(room) -> float:
    """``4 pi c / V`` [1/s]: the late energy response per second relative to the direct
    sound's energy at 1 m, before the decay (module docstring)."""
    return 4.0 * math.pi * SPEED_OF_SOUND / room.volume


def _lattice(room, mic, max_order, source):
    """Every image of ``mic`` with ``|n|_inf <= max_order``: distances from ``source`` (k,) [m]
    and orders ``|n|_1`` (k,) (the room's image formula, :mod:`.rooms`)."""
    n = np.arange(-max_order, max_order + 1)
    grid = np.stack([g.ravel() for g in np.meshgrid(n, n, n, indexing="ij")], axis=1)
    grid = grid[np.abs(grid).sum(axis=1) >= 1]
    L, lo = room.size, room.lo
    pos = np.where(grid % 2 == 0, mic + grid * L, 2 * lo + (grid + 1) * L - mic)
    return np.linalg.norm(pos - source, axis=1), np.abs(grid).sum(axis=1)


def tail_onset(room, mics, source) -> tuple[np.ndarray, np.ndarray]:
    """The tail's onset staircase: times ``T_k`` [s] after the emission and the share ``D_k``
    of the late energy that starts there (sum 1).

    ``T_0 = t_mix``, the first arrival of an image of order ``room.order + 1``; the steps
    follow the fraction of the image lattice (all microphones pooled; a source at
    ``source``) not rendered in :data:`ONSET_BINS` bins up to the last rendered image's
    arrival.
    """
    mics = np.asarray(mics, np.float64).reshape(-1, 3)
    c, N = SPEED_OF_SOUND, room.order
    lattices = []
    for m in mics:
        d, order = _lattice(room, m, N + 1, source)
        lattices.append((d, order))
    t_mix = min(float(d[order > N].min()) for d, order in lattices) / c
    t_full = max(float(d[order <= N].max()) for d, order in lattices) / c
    if t_full <= t_mix:
        return np.array([t_mix]), np.array([1.0])
    reach = int(math.ceil(c * t_full / room.size.min())) + 2
    edges = np.linspace(t_mix, t_full, ONSET_BINS + 1)
    rendered, every = np.zeros(ONSET_BINS), np.zeros(ONSET_BINS)
    for m in mics:
        d, order = _lattice(room, m, reach, source)
        k = np.searchsorted(edges, d / c, side="right") - 1
        inside = (k >= 0) & (k < ONSET_BINS)
        np.add.at(every, k[inside], 1.0)
        np.add.at(rendered, k[inside], (order[inside] <= N).astype(float))
    missing = np.concatenate([1.0 - rendered / np.maximum(every, 1.0), [1.0]])  # (after t_full: all of it)
    share = np.diff(np.maximum.accumulate(np.concatenate([[0.0], missing])))
    return edges, share


def room_tail(room, images, mics, fs: float, source=None) -> LateTail:
    """The late tail of ``room`` for the air microphones ``mics`` (A, 3) [m] (rows ``0 ..
    A-1`` of the synthesizer's block) and their images ``images`` (rows ``A ..``), at the
    sample rate ``fs`` [Hz], calibrated for sources at ``source`` (3,) [m] (default: the
    microphones' centroid) (module docstring).

    Raises
    ------
    ValueError
        For a room whose reverberation times are not positive and finite.
    """
    mics = np.asarray(mics, np.float64).reshape(-1, 3)
    A, I = len(mics), len(images)
    if I == 0:
        raise ValueError("room_tail: the room has no image microphones to feed its tail (order >= 1)")
    T = np.asarray(room.rt60("eyring") if room.rt60_s is None else np.full(len(BANDS_HZ), room.rt60_s), np.float64)
    if not np.all(np.isfinite(T)) or not np.all(T > 0):
        raise ValueError(f"Room: reverberation times {T.tolist()} s must be finite and > 0 for a late tail "
                         "(give walls that reflect something, or tail=False)")
    tau = T / (6.0 * math.log(10.0))
    c = SPEED_OF_SOUND
    source = mics.mean(axis=0) if source is None else np.asarray(source, np.float64).reshape(3)
    if not np.all(np.isfinite(source)):
        raise ValueError(f"room_tail: source={source.tolist()} must be a finite point [m]")
    r_mic = np.maximum(np.linalg.norm(mics - source, axis=1), 0.01)  # (A,) [m]
    r_img = np.linalg.norm(images.positions(mics) - source, axis=1)  # (I,) [m]
    R2 = images.reflection ** 2  # (I, 6)
    P = 1.0 / r_mic[:, None] ** 2 + np.array([(R2[images.parent == a] / r_img[images.parent == a, None] ** 2).sum(0)
                                              for a in range(A)])  # (A, 6)
    w = 1.0 / np.sqrt(A * P[:, 3])  # (the 1 kHz band's)
    q = (w[:, None] ** 2 * P).sum(0)
    rows = np.concatenate([np.arange(A), A + np.arange(I)])
    order = np.argsort(np.concatenate([np.arange(A), images.parent]), kind="stable")  # (each microphone, then its images)
    weight = np.concatenate([w, w[images.parent]])[order]
    rows = rows[order]
    t_first = float(r_mic.min()) / c
    # delay lines: the room's mean free path, long enough for a modal overlap a room's tones can
    # ring in (sum of lengths ~ T/4: the spacing of a room response's maxima, 4/T, Schroeder),
    # short enough not to flutter
    mfp = 4.0 * room.volume / float(room.areas.sum()) / c
    mean_delay = min(max(mfp, float(np.median(T)) / (4 * N_LINES)), 0.025)
    T_k, share = tail_onset(room, mics, source)
    lengths = prime_delays(mean_delay * fs)  # (LateTail's lines)
    m_min = int(lengths.min())
    keep = share > 0
    T_k, share = T_k[keep], share[keep]
    d_k, where = np.unique(np.maximum(0, np.round(fs * (T_k - t_first)).astype(np.int64) - m_min),
                           return_inverse=True)
    share = np.bincount(where.reshape(-1), share, d_k.size)  # (steps that fall on one delay: one tap)
    tau_ref = float(np.interp(1000.0, BANDS_HZ, tau))
    a2 = share * np.exp(-d_k / (fs * tau_ref))  # (the staircase's steps, at 1 kHz's decay)
    F = np.array([np.sum(a2 * np.exp(d_k / (fs * tb))) for tb in tau])
    M = np.array([((w ** 2 / r_mic ** 2) * np.exp(r_mic / (c * tb))).sum()
                  + (w[images.parent] ** 2 * R2[:, k] / r_img ** 2 * np.exp(r_img / (c * tb))).sum()
                  for k, tb in enumerate(tau)]) / q
    phi = 1.0 / float(lengths.sum())  # (|c| = 1, one line per send row: LateTail.impulse_energy)
    G2 = late_energy_rate(room) / (fs * phi * q * F * M)
    return LateTail(fs, BANDS_HZ, T, np.sqrt(G2), np.ones(A), mean_delay, (d_k, np.sqrt(a2)), rows, weight)
