"""Where an :class:`~mjsound.sim.simulator.AudioSimulator`'s microphones are: fixed, at
their sites, or following a body (a mixin of the simulator: it reads the simulator's model,
data, scene and synthesizer)."""

from __future__ import annotations

import numpy as np

from .drive import follow_rows

__all__ = ["ListenerMethods"]


class ListenerMethods:
    """Microphones that move: :meth:`follow` and what the step kernel needs to move them."""

    def follow(self, body: int, offsets) -> None:
        """Move the microphones with ``body`` (translation only): microphone m sits at
        ``data.xpos[body] + offsets[m]``, updated whenever an event needs the positions
        (an impact, or a sustained contact's gains). ``body=None`` stops following."""
        if body is None:
            self._follow = None
            self._drive = None
            return
        off = np.asarray(offsets, np.float64).reshape(-1, 3)
        if not 0 <= int(body) < self.model.nbody:
            raise ValueError(f"follow: body {body} does not exist (the model has {self.model.nbody} bodies)")
        if len(off) != self.n_air or not np.isfinite(off).all():
            raise ValueError(f"follow: give {self.n_air} finite (x, y, z) offsets [m], one per microphone (the air "
                             f"ones); got {len(off)}")
        self._follow = (int(body), np.ascontiguousarray(np.vstack([off, np.zeros((len(self.contact_channels), 3))])))
        self._drive = None

    def _mic_config(self):
        """``(mode, source, rows, offsets, affine)`` per synthesizer row (the air microphones,
        their images, the contact microphones: :mod:`.images`): ``mics[m] = A_m
        (source_positions[rows[m]] + offsets[m]) + b_m`` when mode is 1 (source 0: bodies'
        ``xpos``, 1: ``site_xpos``; ``affine[m] = [A_m | b_m]``, an image's mirrors); mode 0:
        the microphones stay."""
        M = self.n_channels
        if self._follow is not None:
            mode, source, rows, offsets = 1, 0, np.full(M, self._follow[0], np.int64), self._follow[1]
        elif self._sites_move and M == len(self._mic_sites):
            mode, source, rows, offsets = 1, 1, self._mic_sites, np.zeros((M, 3))
        else:
            mode, source, rows, offsets = 0, 0, np.zeros(M, np.int64), np.zeros((M, 3))
        src = self._row_channel  # (synthesizer row -> the channel whose position it follows)
        return mode, source, np.ascontiguousarray(rows[src]), np.ascontiguousarray(offsets[src]), self._row_affine

    def _update_mics(self) -> None:
        """Microphones (and their images) to where their sites / the followed body are now
        (nothing when they cannot move)."""
        mode, source, rows, offsets, affine = self._mic_config()
        if mode:  # (mics updated in place; a non-finite position keeps the last)
            follow_rows(self.data.site_xpos if source else self.data.xpos, rows, offsets, affine,
                        self.synth.kernel_state().mics)
