"""Every observable signal of the env, declared once.

One table, :data:`OBSERVABLES`, says for each signal an observation may carry its name (which
ends with its unit), what it is, the quantity it reads (:data:`QUANTITIES`, computed by
:func:`capsule_env.engine.env_kernel.env_sense`), its sensor-noise channel (:data:`NOISE_CHANNELS`),
the bounds at which its sensor saturates, the observation sets that hold it and whether it is
kept among the measurements (what the inverse model and the velocity estimators read). The
table's row order is the column order of every set. Everything else is generated from it:

- the column names of each set (:data:`OBSERVATION_NAMES`, ``config.SENSOR_NAMES`` ...), the
  measurement names (``layout.MEASUREMENT_NAMES``) and the noise channel names
  (``layout.NOISE_CHANNEL_NAMES``);
- the sensor noise per channel, by name (:data:`SENSOR_NOISE_STD`);
- the observation space's bounds (:func:`bounds`, ``config.observation_bounds``);
- the kernel's column map: which quantity and which noise channel each column reads
  (:data:`COLUMN_SOURCES`, :data:`COLUMN_NOISE`, :data:`MEASUREMENT_SOURCES`, ...: integer
  arrays, compile-time constants of the kernel);
- the observation tables of ``docs/env.md`` (:mod:`capsule_env.engine.observations_docs`: ``python
  -m capsule_env.engine.observations_docs docs/env.md`` rewrites them; a test checks they are in
  sync).

After a set's own columns come two groups the configuration adds, declared here too
(:data:`TRIP_COLUMNS`, :func:`preview_columns`; :func:`columns` lists them in order and
:func:`first_column` gives the kernels their offsets): a trip's speed and longitudinal
acceleration (``speed_profile="trip"``; the envelope kernel writes them) and the surveyed
guideway preview (``preview_points``; the env kernel writes them).

Adding a signal is one row of :data:`OBSERVABLES` (and, if it reads a quantity the env does not
compute yet, a row of :data:`QUANTITIES` and its line in ``env_kernel._quantities``; a new noise
channel is appended to :data:`NOISE_CHANNELS`). A new row placed after the others appends a
column to the sets that hold it, so that policies trained on the old columns keep their
meaning. No numba, no Gym import.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from capsule_env.common.units import kmh_to_m_s

__all__ = [
    "Quantity",
    "NoiseChannel",
    "Bound",
    "Observable",
    "QUANTITIES",
    "QUANTITY_NAMES",
    "NOISE_CHANNELS",
    "NOISE_CHANNEL_NAMES",
    "SENSOR_NOISE_STD",
    "OBSERVABLES",
    "OBSERVATION_SETS",
    "OBSERVATION_NAMES",
    "MEASUREMENT_NAMES",
    "observables",
    "bounds",
    "noise_channels_read",
    "rest_observation",
    "Column",
    "TRIP_COLUMNS",
    "TRIP_COLUMN_NAMES",
    "preview_columns",
    "columns",
    "column_bounds",
    "first_column",
]


class Quantity(NamedTuple):
    """A per-vehicle quantity the env computes every step (its true value, before noise)."""

    name: str
    what: str
    #: The ``info`` signal that holds it (a name in ``layout.SIGNAL_NAMES``), where the kernel
    #: reads it; None: the kernel computes it into its scratch.
    signal: str | None
    #: Its value at a vehicle's reset (the static equilibrium over the start elevation ``z0``):
    #: ``at_rest * z0``.
    at_rest: float = 0.0


class NoiseChannel(NamedTuple):
    """A sensor-noise channel: standard normals drawn per vehicle and step (channel ``c`` is
    member ``c % 2`` of Box-Muller pair ``c // 2``), times ``std`` x ``sensor_noise``."""

    name: str
    #: Standard deviation at ``sensor_noise=1`` (the ``hils`` default), in the signal's unit.
    std: float


class Bound(NamedTuple):
    """A saturation limit ``constant + per_stroke_limit * stroke_limit_m + per_i_max * i_max``."""

    constant: float
    per_stroke_limit: float = 0.0
    per_i_max: float = 0.0

    def value(self, stroke_limit_m: float, i_max_a: float) -> float:
        """The limit for a configuration's bump stop and maximum current."""
        return self.constant + self.per_stroke_limit * stroke_limit_m + self.per_i_max * i_max_a

    def text(self) -> str:
        """The limit as the docs write it (e.g. ``-2 x stroke_limit_m``, ``i_max + 0.5``)."""
        terms = [(self.per_stroke_limit, "stroke_limit_m"), (self.per_i_max, "i_max")]
        parts = [f"{c:g} x {name}" if c not in (1.0, -1.0) else f"{'-' if c < 0 else ''}{name}"
                 for c, name in terms if c != 0.0]  # fmt: skip
        if self.constant != 0.0 or not parts:
            parts.append(f"{self.constant:g}")
        return " + ".join(parts).replace("+ -", "- ")


class Observable(NamedTuple):
    """One signal an observation may carry: a row of :data:`OBSERVABLES`."""

    name: str  # the column's name, ending with its unit
    unit: str  # as the docs write it
    what: str  # what it is, for the docs
    source: str  # the quantity it reads (a name in QUANTITY_NAMES)
    noise: str | None  # its noise channel (a name in NOISE_CHANNEL_NAMES); None: exact
    low: Bound
    high: Bound
    sets: tuple[str, ...]  # the observation sets that hold it
    measured: bool = False  # kept in the measurements (the inverse and the estimators read it)


#: What :func:`capsule_env.engine.env_kernel.env_sense` computes for each vehicle every step (the
#: estimates from the noisy accelerometers, the rest from the plant): most are ``info``
#: signals, the others rows of the kernel's scratch.
QUANTITIES = (
    Quantity("car_body_displacement_m", "car body displacement `z_c`",
             "car_body_displacement_m", 1.0),
    Quantity("car_body_velocity_m_s", "car body velocity", "car_body_velocity_m_s"),
    Quantity("bogie_displacement_m", "bogie displacement `z_b`", "bogie_displacement_m", 1.0),
    Quantity("bogie_velocity_m_s", "bogie velocity", "bogie_velocity_m_s"),
    Quantity("guideway_elevation_m", "guideway elevation under the bogie `z_g`",
             "guideway_elevation_m", 1.0),
    Quantity("car_body_acceleration_m_s2", "car body vertical acceleration",
             "car_body_acceleration_m_s2"),
    Quantity("bogie_acceleration_m_s2", "bogie vertical acceleration", "bogie_acceleration_m_s2"),
    Quantity("stroke_m", "damper stroke `x = z_c - z_b`", "stroke_m"),
    Quantity("stroke_rate_m_s", "stroke rate `v`", "stroke_rate_m_s"),
    Quantity("coil_current_a", "coil current (after the coil lag)", "coil_current_a"),
    Quantity("levitation_gap_m", "levitation gap change `z_b - z_g`", None),
    Quantity("last_current_command_a", "last coil current command", "current_command_a"),
    Quantity("car_body_velocity_estimate_m_s", "car body absolute velocity estimate",
             "car_body_velocity_estimate_m_s"),
    Quantity("bogie_velocity_estimate_m_s", "bogie absolute velocity estimate",
             "bogie_velocity_estimate_m_s"),
)  # fmt: skip
QUANTITY_NAMES = tuple(q.name for q in QUANTITIES)

#: Sensor-noise channels in the order their normals are drawn: a channel keeps its noise
#: whatever other channels a set reads; new channels are appended. Standard deviations
#: [reconstructed]: a few per cent of each channel's typical level on the default guideway.
NOISE_CHANNELS = (
    NoiseChannel("car_body_acceleration_m_s2", 0.02),
    NoiseChannel("bogie_acceleration_m_s2", 0.1),
    NoiseChannel("stroke_m", 1e-4),
    NoiseChannel("stroke_rate_m_s", 2e-3),
    NoiseChannel("car_body_displacement_m", 1e-4),
    NoiseChannel("car_body_velocity_m_s", 2e-3),
    NoiseChannel("bogie_displacement_m", 1e-4),
    NoiseChannel("bogie_velocity_m_s", 2e-3),
    NoiseChannel("guideway_elevation_m", 1e-4),
    NoiseChannel("levitation_gap_m", 1e-4),  # like the LVDT's
    NoiseChannel("coil_current_a", 0.01),  # 0.7 % of 1.5 A
)
NOISE_CHANNEL_NAMES = tuple(c.name for c in NOISE_CHANNELS)
#: Standard deviation of each noise channel at ``sensor_noise=1``, in
#: :data:`NOISE_CHANNEL_NAMES` order (read from :data:`NOISE_CHANNELS`, by name).
SENSOR_NOISE_STD = np.array([c.std for c in NOISE_CHANNELS])
SENSOR_NOISE_STD.flags.writeable = False

#: The observation sets (``EnvConfig.observation``).
OBSERVATION_SETS = ("sensors", "full_state", "measured")


def _neg(bound: Bound) -> Bound:
    """The limit on the other side: ``-bound``."""
    return Bound(-bound.constant, -bound.per_stroke_limit, -bound.per_i_max)


_ACC, _RATE, _DISP = Bound(100.0), Bound(10.0), Bound(1.0)
_STROKE = Bound(0.0, 2.0)  # twice the bump stop
_ALL, _SENSORS_MEASURED = OBSERVATION_SETS, ("sensors", "measured")
#: Every observable signal; the row order is every set's column order.
OBSERVABLES = (
    Observable("car_body_displacement_m", "m", "car body displacement `z_c`",
               "car_body_displacement_m", "car_body_displacement_m", _neg(_DISP), _DISP,
               ("full_state",)),
    Observable("car_body_velocity_m_s", "m/s", "car body velocity", "car_body_velocity_m_s",
               "car_body_velocity_m_s", _neg(_RATE), _RATE, ("full_state",)),
    Observable("bogie_displacement_m", "m", "bogie displacement `z_b`", "bogie_displacement_m",
               "bogie_displacement_m", _neg(_DISP), _DISP, ("full_state",)),
    Observable("bogie_velocity_m_s", "m/s", "bogie velocity", "bogie_velocity_m_s",
               "bogie_velocity_m_s", _neg(_RATE), _RATE, ("full_state",)),
    Observable("guideway_elevation_m", "m", "guideway elevation under the bogie `z_g`",
               "guideway_elevation_m", "guideway_elevation_m", _neg(_DISP), _DISP, ("full_state",)),
    Observable("car_body_acceleration_m_s2", "m/s²",
               "car body vertical acceleration (accelerometer)", "car_body_acceleration_m_s2",
               "car_body_acceleration_m_s2", _neg(_ACC), _ACC, _ALL, measured=True),
    Observable("bogie_acceleration_m_s2", "m/s²", "bogie vertical acceleration (accelerometer)",
               "bogie_acceleration_m_s2", "bogie_acceleration_m_s2", _neg(_ACC), _ACC, _ALL,
               measured=True),
    Observable("stroke_m", "m", "damper stroke `x = z_c - z_b` (LVDT)", "stroke_m", "stroke_m",
               _neg(_STROKE), _STROKE, _ALL, measured=True),
    Observable("stroke_rate_m_s", "m/s", "stroke rate `v`", "stroke_rate_m_s",
               "stroke_rate_m_s", _neg(_RATE), _RATE, _ALL, measured=True),
    Observable("coil_current_a", "A", "actual coil current (after the coil lag), exact",
               "coil_current_a", None, Bound(0.0), Bound(0.0, 0.0, 1.0), ("full_state",)),
    Observable("levitation_gap_m", "m", "levitation gap change `z_b - z_g` (gap sensor)",
               "levitation_gap_m", "levitation_gap_m", _neg(_DISP), _DISP, ("measured",)),
    Observable("coil_current_a", "A", "coil current (the driver's measurement)",
               "coil_current_a", "coil_current_a", Bound(-0.5), Bound(0.5, 0.0, 1.0),
               ("measured",)),
    Observable("last_current_command_a", "A", "last coil current command",
               "last_current_command_a", None, Bound(0.0), Bound(0.0, 0.0, 1.0),
               _SENSORS_MEASURED, measured=True),
    Observable("car_body_velocity_estimate_m_s", "m/s",
               "car body absolute velocity estimate (from the accelerometer)",
               "car_body_velocity_estimate_m_s", None, _neg(_RATE), _RATE, ("measured",)),
    Observable("bogie_velocity_estimate_m_s", "m/s",
               "bogie absolute velocity estimate (from the accelerometer)",
               "bogie_velocity_estimate_m_s", None, _neg(_RATE), _RATE, ("measured",)),
)  # fmt: skip


def observables(observation: str) -> tuple[Observable, ...]:
    """The rows an observation set holds, in column order."""
    if observation not in OBSERVATION_SETS:
        raise ValueError(f"observation must be one of {OBSERVATION_SETS}, got {observation!r}")
    return tuple(row for row in OBSERVABLES if observation in row.sets)


#: The column names of each observation set (preview columns, if any, come after them).
OBSERVATION_NAMES = {s: tuple(row.name for row in observables(s)) for s in OBSERVATION_SETS}
#: The measurements, one row each of ``EnvState.measured``: what the vehicle's sensors read
#: this step (with noise), kept for the inverse model and the velocity estimators.
MEASUREMENTS = tuple(row for row in OBSERVABLES if row.measured)
MEASUREMENT_NAMES = tuple(row.name for row in MEASUREMENTS)


def bounds(observation: str, stroke_limit_m: float, i_max_a: float) -> tuple[list, list]:
    """``(low, high)`` of a set's columns (float64 lists, preview columns not included)."""
    rows = observables(observation)
    low = [row.low.value(stroke_limit_m, i_max_a) for row in rows]
    high = [row.high.value(stroke_limit_m, i_max_a) for row in rows]
    return low, high


#: A declared vehicle's column (:mod:`capsule_env.engine.declared_batch`) takes the bounds of
#: the quarter-car's column named here, by the first suffix its name ends with (its quantity
#: and unit); a pitch (rad, rad/s) those of a displacement and a rate. Another is unbounded.
DECLARED_BOUNDS_BY_SUFFIX = (
    ("_stroke_m", "stroke_m"),
    ("_acceleration_m_s2", "car_body_acceleration_m_s2"),
    ("_current_command_a", "last_current_command_a"),
    ("_m_s", "stroke_rate_m_s"),
    ("_rad_s", "stroke_rate_m_s"),
    ("_m", "car_body_displacement_m"),
    ("_rad", "car_body_displacement_m"),
)


def declared_bounds(
    names: tuple[str, ...], stroke_limit_m: float, i_max_a: float
) -> tuple[list, list]:
    """``(low, high)`` of a declared vehicle's columns ``names`` (float64 lists): the quarter-
    car's sensors saturate there too (:data:`DECLARED_BOUNDS_BY_SUFFIX`)."""
    rows = {row.name: row for row in OBSERVABLES if row.name != "coil_current_a"}
    low, high = [], []
    for name in names:
        source = next((q for suffix, q in DECLARED_BOUNDS_BY_SUFFIX if name.endswith(suffix)), None)
        row = rows.get(source) if source is not None else None
        low.append(row.low.value(stroke_limit_m, i_max_a) if row else -math.inf)
        high.append(row.high.value(stroke_limit_m, i_max_a) if row else math.inf)
    return low, high


def noise_channels_read(observation: str) -> tuple[int, ...]:
    """The noise channels (indices in :data:`NOISE_CHANNEL_NAMES`) a set reads, measurements
    included, in increasing order."""
    rows = (*observables(observation), *MEASUREMENTS)
    return tuple(sorted({NOISE_CHANNEL_NAMES.index(r.noise) for r in rows if r.noise}))


def rest_observation(observation: str, elevation_m: float) -> np.ndarray:
    """A set's columns at a vehicle's reset (exact, no noise): the static equilibrium over the
    start elevation ``elevation_m`` (displacements and elevation equal to it, the rest 0)."""
    at_rest = {q.name: q.at_rest for q in QUANTITIES}
    factors = [at_rest[row.source] for row in observables(observation)]
    return np.array([f * elevation_m if f else 0.0 for f in factors])


# ----------------------------------------------------------------------------- kernel map
def _indices(rows: tuple[Observable, ...]) -> tuple[np.ndarray, np.ndarray]:
    source = np.array([QUANTITY_NAMES.index(r.source) for r in rows], dtype=np.int64)
    noise = np.array(
        [NOISE_CHANNEL_NAMES.index(r.noise) if r.noise else -1 for r in rows], dtype=np.int64
    )
    for a in (source, noise):
        a.flags.writeable = False
    return source, noise


#: Per set, the quantity row (:data:`QUANTITY_NAMES`) each column reads and its noise channel
#: (-1: none): the kernel's column map.
COLUMN_SOURCES, COLUMN_NOISE = {}, {}
for _set in OBSERVATION_SETS:
    COLUMN_SOURCES[_set], COLUMN_NOISE[_set] = _indices(observables(_set))
#: The same for the measurements (rows of ``EnvState.measured``).
MEASUREMENT_SOURCES, MEASUREMENT_NOISE = _indices(MEASUREMENTS)
#: Per set, the measurement row each column equals (-1: none), which the kernel copies
#: instead of adding the noise again (the same bits, fewer operations).
COLUMN_MEASUREMENTS = {
    s: np.array([MEASUREMENTS.index(r) if r in MEASUREMENTS else -1 for r in observables(s)])
    for s in OBSERVATION_SETS
}
for _a in COLUMN_MEASUREMENTS.values():
    _a.flags.writeable = False


def _check_table() -> None:
    """The table's names refer to what exists, and no set holds a name twice."""
    for row in OBSERVABLES:
        assert row.source in QUANTITY_NAMES, row
        assert row.noise is None or row.noise in NOISE_CHANNEL_NAMES, row
        assert row.sets and set(row.sets) <= set(OBSERVATION_SETS), row
    for names in OBSERVATION_NAMES.values():
        assert len(set(names)) == len(names), names
    assert len(set(NOISE_CHANNEL_NAMES)) == len(NOISE_CHANNEL_NAMES)
    assert len(set(QUANTITY_NAMES)) == len(QUANTITY_NAMES)


_check_table()


# ----------------------------------------------------------------- appended column groups
class Column(NamedTuple):
    """A column a configuration appends after a set's own: its name (ending with its unit),
    what it is, and its ``(low, high)`` bounds."""

    name: str
    what: str
    low: float
    high: float


#: The trip's columns (``speed_profile="trip"``): exact, from the trip's schedule.
TRIP_COLUMNS = (
    Column("speed_m_s", "the capsule's speed (up to 2000 km/h)", 0.0, kmh_to_m_s(2000.0)),
    Column("longitudinal_acceleration_m_s2",
           "longitudinal acceleration (> 0 speeding up; up to 2 g)", -20.0, 20.0),
)  # fmt: skip
TRIP_COLUMN_NAMES = tuple(c.name for c in TRIP_COLUMNS)


def preview_columns(preview_points: int) -> tuple[Column, ...]:
    """The guideway preview's columns: ``preview_ahead_<k>`` is the surveyed elevation ``k *
    preview_horizon_s / preview_points`` seconds ahead of the bogie, relative to the surveyed
    elevation under it now (m, saturating at 1 m)."""
    return tuple(Column(f"preview_ahead_{k}", f"surveyed guideway {k} preview steps ahead, "
                        "relative to under the bogie now", -1.0, 1.0)
                 for k in range(1, preview_points + 1))  # fmt: skip


def _groups(trip: bool, preview_points: int) -> tuple[tuple[str, tuple[Column, ...]], ...]:
    return (("trip", TRIP_COLUMNS if trip else ()), ("preview", preview_columns(preview_points)))


def columns(observation: str, trip: bool = False, preview_points: int = 0) -> tuple[str, ...]:
    """Every column of an observation, in order: the set's, the trip's, the preview's."""
    if observation not in OBSERVATION_NAMES:
        raise ValueError(f"observation must be one of {', '.join(OBSERVATION_NAMES)}, "
                         f"got {observation!r}")  # fmt: skip
    appended = tuple(c.name for _, group in _groups(trip, preview_points) for c in group)
    return OBSERVATION_NAMES[observation] + appended


def first_column(observation: str, group: str, trip: bool, preview_points: int) -> int:
    """The index of ``group``'s (``"trip"`` or ``"preview"``) first column, -1 if absent."""
    at = len(OBSERVATION_NAMES[observation])
    for name, group_columns in _groups(trip, preview_points):
        if name == group:
            return at if group_columns else -1
        at += len(group_columns)
    raise ValueError(f"group must be 'trip' or 'preview', got {group!r}")


def column_bounds(observation: str, stroke_limit_m: float, i_max_a: float, trip: bool = False,
                  preview_points: int = 0) -> tuple[list, list]:  # fmt: skip
    """``(low, high)`` of every column of :func:`columns` (float64 lists)."""
    low, high = bounds(observation, stroke_limit_m, i_max_a)
    for _, group in _groups(trip, preview_points):
        low += [c.low for c in group]
        high += [c.high for c in group]
    return low, high
