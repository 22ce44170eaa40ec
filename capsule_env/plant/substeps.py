"""How many RK4 substeps each vehicle needs per control step: from its own linearised plant.

The automatic rule picks, for each vehicle and coil-current bin, the fewest substeps ``n`` with
``h = dt / n`` such that ``|Re lambda| h <= MAX_LAMBDA_H`` and ``|Im lambda| h <= MAX_OMEGA_H``
for every eigenvalue ``lambda`` of the plant with its damper linearised near rest in each of its
regimes, and ``input_rate h <= MAX_INPUT_OMEGA_H`` for the guideway input. It keeps the damper
force within 0.5 % RMS of a much finer step for every vehicle (``tests/test_substeps.py``).
"""

from __future__ import annotations

import math

import numpy as np

from capsule_env.dampers.base import DamperParamsBase as DamperParams  # any registered model
from capsule_env.dampers.registry import model_of_code
from capsule_env.vehicles import VehicleParams
from capsule_env.vehicles.linear import packed_matrices
from capsule_env.vehicles.quarter_car import MODEL as QUARTER_CAR

__all__ = [
    "DEFAULT_INPUT_RATE",
    "SUBSTEP_BINS",
    "MAX_LAMBDA_H",
    "MAX_OMEGA_H",
    "MAX_INPUT_OMEGA_H",
    "MAX_AUTO_SUBSTEPS",
    "stiffness_rates",
    "substep_tables",
    "substep_table",
    "default_substeps",
    "as_substep_table",
]

#: Highest angular frequency of the default guideway input (rad/s): the 2 m shortest
#: wavelength of the random profile at 810 km/h (225 m/s).
DEFAULT_INPUT_RATE = 2.0 * math.pi * 225.0 / 2.0
#: Current bins of a :func:`substep_table`.
SUBSTEP_BINS = 16
#: Largest ``|Re lambda| h`` for the decay rates of the linearised plant (Spencer's pre-yield
#: relaxation, the damper's dashpot on the relative mass). RK4 is stable to 2.785 on the real
#: axis, but the transient that every current change kicks is followed accurately only well
#: inside that: the force is sampled right after it.
MAX_LAMBDA_H = 1.0
#: Largest ``omega h`` for the oscillations of the linearised plant (its modes, the pre-yield
#: springs of Spencer's and Bouc-Wen's models on light vehicles, the branch blend of the
#: sign-of-stroke models).
MAX_OMEGA_H = 0.15
#: Largest ``omega h`` for the guideway input's highest angular frequency (the plant filters it:
#: this bound only keeps the stages sampling the profile).
MAX_INPUT_OMEGA_H = 2.0
#: Most substeps per control interval the automatic rule may choose; a configuration that needs
#: more is refused (``EnvConfig`` says which parameters make it so stiff).
MAX_AUTO_SUBSTEPS = 1024


def _linearised_damper(damper: DamperParams, i: np.ndarray) -> list[tuple[np.ndarray, ...]]:
    """The damper near ``x = v = 0`` in each of its regimes, as ``(c, k, K, C)`` arrays over the
    currents ``i``: the model's own ``linearise`` (:class:`capsule_env.dampers.DamperModel`):
    ``F = c x' + k x`` for the algebraic models (``C = 0``); for Spencer's model
    ``y' = (K (x - y) + c x') / C`` and ``F = (C - c) y' + k x``."""
    return model_of_code(damper.code).linearise(damper.as_array(), i)


def stiffness_rates(
    damper: DamperParams, vehicle_params: np.ndarray, current_a: np.ndarray | float
) -> tuple[np.ndarray, np.ndarray]:
    """``(rate, omega)``: per vehicle (rows of the packed ``vehicle_params``, ``[m_c, m_b, k_s,
    k_p, c_p]``; ``c_p`` 0 where absent) and current (columns), the largest ``|Re lambda|`` (1/s) and ``|Im lambda|``
    (rad/s) over the eigenvalues of the plant with its damper linearised near rest in each of
    its regimes (:func:`_linearised_damper`). A light vehicle turns Spencer's pre-yield
    relaxation into a lightly damped oscillation: hence two numbers and two bounds."""
    inertia, stiffness, damping, slots = packed_matrices(QUARTER_CAR, vehicle_params)
    j_s = slots[0]  # the one damper slot's stroke over the coordinates
    n = inertia.shape[1]
    i = np.atleast_1d(np.asarray(current_a, dtype=float))[None, :]
    shape = np.broadcast_shapes(inertia[:, :1].shape, i.shape)
    rate, omega = np.zeros(shape), np.zeros(shape)
    outer = np.outer(j_s, j_s)
    for c, k, big_k, big_c in _linearised_damper(damper, i):
        # states [q_0, q_0', q_1, q_1', ..., y]; the damper force F = fx x + fv x' + fy y on
        # the stroke x (the slot's deflection)
        spencer = big_c > 0.0
        inv_c = np.where(spencer, 1.0 / np.where(spencer, big_c, 1.0), 0.0)
        c1 = big_c - c
        fx = k + c1 * big_k * inv_c
        fv = np.where(spencer, c1 * c * inv_c, c)
        fy = -c1 * big_k * inv_c
        m = np.zeros((*shape, 2 * n + 1, 2 * n + 1))
        for r in range(n):
            m[..., 2 * r, 2 * r + 1] = 1.0
            mass = inertia[:, r, None]
            for col in range(n):
                m[..., 2 * r + 1, 2 * col] = (
                    -(stiffness[:, r, col, None] + fx * outer[r, col]) / mass
                )
                m[..., 2 * r + 1, 2 * col + 1] = (
                    -(damping[:, r, col, None] + fv * outer[r, col]) / mass
                )
            m[..., 2 * r + 1, 2 * n] = -(j_s[r] * fy) / mass
            m[..., 2 * n, 2 * r] = big_k * inv_c * j_s[r]
            m[..., 2 * n, 2 * r + 1] = c * inv_c * j_s[r]
        m[..., 2 * n, 2 * n] = np.where(spencer, -big_k * inv_c, 0.0)  # y unused: an eigenvalue 0
        lam = np.linalg.eigvals(m)
        rate = np.maximum(rate, np.abs(lam.real).max(axis=-1))
        omega = np.maximum(omega, np.abs(lam.imag).max(axis=-1))
    return rate, omega


def substep_tables(
    damper: DamperParams,
    dt_s: float,
    vehicle_params: np.ndarray,
    input_rate_rad_s: np.ndarray | float = DEFAULT_INPUT_RATE,
    bins: int = SUBSTEP_BINS,
) -> np.ndarray:
    """Substeps per control interval, per vehicle (rows of the packed ``vehicle_params``) and
    coil-current bin (columns), from each vehicle's own parameters: ``rate h <= MAX_LAMBDA_H``
    and ``omega h <= MAX_OMEGA_H`` (:func:`stiffness_rates`) at the highest current of the bin
    and of every lower bin, and ``input_rate h <= MAX_INPUT_OMEGA_H`` for the guideway input
    (``input_rate_rad_s``: 2 pi speed / shortest wavelength, per vehicle or shared).

    ``tests/test_substeps.py`` checks that this keeps the damper force within 0.5 % RMS of a
    run 10 times finer (at least 100 substeps) for every vehicle, for every damper model, both
    settings, control rates 50-1000 Hz and vehicle randomisation up to 0.9. The kernels pick the
    bin from ``max(command, current at the start)`` (with coil lag), not from the highest current
    the lag actually reaches in the interval, which would save substeps at a measured cost in
    accuracy under bang-bang commands. Entries above :data:`MAX_AUTO_SUBSTEPS` are returned as
    they are; ``EnvConfig`` refuses them.
    """
    i_max = float(getattr(damper, "max_current_a", 0.0))
    currents = i_max * np.arange(1, bins + 1) / bins
    rate, omega = stiffness_rates(damper, vehicle_params, currents)
    input_rate = np.asarray(input_rate_rad_s, dtype=float).reshape(-1, 1)
    need = np.maximum.reduce(
        [
            np.ceil(rate * dt_s / MAX_LAMBDA_H),
            np.ceil(omega * dt_s / MAX_OMEGA_H),
            np.ceil(input_rate * dt_s / MAX_INPUT_OMEGA_H) + 0.0 * rate,
            np.ones_like(rate),
        ]
    )
    need = np.maximum.accumulate(need, axis=1)
    return np.ascontiguousarray(np.minimum(need, np.iinfo(np.int32).max).astype(np.int64))


def substep_table(
    damper: DamperParams,
    dt_s: float,
    vehicle: VehicleParams | None = None,
    bins: int = SUBSTEP_BINS,
    input_rate_rad_s: float = DEFAULT_INPUT_RATE,
) -> np.ndarray:
    """:func:`substep_tables` of one vehicle (default :class:`VehicleParams`): a (bins,) array."""
    vehicle = vehicle or VehicleParams()
    return substep_tables(damper, dt_s, vehicle.as_array(), input_rate_rad_s, bins)[0]


def default_substeps(
    damper: DamperParams,
    dt_s: float,
    vehicle: VehicleParams | None = None,
    input_rate_rad_s: float = DEFAULT_INPUT_RATE,
) -> int:
    """The largest entry of :func:`substep_table`: substeps at the maximum current."""
    return int(substep_table(damper, dt_s, vehicle, input_rate_rad_s=input_rate_rad_s).max())


def as_substep_table(substeps: int | np.ndarray, n: int) -> np.ndarray:
    """``substeps`` (an int, a (bins,) table or an (n, bins) table) as an (n, bins) table."""
    if np.ndim(substeps) == 0:
        if int(substeps) != substeps or int(substeps) < 1:
            raise ValueError(f"substeps must be an integer >= 1, got {substeps!r}")
        return np.full((n, SUBSTEP_BINS), int(substeps), dtype=np.int64)
    table = np.asarray(substeps)
    if table.ndim == 1:
        table = np.broadcast_to(table, (n, table.shape[0]))
    if table.ndim != 2 or table.shape[0] != n or np.any(table < 1):
        raise ValueError(
            f"substeps must be an int >= 1 or a table of them, got shape {table.shape}"
        )
    return np.ascontiguousarray(table, dtype=np.int64)
