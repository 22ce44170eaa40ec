"""The vehicle's equations of motion, written once (docs/model.md, section 2).

::

    m_c z_c'' = -k_s (z_c - z_b) - F
    m_b z_b'' =  k_s (z_c - z_b) + F - F_lev,      F_lev = k_p (z_b - z_g)

``F``: the damper force (N, > 0 resisting a positive stroke rate, acting as ``-F`` on the car
body and ``+F`` on the bogie); ``F_lev``: the EDS levitation's restoring force on the bogie
(the primary suspension, undamped, its stiffness taken at the design speed). Every RK4 stage
of the plant (:mod:`capsule_env.plant.rk4`) and its outputs call :func:`accelerations`; a
change of the vehicle (a speed-dependent levitation, a second body) is made here.

``vehicle``: the per-vehicle values the equations read, a tuple in the order of
:data:`VEHICLE_LANE_NAMES` (inverse masses, so that no stage divides). The functions are
inlined into the kernels' loops by LLVM (``forceinline``) and written without branches, so
that a loop over vehicles vectorises.
"""

from __future__ import annotations

from capsule_env._jit import kernel_function

__all__ = [
    "VEHICLE_LANE_NAMES",
    "INV_M_C",
    "INV_M_B",
    "K_S",
    "K_P",
    "levitation_force",
    "accelerations",
]

#: The per-vehicle values of :func:`accelerations` and :func:`levitation_force`: inverse car
#: body and bogie masses (1/kg), secondary and levitation stiffnesses (N/m).
VEHICLE_LANE_NAMES = ("inv_m_c", "inv_m_b", "k_s", "k_p")
INV_M_C, INV_M_B, K_S, K_P = (VEHICLE_LANE_NAMES.index(n) for n in VEHICLE_LANE_NAMES)


@kernel_function(inline=True)
def levitation_force(bogie_disp_m: float, guideway_m: float, vehicle) -> float:
    """The levitation's force on the bogie, ``k_p (z_b - z_g)`` (N, > 0 pulling it down)."""
    return vehicle[K_P] * (bogie_disp_m - guideway_m)


@kernel_function(inline=True)
def accelerations(
    body_disp_m: float, bogie_disp_m: float, damper_force_n: float, levitation_n: float, vehicle
):
    """``(z_c'', z_b'')`` (m/s^2) from the displacements, the damper force and the
    levitation force (:func:`levitation_force`): the secondary suspension's force
    ``k_s (z_c - z_b) + F`` pushes the car body down and the bogie up."""
    secondary = vehicle[K_S] * (body_disp_m - bogie_disp_m) + damper_force_n
    return -secondary * vehicle[INV_M_C], (secondary - levitation_n) * vehicle[INV_M_B]
