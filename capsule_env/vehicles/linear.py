"""The one linear model of a declared vehicle, in the two coordinate forms its readers use.

Derived from the declaration (:mod:`capsule_env.vehicles.declaration`), element by element in
declared order, so that every reader (the substep rule, the reference solver, the modal and
frequency-response functions, the clipped LQR, the preview LQ, the MPC) reads the same numbers:

- :func:`absolute_model`: state ``[q_0, q_0', q_1, q_1', ...]``, inputs the damper forces, the
  guideway's elevation and its rate at each contact::

      x' = A x + B F + E z_g + E_rate z_g'

- :func:`relative_model`: the position states are the springs' deflections
  (``relative_positions``: for the 1/4-car the stroke ``z_c - z_b`` and the levitation gap
  ``z_b - z_g``), the velocities absolute; the guideway enters only through its velocity::

      x' = A x + B F + E_v z_g'

  the form of the controllers, whose state is what the sensors measure (strokes, gaps,
  velocities) and whose cost needs no guideway position.

Both give the comfort points' accelerations ``a = C_acc x + D_acc F (+ ...)`` and the damper
strokes. The arithmetic is written so that the 1/4-car's matrices are, bit for bit, those the
package built by hand before the declaration (``tests/test_vehicles.py``): each entry is a sum
over elements in declared order, started from 0.0, divided once by the coordinate's inertia.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from capsule_env.vehicles.declaration import DAMPER, SPRING, VehicleModel

__all__ = [
    "LinearModel",
    "absolute_model",
    "relative_model",
    "relative_state_names",
    "mechanical_matrices",
    "packed_matrices",
]


@dataclass(frozen=True)
class LinearModel:
    """``x' = A x + B F + E u + E_rate u'`` and outputs (module doc).

    Attributes
    ----------
    state_names : the state's names (with units).
    a, b : (n, n) and (n, n_dampers): the damper forces' input (N).
    e, e_rate : (n, n_contacts): the guideway's elevation (m; zero in the relative form) and
        rate (m/s) at each contact.
    c_acc, d_acc, e_acc, e_rate_acc : the comfort points' accelerations (m/s^2) from the state,
        the damper forces, the elevation and the rate.
    stroke : (n_dampers, n): each damper slot's deflection (m) from the state (a slot joins two
        points, never the guideway).
    """

    state_names: tuple[str, ...]
    a: np.ndarray
    b: np.ndarray
    e: np.ndarray
    e_rate: np.ndarray
    c_acc: np.ndarray
    d_acc: np.ndarray
    e_acc: np.ndarray
    e_rate_acc: np.ndarray
    stroke: np.ndarray


def _matrices(model: VehicleModel, values: dict[str, float], slot_damping: Sequence[float]):
    """``K, C`` (coordinates x coordinates), ``K_g, C_g`` (coordinates x contacts) and the
    slots' rows ``J_s`` (slots x coordinates), summed over elements in declared order; a slot
    with a nonzero ``slot_damping`` is a linear dashpot in the sums at its place."""
    n, n_g = len(model.coordinates), len(model.contacts)
    k, c = np.zeros((n, n)), np.zeros((n, n))
    k_g, c_g = np.zeros((n, n_g)), np.zeros((n, n_g))
    slots = []
    for e in model.elements:
        j, g = model.element_rows(e, values)
        if e.kind == DAMPER:
            coef = float(slot_damping[len(slots)])
            slots.append((j, g))
            if coef == 0.0:
                continue
            target, target_g = c, c_g
        else:
            coef = float(values[e.coefficient])  # type: ignore[index]
            target, target_g = (k, k_g) if e.kind == SPRING else (c, c_g)
        for r in np.flatnonzero(j):
            for col in np.flatnonzero(j):
                target[r, col] = target[r, col] + coef * (j[r] * j[col])
            for col in np.flatnonzero(g):
                target_g[r, col] = target_g[r, col] + coef * (j[r] * g[col])
    return k, c, k_g, c_g, slots


def _check_model(model: Any) -> None:
    if not isinstance(model, VehicleModel):
        raise TypeError(f"model must be a VehicleModel (capsule_env.vehicles.model_named(name)), "
                        f"got {type(model).__name__}")  # fmt: skip


def mechanical_matrices(
    model: VehicleModel, params: Any = None, **overrides: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(M, K, C)``: the mass, stiffness and damping matrices over the coordinates, with the
    guideway held fixed and the damper slots open (their forces are inputs)."""
    _check_model(model)
    values = model.values(params, **overrides)
    k, c, _, _, _ = _matrices(model, values, [0.0] * len(model.dampers))
    return np.diag([float(values[co.inertia]) for co in model.coordinates]), k, c


def packed_matrices(
    model: VehicleModel, packed: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(inertia, K, C, J_slots)`` for many vehicles at once: ``packed`` rows in
    :attr:`~VehicleModel.packed_param_names` order (the compiled plant's per-vehicle values;
    trailing ones absent are 0, e.g. a 1/4-car row without ``c_p``), giving ``inertia``
    (N, n), ``K`` and ``C`` (N, n, n); the geometry (lever arms) is the defaults', ``J_slots``
    (slots, n) the damper slots' rows."""
    packed = np.atleast_2d(np.asarray(packed, dtype=float))
    names = model.packed_param_names
    if packed.shape[1] < len(names):
        packed = np.concatenate(
            [packed, np.zeros((packed.shape[0], len(names) - packed.shape[1]))], axis=1
        )
    values = model.values()
    column = {name: packed[:, j] for j, name in enumerate(names)}
    n = len(model.coordinates)
    k, c = np.zeros((packed.shape[0], n, n)), np.zeros((packed.shape[0], n, n))
    slots = []
    for e in model.elements:
        j, _ = model.element_rows(e, values)
        if e.kind == DAMPER:
            slots.append(j)
            continue
        target = k if e.kind == SPRING else c
        for r in np.flatnonzero(j):
            for col in np.flatnonzero(j):
                target[:, r, col] = target[:, r, col] + column[e.coefficient] * (j[r] * j[col])  # type: ignore[index]
    inertia = np.stack([column[co.inertia] for co in model.coordinates], axis=1)
    return inertia, k, c, np.array(slots).reshape(len(slots), n)


def _slot_damping(model: VehicleModel, slot_damping: Sequence[float] | float) -> list[float]:
    n = len(model.dampers)
    if np.ndim(slot_damping) == 0:
        return _slot_damping(model, [float(slot_damping)] * n)  # type: ignore[arg-type]
    values = [float(v) for v in slot_damping]  # type: ignore[union-attr]
    if len(values) != n:
        raise ValueError(f"slot_damping: {n} values (one per damper slot), got {len(values)}")
    if not all(np.isfinite(v) and v >= 0.0 for v in values):
        raise ValueError(f"slot_damping must be finite and >= 0 N s/m, got {values}")
    return values


def _comfort_rows(model: VehicleModel, values: dict[str, float], *accelerating: np.ndarray):
    """The comfort points' rows over each ``accelerating`` matrix (rows: coordinates): a point
    on one coordinate with coefficient 1 copies its row (bit for bit), otherwise the sum."""
    points = [model.point_row(name, values) for name in model.comfort_points]
    out = []
    for m in accelerating:
        rows = np.zeros((len(points), m.shape[1]))
        for p, point in enumerate(points):
            nonzero = np.flatnonzero(point)
            if len(nonzero) == 1 and point[nonzero[0]] == 1.0:
                rows[p] = m[nonzero[0]]
            else:
                rows[p] = sum(point[i] * m[i] for i in nonzero)
        out.append(rows)
    return out


def absolute_model(
    model: VehicleModel, params: Any = None, slot_damping: Sequence[float] | float = 0.0,
    **overrides: float,
) -> LinearModel:  # fmt: skip
    """The absolute form (module doc). ``slot_damping``: a linear damper (N s/m) in each
    damper slot (the passive baseline; 0: the slot's force is an input); ``overrides``:
    parameter values taking precedence over ``params`` (e.g. a scheduled levitation)."""
    _check_model(model)
    values = model.values(params, **overrides)
    k, c, k_g, c_g, slots = _matrices(model, values, _slot_damping(model, slot_damping))
    n = len(model.coordinates)
    inertia = [float(values[co.inertia]) for co in model.coordinates]
    a, b = np.zeros((2 * n, 2 * n)), np.zeros((2 * n, len(slots)))
    e, e_rate = np.zeros((2 * n, k_g.shape[1])), np.zeros((2 * n, k_g.shape[1]))
    for i in range(n):
        a[2 * i, 2 * i + 1] = 1.0
        a[2 * i + 1, 0::2] = -k[i] / inertia[i]
        a[2 * i + 1, 1::2] = -c[i] / inertia[i]
        e[2 * i + 1] = k_g[i] / inertia[i]
        e_rate[2 * i + 1] = c_g[i] / inertia[i]
        for s, (j, _) in enumerate(slots):
            b[2 * i + 1, s] = -j[i] / inertia[i]
    vel = slice(1, 2 * n, 2)
    c_acc, d_acc, e_acc, e_rate_acc = _comfort_rows(model, values, a[vel], b[vel], e[vel],
                                                    e_rate[vel])  # fmt: skip
    stroke = np.zeros((len(slots), 2 * n))
    for s, (j, _) in enumerate(slots):
        stroke[s, 0::2] = j
    return LinearModel(model.state_names, a, b, e, e_rate, c_acc, d_acc, e_acc, e_rate_acc, stroke)


def relative_state_names(model: VehicleModel) -> tuple[str, ...]:
    """The relative form's state: each ``relative_positions`` spring's deflection, then the
    coordinate's velocity, per coordinate."""
    return tuple(n for s, c in zip(model.relative_positions, model.coordinates, strict=True)
                 for n in (f"{s}_deflection_m", c.rate_name))  # fmt: skip


def relative_model(
    model: VehicleModel, params: Any = None, slot_damping: Sequence[float] | float = 0.0,
    **overrides: float,
) -> LinearModel:  # fmt: skip
    """The relative form (module doc): needs ``relative_positions`` naming one spring per
    coordinate, together every spring of the vehicle, their deflections independent."""
    _check_model(model)
    values = model.values(params, **overrides)
    springs = {e.name: e for e in model.elements if e.kind == SPRING}
    n = len(model.coordinates)
    if sorted(model.relative_positions) != sorted(springs) or len(springs) != n:
        raise ValueError(f"vehicle {model.name!r}: relative_positions must name each of its "
                         f"{len(springs)} springs once, one per coordinate ({n})")  # fmt: skip
    rows = [model.element_rows(springs[s], values) for s in model.relative_positions]
    d = np.array([j for j, _ in rows])
    if abs(np.linalg.det(d)) < 1e-12:
        raise ValueError(f"vehicle {model.name!r}: the relative_positions' deflections are not "
                         "independent")  # fmt: skip
    damping = _slot_damping(model, slot_damping)
    _, c, _, c_g, slots = _matrices(model, values, damping)
    inertia = [float(values[co.inertia]) for co in model.coordinates]
    n_g = len(model.contacts)
    a, b = np.zeros((2 * n, 2 * n)), np.zeros((2 * n, len(slots)))
    e_v = np.zeros((2 * n, n_g))
    for p, (j, g) in enumerate(rows):  # the deflections' rates
        a[2 * p, 1::2] = j
        e_v[2 * p] = 0.0 - g
    stiffness = [float(values[springs[s].coefficient]) for s in model.relative_positions]  # type: ignore[index]
    for i in range(n):
        for p, (j, _) in enumerate(rows):  # a spring's force is its stiffness x its state
            a[2 * i + 1, 2 * p] = 0.0 - (j[i] * stiffness[p]) / inertia[i]
        a[2 * i + 1, 1::2] = 0.0 - c[i] / inertia[i]
        e_v[2 * i + 1] = c_g[i] / inertia[i]
        for s, (j, _) in enumerate(slots):
            b[2 * i + 1, s] = -j[i] / inertia[i]
    vel = slice(1, 2 * n, 2)
    c_acc, d_acc, e_rate_acc = _comfort_rows(model, values, a[vel], b[vel], e_v[vel])
    stroke = np.zeros((len(slots), 2 * n))
    stroke[:, 0::2] = np.array([j for j, _ in slots]) @ np.linalg.inv(d)
    zeros = np.zeros((2 * n, n_g))
    return LinearModel(relative_state_names(model), a, b, zeros, e_v, c_acc, d_acc,
                       np.zeros((len(model.comfort_points), n_g)), e_rate_acc, stroke)  # fmt: skip
