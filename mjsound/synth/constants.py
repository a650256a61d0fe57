"""Constants of the synthesizer (units in each comment)."""

from __future__ import annotations

__all__ = ["GRID", "D_MIN_PER_S", "R_MIN_M", "TIME_TOLERANCE_S", "RHO_AIR", "FLOOR_PA", "MAX_AMPLITUDE",
           "SLIDE_ROUGHNESS", "SLIDE_GRAIN_M", "ROLL_ROUGHNESS", "ROLL_PATCH_M", "SAMPLE_TOL", "P_REF_PA"]

#: Samples between exact-pole corrections / culling checks (absolute grid).
GRID = 256
#: Decay rate [1/s] given to modes whose damping is zero or negative (e-folding in 1000 s).
D_MIN_PER_S = 1e-3
#: Smallest source-microphone distance [m] used for 1/r.
R_MIN_M = 0.01
#: Events up to this much before the rendered time are accepted (and start now) [s].
TIME_TOLERANCE_S = 1e-6
#: Reference pressure of sound pressure levels, dB SPL [Pa] (RMS).
P_REF_PA = 20e-6
#: Air density [kg/m^3] (``radiation=False`` proxy).
RHO_AIR = 1.2
#: Absolute amplitude floor [Pa at the microphone]: modes below it are culled.
FLOOR_PA = 1e-30
#: Largest accepted modal amplitude at a microphone [Pa]; above it the input is rejected.
MAX_AMPLITUDE = 1e30
#: Sliding: force fluctuation per newton of normal force and per m/s of speed [1/(m/s)].
SLIDE_ROUGHNESS = 0.05
#: Sliding: roughness grain [m]; the noise is low-passed at speed / grain.
SLIDE_GRAIN_M = 20e-6
#: Rolling: force fluctuation per newton of normal force and per m/s of speed [1/(m/s)].
ROLL_ROUGHNESS = 0.05
#: Rolling: contact-patch length [m]; the noise is low-passed at speed / length
#: (van den Doel et al. 2001: rolling filters the roughness through the contact patch).
ROLL_PATCH_M = 2e-3

SAMPLE_TOL = 1e-6  # in samples: ceil(x - tol) so on-sample times are not pushed one late
