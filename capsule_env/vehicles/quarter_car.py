"""The built-in ``quarter_car``: the paper's 2-DOF vertical 1/4-car of the capsule (docs/model.md,
section 2), declared as data (:mod:`capsule_env.vehicles.declaration`).

A car body ``z_c`` on a bogie ``z_b`` through the secondary spring ``k_s`` and the damper slot
(the MR damper); the bogie on the EDS levitation, a spring ``k_p`` and a dashpot ``c_p`` to the
guideway ``z_g`` under it::

    m_c z_c'' = -k_s (z_c - z_b) - F
    m_b z_b'' =  k_s (z_c - z_b) + F - k_p (z_b - z_g) - c_p (z_b' - z_g')

The compiled plant (:mod:`capsule_env.plant.equations`) runs these sums in this order; the
linear model of every controller is derived from this declaration
(:mod:`capsule_env.vehicles.linear`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capsule_env.common.validation import check_in_range
from capsule_env.vehicles.declaration import (
    DAMPER,
    DASHPOT,
    SPRING,
    Contact,
    Coordinate,
    Element,
    Point,
    VehicleModel,
)
from capsule_env.vehicles.linear import mechanical_matrices

__all__ = ["VehicleParams", "MODEL"]


#: Accepted range of each :class:`VehicleParams` field (SI units).
_RANGES = {
    "car_body_mass_kg": (1.0, 1e6),
    "bogie_mass_kg": (1.0, 1e6),
    "secondary_stiffness_n_per_m": (1.0, 1e10),
    "levitation_stiffness_n_per_m": (1.0, 1e10),
    "passive_damping_n_s_per_m": (0.0, 1e9),
    "levitation_damping_n_s_per_m": (-2e4, 2e4),
}


@dataclass(frozen=True)
class VehicleParams:
    """Parameters of the 1/4-car capsule vehicle.

    Provenance: the form is standard; the values are **[reconstructed]** (docs/model.md, section 2) to
    put the undamped modes at about 1.30 Hz (car body) and 5.42 Hz (bogie), inside the paper's
    bands. Every field can be overridden.

    Attributes
    ----------
    car_body_mass_kg : m_c, car body mass per quarter (kg), default 6000.
    bogie_mass_kg : m_b, bogie mass (kg), default 2400.
    secondary_stiffness_n_per_m : k_s, secondary (air) spring (N/m), default 4.95e5.
    levitation_stiffness_n_per_m : k_p, EDS levitation stiffness at 810 km/h (N/m), default
        2.25e6; the paper models the primary suspension as this spring with no damping.
    passive_damping_n_s_per_m : c_s, the passive secondary damper of the linear passive
        plant (N s/m; ``state_space``, ``frequency_response``), default 1.5e4. It is *not*
        part of the MR-damped plant; the env's ``damper="passive"`` reads ``damper_params``
        (the same 1.5e4 by default), not this: change both.
    levitation_damping_n_s_per_m : c_p, the levitation's damping on the bogie's velocity
        relative to the guideway (N s/m), default 0 (the paper's undamped primary suspension).
        An EDS levitation's electromagnetic damping is small and negative at high speed
        (:mod:`capsule_env.envelope.levitation`; the env's ``levitation="eds"`` sets it per speed), hence
        negative values are accepted; -2e4 to 2e4 N s/m.

    Notes
    -----
    Accepted ranges: masses 1 kg to 1e6 kg, stiffnesses 1 to 1e10 N/m, passive damping 0 to
    1e9 N s/m, levitation damping -2e4 to 2e4 N s/m (``ValueError`` naming the field otherwise;
    the substep rule's accuracy bound is verified to those ends, and the EDS coil model's
    damping stays within them: at most ``K_inf tau`` = 18 kN s/m).
    """

    car_body_mass_kg: float = 6000.0
    bogie_mass_kg: float = 2400.0
    secondary_stiffness_n_per_m: float = 4.95e5
    levitation_stiffness_n_per_m: float = 2.25e6
    passive_damping_n_s_per_m: float = 1.5e4
    levitation_damping_n_s_per_m: float = 0.0

    def __post_init__(self) -> None:
        # Physically plausible ranges, wide enough for scaled test rigs and other vehicles; an
        # absurd value (a 1e-9 kg bogie) would otherwise ask the integrator for 1e12 substeps.
        for name, (low, high) in _RANGES.items():
            check_in_range(name, getattr(self, name), low, high)

    @property
    def mass_matrix(self) -> np.ndarray:
        """Diagonal mass matrix (kg), order ``[car body, bogie]``."""
        return mechanical_matrices(MODEL, self)[0]

    @property
    def stiffness_matrix(self) -> np.ndarray:
        """Stiffness matrix (N/m) of the undamped plant with the guideway held fixed."""
        return mechanical_matrices(MODEL, self)[1]

    def as_array(self) -> np.ndarray:
        """Packed float64 vector ``[m_c, m_b, k_s, k_p, c_p]`` used by the compiled kernels
        (``MODEL.packed_param_names``, ``layout.VEHICLE_PARAM_NAMES``)."""
        return MODEL.as_array(self)


MODEL = VehicleModel(
    name="quarter_car",
    params=VehicleParams,
    coordinates=(
        Coordinate("car_body_displacement_m", "m", "car_body_mass_kg", "car_body_velocity_m_s"),
        Coordinate("bogie_displacement_m", "m", "bogie_mass_kg", "bogie_velocity_m_s"),
    ),
    points=(
        Point("car_body", (("car_body_displacement_m", 1.0),)),
        Point("bogie", (("bogie_displacement_m", 1.0),)),
    ),
    contacts=(Contact("guideway", 0.0),),
    elements=(
        Element(SPRING, "secondary_spring", "car_body", "bogie", "secondary_stiffness_n_per_m"),
        Element(
            DAMPER, "secondary_damper", "car_body", "bogie", passive="passive_damping_n_s_per_m"
        ),  # fmt: skip
        Element(SPRING, "levitation_spring", "bogie", "guideway", "levitation_stiffness_n_per_m"),
        Element(DASHPOT, "levitation_damping", "bogie", "guideway", "levitation_damping_n_s_per_m"),
    ),
    comfort_points=("car_body",),
    relative_positions=("secondary_spring", "levitation_spring"),
    description="The paper's 2-DOF 1/4-car: car body on a bogie on the EDS levitation.",
)
