"""Guideway vertical irregularity ``z_g`` (docs/model.md, section 3).

The capsule rides over a guideway whose vertical irregularity ``z_g(x)`` (m) excites the
1/4-car suspension through ``z_g(t) = profile(V t)``.  This module builds such profiles as
uniformly sampled arrays ``z[j]`` at ``x_j = j * spacing_m`` (m) and evaluates them at arbitrary
positions or times.

Available profiles
------------------
* ``random`` (default): a random vertical profile whose one-sided spatial PSD is the FRA
  (US Federal Railroad Administration) shape

  .. math:: S(W) = k A_v W_c^2 / (W^2 (W^2 + W_c^2))

  with ``W`` in rad/m and ``S`` in m^2/(rad/m), synthesised by the spectral (random-phase)
  method over wavelengths 2-500 m and scaled so that ``max |z_g| = 8 mm``.
* ``sine``: a pure sine of a given temporal frequency at the running speed.
* ``swept_sine``: a linear chirp in time, for frequency responses.
* ``bump``: an isolated (1 - cos) bump.
* ``step``: a smoothed (half-cosine ramp) step.

[reconstructed] Every numerical value here -- the FRA class-6 coefficients, the 2-500 m band,
the 8 mm peak, the 810 km/h (225 m/s) speed, the sine / sweep frequencies and the bump / step
geometry -- is a documented, overridable default reconstructed for this project, not a value
taken from a measured guideway.

The module is pure numpy (no gymnasium import).
"""

from capsule_env.guideway.deterministic import (
    bump_profile,
    sine_profile,
    step_profile,
    swept_sine_profile,
)
from capsule_env.guideway.params import (
    GUIDEWAY_KINDS,
    GuidewayParams,
    elevation_at,
    kmh_to_mps,
    make_profile,
    time_signal,
)
from capsule_env.guideway.random import (
    FRA_CLASS6,
    FraPsdParams,
    fft_length,
    fra_psd,
    random_profile,
)

__all__ = [
    "FRA_CLASS6",
    "GUIDEWAY_KINDS",
    "FraPsdParams",
    "GuidewayParams",
    "bump_profile",
    "elevation_at",
    "fft_length",
    "fra_psd",
    "kmh_to_mps",
    "make_profile",
    "random_profile",
    "sine_profile",
    "step_profile",
    "swept_sine_profile",
    "time_signal",
]
