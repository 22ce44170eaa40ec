"""The capsule's operating envelope in the env: EDS levitation against speed, trips, tube spans.

Four options of :class:`capsule_env.engine.config.EnvConfig`, each off by default (the paper's
setting, bit for bit):

- ``levitation="eds"`` (``levitation_params``: :class:`capsule_env.envelope.levitation.EdsParams`
  fields): the levitation's stiffness ``k_p(v)`` and damping ``c_p(v)`` follow the vehicle's
  speed (the null-flux coil model of :mod:`capsule_env.envelope.levitation`, calibrated so that
  ``k_p(810 km/h)`` is the vehicle's ``levitation_stiffness_n_per_m``). At a constant speed
  they are set at each reset; on a trip, every control step at the interval's mid-time. Speeds
  below the lift-off speed are refused (the capsule then rolls on its wheels).
- ``speed_profile="trip"`` (``trip_params``: :class:`capsule_env.envelope.trips.TripParams` fields):
  each episode is a window of a trip (lift-off, acceleration, cruise, braking), its start drawn
  from the vehicle's own stream. The guideway is read at the distance travelled: over each
  control interval the route is the chord of the exact trajectory (exact at both ends; at
  1 m/s^2 and 200 Hz the mid-interval position is off by ``a dt^2 / 8 = 3 um``). Every
  observation set gets two more columns after its own, :data:`capsule_env.engine.observations.TRIP_COLUMN_NAMES` (exact: a
  capsule knows its speed and acceleration from its propulsion control). A trip that never
  changes speed reduces to the constant-speed env bit for bit (the extra distance is a sum of
  terms proportional to the accelerations, exactly 0 then).
- ``spans="continuous"`` or ``"simply_supported"`` (``span_params``:
  :class:`capsule_env.guideway.spans.SpanParams` fields but ``shape``): the tube's static sag
  between pylons and the pylons' settlement are added to every profile of the guideway bank
  (the survey map of the preview includes them: they are part of the true guideway).
- ``magnet_length_m`` (None: a point magnet): the plant reads the guideway bank (spans
  included) averaged over the magnet's length (:mod:`capsule_env.envelope.magnet`); the survey
  map of the preview and each window's scaling keep the true guideway (``CapsuleBatch``).

Pure numpy; the compiled per-step part is :mod:`capsule_env.envelope.kernel`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from capsule_env.common.units import kmh_to_m_s, m_s_to_kmh
from capsule_env.common.validation import check_choice, check_in_range
from capsule_env.envelope.levitation import (
    GRAVITY_M_S2,
    EdsCoil,
    EdsParams,
    check_levitating,
    eds_coil,
    lift_off_speed_m_s,
    lowest_accepted_kmh,
)
from capsule_env.envelope.trips import TripParams, own_trip_s
from capsule_env.guideway.spans import SPAN_SHAPES, SpanParams
from capsule_env.vehicles import VehicleParams

__all__ = [
    "LEVITATION_MODELS",
    "SPEED_PROFILES",
    "SPAN_OPTIONS",
    "ENVELOPE_TRIP",
    "ENVELOPE_EDS_PER_STEP",
    "Envelope",
    "build_envelope",
]

LEVITATION_MODELS = ("fixed", "eds")
SPEED_PROFILES = ("constant", "trip")
SPAN_OPTIONS = ("none", *SPAN_SHAPES)
#: Flags of the env kernel (compile-time): the route and the trip columns follow a trip, and
#: the levitation follows the speed every step.
ENVELOPE_TRIP, ENVELOPE_EDS_PER_STEP = 1, 2


def _build(name: str, cls: type, overrides: dict, exclude: tuple[str, ...] = ()) -> Any:
    if not isinstance(overrides, dict):
        raise TypeError(f"{name} must be a dict of parameter overrides, got {overrides!r}")
    known = {f.name for f in fields(cls)} - set(exclude)
    for key in overrides:
        if key not in known:
            raise ValueError(f"unknown key {key!r} in {name}; accepted: {', '.join(sorted(known))}")
    try:
        return cls(**overrides)
    except (ValueError, TypeError) as exc:  # say which dict the field came from (two have
        raise type(exc)(f"{name}: {exc}") from None  # lift-off speeds)


def _down(seconds: float) -> str:
    """A longest accepted duration as an error states it: rounded down to the tenth of a
    second (to nearest, the stated one could be refused)."""
    return f"{math.floor(seconds * 10.0) / 10.0:.1f}"


def _lift_shape(r: float) -> float:
    return r * r / (1.0 + r * r)


@dataclass(frozen=True)
class Envelope:
    """The envelope options of one configuration, validated (:func:`build_envelope`)."""

    levitation: str
    speed_profile: str
    spans: str
    eds: EdsParams | None
    coil: EdsCoil | None
    trip: TripParams | None
    span: SpanParams | None
    magnet_length_m: float | None = None

    @property
    def flags(self) -> int:
        """The env kernel's envelope flags (0: the paper's kernel)."""
        if self.trip is None:
            return 0
        return ENVELOPE_TRIP | (ENVELOPE_EDS_PER_STEP if self.coil is not None else 0)

    @property
    def damped(self) -> bool:
        """Whether the levitation may have damping (the kernels compile its term)."""
        return self.coil is not None

    @property
    def reference_shape(self) -> float:
        """``k_p(v_ref) / K_inf``: a vehicle's ``K_inf`` is its reference ``k_p`` over this."""
        assert self.coil is not None and self.eds is not None
        return _lift_shape(
            kmh_to_m_s(self.eds.reference_speed_kmh) / self.coil.characteristic_speed_m_s
        )

    def trip_array(self) -> np.ndarray:
        """``(a, b, t1, t2, t3)``: the trip's acceleration, braking (m/s^2) and phase ends (s)
        as the kernel reads them (zeros without a trip)."""
        if self.trip is None:
            return np.zeros(5)
        return np.array([self.trip.acceleration_m_s2, self.trip.braking_m_s2,
                         *self.trip.phase_ends_s])  # fmt: skip

    def eds_array(self) -> np.ndarray:
        """``(v_c, tau)`` of the coil model (m/s, s; ones without EDS)."""
        if self.coil is None:
            return np.ones(2)
        return np.array([self.coil.characteristic_speed_m_s, self.coil.time_constant_s])

    def levitation_at(self, limit_n_per_m: Any, speed_m_s: Any) -> tuple[Any, Any]:
        """``(k_p, c_p)`` (N/m, N s/m) at ``speed_m_s`` of vehicles whose stiffness limit is
        ``limit_n_per_m`` (:mod:`capsule_env.envelope.levitation`; the kernel's is the same formula)."""
        assert self.coil is not None
        r2 = (np.asarray(speed_m_s, dtype=float) / self.coil.characteristic_speed_m_s) ** 2
        k = np.asarray(limit_n_per_m, dtype=float)
        return k * r2 / (1.0 + r2), k * self.coil.time_constant_s * (1.0 - r2) / (1.0 + r2) ** 2

    @property
    def payload_lift_off(self) -> bool:
        """Whether each vehicle levitates from its own lift-off speed
        (``levitation_params['lift_off']='payload'``)."""
        return self.eds is not None and self.eds.lift_off == "payload"

    def vehicle_lift_off_m_s(self, body_kg: float, bogie_kg: float, limit_n_per_m: float) -> float:
        """The lift-off speed (m/s) of a vehicle of these masses whose coil's stiffness limit
        is ``limit_n_per_m`` (:func:`capsule_env.envelope.levitation.lift_off_speed_m_s`)."""
        assert self.coil is not None and self.eds is not None
        weight = (body_kg + bogie_kg) * GRAVITY_M_S2
        return lift_off_speed_m_s(self.coil, weight, self.eds.levitation_travel_m, limit_n_per_m)

    def lift_off_range_m_s(self, config: Any) -> tuple[float, float]:
        """The lowest and highest lift-off speeds (m/s) of the vehicles ``config`` draws: the
        payload and the randomisation at their lightest (with the stiffest coil) and heaviest
        (with the softest), in the order of operations of a vehicle's reset."""
        vehicle = config.packed_vehicle
        r = config.vehicle_randomization
        lo, hi = config.payload_range or (0.0, 0.0)
        light = self.vehicle_lift_off_m_s(vehicle[0] * (1.0 - r) * (1.0 + lo),
                                          vehicle[1] * (1.0 - r),
                                          vehicle[3] * (1.0 + r) / self.reference_shape)  # fmt: skip
        heavy = self.vehicle_lift_off_m_s(vehicle[0] * (1.0 + r) * (1.0 + hi),
                                          vehicle[1] * (1.0 + r),
                                          vehicle[3] * (1.0 - r) / self.reference_shape)  # fmt: skip
        return light, heavy

    def highest_speed_m_s(self, speed_high_m_s: float) -> float:
        """The highest speed a vehicle reaches (m/s): the trip's cruise, else the given one."""
        return kmh_to_m_s(self.trip.cruise_speed_kmh) if self.trip is not None else speed_high_m_s


def _payload_lift_off(config: Any, envelope: Envelope) -> TripParams:
    """With ``levitation_params['lift_off']='payload'``: refuse a constant speed below the
    heaviest vehicle's lift-off speed (the payload and the randomisation at their heaviest);
    return the trip that runs from the lightest vehicle's lift-off speed (each vehicle's
    windows then lie where the trip is at or above its own, :meth:`Envelope.vehicle_lift_off_m_s`)."""
    low, high = envelope.lift_off_range_m_s(config)
    what = (f"the lift-off speed of the heaviest vehicle that payload_range "
            f"{config.payload_range} and vehicle_randomization {config.vehicle_randomization:g} "
            f"allow, with levitation_params['lift_off']='payload'")  # fmt: skip
    if not math.isfinite(high):
        raise ValueError(f"payload_range must leave every vehicle a lift-off speed: {what} does "
                         "not exist (the coil's K_inf does not carry that weight at the travel)")  # fmt: skip
    trip = envelope.trip
    assert trip is not None
    if config.speed_profile == "constant":
        name = "speed_kmh" if config.speed_range_kmh is None else "speed_range_kmh[0]"
        if not config.speed_range_mps[0] >= high:
            raise ValueError(f"{name} must be at least {lowest_accepted_kmh(high):.2f} km/h, "
                             f"{what}; got {m_s_to_kmh(config.speed_range_mps[0]):.10g} km/h")  # fmt: skip
        return trip
    if "lift_off_speed_kmh" in config.trip_params:
        raise ValueError("trip_params['lift_off_speed_kmh'] must not be set with "
                         "levitation_params['lift_off']='payload': each vehicle's trip runs from "
                         "and to its own lift-off speed")  # fmt: skip
    if not kmh_to_m_s(trip.cruise_speed_kmh) > high:
        raise ValueError(f"trip_params['cruise_speed_kmh'] must be at least "
                         f"{lowest_accepted_kmh(high, strict=True):.2f} "
                         f"km/h, {what}; got {trip.cruise_speed_kmh}")  # fmt: skip
    trip = replace(trip, lift_off_speed_kmh=m_s_to_kmh(low))
    start, end = own_trip_s(trip, high)
    if end - start < config.episode_length_s:
        raise ValueError(f"episode_length_s must be at most {_down(end - start)} s, the trip of the "
                         f"heaviest vehicle (its lift-off {m_s_to_kmh(high):.1f} km/h), got "
                         f"{config.episode_length_s}")  # fmt: skip
    return trip


def _eds(config: Any, eds: EdsParams, trip: TripParams) -> tuple[EdsCoil, TripParams]:
    """The calibrated coil, the speeds checked against the lift-off, and the trip (its
    lift-off set by the vehicles' own with ``lift_off='payload'``)."""
    vehicle: VehicleParams = config.vehicle_parameters
    try:
        coil = eds_coil(vehicle, eds)
    except ValueError as exc:
        raise ValueError(
            f"levitation_params and vehicle_params do not calibrate an EDS coil "
            f"(levitation_stiffness_n_per_m {vehicle.levitation_stiffness_n_per_m:g} N/m at "
            f"{eds.reference_speed_kmh:g} km/h, lift-off {eds.lift_off_speed_kmh:g} km/h): "
            f"{exc}"
        ) from None
    if eds.lift_off == "payload":
        trip = _payload_lift_off(config, Envelope(config.levitation, config.speed_profile,
                                                  config.spans, eds, coil, trip, None))  # fmt: skip
    elif config.speed_profile == "trip":
        check_levitating("trip_params['lift_off_speed_kmh']", kmh_to_m_s(trip.lift_off_speed_kmh),
                         coil)  # fmt: skip
    else:
        name = "speed_kmh" if config.speed_range_kmh is None else "speed_range_kmh[0]"
        check_levitating(name, config.speed_range_mps[0], coil)
    return coil, trip


def build_envelope(config: Any) -> Envelope:
    """Validate the envelope options of an :class:`~capsule_env.engine.config.EnvConfig` (one
    ``ValueError``/``TypeError`` naming the option) and make its :class:`Envelope`."""
    check_choice("levitation", config.levitation, LEVITATION_MODELS)
    check_choice("speed_profile", config.speed_profile, SPEED_PROFILES)
    check_choice("spans", config.spans, SPAN_OPTIONS)
    eds = _build("levitation_params", EdsParams, config.levitation_params)
    trip_params = config.trip_params
    if eds.lift_off == "payload" and isinstance(trip_params, dict):  # set by _payload_lift_off
        trip_params = {"lift_off_speed_kmh": 0.0, **trip_params}
    trip = _build("trip_params", TripParams, trip_params)
    if config.speed_profile == "trip" and config.speed_kmh != 810.0:
        raise ValueError(
            f"speed_kmh must be left at its default (810) with speed_profile='trip': the trip "
            f"sets the speed (trip_params), got {config.speed_kmh}"
        )
    if config.levitation == "eds" and "levitation_damping_n_s_per_m" in config.vehicle_params:
        raise ValueError(
            "vehicle_params['levitation_damping_n_s_per_m'] must not be set with "
            "levitation='eds': the coil model sets the damping at each speed"
        )
    _build("span_params", SpanParams, config.span_params, exclude=("shape",))  # validates
    if config.magnet_length_m is not None:  # None: the guideway read at a point (the paper's)
        check_in_range("magnet_length_m", config.magnet_length_m, 1e-3, 50.0)
    if config.levitation == "fixed" and config.levitation_params:
        raise ValueError("levitation_params needs levitation='eds'")
    if config.speed_profile == "constant" and config.trip_params:
        raise ValueError("trip_params needs speed_profile='trip'")
    if config.spans == "none" and config.span_params:
        raise ValueError("span_params needs spans='continuous' or 'simply_supported'")
    coil = None
    if config.levitation == "eds":
        coil, trip = _eds(config, eds, trip)
    if config.speed_profile == "trip" and trip.duration_s < config.episode_length_s:
        raise ValueError(
            f"episode_length_s must be at most the trip's duration {_down(trip.duration_s)} s "
            f"(trip_params), got {config.episode_length_s}"
        )
    return Envelope(
        levitation=config.levitation,
        speed_profile=config.speed_profile,
        spans=config.spans,
        eds=eds if coil is not None else None,
        coil=coil,
        trip=trip if config.speed_profile == "trip" else None,
        span=SpanParams(**{**config.span_params, "shape": config.spans})
        if config.spans != "none"
        else None,
        magnet_length_m=None if config.magnet_length_m is None else float(config.magnet_length_m),
    )
