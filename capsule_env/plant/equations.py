"""The vehicle's equations of motion, written once (docs/model.md, section 2).

::

    m_c z_c'' = -k_s (z_c - z_b) - F
    m_b z_b'' =  k_s (z_c - z_b) + F - F_lev,      F_lev = k_p (z_b - z_g) + c_p (z_b' - z_g')

``F``: the damper force (N, > 0 resisting a positive stroke rate, acting as ``-F`` on the car
body and ``+F`` on the bogie); ``F_lev``: the EDS levitation's restoring force on the bogie
(the primary suspension; the paper's is undamped, ``c_p = 0``, its stiffness taken at the
design speed; ``levitation="eds"`` makes both follow the speed, :mod:`capsule_env.envelope.levitation`).
The damping term is compiled only into the kernels of plants that have it (the ``damped``
flag): the paper's plant runs the arithmetic it always ran, bit for bit. Every RK4 stage
of the plant (:mod:`capsule_env.plant.rk4`) and its outputs call :func:`accelerations`; a
change of the vehicle (a speed-dependent levitation, a second body) is made here.

``vehicle``: the per-vehicle values the equations read, a tuple in the order of
:data:`VEHICLE_LANE_NAMES` (inverse masses, so that no stage divides). The functions are
inlined into the kernels' loops by LLVM (``forceinline``) and written without branches, so
that a loop over vehicles vectorises.
"""

from __future__ import annotations

from capsule_env._jit import kernel_function, specialised

__all__ = [
    "VEHICLE_LANE_NAMES",
    "INV_M_C",
    "INV_M_B",
    "K_S",
    "K_P",
    "C_P",
    "levitation_force",
    "accelerations",
]

#: The per-vehicle values of :func:`accelerations` and :func:`levitation_force`: inverse car
#: body and bogie masses (1/kg), secondary and levitation stiffnesses (N/m), levitation
#: damping (N s/m).
VEHICLE_LANE_NAMES = ("inv_m_c", "inv_m_b", "k_s", "k_p", "c_p")
INV_M_C, INV_M_B, K_S, K_P, C_P = (VEHICLE_LANE_NAMES.index(n) for n in VEHICLE_LANE_NAMES)


@specialised("damped")
def levitation_force(damped, gap_m, gap_rate_m_s, vehicle):
    """The levitation's force on the bogie (N, > 0 pulling it down) at the gap change
    ``z_b - z_g`` and its rate: ``k_p (z_b - z_g)``, plus ``c_p (z_b' - z_g')`` when ``damped``
    (a compile-time flag)."""
    if damped:

        def impl(damped, gap_m, gap_rate_m_s, vehicle):
            return vehicle[K_P] * gap_m + vehicle[C_P] * gap_rate_m_s

    else:

        def impl(damped, gap_m, gap_rate_m_s, vehicle):
            return vehicle[K_P] * gap_m

    return impl


@kernel_function(inline=True)
def accelerations(
    body_disp_m: float, bogie_disp_m: float, damper_force_n: float, levitation_n: float, vehicle
):
    """``(z_c'', z_b'')`` (m/s^2) from the displacements, the damper force and the
    levitation force (:func:`levitation_force`): the secondary suspension's force
    ``k_s (z_c - z_b) + F`` pushes the car body down and the bogie up."""
    secondary = vehicle[K_S] * (body_disp_m - bogie_disp_m) + damper_force_n
    return -secondary * vehicle[INV_M_C], (secondary - levitation_n) * vehicle[INV_M_B]
