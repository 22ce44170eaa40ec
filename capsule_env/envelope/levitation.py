"""Electrodynamic (EDS) levitation against speed: the first-order L-R coil model.

The paper's capsule levitates on a *sidewall* EDS: superconducting magnets on the bogie pass
figure-eight (null-flux) coils in the guideway's walls (the paper, section "Capsule vehicle
model", after its refs. 40-41; the Japanese SCMaglev layout). Its primary suspension is a
spring of 2.25e6 N/m "at the running speed of 810 km/h, excluding the nonlinear characteristics
in the levitation stiffness", with no damping. This module gives that spring's speed
dependence from the standard first-order model of an EDS coil (one L-R circuit per coil, the
magnet's flux linking it at the electrical angular frequency ``omega = 2 pi v / lambda``):

**Null-flux coil** (the default ``geometry="null_flux"``). A magnet displaced ``z`` below the
coil's null line links a flux ``A(z) cos(omega t)`` with ``A = a z``. The induced current lags
the emf by ``atan(r)``, ``r = omega L / R = v / v_c``, and the mean vertical force is a spring
and a damper (derived below, checked in tests against a direct simulation of the circuit):

.. math::

    k_p(v) = K_\\infty \\frac{r^2}{1 + r^2}, \\qquad
    c_p(v) = K_\\infty \\tau \\frac{1 - r^2}{(1 + r^2)^2}, \\qquad
    v_c = \\frac{\\lambda}{2 \\pi \\tau}, \\quad \\tau = L / R.

The stiffness rises from 0 to ``K_inf`` with speed; the damping is positive below ``v_c`` and
*negative* above it, and small (about -1 kN s/m at 810 km/h with the defaults, 0.7 % of the
bogie's critical damping): the electrodynamic suspension's known weak negative heave damping at
high speed (He, Rote & Coffey, "Study of Japanese electrodynamic-suspension maglev systems",
Argonne National Laboratory ANL/ESD-20, 1994; Moon, *Superconducting Levitation*, Wiley 1994,
ch. 5). The mean magnetic drag is ``F_D = R <i^2> / v``; at the equilibrium sag
``z_eq = W / k_p(v)`` it is ``F_D = W k z_eq / r`` (``k = 2 pi / lambda``).

Derivation (first order in the heave frequency over ``omega``): with the flux phasor amplitude
``A(q)`` and ``Z = R + j omega L``, the current phasor is ``I = -j omega A / Z - A' q' R / Z^2``
and the cycle-mean force ``F = A' Re(I) / 2``, which gives the spring (first term) and the
damper (second term) above. A Halbach array over a ladder track (Inductrack, Post & Ryutov,
IEEE Trans. Appl. Supercond. 10(1), 2000) has ``A = A0 exp(-k g)`` instead; its lift over drag is
exactly ``v / v_c`` and its stiffness at equilibrium ``2 k W`` does not depend on speed
(:func:`halbach_lift_drag`, kept for that comparison; the env models the paper's null-flux
coils).

**Calibration** ([reconstructed], every value overridable in :class:`EdsParams`): ``K_inf`` so
that ``k_p(810 km/h)`` equals the vehicle's levitation stiffness (2.25e6 N/m, the paper's
Table 4); ``v_c`` so that the sag at the lift-off speed (150 km/h, the speed at which SCMaglev
retracts its wheels) equals the levitation travel the landing wheels leave (0.1 m); the pole
pitch 1.35 m (the Yamanashi line's magnets; ``lambda = 2.7 m``) gives ``tau``. With the default
vehicle this is ``v_c = 57.6 m/s`` (207 km/h) and ``tau = 7.5 ms``. Below the lift-off speed the
capsule rolls on its wheels and is not levitating: :func:`check_levitating` refuses such speeds.

**Lift-off under payload.** The coil is calibrated on the unladen vehicle; a vehicle of weight
``W`` (a payload, a randomised vehicle) leaves its wheels where its sag ``W / k_p(v)`` equals the
travel: :func:`lift_off_speed_m_s`. ``EdsParams.lift_off="unladen"`` (the default) levitates
every vehicle from the calibration's lift-off speed; ``"payload"`` from its own.

Pure numpy, no Gym import.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from capsule_env.common.units import kmh_to_m_s, m_s_to_kmh
from capsule_env.common.validation import check_choice, check_in_range, check_positive
from capsule_env.vehicles import VehicleParams

__all__ = [
    "EDS_GEOMETRIES",
    "GRAVITY_M_S2",
    "EdsParams",
    "EdsCoil",
    "eds_coil",
    "check_levitating",
    "LIFT_OFF_MODES",
    "lift_off_speed_m_s",
    "lowest_accepted_kmh",
    "levitation_stiffness_n_per_m",
    "levitation_damping_n_s_per_m",
    "equilibrium_sag_m",
    "magnetic_drag_n",
    "halbach_lift_drag",
]

#: Standard gravity (m/s^2), the weight the levitation carries.
GRAVITY_M_S2 = 9.80665
#: Coil geometries of :class:`EdsParams` (only ``null_flux`` is calibrated for the env).
EDS_GEOMETRIES = ("null_flux",)
#: Whose lift-off speed a vehicle levitates from (:class:`EdsParams`): the unladen vehicle's
#: (the calibration's ``lift_off_speed_kmh``, for every payload) or each vehicle's own.
LIFT_OFF_MODES = ("unladen", "payload")


@dataclass(frozen=True)
class EdsParams:
    """The EDS coil model's parameters (all [reconstructed]; see the module docstring).

    Attributes
    ----------
    geometry : coil geometry, ``"null_flux"`` (the paper's sidewall figure-eight coils).
    reference_speed_kmh : speed at which ``k_p`` equals the vehicle's levitation stiffness
        (810 km/h, the paper's).
    lift_off_speed_kmh : lowest levitating speed (150 km/h; SCMaglev's wheel retraction).
    levitation_travel_m : sag below the null line at the lift-off speed, the clearance the
        landing wheels leave (0.1 m).
    pole_pitch_m : magnet pole pitch (1.35 m; the Yamanashi line), ``lambda = 2 pole_pitch_m``.
    lift_off : ``"unladen"`` (every vehicle levitates from ``lift_off_speed_kmh``, the unladen
        vehicle's) or ``"payload"`` (each vehicle from its own lift-off speed, where the coil
        carries its weight at the travel: :func:`lift_off_speed_m_s`).
    """

    geometry: str = "null_flux"
    reference_speed_kmh: float = 810.0
    lift_off_speed_kmh: float = 150.0
    levitation_travel_m: float = 0.1
    pole_pitch_m: float = 1.35
    lift_off: str = "unladen"

    def __post_init__(self) -> None:
        check_choice("geometry", self.geometry, EDS_GEOMETRIES)
        check_choice("lift_off", self.lift_off, LIFT_OFF_MODES)
        check_in_range("reference_speed_kmh", self.reference_speed_kmh, 1.0, 2000.0)
        check_in_range("lift_off_speed_kmh", self.lift_off_speed_kmh, 1.0, 2000.0)
        check_in_range("levitation_travel_m", self.levitation_travel_m, 1e-3, 1.0)
        check_in_range("pole_pitch_m", self.pole_pitch_m, 0.01, 10.0)
        if self.lift_off_speed_kmh >= self.reference_speed_kmh:
            raise ValueError(
                f"lift_off_speed_kmh must be below reference_speed_kmh "
                f"({self.reference_speed_kmh}), got {self.lift_off_speed_kmh}"
            )


@dataclass(frozen=True)
class EdsCoil:
    """The calibrated coil model of one vehicle: ``K_inf`` (N/m), ``v_c`` (m/s), ``tau`` (s),
    the weight carried ``W`` (N) and the lift-off speed (m/s)."""

    stiffness_limit_n_per_m: float
    characteristic_speed_m_s: float
    time_constant_s: float
    weight_n: float
    lift_off_speed_m_s: float
    wavenumber_per_m: float


def _lift_shape(r: np.ndarray | float) -> np.ndarray | float:
    """``r^2 / (1 + r^2)``: the in-phase part of the coil's response."""
    return r * r / (1.0 + r * r)


def eds_coil(vehicle: VehicleParams | None = None, params: EdsParams | None = None) -> EdsCoil:
    """Calibrate the coil model to a vehicle (see the module docstring).

    ``v_c`` solves ``k_p(v_lo) / k_p(v_ref) = sag_ref / travel`` in closed form, with
    ``sag_ref = W / k_ref``: ``v_c^2 = a^2 b^2 (1 - rho) / (rho b^2 - a^2)`` (``a = v_lo``,
    ``b = v_ref``, ``rho = sag_ref / travel``). Raises ``ValueError`` when no ``v_c`` exists
    (the travel is shorter than the sag at the reference speed divided by ``(a/b)^2``).
    """
    vehicle = vehicle or VehicleParams()
    params = params or EdsParams()
    weight = (vehicle.car_body_mass_kg + vehicle.bogie_mass_kg) * GRAVITY_M_S2
    k_ref = vehicle.levitation_stiffness_n_per_m
    a = kmh_to_m_s(params.lift_off_speed_kmh)
    b = kmh_to_m_s(params.reference_speed_kmh)
    rho = weight / k_ref / params.levitation_travel_m
    if not (a / b) ** 2 < rho < 1.0:
        raise ValueError(
            f"levitation_travel_m must lie in ({weight / k_ref:.4g}, "
            f"{weight / k_ref / (a / b) ** 2:.4g}) m for this vehicle and these speeds "
            f"(the sag at the reference speed and at lift-off), got {params.levitation_travel_m}"
        )
    v_c = math.sqrt(a * a * b * b * (1.0 - rho) / (rho * b * b - a * a))
    k = math.pi / params.pole_pitch_m
    return EdsCoil(
        stiffness_limit_n_per_m=k_ref / _lift_shape(b / v_c),
        characteristic_speed_m_s=v_c,
        time_constant_s=1.0 / (k * v_c),
        weight_n=weight,
        lift_off_speed_m_s=a,
        wavenumber_per_m=k,
    )


def lowest_accepted_kmh(limit_m_s: float, strict: bool = False) -> float:
    """The lowest speed in km/h with two decimals that passes ``kmh_to_m_s(v) >= limit_m_s``
    (``>`` if ``strict``): what an error message states as the lowest accepted speed, rounded
    up so that a user who gives it is accepted."""
    kmh = math.floor(m_s_to_kmh(limit_m_s) * 100.0) / 100.0
    while not (kmh_to_m_s(kmh) > limit_m_s if strict else kmh_to_m_s(kmh) >= limit_m_s):
        kmh = round(kmh + 0.01, 2)
    return kmh


def check_levitating(name: str, speed_m_s: np.ndarray | float, coil: EdsCoil) -> None:
    """Raise ``ValueError`` naming ``name`` when a speed is below the lift-off speed (the
    capsule is then on its wheels, which this model does not include)."""
    low = float(np.min(speed_m_s))
    if not low >= coil.lift_off_speed_m_s:
        raise ValueError(
            f"{name} must be at least the lift-off speed "
            f"{lowest_accepted_kmh(coil.lift_off_speed_m_s):.2f} km/h "
            f"with levitation='eds' (below it the capsule rolls on its wheels), got "
            f"{m_s_to_kmh(low):.10g} km/h"
        )


def lift_off_speed_m_s(coil: EdsCoil, weight_n: float, travel_m: float,
                       stiffness_limit_n_per_m: float | None = None) -> float:  # fmt: skip
    """The speed (m/s) at which the sag ``weight_n / k_p(v)`` equals ``travel_m``: from
    ``k_p = K_inf r^2 / (1 + r^2)``, ``r^2 = k / (K_inf - k)`` with ``k = W / travel``.
    ``K_inf`` is the coil's unless ``stiffness_limit_n_per_m`` is given (a randomised
    vehicle's); ``inf`` when even ``K_inf`` leaves a sag over the travel."""
    check_positive("weight_n", weight_n)
    check_positive("travel_m", travel_m)
    limit = (
        coil.stiffness_limit_n_per_m if stiffness_limit_n_per_m is None else stiffness_limit_n_per_m
    )
    needed = weight_n / travel_m
    if needed >= limit:
        return math.inf
    return coil.characteristic_speed_m_s * math.sqrt(needed / (limit - needed))


def levitation_stiffness_n_per_m(speed_m_s: np.ndarray | float, coil: EdsCoil):
    """``k_p(v) = K_inf r^2 / (1 + r^2)``, ``r = v / v_c`` (N/m)."""
    return coil.stiffness_limit_n_per_m * _lift_shape(
        np.asarray(speed_m_s) / coil.characteristic_speed_m_s
    )


def levitation_damping_n_s_per_m(speed_m_s: np.ndarray | float, coil: EdsCoil):
    """``c_p(v) = K_inf tau (1 - r^2) / (1 + r^2)^2`` (N s/m): positive below ``v_c``,
    negative above."""
    r2 = (np.asarray(speed_m_s) / coil.characteristic_speed_m_s) ** 2
    return coil.stiffness_limit_n_per_m * coil.time_constant_s * (1.0 - r2) / (1.0 + r2) ** 2


def equilibrium_sag_m(speed_m_s: np.ndarray | float, coil: EdsCoil):
    """The static sag below the coils' null line, ``W / k_p(v)`` (m)."""
    return coil.weight_n / levitation_stiffness_n_per_m(speed_m_s, coil)


def magnetic_drag_n(speed_m_s: np.ndarray | float, coil: EdsCoil):
    """Mean magnetic drag at the equilibrium sag, ``W k z_eq / r`` (N): the circuit's
    dissipated power over the speed."""
    r = np.asarray(speed_m_s) / coil.characteristic_speed_m_s
    return coil.weight_n * coil.wavenumber_per_m * equilibrium_sag_m(speed_m_s, coil) / r


def halbach_lift_drag(speed_m_s: float, characteristic_speed_m_s: float) -> tuple[float, float]:
    """Inductrack's normalised lift and drag, ``(r^2, r) / (1 + r^2)`` with ``r = v / v_c``
    (Post & Ryutov 2000): their ratio is ``v / v_c``."""
    r = speed_m_s / characteristic_speed_m_s
    return r * r / (1.0 + r * r), r / (1.0 + r * r)
