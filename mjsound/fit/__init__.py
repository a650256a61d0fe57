"""Modal models from recordings, example-guided materials, and sound design with force signals.

Three tools for people who have a real object and a recording of it being struck (seeds 003
and 004: "hand and hear" modal models, analysis / resynthesis, Ren, Yeh and Lin 2013,
*Example-guided physically based modal sound synthesis*):

:func:`fit_recording`
    Estimate a modal resonance model ``{f, d, A}`` from one impact recording
    (``mjsound fit RECORDING.wav``). The result converts to a :class:`~mjsound.ModalModel`
    (:meth:`FitResult.to_model`) that plays in the :class:`~mjsound.synth.synthesizer.Synthesizer`
    like an analysed one and can stand in for an analysed model in a scene.
:func:`fit_material`
    Fit Rayleigh damping (alpha, beta) and a stiffness scale of a material so that the
    analysed model of a mesh matches a recording of that object; the fitted
    :class:`~mjsound.Material` is reusable on other meshes.
:func:`render_excitation`
    Drive a model with a user force signal (a recorded scrape, a mallet) through
    :meth:`Synthesizer.excite` and return the audio.

The signal model
----------------
After the onset time ``t0`` the recording is modelled as::

    y(t) = sum_i Im(b_i e^{lambda_i (t - t0)}) = sum_i A_i e^{-d_i (t - t0)} sin(w_i (t - t0) + phi_i)

with ``lambda_i = -d_i + j w_i`` (``w_i`` the *damped* angular frequency), amplitude
``A_i = |b_i|`` (in the recording's units: pascals for a calibrated recording, else full
scale) and phase ``phi_i = arg b_i``. An ideal impulse at ``t0`` gives ``phi_i`` = 0 or pi,
and ``t0`` is refined (to a fraction of a sample) to the time that makes the phases most
impulse-like.

Method (high-resolution, band-split ESPRIT)
-------------------------------------------
1. Mix the channels (or pick one), check the input (silence, clipping, length, a second
   impact), find the onset from a 2.5 ms energy envelope and the end of the decay (where
   the envelope reaches the noise floor).
2. Split the decay into overlapping bands ``[f_c - B/2, f_c + B/2)``: heterodyne by
   ``f_c``, low-pass with an *anti-causal* Kaiser FIR (output sample n depends on samples
   n .. n + L only, so a sum of damped exponentials that starts at the analysis start stays
   exactly a sum of the same exponentials, with no filter transient lost) and decimate to
   about ``2 B``. The Hankel matrices stay small (at most ``MAX_ROWS`` rows).
3. ESPRIT in each band: SVD of the Hankel matrix, model order = number of singular values
   above the band's noise level (``sigma (sqrt(L) + sqrt(C))``, the largest singular value of
   an L x C noise matrix; the noise density is the median of the periodogram in the band),
   poles from the shift invariance of the signal subspace. Poles outside the band's centre,
   growing or too damped are dropped, and so are poles whose matched-filter SNR in the band
   is below ``min_snr_db``.
4. Complex amplitudes by linear least squares on the full-rate signal; modes below
   ``min_snr_db`` are pruned and the ``n_modes`` most energetic are kept. The residual energy
   the model leaves, relative to the signal energy over the analysed span, is
   ``residual_db`` (about minus the SNR for a clean modal sound in white noise).

Bad input raises ``ValueError`` (silent / noise only, too short, non-finite) or warns with
:class:`FitWarning` (clipped: the clipped start is skipped; a second impact: the recording is
cut before it), always naming the problem and the fix.
"""

from __future__ import annotations

from .material import MaterialFit, fit_material, render_excitation
from .recording import (
    FRAME_S,
    MAX_BAND_SAMPLES,
    MAX_ROWS,
    MIN_DURATION_S,
    MIN_PEAK_DB,
    SECOND_ONSET_DB,
    fit_recording,
    read_recording,
)
from .result import FitResult, FitWarning, rayleigh_fit

__all__ = [
    "FitResult",
    "FitWarning",
    "MaterialFit",
    "fit_recording",
    "fit_material",
    "render_excitation",
    "read_recording",
    "rayleigh_fit",
    "FRAME_S",
    "MAX_BAND_SAMPLES",
    "MAX_ROWS",
    "MIN_DURATION_S",
    "MIN_PEAK_DB",
    "SECOND_ONSET_DB",
]
