"""The damper models, found once: every module of this package that exports ``MODEL``.

Adding a model is one new module (``capsule_env/dampers/<name>.py`` exporting a
:class:`~capsule_env.dampers.base.DamperModel`), or :func:`register` for a model defined
elsewhere (a user's package, a test). Everything that depends on the model reads this
registry: the packed layout (``layout.DAMPER_PARAM_NAMES``), the kernels' compile-time
dispatch (:mod:`capsule_env.dampers.dispatch`), the substep rule, the inverses, ``EnvConfig``.
"""

from __future__ import annotations

from capsule_env.common.discover import modules_exporting_model
from capsule_env.common.validation import check_choice
from capsule_env.dampers.base import DamperModel

__all__ = [
    "MODELS",
    "MODELS_BY_CODE",
    "DAMPER_NAMES",
    "model_named",
    "model_of_code",
    "register",
    "unregister",
]

#: Modules of this package that are machinery, not models.
_NOT_MODELS = frozenset({"base", "registry", "dispatch", "api", "hysteresis", "inverse", "rig"})

#: Every model by name, in code order (the built-in ones, then registered ones).
MODELS: dict[str, DamperModel] = {}
#: Every model by its integer code.
MODELS_BY_CODE: dict[int, DamperModel] = {}
#: The names of the built-in models, in code order (a snapshot; :data:`MODELS` for all).
DAMPER_NAMES: tuple[str, ...] = ()


def register(model: DamperModel) -> DamperModel:
    """Add a model to the registry (its name and code must be new); returns it.

    A registered model runs through the plant, the env (``EnvConfig(damper=name)``) and, when
    it has an ``affine`` form, the inverse controllers' kernels, compiled for its code."""
    if not isinstance(model, DamperModel):
        raise TypeError(f"model must be a DamperModel, got {type(model).__name__}")
    same = MODELS.get(model.name) or MODELS_BY_CODE.get(model.code)
    if same is model:
        return model
    if same is not None:
        raise ValueError(
            f"damper model name {model.name!r} and code {model.code} must be new; "
            f"{same.name!r} has code {same.code}"
        )
    MODELS[model.name] = model
    MODELS_BY_CODE[model.code] = model
    return model


def unregister(name: str) -> None:
    """Remove a registered model (not a built-in one: ``ValueError``)."""
    if name in DAMPER_NAMES:
        raise ValueError(f"damper model {name!r} is built in; only registered ones can go")
    model = model_named(name)
    del MODELS[name], MODELS_BY_CODE[model.code]


def model_named(name: str) -> DamperModel:
    """The model called ``name`` (``ValueError`` naming the accepted ones otherwise)."""
    check_choice("damper model", name, tuple(MODELS))
    return MODELS[name]


def model_of_code(code: int) -> DamperModel:
    """The model of integer ``code`` (``ValueError`` otherwise)."""
    if code not in MODELS_BY_CODE:
        raise ValueError(f"damper model code must be one of {sorted(MODELS_BY_CODE)}, got {code!r}")
    return MODELS_BY_CODE[code]


def _discover() -> tuple[str, ...]:
    found = modules_exporting_model(__package__, DamperModel, _NOT_MODELS)
    for model in sorted(found, key=lambda m: m.code):
        register(model)
    return tuple(m.name for m in sorted(found, key=lambda m: m.code))


DAMPER_NAMES = _discover()
