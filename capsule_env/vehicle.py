"""The 2-DOF vertical 1/4-car model of the capsule vehicle (docs/model.md, section 2).

State vector ``[car_body_displacement, car_body_velocity, bogie_displacement, bogie_velocity]``
(m, m/s), input the guideway irregularity ``z_g`` (m) under the EDS levitation "spring" and the
secondary damper force ``F`` (N, positive when it resists a positive stroke rate)::

    m_c z_c'' = -k_s (z_c - z_b) - c (z_c' - z_b') - F
    m_b z_b'' =  k_s (z_c - z_b) + c (z_c' - z_b') + F - k_p (z_b - z_g)

``c`` is an optional linear secondary damper (the passive baseline); with the MR damper fitted it
is 0 and the damper enters through ``F``. Pure numpy, no Gym import.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capsule_env._validation import check_in_range, check_nonnegative

__all__ = [
    "VehicleParams",
    "ModalProperties",
    "modal_properties",
    "natural_frequencies_hz",
    "state_space",
    "frequency_response",
]


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
    passive_damping_n_s_per_m : c_s, the passive secondary damper of the passive baseline
        (N s/m), default 1.5e4. It is *not* part of the MR-damped plant.
    levitation_damping_n_s_per_m : c_p, the levitation's damping on the bogie's velocity
        relative to the guideway (N s/m), default 0 (the paper's undamped primary suspension).
        An EDS levitation's electromagnetic damping is small and negative at high speed
        (:mod:`capsule_env.levitation`; the env's ``levitation="eds"`` sets it per speed), hence
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
        return np.diag([self.car_body_mass_kg, self.bogie_mass_kg])

    @property
    def stiffness_matrix(self) -> np.ndarray:
        """Stiffness matrix (N/m) of the undamped plant with the guideway held fixed."""
        ks, kp = self.secondary_stiffness_n_per_m, self.levitation_stiffness_n_per_m
        return np.array([[ks, -ks], [-ks, ks + kp]])

    def as_array(self) -> np.ndarray:
        """Packed float64 vector ``[m_c, m_b, k_s, k_p, c_p]`` used by the compiled kernels
        (``layout.VEHICLE_PARAM_NAMES``)."""
        return np.array(
            [
                self.car_body_mass_kg,
                self.bogie_mass_kg,
                self.secondary_stiffness_n_per_m,
                self.levitation_stiffness_n_per_m,
                self.levitation_damping_n_s_per_m,
            ]
        )


@dataclass(frozen=True)
class ModalProperties:
    """Undamped modes, sorted by frequency.

    Attributes
    ----------
    frequencies_hz : (2,) natural frequencies (Hz).
    mode_shapes : (2, 2) columns are the mode shapes ``[car body, bogie]``, each scaled so its
        largest-magnitude entry is +1.
    """

    frequencies_hz: np.ndarray
    mode_shapes: np.ndarray


def modal_properties(params: VehicleParams | None = None) -> ModalProperties:
    """Natural frequencies and mode shapes of the undamped 2-DOF plant (eigenvalues of M^-1 K)."""
    params = params or VehicleParams()
    eigenvalues, eigenvectors = np.linalg.eig(
        np.linalg.solve(params.mass_matrix, params.stiffness_matrix)
    )
    order = np.argsort(eigenvalues.real)
    omegas = np.sqrt(eigenvalues.real[order])
    shapes = eigenvectors.real[:, order]
    shapes = shapes / shapes[np.argmax(np.abs(shapes), axis=0), [0, 1]]
    return ModalProperties(frequencies_hz=omegas / (2.0 * np.pi), mode_shapes=shapes)


def natural_frequencies_hz(params: VehicleParams | None = None) -> np.ndarray:
    """The two undamped natural frequencies (Hz), body mode first."""
    return modal_properties(params).frequencies_hz


def state_space(
    params: VehicleParams | None = None, secondary_damping_n_s_per_m: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Continuous-time state-space form ``x' = A x + B F + E z_g``.

    Parameters
    ----------
    params : vehicle parameters (defaults if None).
    secondary_damping_n_s_per_m : linear secondary damper c included in ``A`` (N s/m). Use
        ``params.passive_damping_n_s_per_m`` for the passive baseline, 0 for the MR-damped plant.

    Returns
    -------
    A : (4, 4), B : (4, 1) for the damper force F (N), E : (4, 1) for the guideway z_g (m), with
    state ``[z_c, z_c', z_b, z_b']``. The levitation's damping ``c_p`` is in ``A``; its
    guideway-rate term ``c_p z_g' / m_b`` is not in ``E`` (0 for the paper's undamped levitation).
    """
    params = params or VehicleParams()
    c = check_nonnegative("secondary_damping_n_s_per_m", secondary_damping_n_s_per_m)
    mc, mb = params.car_body_mass_kg, params.bogie_mass_kg
    ks, kp = params.secondary_stiffness_n_per_m, params.levitation_stiffness_n_per_m
    cp = params.levitation_damping_n_s_per_m
    a = np.array(
        [
            [0.0, 1.0, 0.0, 0.0],
            [-ks / mc, -c / mc, ks / mc, c / mc],
            [0.0, 0.0, 0.0, 1.0],
            [ks / mb, c / mb, -(ks + kp) / mb, -(c + cp) / mb],
        ]
    )
    b = np.array([[0.0], [-1.0 / mc], [0.0], [1.0 / mb]])
    e = np.array([[0.0], [0.0], [0.0], [kp / mb]])
    return a, b, e


def frequency_response(
    frequencies_hz: np.ndarray,
    params: VehicleParams | None = None,
    secondary_damping_n_s_per_m: float = 0.0,
) -> np.ndarray:
    """Complex transfer functions from ``z_g`` to each state, ``(sI - A)^-1 (E + s E_r)`` at
    ``s = j w``, where ``E_r = [0, 0, 0, c_p / m_b]`` is the levitation damping's guideway-rate
    input (0 for the paper's undamped levitation).

    Returns an array of shape ``(len(frequencies_hz), 4)``.
    """
    params = params or VehicleParams()
    a, _, e = state_space(params, secondary_damping_n_s_per_m)
    e_rate = np.array([0.0, 0.0, 0.0, params.levitation_damping_n_s_per_m / params.bogie_mass_kg])
    freqs = np.atleast_1d(np.asarray(frequencies_hz, dtype=float))
    out = np.empty((freqs.size, 4), dtype=complex)
    for j, f in enumerate(freqs):
        s = 2j * np.pi * f
        out[j] = np.linalg.solve(s * np.eye(4) - a, e[:, 0] + s * e_rate)
    return out
