"""``NAME.contract.json``: what a rig must feed an exported policy and what it gets back.

The contract records, for the exported artifacts:

- ``observation``: the columns in order (index, name, unit, what it is, the sensor's
  saturation bounds at which the env clips it) and the normalisation inside the artifacts
  (mean, standard deviation, clip, the formula);
- ``action``: its size, bounds and meaning (the env's ``action_mode``: a force request through
  the inverse model, or a coil current), and what stays on the rig (the inverse model);
- ``control``: the control period and the delay the policy was trained with (the setting's
  coil lag and sensor noise beside them);
- ``task``: the registered task whose options the policy was trained with (None when none
  matches; ``env_id`` and ``env_kwargs`` then say what it was trained on);
- ``residual``: for a residual policy, the law it rides on, its scale and the combination rule,
  and whether the C export includes the law (else the rig provides it); ``base_law``: the law
  in the C file, or what the rig needs to rebuild it, its constructor's arguments included
  (:mod:`capsule_env.export.base_law`, :mod:`capsule_env.export.quarter_law`);
- ``sources`` and ``artifacts``: sizes and SHA-256 of the policy's files (model, normaliser,
  metadata) and of each exported file.
"""

from __future__ import annotations

import dataclasses
import hashlib
from typing import Any

import numpy as np

from capsule_env.common.safe_io import file_digest
from capsule_env.engine import observations as obs_table
from capsule_env.engine.config import EnvConfig, observation_bounds
from capsule_env.export.base_law import base_law
from capsule_env.export.network import Dense, DeterministicActor, Renorm
from capsule_env.export.source import PolicySource
from capsule_env.tasks import TASKS

__all__ = ["CONTRACT_VERSION", "training_config", "task_of", "contract"]

#: Raised when a field is removed or changes meaning; a field added (``residual.base_law``)
#: keeps it, a reader ignoring what it does not know.
CONTRACT_VERSION = 1
#: Units of the columns appended after a set's own (the trip's, the preview's).
_APPENDED_UNITS = {"speed_m_s": "m/s", "longitudinal_acceleration_m_s2": "m/s^2"}


#: Units of a declared vehicle's columns, by the end of their names (longest first).
_UNIT_SUFFIXES = (("_m_s2", "m/s^2"), ("_m_s", "m/s"), ("_a", "A"), ("_m", "m"))


def _declared_batch(kwargs: dict[str, Any]) -> Any:
    """One vehicle of a declared vehicle's env (its ``kwargs`` name a ``vehicle`` other than
    the 1/4-car, e.g. the half-car task's policy), or None for the 1/4-car's env."""
    if kwargs.get("vehicle", "quarter_car") == "quarter_car":
        return None
    from capsule_env.envs.declared_vehicle import declared_setup

    return declared_setup("the policy's env options", kwargs, 1)


def training_config(source: PolicySource) -> tuple[EnvConfig, dict[str, Any]]:
    """The env configuration the policy was trained with (a declared vehicle's: its env's
    settings, control period and action), and its options as recorded."""
    meta = source.meta
    kwargs = dict(meta.get("train_env_kwargs", meta.get("env_kwargs", {})))
    try:
        batch = _declared_batch(kwargs)
        return (EnvConfig.from_kwargs(**kwargs) if batch is None else batch.config), kwargs
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"{source.zip_path}: its recorded env options are not valid: {exc}"
        ) from None


def task_of(source: PolicySource, config: EnvConfig) -> str | None:
    """The registered task the policy was trained on: its ``train.py --task``, else the task
    whose options give the same env (guideway seed and episode length aside), else None."""
    args = source.meta.get("args")
    if isinstance(args, dict) and args.get("task"):
        return str(args["task"])
    plain = dataclasses.replace(config, guideway_seed=0, episode_length_s=10.0)
    for task in TASKS:
        if EnvConfig.from_kwargs(**task.kwargs) == plain:
            return task.env_id
    return None


def _table(config: EnvConfig, kwargs: dict[str, Any]) -> tuple[tuple[str, ...], dict, Any, Any]:
    """The observation's column names, their ``(unit, what)`` by name, and the saturation
    bounds: the 1/4-car's table, or a declared vehicle's per-slot columns (units by name)."""
    batch = _declared_batch(kwargs)
    if batch is not None:
        names = batch.observation_names()
        units = {n: next(u for end, u in _UNIT_SUFFIXES if n.endswith(end)) for n in names}
        rows = {n: (units[n], f"{config.observation} signal of a damper slot: {n}") for n in names}
        return names, rows, *batch.observation_bounds()
    rows = {row.name: (row.unit, row.what) for row in obs_table.observables(config.observation)}
    appended = (*obs_table.TRIP_COLUMNS, *obs_table.preview_columns(config.preview_points))
    rows.update({c.name: (_APPENDED_UNITS.get(c.name, "m"), c.what) for c in appended})
    return config.observation_names, rows, *observation_bounds(config, config.max_current_a)


def _bound(value: float) -> float | None:
    """A saturation bound as JSON: None where the env does not clip (an infinite bound)."""
    return float(value) if np.isfinite(value) else None


def _columns(names: tuple[str, ...], rows: dict, low: Any, high: Any,
             actor: DeterministicActor) -> list[dict[str, Any]]:  # fmt: skip
    out = []
    for k, name in enumerate(names):
        unit, what = rows[name]
        column = {"index": k, "name": name, "unit": unit, "what": what,
                  "saturation_low": _bound(low[k]), "saturation_high": _bound(high[k])}  # fmt: skip
        if actor.normaliser is not None:
            column["mean"] = float(actor.normaliser.mean[k])
            column["std"] = float(actor.normaliser.std[k])
        out.append(column)
    return out


def _observation(config: EnvConfig, actor: DeterministicActor,
                 kwargs: dict[str, Any]) -> dict[str, Any]:  # fmt: skip
    names, rows, low, high = _table(config, kwargs)
    if len(names) != actor.obs_size:
        raise ValueError(f"the network takes {actor.obs_size} observations, its training env "
                         f"gives {len(names)}")  # fmt: skip
    norm = actor.normaliser
    normalisation: dict[str, Any] = {"inside_artifacts": True, "kind": "none"}
    if norm is not None:
        normalisation = {
            "inside_artifacts": True, "kind": "VecNormalize", "clip": norm.clip,
            "epsilon": norm.epsilon, "formula": "clip((obs - mean) / std, -clip, clip) in double "
            "precision, then float32; std = sqrt(var + epsilon)",
        }  # fmt: skip
    return {"size": actor.obs_size, "dtype": "float32", "set": config.observation,
            "columns": _columns(names, rows, low, high, actor), "normalisation": normalisation,
            "note": "raw SI values in this order, as the env gives them; the env clips each "
                    "column to its saturation bounds (the sensor's)"}  # fmt: skip


def _action(config: EnvConfig, actor: DeterministicActor) -> dict[str, Any]:
    if config.action_mode == "force":
        meaning = (f"desired damper force F_d = a * {config.max_force_n:g} N (max_force_n), "
                   f"turned into a coil current by the inverse model {config.inverse_model!r} "
                   "from the measured stroke and stroke rate")  # fmt: skip
        rig = f"the inverse model ({config.inverse_model}) and the damper's coil driver"
    else:
        meaning = f"coil current command i = (a + 1) / 2 * {config.max_current_a:g} A"
        rig = "the damper's coil driver"
    return {"size": actor.action_size, "dtype": "float32", "low": -1.0, "high": 1.0,
            "mode": config.action_mode, "meaning": meaning, "max_force_n": config.max_force_n,
            "max_current_a": config.max_current_a, "rig_provides": rig}  # fmt: skip


def _control(config: EnvConfig) -> dict[str, Any]:
    steps = config.effective_control_delay_steps
    return {"period_s": config.dt_s, "rate_hz": config.control_rate_hz,
            "delay_steps": steps, "delay_s": steps * config.dt_s, "setting": config.setting,
            "coil_time_constant_s": config.effective_coil_time_constant_s,
            "sensor_noise": config.effective_sensor_noise,
            "note": "the policy was trained with the action applied delay_steps control periods "
                    "after the observation it was computed from"}  # fmt: skip


def _network(actor: DeterministicActor) -> dict[str, Any]:
    layers = []
    for layer in actor.layers:
        if isinstance(layer, Dense):
            layers.append(f"linear {layer.weight.shape[1]} -> {layer.weight.shape[0]}")
        elif isinstance(layer, Renorm):
            layers.append(f"batch renorm {layer.mean.size} (running statistics)")
        else:
            layers.append(getattr(layer, "kind", "hardtanh"))
    post = ["tanh"] if actor.tanh_output else []
    post.append("rescale [-1, 1] to [low, high]" if actor.rescale else "clip to [low, high]")
    return {"algo": actor.algo, "layers": layers, "after": [*post, "clip to [-1, 1]"],
            "model_action_low": actor.low.tolist(), "model_action_high": actor.high.tolist(),
            "parameters": int(sum(np.asarray(v).size for layer in actor.layers
                                  for v in vars(layer).values() if isinstance(v, np.ndarray)))}  # fmt: skip


def _residual(source: PolicySource, kwargs: dict[str, Any],
              names: tuple[str, ...]) -> dict[str, Any] | None:  # fmt: skip
    res = source.residual
    if res is None:
        return None
    return {"law": res.law_name, "scale": res.scale,
            "combine": "action = clip(law_action + scale * residual, -1, 1) (double precision, "
                       "then float32); the artifacts' action is the residual, 0 on a row whose "
                       "observation holds a NaN or inf (the law alone)",
            "law_in_c": res.law is not None, "law_gains": res.law.gains() if res.law else None,
            "rig_provides_law": res.law is None, "why_not_in_c": res.reason or None,
            "base_law": base_law(source, kwargs, names)}  # fmt: skip


def _sources(source: PolicySource) -> dict[str, Any]:
    from capsule_env.agents.learning.policy_files import sibling

    files = {"model": source.zip_path, "normaliser": sibling(source.zip_path, ".vecnormalize.pkl"),
             "metadata": sibling(source.zip_path, ".json")}  # fmt: skip
    return {role: {"file": path.name, **file_digest(path)}
            for role, path in files.items() if path.is_file()}  # fmt: skip


def contract(source: PolicySource, actor: DeterministicActor,
             artifacts: dict[str, bytes]) -> dict[str, Any]:  # fmt: skip
    """The contract of ``source`` exported as ``artifacts`` (file name -> content)."""
    config, kwargs = training_config(source)
    observation = _observation(config, actor, kwargs)
    names = tuple(column["name"] for column in observation["columns"])
    return {
        "contract_version": CONTRACT_VERSION,
        "name": source.name,
        "task": task_of(source, config),
        "env_id": "CapsuleSuspension-v0",
        "env_kwargs": kwargs,
        "control": _control(config),
        "observation": observation,
        "action": _action(config, actor),
        "network": _network(actor),
        "residual": _residual(source, kwargs, names),
        "sources": _sources(source),
        "artifacts": {
            name: {"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}
            for name, data in artifacts.items()
        },  # fmt: skip
    }
