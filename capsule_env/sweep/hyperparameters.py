"""The values of a ``train`` trial's ``hp.<key>`` parameters, checked before the study runs.

A value of the wrong type would otherwise fail deep inside stable-baselines3 once the trial
has started, with a message that names no key (``hp.n_steps: "abc"``: "unsupported operand
type(s) for %"). :func:`check_hp_values` refuses it in one line naming ``hp.<key>`` and what
it accepts:

- ``learning_rate``, ``clip_range``: a number > 0 or a ``lin_<value>`` schedule
  (``clip_range_vf`` also ``null``);
- ``policy_kwargs``, ``normalize``: what the hyperparameter file accepts (``"dict(...)"``);
- the integer counts (``n_steps``, ``batch_size``, ``n_epochs``, ``n_envs``, ``buffer_size``,
  ...): integers >= 1 (``learning_starts`` >= 0, ``gradient_steps`` >= -1);
- ``gamma``, ``gae_lambda``, ``tau``: numbers in [0, 1]; ``n_timesteps``, ``noise_std``:
  numbers >= 0;
- any other argument of the algorithm whose default is a bool, an integer or a float: a
  value of that type (a bool is not a number; an integer is a float).
"""

from __future__ import annotations

import inspect
import math
from typing import Any

from capsule_env.sweep._rl import learning

#: Integer hyperparameters and their least value (RL-Zoo keys and SB3 arguments).
INTEGER_MINIMUM = {
    "n_envs": 1, "n_steps": 1, "batch_size": 1, "n_epochs": 1, "buffer_size": 1,
    "learning_starts": 0, "gradient_steps": -1, "policy_delay": 1, "stats_window_size": 1,
    "sde_sample_freq": -1, "target_update_interval": 1,
}  # fmt: skip
#: Hyperparameters that are fractions in [0, 1].
FRACTIONS = ("gamma", "gae_lambda", "tau")
#: Numbers >= 0 that are not SB3 arguments (RL-Zoo keys).
NON_NEGATIVE = ("n_timesteps", "noise_std")
#: A number > 0 or a ``lin_<value>`` schedule.
SCHEDULES = ("learning_rate", "clip_range", "clip_range_vf")
#: Read by the hyperparameter file's own parsers (their errors name the key).
PARSED = ("policy_kwargs", "normalize", "train_freq", "noise_type", "policy")


def _is_number(value: Any) -> bool:
    return (
        isinstance(value, (int, float))
        and not isinstance(value, bool)
        and math.isfinite(value)
    )  # fmt: skip


def _refuse(key: str, accepted: str, value: Any) -> None:
    raise ValueError(f"hp.{key}: expected {accepted}, got {value!r}")


def _check_schedule(key: str, value: Any) -> None:
    algo_kwargs_from = learning("hyperparams").algo_kwargs_from
    accepted = "a number > 0 or a 'lin_<value>' schedule" + (" or null" * (key == "clip_range_vf"))
    if value is None and key == "clip_range_vf":
        return
    if isinstance(value, str):
        try:
            value = algo_kwargs_from({key: value})[key]  # as train.py reads it
        except ValueError:
            _refuse(key, accepted, value)
        if callable(value):
            return
    if not _is_number(value) or value <= 0:
        _refuse(key, accepted, value)


def _check_by_default(key: str, value: Any, default: Any) -> None:
    """A value of the type of the algorithm's default (bool, integer or float)."""
    if isinstance(default, bool):
        if not isinstance(value, bool):
            _refuse(key, "true or false", value)
    elif isinstance(default, int):
        if isinstance(value, bool) or not isinstance(value, int):
            _refuse(key, "an integer", value)
    elif isinstance(default, float) and not _is_number(value):
        _refuse(key, "a number", value)


def check_hp_value(key: str, value: Any, defaults: dict[str, Any]) -> None:
    """One ``hp.<key>`` value (``defaults``: the algorithm's constructor defaults); a
    ``ValueError`` naming ``hp.<key>`` and what it accepts."""
    if key in SCHEDULES:
        _check_schedule(key, value)
    elif key in INTEGER_MINIMUM:
        least = INTEGER_MINIMUM[key]
        if isinstance(value, bool) or not isinstance(value, int) or value < least:
            _refuse(key, f"an integer >= {least}", value)
    elif key in FRACTIONS:
        if not _is_number(value) or not 0.0 <= value <= 1.0:
            _refuse(key, "a number in [0, 1]", value)
    elif key in NON_NEGATIVE:
        if not _is_number(value) or value < 0:
            _refuse(key, "a number >= 0", value)
    elif key not in PARSED and key in defaults:
        _check_by_default(key, value, defaults[key])


def check_hp_values(algo: str, base: dict[str, Any], given: dict[str, Any]) -> None:
    """The study's ``hp.<key>`` values (``given``) for ``algo`` over the hyperparameter file's
    entry ``base``: each value checked (:func:`check_hp_value`), then the merged entry parsed
    as train.py parses it (schedules, ``policy_kwargs``, ``normalize``)."""
    hyperparams = learning("hyperparams")
    # the class by name (sb3-contrib's TQC, CrossQ, RecurrentPPO are not in stable_baselines3)
    signature = inspect.signature(learning("algorithms").algorithm_class(algo).__init__)
    defaults = {name: p.default for name, p in signature.parameters.items()}
    for key, value in given.items():
        check_hp_value(key, value, defaults)
    merged = {**base, **given}
    try:
        hyperparams.algo_kwargs_from(merged)
        hyperparams.normalize_kwargs_from(merged)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"hp.{' '.join(str(exc).split())}") from None
