"""Vehicle models as data: a registry like the dampers' (:mod:`capsule_env.dampers`).

- :mod:`~capsule_env.vehicles.declaration`: what a vehicle declares (coordinates, points,
  contacts with their longitudinal offsets, springs, dashpots and damper slots);
- :mod:`~capsule_env.vehicles.linear`: the one linear model every controller reads;
- :mod:`~capsule_env.vehicles.registry`: ``register``, ``unregister``, ``model_named``,
  ``names``;
- :mod:`~capsule_env.vehicles.quarter_car`: the built-in ``quarter_car`` (today's plant);
- :mod:`~capsule_env.vehicles.half_car`: the built-in ``half_car`` (car body heave and pitch on
  two bogies, :class:`HalfCarParams`).

A new vehicle is one module here exporting ``MODEL`` or one :func:`register` call.
"""

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
from capsule_env.vehicles.half_car import HalfCarParams
from capsule_env.vehicles.linear import (
    LinearModel,
    absolute_model,
    mechanical_matrices,
    relative_model,
)
from capsule_env.vehicles.quarter_car import VehicleParams
from capsule_env.vehicles.registry import (
    BUILT_IN,
    MODELS,
    model_named,
    model_of_params,
    names,
    register,
    unregister,
)

__all__ = [
    "DAMPER",
    "DASHPOT",
    "SPRING",
    "BUILT_IN",
    "MODELS",
    "Contact",
    "Coordinate",
    "Element",
    "HalfCarParams",
    "LinearModel",
    "Point",
    "VehicleModel",
    "VehicleParams",
    "absolute_model",
    "mechanical_matrices",
    "model_named",
    "model_of_params",
    "names",
    "register",
    "relative_model",
    "unregister",
]
