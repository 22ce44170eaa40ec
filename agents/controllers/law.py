"""What every classical feedback law shares: the physical signals it reads, from either
observation set, and its gains (scalars, or one per vehicle).

A law names the physical signals it needs (``SIGNALS``: body velocity, stroke rate, ...);
:data:`SOURCES` says which observation columns give each in the ``full_state`` set (ideal
sensors: true states, noisy in ``hils``) and in the ``measured`` set (the capsule's own
sensors and on-board velocity estimates). So one law's code runs on either set, and
:attr:`ClassicalLaw.signals_read` lists exactly the columns it reads.

Gains are numpy arrays: a scalar, or one value per vehicle of the batch (shape ``(N,)``), so
that one vector env evaluates many gain candidates at once (:mod:`capsule_env.agents.controllers.tuning`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from capsule_env.agents.controllers.base import Controller
from capsule_env.agents.controllers.tuned import tuned_gains

from capsule_env.engine.config import OBSERVATION_NAMES

#: Each physical signal a law may read, per observation set: one column, or ``(a, b)`` for
#: the difference of two columns.
SOURCES: dict[str, dict[str, tuple[str, ...]]] = {
    "full_state": {
        "body_velocity": ("car_body_velocity_m_s",),  # z_c'
        "bogie_velocity": ("bogie_velocity_m_s",),  # z_b'
        "relative_velocity": ("car_body_velocity_m_s", "bogie_velocity_m_s"),  # x' = z_c' - z_b'
        "stroke": ("car_body_displacement_m", "bogie_displacement_m"),  # x = z_c - z_b
        "gap": ("bogie_displacement_m", "guideway_elevation_m"),  # z_b - z_g
        "body_acceleration": ("car_body_acceleration_m_s2",),  # z_c''
    },
    "measured": {
        "body_velocity": ("car_body_velocity_estimate_m_s",),  # integrated accelerometer
        "bogie_velocity": ("bogie_velocity_estimate_m_s",),
        "relative_velocity": ("stroke_rate_m_s",),  # the LVDT's rate
        "stroke": ("stroke_m",),  # LVDT
        "gap": ("levitation_gap_m",),  # gap sensor
        "body_acceleration": ("car_body_acceleration_m_s2",),  # accelerometer
    },
}
#: Observation sets a classical law can read.
LAW_OBSERVATIONS = tuple(SOURCES)
#: Name suffix of a law on the measured set (its ideal-sensor twin has the bare name).
MEASURED_SUFFIX = "-meas"


def law_name(base: str, observation: str) -> str:
    """``base`` on ``full_state`` (ideal sensors), ``base-meas`` on ``measured``."""
    return base + (MEASURED_SUFFIX if observation == "measured" else "")


def _plain(value: np.ndarray) -> float | list[float]:
    return float(value) if value.ndim == 0 else value.tolist()


class ClassicalLaw(Controller):
    """A feedback law on named physical signals with named gains.

    Subclasses set ``SIGNALS`` (the physical signals they read) and call :meth:`_set_gains`
    in their constructor with ``gain_units`` (gain name -> unit suffix of its key) and the
    given gains (None: the shipped tuned value, else ``fallback``).
    """

    SIGNALS: tuple[str, ...] = ()

    def __init__(self, observation: str) -> None:
        if observation not in SOURCES:
            raise ValueError(
                f"observation must be one of {', '.join(LAW_OBSERVATIONS)}, got {observation!r}"
            )
        self._columns = {name: k for k, name in enumerate(OBSERVATION_NAMES[observation])}
        self._sources = SOURCES[observation]
        self._gain_units: dict[str, str] = {}
        self.gains_tuned = False

    @property
    def signals_read(self) -> tuple[str, ...]:
        """The observation columns this law reads (names of its observation set)."""
        names = [col for signal in self.SIGNALS for col in self._sources[signal]]
        return tuple(dict.fromkeys(names))

    def signal(self, obs: np.ndarray, name: str) -> np.ndarray:
        """Physical signal ``name`` (one of ``SIGNALS``) for each vehicle, from ``obs``."""
        if name not in self.SIGNALS:
            raise KeyError(f"{type(self).__name__} does not declare the signal {name!r}")
        cols = [self._columns[c] for c in self._sources[name]]
        return obs[:, cols[0]] if len(cols) == 1 else obs[:, cols[0]] - obs[:, cols[1]]

    def _set_gains(
        self, gain_units: dict[str, str], given: dict[str, Any], fallback: dict[str, float]
    ) -> None:
        """Store each gain as a float array (attribute of the gain's name): ``given`` where
        not None, else the tuned value for :attr:`name` (``agents/controllers/tuned_gains.json``), else
        ``fallback``. :attr:`gains_tuned` says whether the tuned values were used."""
        self._gain_units = dict(gain_units)
        tuned = tuned_gains(self.name) or {}
        for gain in gain_units:
            value = given[gain]
            if value is None:
                key = self.gain_key(gain)
                value = tuned.get(key, fallback[gain])
                self.gains_tuned = self.gains_tuned or key in tuned
            setattr(self, gain, np.asarray(value, dtype=np.float64))

    def gain_key(self, gain: str) -> str:
        """The key (with its unit) of constructor gain ``gain`` in :meth:`gains`."""
        return f"{gain}_{self._gain_units[gain]}"

    def gains(self) -> dict[str, Any]:
        return {self.gain_key(g): _plain(getattr(self, g)) for g in self._gain_units}
