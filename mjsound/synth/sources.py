"""Forcing sources of the synthesizer: sliding and rolling noise and user force signals
(``Synthesizer.slide``, ``roll``, ``excite``; the per-step driver's persistent streams are in
:mod:`.stream_table`).

A source adds ``g_i f[k]`` to mode i at every sample it acts on: ``f`` [N] the force along a
world direction at a world point, ``g_i = phi_i(x) . d / (fs w_i) * w_i^rad / r *
e^{lambda_i dt}`` at each air microphone (distance ``r``, delay ``r / c`` with its sub-sample
phase ``dt``); a contact microphone on the object hears it with its own weights and no delay
(:mod:`.contact_mic`), one on another object not at all. Sliding / rolling force:
``roughness |F_n| |v| w[k]``, ``w`` unit-variance Gaussian noise (seeded per object)
low-passed at ``|v| / length`` (van den Doel et al. 2001).
"""

from __future__ import annotations

import math

import numpy as np

from . import kernels
from .constants import MAX_AMPLITUDE, R_MIN_M, ROLL_PATCH_M, ROLL_ROUGHNESS, SAMPLE_TOL, SLIDE_GRAIN_M, SLIDE_ROUGHNESS
from .objects import finite_array
from .records import AIR, SourceRows

__all__ = ["ForcingSources"]


class ForcingSources:
    """The forcing-source methods of :class:`mjsound.synth.Synthesizer` (a mixin: it uses the
    synthesizer's objects, event queue ``_ev``, source list ``_src``, channels and layout)."""

    def _distances(self, ob):
        r = np.linalg.norm(self._mics - ob.pos[None, :], axis=1)
        return np.maximum(r, R_MIN_M)



    def slide(self, name, point, normal, normal_force, speed, t0, t1, *, roughness=SLIDE_ROUGHNESS) -> None:
        """Sliding contact on ``[t0, t1)`` [s]: surface-roughness noise drives the modes.

        The force along ``normal`` is ``roughness * |normal_force| * speed * w[k]`` [N], ``w``
        unit-variance Gaussian noise (seeded, per object) low-passed at ``speed / SLIDE_GRAIN_M``
        (faster sliding is brighter; van den Doel et al. 2001). ``speed == 0`` is silence.

        Parameters
        ----------
        point : (3,) world contact point [m];  normal : (3,) world contact normal;
        normal_force : float [N];  speed : float, relative sliding speed [m/s];
        t0, t1 : float, interval [s] (samples with t0 <= n/fs < t1 are driven);
        roughness : float, force fluctuation per N and per m/s.
        """
        self._sustained("slide", name, point, normal, normal_force, speed, t0, t1, roughness, SLIDE_GRAIN_M)

    def roll(self, name, point, normal, normal_force, speed, t0, t1, *, roughness=ROLL_ROUGHNESS) -> None:
        """Rolling contact on ``[t0, t1)`` [s]: like :meth:`slide` but the roughness noise is
        low-passed at ``speed / ROLL_PATCH_M`` (the contact patch averages the roughness; van
        den Doel et al. 2001), so rolling is a duller rumble. ``speed == 0`` is silence."""
        self._sustained("roll", name, point, normal, normal_force, speed, t0, t1, roughness, ROLL_PATCH_M)

    def _sustained(self, kind, name, point, normal, normal_force, speed, t0, t1, roughness, length):
        ob = self._get(name)
        p = finite_array(point, "point", "give world coordinates in metres").reshape(-1)
        nv = finite_array(normal, "normal", "give a finite direction vector").reshape(-1)
        if p.shape != (3,) or nv.shape != (3,):
            raise ValueError("point and normal must be 3-vectors")
        fn = float(finite_array(normal_force, "normal_force", "give the normal force in N"))
        v = float(finite_array(speed, "speed", "give the sliding/rolling speed in m/s"))
        rough = float(finite_array(roughness, "roughness", "give a non-negative number"))
        t0 = float(self._check_time(t0, "t0"))
        t1 = float(finite_array(t1, "t1", "give the end time in seconds"))
        if t1 < t0:
            raise ValueError(f"t1={t1!r} is before t0={t0!r}; give an interval t0 <= t1 in seconds")
        self._sustained_trusted(kind, ob, p, nv, fn, v, t0, t1, rough, length)

    def _sustained_trusted(self, kind, ob, p, nv, fn, v, t0, t1, rough, length):
        """Internal fast path of :meth:`slide` / :meth:`roll` (inputs already checked)."""
        fs = self.sample_rate
        k0 = int(math.ceil(t0 * fs - SAMPLE_TOL))
        k1 = int(math.ceil(t1 * fs - SAMPLE_TOL))
        L = k1 - k0
        nn = math.sqrt(nv[0] * nv[0] + nv[1] * nv[1] + nv[2] * nv[2])
        if L <= 0 or v == 0.0 or fn == 0.0 or rough == 0.0 or nn == 0.0 or len(ob.keep) == 0:
            return
        if ob.rng is None:
            ob.rng = np.random.default_rng([self.seed, ob.index])
        x = ob.rng.standard_normal(L)
        fc = min(abs(v) / length, 0.45 * fs)
        a = 1.0 - math.exp(-2 * math.pi * fc / fs)
        nxt, y = ob.filter_state.get(kind, (None, 0.0))
        if nxt != k0:
            y = 0.0
        f = kernels.one_pole(x, a, y)
        ob.filter_state[kind] = (k1, float(f[-1]))
        f *= rough * abs(fn) * abs(v)
        self._add_source(ob, p, nv / nn, k0 / fs, f)

    def excite(self, name, point, direction, signal, time) -> None:
        """Drive ``name`` with a force signal: ``signal[k]`` [N] along ``direction`` (world,
        normalised) at world ``point``, sample k at time ``time + k / fs`` [s]."""
        ob = self._get(name)
        p = finite_array(point, "point", "give world coordinates in metres").reshape(-1)
        dv = finite_array(direction, "direction", "give a finite direction vector").reshape(-1)
        if p.shape != (3,) or dv.shape != (3,):
            raise ValueError("point and direction must be 3-vectors")
        f = finite_array(signal, "signal", "give a 1-D force signal in N at the sample rate").reshape(-1)
        t = float(self._check_time(time, "time"))
        nn = np.linalg.norm(dv)
        if nn == 0 or len(f) == 0 or len(ob.keep) == 0:
            return
        self._add_source(ob, p, dv / nn, t, f.copy())

    def _add_source(self, ob, p, dirw, t_start, f):
        fs = self.sample_rate
        pl = (p - ob.pos) @ ob.R
        dl = dirw @ ob.R
        idx = int(ob.model.nearest_points(pl)[0])
        G = dl @ ob.shk[idx]  # (n,)
        base = G / (fs * ob.wd)
        r = self._distances(ob)
        owner = self._channels["owner"]
        r[owner != AIR] = 1.0
        ta = t_start + np.where(owner == AIR, r / self.speed_of_sound, 0.0)
        na = np.maximum(np.ceil(ta * fs - SAMPLE_TOL).astype(np.int64), self.samples_rendered)
        dts = na / fs - ta
        w = np.zeros((len(r), len(ob.keep)), np.complex128)  # contact channels of other bodies: 0
        w[owner == AIR] = ob.weights[None, :] / r[owner == AIR, None]
        if self._dirty:
            self._rebuild()
        for m in np.flatnonzero((owner == AIR) & (self._channels["w_off"] >= 0)).tolist():  # image microphones
            off = int(self._channels["w_off"][m]) + int(self._object_table.mode_off[ob.index])
            w[m] *= self._chan_w[off:off + len(ob.keep)].real
        for m in np.flatnonzero(owner == ob.index).tolist():
            off = int(self._channels["w_off"][m])
            w[m] = self._chan_w[off:off + len(ob.keep)]
        g = base[None, :] * w * np.exp(ob.lam[None, :] * dts[:, None])  # (M, n)
        fmax = np.abs(f).max()
        gm = np.abs(g).max() if g.size else 0.0
        if not (gm <= MAX_AMPLITUDE) or not (gm * fmax <= MAX_AMPLITUDE):
            raise ValueError(f"force on {ob.name!r} is too large; check units (N)")
        L = len(f)
        M = len(r)
        for m in range(M):
            a = int(na[m])
            self._src.append((ob.index, m, a, a + L, g[m], f))
        self._ev.push(ob.index, np.arange(M, dtype=np.int64), na, np.ones(M, np.int8),
                      (g != 0).astype(np.complex128))

    def _source_rows(self, srcs, start, end):
        """Forcing sources ``srcs`` (entries of ``_src`` overlapping ``[start, end)``) as
        :func:`.kernels.render_all` rows: ``(ptr, a, b, gr, gi, F)``, gains placed in the
        microphone banks, grouped by microphone (by voice, then in order, within one)."""
        vb = self._vbase
        dt = self.dtype
        n = end - start
        sv = np.array([vb[s[0]] + s[1] for s in srcs], np.int64)
        order = np.argsort(sv, kind="stable")
        q = len(srcs)
        src_a = np.empty(q, np.int64)
        src_b = np.empty(q, np.int64)
        gr = np.zeros((q, self._nmax), dt)
        gi = np.zeros((q, self._nmax), dt)
        F = np.zeros((q, n), dt)
        for j, i in enumerate(order.tolist()):
            _, _, a, b, g, f = srcs[i]
            src_a[j] = a
            src_b[j] = b
            gr[j, : len(g)] = g.real
            gi[j, : len(g)] = g.imag
            lo, hi = max(a, start), min(b, end)
            F[j, lo - start: hi - start] = f[lo - a: hi - a]
        lay = self._layout
        sm, gr, gi = kernels.place_rows(sv[order], gr, gi, lay.v_rel, lay.v_len, lay.v_mic, lay.width)
        if self.n_channels > 1:  # rows by microphone (one microphone: already in order)
            order = np.argsort(sm, kind="stable")
            src_a, src_b, gr, gi, F, sm = src_a[order], src_b[order], gr[order], gi[order], F[order], sm[order]
        return SourceRows(np.searchsorted(sm, self._mic_ptr), src_a, src_b, gr, gi, F)
