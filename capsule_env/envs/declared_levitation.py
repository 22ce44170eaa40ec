"""EDS levitation against speed for a declared vehicle on bogies (the half-car): each bogie's
levitation spring and dashpot at the env's constant speed.

Each bogie has its own null-flux coil model (:mod:`capsule_env.envelope.levitation`),
calibrated as the 1/4-car env calibrates its one: on the 1/4-car that bogie carries
(``params.quarter_params(bogie)``: its corner's values and its static share of the body), so
that its ``k_p`` at the reference speed (810 km/h) is its levitation stiffness and its sag at
lift-off the levitation travel. At the episode's speed ``v`` the bogie's contact then has
``k_p(v)`` and ``c_p(v)``; with equal halves and a dynamic index of 1 each end is the 1/4-car
env with ``levitation="eds"`` at that speed. A speed that changes (``speed_range_kmh``, a trip)
is not built for declared vehicles: :data:`capsule_env.envs.declared_vehicle.UNSUPPORTED_OPTIONS`
refuses it by name.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from capsule_env.engine.config import EnvConfig
from capsule_env.envelope.levitation import (
    EdsParams,
    check_levitating,
    eds_coil,
    levitation_damping_n_s_per_m,
    levitation_stiffness_n_per_m,
)

__all__ = ["eds_at_speed"]

_STIFFNESS, _DAMPING = "levitation_stiffness_n_per_m", "levitation_damping_n_s_per_m"


def _bogies(model: Any, params: Any) -> tuple[str, ...]:
    """The bogies of a vehicle whose parameters give each bogie's 1/4-car, else a
    ``ValueError``: EDS levitation is built for vehicles on bogies (the half-car)."""
    bogies = tuple(c.name.removesuffix("_guideway") for c in model.contacts)
    fields = {f.name for f in dataclasses.fields(params)}
    if not hasattr(params, "quarter_params") or not all(
        f"{b}_{_STIFFNESS}" in fields and f"{b}_{_DAMPING}" in fields for b in bogies
    ):
        raise ValueError(f"levitation='eds' is built for vehicles on bogies with a levitation "
                         f"each (e.g. 'half_car'), not for vehicle {model.name!r}")  # fmt: skip
    return bogies


def eds_at_speed(model: Any, params: Any, config: EnvConfig, overrides: dict[str, Any]) -> Any:
    """``params`` with each bogie's levitation stiffness and damping of its coil model at
    ``config``'s constant speed (module doc); ``overrides`` (the env's ``vehicle_params``) may
    set the stiffness at the reference speed but not the damping (the coil model sets it)."""
    bogies = _bogies(model, params)
    for b in bogies:
        if f"{b}_{_DAMPING}" in overrides:
            raise ValueError(f"vehicle_params['{b}_{_DAMPING}'] must not be set with "
                             "levitation='eds': the coil model sets the damping at each speed")  # fmt: skip
    eds = EdsParams(**config.levitation_params)
    speed_m_s = config.speed_m_s
    values = {}
    for b in bogies:
        quarter = params.quarter_params(b)
        try:
            coil = eds_coil(quarter, eds)
        except ValueError as exc:
            raise ValueError(f"levitation_params and vehicle_params do not calibrate the EDS coil "
                             f"of the {b} bogie: {exc}") from None  # fmt: skip
        check_levitating("speed_kmh", speed_m_s, coil)
        values[f"{b}_{_STIFFNESS}"] = float(levitation_stiffness_n_per_m(speed_m_s, coil))
        values[f"{b}_{_DAMPING}"] = float(levitation_damping_n_s_per_m(speed_m_s, coil))
    return dataclasses.replace(params, **values)
