"""The magnet's length: the guideway the levitation reads, averaged over the magnet.

A magnet of length ``L`` feels the guideway's height averaged over its length, not at a point:
a moving (boxcar) average, gain ``sinc(pi L / lambda)`` at wavelength ``lambda``
(:func:`capsule_env.envelope.published.magnet_length_gain`), which removes the waves whose
wavelength is ``L`` (or ``L / 2``, ``L / 3`` ...) and inverts the sign between them.

:func:`magnet_average` applies it to a bank of profiles sampled every ``spacing_m``: the exact
mean of the profile's piecewise-linear interpolant (what the plant reads between samples) over
``[x - L / 2, x + L / 2]`` at each sample ``x``, which multiplies each Fourier component of the
interpolant by exactly ``sinc(L / lambda)``. The plant then interpolates these means linearly
once more, which would multiply a wave by ``sinc^2(h / lambda)`` again (``h`` the spacing: 0.7 %
at 5.4 m, 5 % at the random profile's shortest 2 m); the three-point correction
``m_j + c (2 m_j - m_{j-1} - m_{j+1})`` undoes it to second order in ``h / lambda``
(:func:`_correction_weight`): ``c`` is 1/12 (gain ``1 + (1 - cos(2 pi h / lambda)) / 6``) for a
magnet of a whole number of spacings, close to it for longer ones, and fades to 0 below one
spacing, where the mean is the sample itself (a constant 1/12 made a 1 mm magnet read 4.9 %
more of a 2 m wave than the point magnet). A wave the plant reads is then the point magnet's
times ``sinc(L / lambda)`` to within 5.1e-3 of its amplitude (the worst: a 0.5 m magnet, a
2 m wave), 1.3e-3 from 1.35 m up and 5e-4 from 5 m up (51 lengths from 0.001 to 50 m, 30
wavelengths from 2 to 40 m, the 0.25 m spacing: ``tests/test_envelope_magnet.py``). Within ``L / 2`` of a profile's ends the window is cut to the
profile (the mean over the part that exists; the correction leaves the end samples). Pure
numpy.
"""

from __future__ import annotations

import numpy as np

from capsule_env.common.validation import check_positive

__all__ = ["magnet_average"]


def _integral(row: np.ndarray, cumulative: np.ndarray, spacing_m: float,
              position_m: np.ndarray) -> np.ndarray:  # fmt: skip
    """The integral of ``row``'s piecewise-linear interpolant from 0 to ``position_m`` (m^2;
    positions within the profile), ``cumulative`` its trapezoid sums at the samples."""
    u = position_m / spacing_m
    i = np.clip(np.floor(u).astype(np.int64), 0, row.size - 2)
    f = u - i
    return cumulative[i] + spacing_m * f * (row[i] + 0.5 * f * (row[i + 1] - row[i]))


def magnet_average(profiles: np.ndarray, spacing_m: float, length_m: float) -> np.ndarray:
    """``profiles`` (K, L) averaged over a magnet of ``length_m`` (module docstring): a new
    C-contiguous array of the same shape, computed one profile at a time."""
    spacing_m = check_positive("spacing_m", spacing_m)  # Python floats: no float32 arithmetic
    length_m = check_positive("length_m", length_m)
    bank = np.atleast_2d(np.asarray(profiles, dtype=np.float64))
    end = (bank.shape[1] - 1) * spacing_m
    x = np.arange(bank.shape[1]) * spacing_m
    lo = np.maximum(x - 0.5 * length_m, 0.0)
    hi = np.minimum(x + 0.5 * length_m, end)
    out = np.empty_like(bank)
    weight = _correction_weight(length_m / spacing_m)
    for k, row in enumerate(bank):
        cumulative = np.concatenate(([0.0], np.cumsum(0.5 * spacing_m * (row[1:] + row[:-1]))))
        mean = (_integral(row, cumulative, spacing_m, hi)
                - _integral(row, cumulative, spacing_m, lo)) / (hi - lo)  # fmt: skip
        out[k] = mean
        # undo the linear interpolation's second pass (module docstring)
        out[k, 1:-1] += weight * (2.0 * mean[1:-1] - mean[:-2] - mean[2:])
    return np.ascontiguousarray(out)


def _correction_weight(samples: float) -> float:
    """The three-point correction's weight for a magnet ``samples`` spacings long: half the
    mean of ``f (1 - f)`` (``f`` the position's fraction of a spacing) over a window centred on
    a sample, the interpolant's excess over a parabola, which the mean carries into the
    kernel's second moment. ``1/12`` at a whole number of spacings; 0 for a point magnet."""
    half = 0.5 * samples
    whole, part = divmod(half, 1.0)
    return 0.5 * (whole / 6.0 + part * part / 2.0 - part**3 / 3.0) / half
