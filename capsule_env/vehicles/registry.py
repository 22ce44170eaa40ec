"""The vehicle models, found once: every module of this package that exports ``MODEL``.

Adding a vehicle is one new module (``capsule_env/vehicles/<name>.py`` exporting a
:class:`~capsule_env.vehicles.declaration.VehicleModel`), or :func:`register` for one declared
elsewhere (a user's package, a test). ``gym.make(..., vehicle=name)`` selects one
(:class:`capsule_env.engine.config.EnvConfig`).
"""

from __future__ import annotations

import dataclasses

from capsule_env.common.discover import modules_exporting_model
from capsule_env.common.validation import check_choice
from capsule_env.vehicles.declaration import VehicleModel

__all__ = [
    "MODELS",
    "BUILT_IN",
    "names",
    "model_named",
    "model_of_params",
    "register",
    "unregister",
]

#: Modules of this package that are machinery, not vehicles.
_NOT_MODELS = frozenset({"declaration", "linear", "registry", "compiled", "modes"})

#: Every vehicle model by name (the built-in ones, then registered ones).
MODELS: dict[str, VehicleModel] = {}
#: The names of the built-in models (a snapshot; :data:`MODELS` for all).
BUILT_IN: tuple[str, ...] = ()


def register(model: VehicleModel) -> VehicleModel:
    """Add a vehicle model (its name must be new, and its parameter class read by no
    registered vehicle declared differently: the readers given only parameters find the
    model by that class); returns it."""
    if not isinstance(model, VehicleModel):
        raise TypeError(f"model must be a VehicleModel, got {type(model).__name__}")
    same = MODELS.get(model.name)
    if same is model:
        return model
    if same is not None:
        raise ValueError(f"vehicle model name {model.name!r} is taken; choose a new one")
    unnamed = dataclasses.replace(model, name="_")
    for other in MODELS.values():
        if other.params is model.params and dataclasses.replace(other, name="_") != unnamed:
            raise ValueError(
                f"vehicle {model.name!r}: {model.params.__name__} is read by {other.name!r}, "
                "declared differently; the readers given only parameters (lqr_gain, the "
                "preview LQ, the MPC, the reference solver) find a vehicle by its parameter "
                "class: give "
                f"{model.name!r} its own (e.g. a subclass: class MyParams({model.params.__name__}): "
                "pass, decorated with @dataclass(frozen=True))"
            )
    MODELS[model.name] = model
    return model


def unregister(name: str) -> None:
    """Remove a registered model (not a built-in one: ``ValueError``)."""
    if name in BUILT_IN:
        raise ValueError(f"vehicle model {name!r} is built in; only registered ones can go")
    model_named(name)
    del MODELS[name]


def model_named(name: str) -> VehicleModel:
    """The model called ``name`` (``ValueError`` naming the accepted ones otherwise)."""
    check_choice("vehicle", name, tuple(MODELS))
    return MODELS[name]


def model_of_params(params: object) -> VehicleModel:
    """The registered model whose parameter dataclass ``params`` is an instance of (the first
    registered, so a built-in before a copy under another name): what a reader given only
    parameters (``VehicleParams`` for the 1/4-car) derives its linear model from."""
    readers = [m for m in MODELS.values() if type(params) is m.params]
    declarations = {dataclasses.replace(m, name="_") for m in readers}  # all but the name
    if len(declarations) > 1:
        raise ValueError(
            f"{type(params).__name__} is read by vehicles declared differently "
            f"({', '.join(m.name for m in readers)}): give each its own parameter class, or pass "
            "the model to the linear-model functions (absolute_model, relative_model)"
        )
    if readers:
        return readers[0]
    raise TypeError(f"no registered vehicle model reads {type(params).__name__}; "
                    f"registered: {', '.join(MODELS)}")  # fmt: skip


def names() -> tuple[str, ...]:
    """The names of every registered vehicle model."""
    return tuple(MODELS)


def _discover() -> tuple[str, ...]:
    found = modules_exporting_model(__package__, VehicleModel, _NOT_MODELS)
    for model in found:
        register(model)
    return tuple(m.name for m in found)


BUILT_IN = _discover()
