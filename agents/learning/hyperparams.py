"""Hyperparameters in RL-Zoo format, and env arguments from the command line, for ``train.py``.

``hyperparams/<algo>.yml`` is keyed by the env id, so ``python -m rl_zoo3.train --algo ppo
--env CapsuleSuspension-v0 --gym-packages capsule_env --conf-file hyperparams/ppo.yml`` reads
it too (rl_zoo3 >= 2.x accepts ``env_kwargs`` in the file; rl_zoo3 is not a dependency). This
module reads it with PyYAML (:func:`load_hyperparams`) and turns the RL-Zoo conventions into
SB3 arguments (:func:`algo_kwargs_from`, :func:`normalize_kwargs_from`): ``n_envs``,
``n_timesteps``, ``policy``, ``normalize``, ``policy_kwargs``, ``env_kwargs``, ``lin_<x>``
schedules and ``noise_type``/``noise_std`` are understood, every other key goes to the SB3
algorithm.

Nothing is ``eval``-ed. RL Zoo writes ``policy_kwargs`` and ``normalize`` as Python source
(``"dict(net_arch=[64, 64], activation_fn=nn.Tanh)"``); :func:`parse_kwargs_expression` reads
such a string with :mod:`ast`: a ``dict(...)`` call or a ``{...}`` literal whose values are
literals, lists, tuples or dicts of them, or one of the names in :data:`ALLOWED_NAMES`.
Env arguments on the command line (``--env KEY=VALUE``, ``--env-kwargs``) are JSON or Python
literals (:func:`capsule_env.common.cli.parse_literal`; ``parse_literal``, ``parse_env_item`` and
``parse_env_kwargs`` are importable from here too). Every error is a ``ValueError`` with a one-line message
naming the key.
"""

from __future__ import annotations

import ast
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from capsule_env.common.cli import parse_env_item as parse_env_item
from capsule_env.common.cli import parse_env_kwargs as parse_env_kwargs
from capsule_env.common.cli import parse_literal as parse_literal
from capsule_env.engine.config import EnvConfig
from capsule_env.tasks import task_named

ENV_ID = "CapsuleSuspension-v0"
#: The registered task ``train.py`` trains on unless the hyperparameter file or the command
#: line says otherwise: the realistic ride task (capsule_env/tasks.py).
TRAIN_TASK = "CapsuleRide-v0"
#: Env arguments used for training unless the hyperparameter file or the command line says
#: otherwise: force requests through the inverse model, and :data:`TRAIN_TASK`'s options read
#: from its registration (the emulated HILS test, the ``measured`` signals a capsule has).
TRAIN_ENV_DEFAULTS = {"action_mode": "force", **task_named(TRAIN_TASK).kwargs}
#: The names an RL-Zoo ``policy_kwargs`` string may use (torch activation functions).
ALLOWED_NAMES = ("nn.ReLU", "nn.Tanh", "nn.ELU", "nn.LeakyReLU", "nn.SiLU", "nn.GELU")
#: Keys of the file that are not arguments of the SB3 algorithm.
NOT_ALGORITHM_ARGUMENTS = ("n_envs", "n_timesteps", "normalize", "env_kwargs", "noise_type",
                           "noise_std")  # fmt: skip


def load_hyperparams(path: str | Path) -> dict[str, Any]:
    """The ``CapsuleSuspension-v0`` entry of an RL-Zoo hyperparameter yml file."""
    import yaml

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"hyperparameter file not found: {path}")
    try:
        content = yaml.safe_load(path.read_text())
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        reason = " ".join(str(exc).split())
        raise ValueError(f"hyperparameter file {path} is not valid YAML: {reason}") from None
    if not isinstance(content, dict) or not isinstance(content.get(ENV_ID), dict):
        keys = list(content) if isinstance(content, dict) else type(content).__name__
        raise ValueError(f"{path} has no {ENV_ID!r} mapping (top level: {keys})")
    return dict(content[ENV_ID])


# ----------------------------------------------------------------------------- no eval()
def _allowed_objects() -> dict[str, Any]:
    import torch.nn as nn

    return {name: getattr(nn, name.split(".", 1)[1]) for name in ALLOWED_NAMES}


def _dotted_name(node: ast.expr) -> str | None:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        base = _dotted_name(node.value)
        return None if base is None else f"{base}.{node.attr}"
    return None


def _value(node: ast.expr, key: str, names: Mapping[str, Any]) -> Any:
    """The value of the expression ``node``: a literal, a list, tuple or dict of values, a
    ``dict(...)`` call of values, or a name in ``names``."""
    if isinstance(node, (ast.List, ast.Tuple)):
        items = [_value(e, key, names) for e in node.elts]
        return items if isinstance(node, ast.List) else tuple(items)
    if isinstance(node, (ast.Dict, ast.Call)):
        return _dict(node, key, names)
    name = _dotted_name(node)
    if name is not None and name in names:
        return names[name]
    try:  # numbers, strings, True/False/None, -1.0
        return ast.literal_eval(node)
    except (ValueError, TypeError):  # not a literal; an unhashable set member
        pass
    accepted = f" (accepted names: {', '.join(names)})" if names else ""
    raise ValueError(f"{key}: {ast.unparse(node)!r} is not a literal or an accepted name{accepted}")


def _dict(node: ast.expr, key: str, names: Mapping[str, Any]) -> dict[str, Any]:
    if isinstance(node, ast.Call):
        if _dotted_name(node.func) != "dict" or node.args:
            raise ValueError(f"{key}: only dict(name=value, ...) calls are read, not "
                             f"{ast.unparse(node)!r}")  # fmt: skip
        call: dict[str, Any] = {}
        for keyword in node.keywords:
            if keyword.arg is None:
                raise ValueError(f"{key}: dict(**...) is not read")
            call[keyword.arg] = _value(keyword.value, f"{key}.{keyword.arg}", names)
        return call
    if isinstance(node, ast.Dict):
        out: dict[str, Any] = {}
        for k, v in zip(node.keys, node.values):
            if not (isinstance(k, ast.Constant) and isinstance(k.value, str)):
                raise ValueError(
                    f"{key}: dict keys must be strings, not {ast.unparse(k) if k else '**'}"
                )
            out[k.value] = _value(v, f"{key}.{k.value}", names)
        return out
    raise ValueError(f"{key}: expected dict(...) or {{...}}, got {ast.unparse(node)!r}")


def parse_kwargs_expression(text: str, key: str, names: Mapping[str, Any] | None = None) -> dict:
    """The dict written as ``text``, a ``dict(...)`` call or a ``{...}`` literal (RL Zoo's
    ``policy_kwargs`` and ``normalize``), read with :mod:`ast`, never evaluated.

    Values may be literals (numbers, strings, booleans, None), lists, tuples and dicts of
    values, or the names in ``names`` (``{"nn.Tanh": torch.nn.Tanh, ...}``). Anything else (a
    function call, an unknown name, ``**``) raises ``ValueError`` naming ``key``.
    """
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except (SyntaxError, ValueError, MemoryError, RecursionError):
        raise ValueError(f"{key}: not a Python expression: {text!r}") from None
    return _dict(tree.body, key, names or {})


# ----------------------------------------------------------------------------- SB3 arguments
def _linear_schedule(initial: float) -> Callable[[float], float]:
    def schedule(progress_remaining: float) -> float:
        return progress_remaining * initial

    return schedule


def _schedule_or_number(key: str, value: Any) -> Any:
    """``lin_3e-4``: linear decay to 0; ``"1e-3"`` (PyYAML reads 1e-3 without a dot as a
    string): the number; numbers stay."""
    if not isinstance(value, str):
        return value
    try:
        return float(value)
    except ValueError:
        pass
    kind, _, number = value.partition("_")
    try:
        if kind == "lin":
            return _linear_schedule(float(number))
    except ValueError:
        pass
    raise ValueError(
        f"{key}: only numbers and 'lin_<value>' schedules are understood, got {value!r}"
    )


def algo_kwargs_from(hp: dict[str, Any]) -> dict[str, Any]:
    """Turn the RL-Zoo conventions into SB3 constructor arguments (the rest pass through)."""
    from stable_baselines3.common.noise import NormalActionNoise

    kwargs = {k: v for k, v in hp.items() if k not in NOT_ALGORITHM_ARGUMENTS}
    kwargs.setdefault("policy", "MlpPolicy")
    for key in ("learning_rate", "clip_range", "clip_range_vf"):
        if key in kwargs:
            kwargs[key] = _schedule_or_number(key, kwargs[key])
    if isinstance(kwargs.get("policy_kwargs"), str):  # "dict(net_arch=[64, 64])"
        kwargs["policy_kwargs"] = parse_kwargs_expression(
            kwargs["policy_kwargs"], "policy_kwargs", _allowed_objects()
        )
    if isinstance(kwargs.get("train_freq"), list):
        kwargs["train_freq"] = tuple(kwargs["train_freq"])
    if hp.get("noise_type"):
        if hp["noise_type"] != "normal":
            raise ValueError(f"noise_type: only 'normal' is understood, got {hp['noise_type']!r}")
        kwargs["action_noise"] = NormalActionNoise(np.zeros(1), float(hp["noise_std"]) * np.ones(1))
    return kwargs


def normalize_kwargs_from(hp: dict[str, Any]) -> dict[str, Any]:
    """``VecNormalize`` arguments: obs and reward normalised, obs clipped at 10, the algorithm's
    gamma; the file's ``normalize`` (``true`` or a ``"dict(...)"`` string) may change them."""
    kwargs = {"norm_obs": True, "norm_reward": True, "clip_obs": 10.0}
    given = hp.get("normalize", True)
    if isinstance(given, str):
        given = parse_kwargs_expression(given, "normalize")
    if isinstance(given, dict):
        kwargs.update(given)
    elif given is not True:
        raise ValueError(f"normalize: must be true or dict(...), got {given!r}")
    kwargs["gamma"] = float(hp.get("gamma", 0.99))
    if not kwargs["norm_obs"]:
        raise ValueError(
            "normalize: norm_obs must stay True (agents/learning/sb3_policy.py normalises)"
        )
    return kwargs


def resolve_env_kwargs(file_kwargs: dict | None, cli_kwargs: dict) -> dict[str, Any]:
    """Training defaults < hyperparameter file < command line; validated, errors name the key."""
    env_kwargs = {**TRAIN_ENV_DEFAULTS, **(file_kwargs or {}), **cli_kwargs}
    try:
        EnvConfig.from_kwargs(**env_kwargs)
    except (ValueError, TypeError) as err:
        culprits = []
        for key, value in env_kwargs.items():  # which argument, if the message does not say
            try:
                EnvConfig.from_kwargs(**{key: value})
            except (ValueError, TypeError):
                culprits.append(f"{key}={value!r}")
        where = f" (check {', '.join(culprits)})" if culprits else ""
        raise ValueError(f"bad environment argument: {err}{where}") from None
    return env_kwargs
