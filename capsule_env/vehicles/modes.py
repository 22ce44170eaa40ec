"""The 2-DOF vertical 1/4-car model of the capsule vehicle (docs/model.md, section 2): its modes,
state-space form and frequency response, from its declaration
(:mod:`capsule_env.vehicles.quarter_car`, whose :class:`VehicleParams` this module re-exports).

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

from capsule_env.common.validation import check_nonnegative
from capsule_env.vehicles.linear import absolute_model, mechanical_matrices
from capsule_env.vehicles.quarter_car import MODEL as QUARTER_CAR
from capsule_env.vehicles.quarter_car import VehicleParams

__all__ = [
    "ModalProperties",
    "modal_properties",
    "natural_frequencies_hz",
    "state_space",
    "frequency_response",
]


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
    mass, stiffness, _ = mechanical_matrices(QUARTER_CAR, params)
    eigenvalues, eigenvectors = np.linalg.eig(np.linalg.solve(mass, stiffness))
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
    model = absolute_model(QUARTER_CAR, params, slot_damping=c)
    return model.a, model.b, model.e


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
    c = check_nonnegative("secondary_damping_n_s_per_m", secondary_damping_n_s_per_m)
    model = absolute_model(QUARTER_CAR, params, slot_damping=c)
    a, e, e_rate = model.a, model.e[:, 0], model.e_rate[:, 0]
    freqs = np.atleast_1d(np.asarray(frequencies_hz, dtype=float))
    out = np.empty((freqs.size, a.shape[0]), dtype=complex)
    for j, f in enumerate(freqs):
        s = 2j * np.pi * f
        out[j] = np.linalg.solve(s * np.eye(a.shape[0]) - a, e + s * e_rate)
    return out
