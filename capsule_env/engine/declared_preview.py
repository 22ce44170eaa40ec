"""The surveyed guideway ahead of each contact of a declared vehicle (``preview_points > 0``).

The 1/4-car env's preview (:func:`capsule_env.engine.env_kernel.preview_row`, docs/env.md), per
contact: for each of a vehicle's contacts (the half-car's two bogies), the surveyed elevation
``k * preview_horizon_s / preview_points`` seconds ahead of that contact (``k = 1 ..
preview_points``), relative to the surveyed elevation under it now, looked up in the survey map
(the true guideway plus the map's error, :func:`capsule_env.engine.batch.survey_error`: the same
map as the 1/4-car env's for the same guideway seed) at the vehicle's estimated position (the
true one plus its episode's position error, drawn from the episode's noise key as the 1/4-car
env draws it; one error per vehicle, shared by its contacts). Each column saturates at the
1/4-car's bounds, +-1 m. The rear bogie's preview starts at the rear bogie: it covers, a
wheelbase later, what the front's covered.

Columns (after the observation set's own): ``<contact>_preview_ahead_<k>`` for each contact in
the declaration's order (the half-car: ``front_guideway_...`` then ``rear_guideway_...``).
"""

from __future__ import annotations

import numpy as np

from capsule_env.engine.batch import survey_error
from capsule_env.engine.config import EnvConfig
from capsule_env.engine.observations import preview_columns
from capsule_env.guideway.params import profile_length_m
from capsule_env.guideway.sampling import n_samples

__all__ = ["DeclaredPreview", "preview_reach_m"]


def preview_reach_m(config: EnvConfig) -> float:
    """How far ahead of the foremost contact the preview looks (m; 0 without preview): the
    horizon at the speed plus 6 standard deviations of the position error (the 1/4-car's
    ``CapsuleBatch._preview_reach_m`` at a constant speed)."""
    if config.preview_points == 0:
        return 0.0
    return config.speed_m_s * config.preview_horizon_s + 6.0 * config.position_error_m


class DeclaredPreview:
    """The preview columns of ``N`` vehicles over the bank ``profiles`` (module doc);
    ``contact_names``: the declaration's contacts, in order."""

    def __init__(
        self, config: EnvConfig, profiles: np.ndarray, contact_names: tuple[str, ...], n: int
    ) -> None:
        gw = config.guideway_spec
        self.points, self.spacing_m = int(config.preview_points), gw.spacing_m
        self.step_s = config.preview_horizon_s / self.points
        self.position_error_m = float(config.position_error_m)
        run = profiles.shape[1]  # a random profile: runs drive over all of it
        if gw.kind != "random":  # a finite profile: its continuation is for the preview
            run = n_samples(profile_length_m(gw, config.window_m / config.speed_m_s), gw.spacing_m)
        self.error = survey_error(config, profiles, run)
        columns = preview_columns(self.points)
        self.names = tuple(f"{c}_{col.name}" for c in contact_names for col in columns)
        self.low = np.array([col.low for _ in contact_names for col in columns])
        self.high = np.array([col.high for _ in contact_names for col in columns])
        self.position_error = np.zeros(n)

    def reset(self, n: int, noise_key: np.uint64) -> None:
        """Vehicle ``n``'s position error for its episode (the 1/4-car env's draw)."""
        draw = np.random.default_rng(int(noise_key)).standard_normal()
        self.position_error[n] = self.position_error_m * draw

    def columns(
        self, profiles: np.ndarray, route, time_s: np.ndarray, offsets_m: np.ndarray
    ) -> np.ndarray:
        """The preview columns (N, contacts * points) at each vehicle's time ``time_s`` (N,);
        ``offsets_m`` (N, contacts): each contact's longitudinal offset."""
        speed = route.speed_mps[:, None]
        here = route.start_m[:, None] + speed * time_s[:, None] + self.position_error[:, None]
        here = here + offsets_m  # (N, contacts)
        ahead = here[:, :, None] + (speed * self.step_s)[:, :, None] * np.arange(1, self.points + 1)
        rows, gain = route.profile[:, None, None], route.gain[:, None, None]
        ref = self._surveyed(profiles, rows[:, :, 0], gain[:, :, 0], here)
        z = self._surveyed(profiles, rows, gain, ahead) - ref[:, :, None]
        return np.clip(z.reshape(z.shape[0], -1), self.low, self.high)

    def _surveyed(self, profiles, rows, gain, position_m):
        """The survey map at ``position_m``: ``gain`` times the profile plus the map's error,
        each linear between samples and held beyond the ends
        (:func:`capsule_env.plant.block.guideway_elevation`'s arithmetic, vectorised)."""
        last = profiles.shape[1] - 1.0
        s = np.minimum(np.maximum(position_m / self.spacing_m, 0.0), last)
        j = np.minimum(s.astype(np.int64), int(last) - 1)
        f = s - j
        true = profiles[rows, j] * (1.0 - f) + profiles[rows, j + 1] * f
        err = self.error[rows, j] * (1.0 - f) + self.error[rows, j + 1] * f
        return gain * true + err
