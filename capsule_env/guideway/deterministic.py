"""Deterministic guideway profiles: sine, swept sine, bump and step."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from capsule_env.common.validation import check_finite, check_nonnegative, check_positive
from capsule_env.guideway.sampling import positions

__all__ = ["bump_profile", "sine_profile", "step_profile", "swept_sine_profile"]

#: Minimum number of samples per spatial wavelength of the sine / swept-sine profiles.
_MIN_SAMPLES_PER_WAVELENGTH = 4.0


def continued(
    shape: Callable[[np.ndarray], np.ndarray], length_m: float, spacing_m: float, extend_m: float
) -> np.ndarray:
    """``shape`` (elevation in m of positions in m) sampled over ``length_m``, then continued
    ``extend_m`` further by the same formula: the first ``n_samples(length_m, spacing_m)``
    samples are those without the continuation, bit for bit."""
    extend_m = check_nonnegative("extend_m", extend_m)
    profile = shape(positions(length_m, spacing_m))
    if extend_m == 0.0:
        return profile
    beyond = positions(float(length_m) + extend_m, spacing_m)[profile.size :]
    return np.concatenate([profile, shape(beyond)])


def _check_sampled(name: str, highest_hz: float, speed_mps: float, spacing_m: float) -> None:
    """Raise unless the shortest spatial wavelength ``speed / f`` has >= 4 samples."""
    wavelength = speed_mps / highest_hz
    if spacing_m > wavelength / _MIN_SAMPLES_PER_WAVELENGTH:
        raise ValueError(
            f"{name} too high for spacing_m: the spatial wavelength speed_mps / {name} = "
            f"{wavelength:.6g} m needs spacing_m <= {wavelength / _MIN_SAMPLES_PER_WAVELENGTH:.6g}"
            f" m, got {spacing_m!r}"
        )


def sine_profile(
    length_m: float,
    spacing_m: float,
    *,
    frequency_hz: float,
    speed_mps: float,
    amplitude_m: float,
    extend_m: float = 0.0,
) -> np.ndarray:
    """Sinusoidal profile ``z(x) = amplitude_m * sin(2 pi frequency_hz x / speed_mps)``.

    Run at ``speed_mps`` it gives ``z_g(t) = amplitude_m * sin(2 pi frequency_hz t)``.

    Parameters
    ----------
    length_m : float
        Profile length in m, > 0.
    spacing_m : float
        Sample spacing in m, > 0, with at least 4 samples per wavelength
        ``speed_mps / frequency_hz``.
    frequency_hz : float
        Temporal frequency at ``speed_mps`` in Hz, > 0.
    speed_mps : float
        Running speed in m/s, > 0.
    amplitude_m : float
        Amplitude in m, >= 0.
    extend_m : float, optional
        The sine continued this far beyond ``length_m`` (m, >= 0; default 0); the samples up
        to ``length_m`` are those without it.

    Returns
    -------
    numpy.ndarray
        Elevation in m at ``x_j = j * spacing_m``.
    """
    positions(length_m, spacing_m)  # checks length_m and spacing_m first
    frequency_hz = check_positive("frequency_hz", frequency_hz)
    speed_mps = check_positive("speed_mps", speed_mps)
    amplitude_m = check_nonnegative("amplitude_m", amplitude_m)
    _check_sampled("frequency_hz", frequency_hz, speed_mps, float(spacing_m))

    def shape(x: np.ndarray) -> np.ndarray:
        return amplitude_m * np.sin(2.0 * np.pi * frequency_hz * x / speed_mps)

    return continued(shape, length_m, spacing_m, extend_m)


def swept_sine_profile(
    length_m: float,
    spacing_m: float,
    *,
    start_hz: float,
    stop_hz: float,
    speed_mps: float,
    amplitude_m: float,
    sweep_duration_s: float | None = None,
    extend_m: float = 0.0,
) -> np.ndarray:
    """Linear-in-time swept sine (chirp) expressed in space.

    ``z_g(t) = A sin(2 pi (f0 t + (f1 - f0) t**2 / (2 T)))`` with ``t = x / speed_mps``, so the
    instantaneous frequency rises (or falls) linearly from ``f0 = start_hz`` at ``t = 0`` to
    ``f1 = stop_hz`` at ``t = T``.  ``T`` defaults to the run duration ``length_m / speed_mps``;
    beyond ``T`` (if ``sweep_duration_s`` is shorter) the chirp continues at the same rate.

    Parameters
    ----------
    length_m : float
        Profile length in m, > 0.
    spacing_m : float
        Sample spacing in m, > 0, with at least 4 samples per shortest wavelength.
    start_hz, stop_hz : float
        Start and stop frequencies in Hz, > 0 (a downward sweep is allowed).
    speed_mps : float
        Running speed in m/s, > 0.
    amplitude_m : float
        Amplitude in m, >= 0.
    sweep_duration_s : float or None, optional
        Sweep duration ``T`` in s, > 0; None (default) uses ``length_m / speed_mps``.
    extend_m : float, optional
        The chirp continued this far beyond ``length_m`` at the same rate (m, >= 0; default
        0; the sampling check covers ``length_m`` only); the samples up to ``length_m`` are
        those without it.

    Returns
    -------
    numpy.ndarray
        Elevation in m at ``x_j = j * spacing_m``.
    """
    x = positions(length_m, spacing_m)
    start_hz = check_positive("start_hz", start_hz)
    stop_hz = check_positive("stop_hz", stop_hz)
    speed_mps = check_positive("speed_mps", speed_mps)
    amplitude_m = check_nonnegative("amplitude_m", amplitude_m)
    if sweep_duration_s is None:
        sweep_duration_s = float(length_m) / speed_mps
    sweep_duration_s = check_positive("sweep_duration_s", sweep_duration_s)
    t = x / speed_mps
    highest_hz = max(start_hz, start_hz + (stop_hz - start_hz) * t[-1] / sweep_duration_s)
    name = "stop_hz" if stop_hz >= start_hz else "start_hz"
    _check_sampled(name, highest_hz, speed_mps, float(spacing_m))

    def shape(x: np.ndarray) -> np.ndarray:
        t = x / speed_mps
        rate = (stop_hz - start_hz) * t * t / (2.0 * sweep_duration_s)
        return amplitude_m * np.sin(2.0 * np.pi * (start_hz * t + rate))

    return continued(shape, length_m, spacing_m, extend_m)


def bump_profile(
    length_m: float,
    spacing_m: float,
    *,
    height_m: float = 0.008,
    bump_length_m: float = 10.0,
    position_m: float = 50.0,
    extend_m: float = 0.0,
) -> np.ndarray:
    """Isolated (1 - cos) bump on an otherwise flat guideway.

    ``z = height_m / 2 * (1 - cos(2 pi (x - position_m) / bump_length_m))`` for
    ``position_m <= x <= position_m + bump_length_m``, 0 elsewhere.

    [reconstructed] Defaults (8 mm high, 10 m long, starting at 50 m) are documented,
    overridable defaults.

    Parameters
    ----------
    length_m : float
        Profile length in m, > 0.
    spacing_m : float
        Sample spacing in m, > 0.
    height_m : float, optional
        Bump height in m (finite; negative gives a dip).  Default 0.008 m.
    bump_length_m : float, optional
        Bump base length in m, > 0.  Default 10 m.
    position_m : float, optional
        Start of the bump in m, in ``[0, length_m]``.  Default 50 m.
    extend_m : float, optional
        The profile continued this far beyond ``length_m`` (m, >= 0; default 0): flat past
        the bump; the samples up to ``length_m`` are those without it.

    Returns
    -------
    numpy.ndarray
        Elevation in m at ``x_j = j * spacing_m``.
    """
    positions(length_m, spacing_m)  # checks length_m and spacing_m first
    height_m = check_finite("height_m", height_m)
    bump_length_m = check_positive("bump_length_m", bump_length_m)
    position_m = _check_position(position_m, length_m)

    def shape(x: np.ndarray) -> np.ndarray:
        u = (x - position_m) / bump_length_m
        inside = (u >= 0.0) & (u <= 1.0)
        return np.where(inside, 0.5 * height_m * (1.0 - np.cos(2.0 * np.pi * u)), 0.0)

    return continued(shape, length_m, spacing_m, extend_m)


def _check_position(position_m: float, length_m: float) -> float:
    """``position_m`` must lie on the profile, else the feature would silently be missing."""
    position_m = check_finite("position_m", position_m)
    if not 0.0 <= position_m <= float(length_m):
        raise ValueError(
            f"position_m must be in [0, length_m] = [0, {float(length_m)}], got {position_m!r}"
        )
    return position_m


def step_profile(
    length_m: float,
    spacing_m: float,
    *,
    height_m: float = 0.008,
    position_m: float = 50.0,
    ramp_length_m: float = 1.0,
    extend_m: float = 0.0,
) -> np.ndarray:
    """Smoothed step: 0 before ``position_m``, ``height_m`` after the ramp.

    On ``position_m <= x <= position_m + ramp_length_m`` the profile is the half-cosine ramp
    ``height_m / 2 * (1 - cos(pi (x - position_m) / ramp_length_m))``; ``ramp_length_m = 0``
    gives a sharp step (``z = height_m`` for ``x >= position_m``).

    [reconstructed] Defaults (8 mm, at 50 m, 1 m ramp) are documented, overridable defaults.

    Parameters
    ----------
    length_m : float
        Profile length in m, > 0.
    spacing_m : float
        Sample spacing in m, > 0.
    height_m : float, optional
        Step height in m (finite; negative gives a step down).  Default 0.008 m.
    position_m : float, optional
        Start of the step in m, in ``[0, length_m]``.  Default 50 m.
    ramp_length_m : float, optional
        Ramp length in m, >= 0.  Default 1 m.
    extend_m : float, optional
        The profile continued this far beyond ``length_m`` (m, >= 0; default 0): flat past
        the ramp; the samples up to ``length_m`` are those without it.

    Returns
    -------
    numpy.ndarray
        Elevation in m at ``x_j = j * spacing_m``.
    """
    positions(length_m, spacing_m)  # checks length_m and spacing_m first
    height_m = check_finite("height_m", height_m)
    position_m = _check_position(position_m, length_m)
    ramp_length_m = check_nonnegative("ramp_length_m", ramp_length_m)

    def shape(x: np.ndarray) -> np.ndarray:
        if ramp_length_m == 0.0:
            return np.where(x >= position_m, height_m, 0.0)
        u = np.clip((x - position_m) / ramp_length_m, 0.0, 1.0)
        return 0.5 * height_m * (1.0 - np.cos(np.pi * u))

    return continued(shape, length_m, spacing_m, extend_m)
