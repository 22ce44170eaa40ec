"""The compiled plant of any declared vehicle: its state layout and its arrays
(:mod:`capsule_env.plant.declared` steps them).

A vehicle declared as data (:class:`capsule_env.vehicles.VehicleModel`) is compiled from its
declaration, not from code written for it: the kernel loops over its coordinates, its elements
and its damper slots. Its state, one row per vehicle::

    [q_0 .. q_{n-1},  q_0' .. q_{n-1}',  z_s, y_s, i_s for each damper slot s,  t]

(the coordinates, their rates, each slot's hysteretic variable, internal displacement and coil
current, the time: :func:`declared_state_names`). Each slot has its own damper parameters (a
row of the packed damper array per vehicle and slot) and its own current command: one action
per slot. Each guideway contact reads the profile at its own position, ``start + speed t +
offset``: a rear bogie meets what the front one met ``(a + b) / speed`` earlier.

The quarter-car's own kernels (:mod:`capsule_env.plant.block`, :mod:`capsule_env.plant.scalar`)
stay as they are for vehicles of its form (vectorised, bit for bit as before); this plant runs
every other form, and the quarter-car too for the tests that compare the two.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from capsule_env.dampers.base import N_DAMPER_PARAMS
from capsule_env.dampers.registry import model_of_code
from capsule_env.plant.substeps import (
    DEFAULT_INPUT_RATE,
    MAX_INPUT_OMEGA_H,
    MAX_LAMBDA_H,
    MAX_OMEGA_H,
    SUBSTEP_BINS,
)
from capsule_env.vehicles.declaration import DAMPER, DASHPOT, VehicleModel

__all__ = [
    "DeclaredPlant",
    "declared_state_names",
    "declared_output_names",
    "declared_plant",
    "declared_substep_tables",
]


class DeclaredPlant(NamedTuple):
    """What the plant of each of ``N`` vehicles is made of (``n`` coordinates, ``e`` springs
    and dashpots, ``s`` damper slots, ``k`` contacts).

    Attributes
    ----------
    inv_inertia : (N, n) the coordinates' inverse masses or inertias (1/kg, 1/(kg m^2)).
    element_rows : (N, e, n) each spring's and dashpot's deflection over the coordinates.
    element_contacts : (N, e, k) the guideway's share of each deflection (``d = J q - g z_g``).
    element_coef : (N, e) stiffness (N/m) or damping (N s/m).
    element_dashpot : (e,) int64, 1 for a dashpot (reads rates), 0 for a spring.
    slot_rows : (N, s, n) each damper slot's stroke over the coordinates.
    damper : (N * s, N_DAMPER_PARAMS) packed damper parameters, row ``n * s + slot``.
    substeps : (N, bins) int64 RK4 substeps per control step by coil-current bin.
    contact_offsets_m : (N, k) each contact's longitudinal offset (m, > 0 ahead).
    profiles, spacing_m, offsets : the guideway bank, as :class:`capsule_env.plant.PlantParams`.
    """

    inv_inertia: np.ndarray
    element_rows: np.ndarray
    element_contacts: np.ndarray
    element_coef: np.ndarray
    element_dashpot: np.ndarray
    slot_rows: np.ndarray
    damper: np.ndarray
    substeps: np.ndarray
    contact_offsets_m: np.ndarray
    profiles: np.ndarray
    spacing_m: float
    offsets: np.ndarray


def declared_state_names(model: VehicleModel) -> tuple[str, ...]:
    """The columns of the declared plant's state (module doc), names with units."""
    q = tuple(c.name for c in model.coordinates)
    v = tuple(c.rate_name for c in model.coordinates)
    slots = tuple(
        f"{d.name}_{part}"
        for d in model.dampers
        for part in ("hysteretic_z_m", "internal_displacement_m", "coil_current_a")
    )
    return (*q, *v, *slots, "time_s")


def declared_output_names(model: VehicleModel) -> tuple[str, ...]:
    """The columns of the declared plant's outputs at the end of a control step: each slot's
    force, each coordinate's acceleration, each contact's guideway elevation."""
    forces = tuple(f"{d.name}_force_n" for d in model.dampers)
    acc = tuple(_acceleration_name(c.name, c.unit) for c in model.coordinates)
    zg = tuple(f"{c.name}_elevation_m" for c in model.contacts)
    return (*forces, *acc, *zg)


def _acceleration_name(name: str, unit: str) -> str:
    """``car_body_displacement_m`` -> ``car_body_acceleration_m_s2``; ``pitch_rad`` ->
    ``pitch_acceleration_rad_s2``."""
    stem = name.removesuffix(f"_{unit}").removesuffix("_displacement")
    return f"{stem}_acceleration_{unit}_s2"


def _vehicle_arrays(model: VehicleModel, values: dict[str, float]) -> tuple[np.ndarray, ...]:
    """One vehicle's rows: inverse inertias, element rows/contacts/coefficients, slot rows."""
    inv = np.array([1.0 / float(values[c.inertia]) for c in model.coordinates])
    rows, ground, coef, slots = [], [], [], []
    for e in model.elements:
        j, g = model.element_rows(e, values)
        if e.kind == DAMPER:
            slots.append(j)
        else:
            rows.append(j)
            ground.append(g)
            coef.append(float(values[e.coefficient]))  # type: ignore[index]
    n, k = len(model.coordinates), len(model.contacts)
    return (inv, np.array(rows).reshape(-1, n), np.array(ground).reshape(-1, k),
            np.array(coef), np.array(slots).reshape(-1, n))  # fmt: skip


def declared_plant(
    model: VehicleModel,
    vehicles: list[dict[str, float]],
    damper: Any,
    profiles: np.ndarray,
    spacing_m: float,
    dt_s: float,
    substeps: int | np.ndarray | None = None,
    input_rate_rad_s: float = DEFAULT_INPUT_RATE,
    offsets: np.ndarray | None = None,
) -> DeclaredPlant:
    """The :class:`DeclaredPlant` of ``len(vehicles)`` vehicles of ``model`` (each a
    ``model.values(...)`` dict), every slot with the damper ``damper`` (a damper parameters
    object, or a sequence of one per slot). ``substeps``: None (the rule of
    :func:`declared_substep_tables`), an int, or an (N, bins) table."""
    if not vehicles:
        raise ValueError("vehicles: give at least one vehicle's values")
    slots = model.dampers
    per_slot = list(damper) if isinstance(damper, list | tuple) else [damper] * len(slots)
    if len(per_slot) != len(slots) or len({d.code for d in per_slot}) > 1:
        raise ValueError(f"damper: one damper model for the {len(slots)} slot(s) of "
                         f"{model.name!r} (or one per slot, all of one model)")  # fmt: skip
    arrays = [_vehicle_arrays(model, v) for v in vehicles]
    stack = [np.ascontiguousarray(np.array([a[j] for a in arrays])) for j in range(5)]
    packed = np.array([d.as_array() for d in per_slot])
    dp = np.ascontiguousarray(np.tile(packed, (len(vehicles), 1)), dtype=np.float64)
    if substeps is None:
        table = declared_substep_tables(model, vehicles, per_slot, dt_s, input_rate_rad_s)
    elif np.ndim(substeps) == 0:
        table = np.full((len(vehicles), SUBSTEP_BINS), int(substeps), dtype=np.int64)
    else:
        shape = (len(vehicles), np.shape(substeps)[-1])
        table = np.array(np.broadcast_to(substeps, shape), dtype=np.int64)
    offsets_m = np.array([[_offset(c.offset_m, v) for c in model.contacts] for v in vehicles])
    dashpot = np.array([int(e.kind == DASHPOT) for e in model.elements if e.kind != DAMPER],
                       dtype=np.int64)  # fmt: skip
    profiles = np.ascontiguousarray(np.atleast_2d(profiles), dtype=np.float64)
    off = np.zeros((0, 0)) if offsets is None else np.ascontiguousarray(offsets, dtype=np.float64)
    assert dp.shape[1] == N_DAMPER_PARAMS
    return DeclaredPlant(stack[0], stack[1], stack[2], stack[3], dashpot, stack[4], dp, table,
                         np.ascontiguousarray(offsets_m), profiles, float(spacing_m), off)  # fmt: skip


def _offset(offset: float | str, values: dict[str, float]) -> float:
    return float(values[offset]) if isinstance(offset, str) else float(offset)


def _linear_plant(model: VehicleModel, values: dict[str, float]) -> tuple[np.ndarray, ...]:
    """``(M, K, C, J_slots)`` over the coordinates, the slots open, the guideway fixed."""
    inv, rows, _, coef, slots = _vehicle_arrays(model, values)
    n = inv.shape[0]
    k, c = np.zeros((n, n)), np.zeros((n, n))
    dashpot = [e.kind == DASHPOT for e in model.elements if e.kind != DAMPER]
    for j, f, is_dashpot in zip(rows, coef, dashpot, strict=True):
        (c if is_dashpot else k)[...] += f * np.outer(j, j)
    return np.diag(1.0 / inv), k, c, slots


def _rates_at(m, k, c, slots, linearised) -> tuple[float, float]:
    """Largest ``|Re lambda|`` and ``|Im lambda|`` of the plant with each slot's damper
    linearised (``(c, k, K, C)`` scalars per slot: ``F = fx x + fv x' + fy y``, Spencer's
    ``y' = (K (x - y) + c x') / C``), states ``[q, q', y_s]``."""
    n, ns = m.shape[0], len(slots)
    a = np.zeros((2 * n + ns, 2 * n + ns))
    inv_m = np.linalg.inv(m)
    stiff, damp = k.copy(), c.copy()
    a[:n, n : 2 * n] = np.eye(n)
    for s, (j, (cs, ks, big_k, big_c)) in enumerate(zip(slots, linearised, strict=True)):
        spencer = big_c > 0.0
        inv_c = 1.0 / big_c if spencer else 0.0
        c1 = big_c - cs
        fx, fv = ks + c1 * big_k * inv_c, (c1 * cs * inv_c if spencer else cs)
        fy = -c1 * big_k * inv_c
        stiff += fx * np.outer(j, j)
        damp += fv * np.outer(j, j)
        a[n : 2 * n, 2 * n + s] = -inv_m @ (j * fy)
        a[2 * n + s, :n] = big_k * inv_c * j
        a[2 * n + s, n : 2 * n] = cs * inv_c * j
        a[2 * n + s, 2 * n + s] = -big_k * inv_c if spencer else 0.0
    a[n : 2 * n, :n] = -inv_m @ stiff
    a[n : 2 * n, n : 2 * n] = -inv_m @ damp
    lam = np.linalg.eigvals(a)
    return float(np.abs(lam.real).max()), float(np.abs(lam.imag).max())


def declared_substep_tables(
    model: VehicleModel,
    vehicles: list[dict[str, float]],
    dampers: list[Any],
    dt_s: float,
    input_rate_rad_s: float = DEFAULT_INPUT_RATE,
    bins: int = SUBSTEP_BINS,
) -> np.ndarray:
    """Substeps per control step per vehicle and current bin, by the quarter-car's rule
    (:mod:`capsule_env.plant.substeps`: ``rate h <= MAX_LAMBDA_H``, ``omega h <= MAX_OMEGA_H``,
    ``input_rate h <= MAX_INPUT_OMEGA_H``) on the vehicle's own linearised plant, every slot
    at the bin's current, each regime of the damper model in turn."""
    table = np.ones((len(vehicles), bins), dtype=np.int64)
    model_of = model_of_code(dampers[0].code)
    for n, values in enumerate(vehicles):
        m, k, c, slots = _linear_plant(model, values)
        for b in range(bins):
            rate = omega = 0.0
            lin = [model_of.linearise(d.as_array(), np.array([_bin_current(d, b, bins)]))
                   for d in dampers]  # fmt: skip
            for regime in range(len(lin[0])):
                per_slot = [tuple(float(x[0]) for x in slot[regime]) for slot in lin]
                r, w = _rates_at(m, k, c, slots, per_slot)
                rate, omega = max(rate, r), max(omega, w)
            need = max(np.ceil(rate * dt_s / MAX_LAMBDA_H), np.ceil(omega * dt_s / MAX_OMEGA_H),
                       np.ceil(input_rate_rad_s * dt_s / MAX_INPUT_OMEGA_H), 1.0)  # fmt: skip
            table[n, b] = int(need)
        table[n] = np.maximum.accumulate(table[n])
    return table


def _bin_current(damper: Any, b: int, bins: int) -> float:
    return float(getattr(damper, "max_current_a", 0.0)) * (b + 1) / bins
