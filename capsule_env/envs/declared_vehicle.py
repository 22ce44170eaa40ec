"""Semi-active control of any declared vehicle: one action per damper slot.

``gymnasium.make("CapsuleSuspension-v0", vehicle=name)`` gives this env when the vehicle named
(a registered :class:`capsule_env.vehicles.VehicleModel`) is not of the quarter-car's form (a
third body, a pitching car on two bogies); a vehicle of that form gets
:class:`~capsule_env.envs.capsule_suspension.CapsuleSuspensionEnv` and its vectorised kernels.

## Plant
The vehicle's declaration, compiled by :mod:`capsule_env.plant.declared`: RK4 with the
quarter-car's substep rule, the damper model in every slot (``damper``, ``damper_params``,
``coil_time_constant_s`` as for the quarter-car), each guideway contact reading the profile at
its own longitudinal offset.

## Action
``Box(-1, 1, (slots,))``: per damper slot, ``action_mode="current"`` maps ``[-1, 1]`` to
``[0, i_max]``; ``"force"`` asks for ``action * max_force_n`` through the inverse model on the
slot's stroke and stroke rate (an inverse in closed form; no CSDC here).

## Observation
``observation="full_state"`` (default here): the coordinates and their rates, each slot's
stroke and stroke rate, each comfort point's acceleration, each contact's elevation (true
values); ``"sensors"``: per slot its stroke, stroke rate, the accelerations of its two ends
(with the quarter-car's sensor noise per channel where ``sensor_noise`` or ``setting="hils"``
asks) and its last current command. Names with units: :attr:`DeclaredVehicleEnv.observation_names`.
``preview_points=P`` appends, for each guideway contact (the half-car's front then rear bogie),
``P`` columns ``<contact>_preview_ahead_<k>``: the surveyed guideway ``k * preview_horizon_s /
P`` seconds ahead of that contact relative to under it now, the 1/4-car env's survey map and
position error (:mod:`capsule_env.engine.declared_preview`); bounds +-1 m. Every column
saturates (is clipped) at the bounds of the quarter-car's column of its quantity
(:func:`capsule_env.engine.observations.declared_bounds`): accelerations at +-100 m/s^2,
strokes at +-2 x ``stroke_limit_m``, rates and velocities at +-10 m/s, displacements, gaps and
elevations at +-1 m, the pitch at +-1 rad and its rate at +-10 rad/s, the last current command
in [0, i_max].

## Reward
:mod:`capsule_env.engine.declared_batch`: the quarter-car's terms, averaged over the comfort
points and the slots; the episode terminates when any stroke passes ``stroke_limit_m``.

## Options
Those of ``CapsuleSuspension-v0`` that concern the damper (``setting="hils"``, the coil lag),
the sensors' noise and the control delay, the guideway, the episode and the reward, and
``levitation="eds"`` at a constant speed (each bogie's coil model at ``speed_kmh``:
:mod:`capsule_env.envs.declared_levitation`), the survey preview. The others (a speed that changes, the
spans, the payload, domain randomisation, the velocity reward, the reward filter) are
refused by name: they are not built for these vehicles yet. The native batched version is
:class:`capsule_env.envs.declared_vector.DeclaredVectorEnv`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import Env, spaces
from gymnasium.error import ResetNeeded

from capsule_env.engine.config import EnvConfig, check_seed
from capsule_env.engine.declared_batch import (
    COST_NAMES,
    DECLARED_OBSERVATIONS,
    DeclaredBatch,
    inverse_is_algebraic,
)
from capsule_env.envs._actions import real_actions
from capsule_env.envs.capsule_suspension import CapsuleSuspensionEnv
from capsule_env.envs.declared_levitation import eds_at_speed
from capsule_env.envs.render import check_render_mode
from capsule_env.envs.spec import LengthSpec
from capsule_env.vehicles import model_named, names
from capsule_env.vehicles.compiled import runs_compiled

__all__ = [
    "DeclaredVehicleEnv",
    "UNSUPPORTED_OPTIONS",
    "declared_setup",
    "declared_spaces",
    "make_suspension_env",
    "runs_compiled_kwargs",
]

#: Options of ``CapsuleSuspension-v0`` not built for declared vehicles, with the values each
#: accepts (its default).
UNSUPPORTED_OPTIONS: dict[str, Any] = {
    "levitation": ("fixed", "eds"), "speed_profile": ("constant",),
    "spans": ("none",), "payload_range": (None,), "vehicle_randomization": (0.0,),
    "speed_range_kmh": (None,), "reward_velocity_weight": (0.0,),
    "reward_acceleration_filter": ("none",), "magnet_length_m": (None,),
}  # fmt: skip


def declared_setup(owner: str, kwargs: dict[str, Any], num_envs: int = 1) -> DeclaredBatch:
    """The checked options and the batch of ``num_envs`` vehicles of an env over a declared
    vehicle (``kwargs``: the env's options, ``vehicle`` and ``vehicle_params`` among them)."""
    kwargs = dict(kwargs)
    name = kwargs.pop("vehicle", "quarter_car")
    vehicle_params = kwargs.pop("vehicle_params", {})
    kwargs.setdefault("observation", "full_state")
    _check_supported(name, kwargs, kwargs["observation"])
    config = EnvConfig.from_kwargs(owner, ("render_mode", "num_envs"), **kwargs)
    if config.action_mode == "force" and not inverse_is_algebraic(config.inverse_model):
        raise ValueError(f"inverse_model {config.inverse_model!r} has no closed-form inverse: "
                         "a declared vehicle's force mode needs one (e.g. 'bi_exponential'), "
                         "or use action_mode='current'")  # fmt: skip
    model = model_named(name)
    if not isinstance(vehicle_params, dict):
        raise TypeError("vehicle_params must be a dict of parameter overrides")
    params = _params(model, vehicle_params)
    if config.levitation == "eds":  # each bogie's levitation at the constant speed
        params = eds_at_speed(model, params, config, vehicle_params)
    return DeclaredBatch(config, model, params, num_envs)


def declared_spaces(batch: DeclaredBatch) -> tuple[spaces.Box, spaces.Box]:
    """``(action_space, observation_space)`` of one vehicle."""
    low, high = batch.observation_bounds()
    return (spaces.Box(-1.0, 1.0, shape=(batch.n_slots,), dtype=np.float32),
            spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32))  # fmt: skip


class DeclaredVehicleEnv(LengthSpec, Env[np.ndarray, np.ndarray]):
    """A declared vehicle's semi-active suspension (module doc)."""

    metadata = {"render_modes": [], "render_fps": 200}

    def __init__(self, render_mode: str | None = None, **kwargs: Any) -> None:
        check_render_mode(render_mode, drawn=False)
        self._batch = batch = declared_setup("DeclaredVehicleEnv.__init__", kwargs)
        self.config, self.vehicle_model = batch.config, batch.model
        self.vehicle_parameters = batch.params
        self.action_space, self.observation_space = declared_spaces(batch)
        self.observation_names = batch.observation_names()
        self.metadata = {**type(self).metadata, "render_fps": self.config.control_rate_hz}
        self.render_mode = None
        self._needs_reset = True

    @property
    def batch(self) -> DeclaredBatch:
        """The underlying simulation (state, plant arrays, route)."""
        return self._batch

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode: ``(observation, info)``; ``seed`` (an integer in ``[0, 2**63)``)
        re-seeds the vehicle's stream; ``options`` accepts no key."""
        if seed is not None:
            check_seed("seed", seed)
        if options:
            raise ValueError(f"unknown reset option(s) {sorted(options)}; accepted: none")
        super().reset(seed=None if seed is None else int(seed))  # Gymnasium wants an int
        if seed is not None:
            self._batch.seed(seed)
        self._batch.reset()
        self._needs_reset = False
        sig = self._batch.signals()
        # the step's info keys, the reward terms 0 (as the quarter-car env's reset info)
        return self._batch.observe(sig)[0], {**_row(sig, 0), **dict.fromkeys(COST_NAMES, 0.0)}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One control step: ``(observation, reward, terminated, truncated, info)``; ``action``
        has the action space's shape (one number per damper slot; a bare number for one slot),
        is clipped to [-1, 1]; another shape, NaN or infinity raises ``ValueError``, complex
        numbers or strings ``TypeError``. ``info``:
        the physical signals (arrays per slot, point or contact) and the reward's terms."""
        if self._needs_reset:
            raise ResetNeeded(
                "call reset() before step(): the episode has not started or has ended"
            )
        a = _checked_action(action, self._batch.n_slots)
        batch = self._batch
        sig = batch.step(a[None, :])
        reward, hit, costs = batch.reward(sig)
        terminated = bool(hit[0])
        truncated = bool(batch.step_count[0] >= batch.max_steps)
        self._needs_reset = terminated or truncated
        info = _row({**sig, **costs}, 0)
        return batch.observe(sig)[0], float(reward[0]), terminated, truncated, info


def _row(values: dict[str, np.ndarray], n: int) -> dict[str, Any]:
    """Vehicle ``n``'s entries: arrays per slot or point, floats per vehicle."""
    return {k: (v[n].copy() if v.ndim > 1 else float(v[n])) for k, v in values.items()}


def _check_supported(name: str, kwargs: dict[str, Any], observation: str) -> None:
    for key, accepted in UNSUPPORTED_OPTIONS.items():
        if key in kwargs and kwargs[key] not in accepted:
            raise ValueError(f"{key}={kwargs[key]!r} is not built for declared vehicles "
                             f"(vehicle {name!r}); accepted: {accepted!r}")  # fmt: skip
    if observation not in DECLARED_OBSERVATIONS:
        raise ValueError(f"observation must be one of {DECLARED_OBSERVATIONS} for vehicle "
                         f"{name!r}, got {observation!r}")  # fmt: skip


def _params(model: Any, overrides: dict[str, Any]) -> Any:
    known = {f for f in model.params.__dataclass_fields__}
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise ValueError(f"unknown key(s) {unknown} in vehicle_params; accepted: "
                         f"{', '.join(sorted(known))}")  # fmt: skip
    return model.params(**overrides)


def _checked_action(action: Any, n: int) -> np.ndarray:
    """The action of shape ``(n,)`` (a number too where ``n`` is 1), finite, clipped to [-1, 1];
    any other shape is refused, not reshaped (a batch of one is a mistake here)."""
    a = real_actions(action, "action")  # not complex numbers, strings or objects
    if a.shape != (n,) and not (n == 1 and a.shape == ()):
        raise ValueError(f"action must have shape ({n},), got {a.shape}")
    a = a.reshape(n).astype(np.float64)
    if not np.all(np.isfinite(a)):
        raise ValueError("action must be finite")
    return np.clip(a, -1.0, 1.0)


def make_suspension_env(render_mode: str | None = None, **kwargs: Any) -> Env:
    """``CapsuleSuspension-v0``'s entry point: the quarter-car env for a vehicle of its form
    (the compiled, vectorised kernels), :class:`DeclaredVehicleEnv` for any other."""
    if runs_compiled_kwargs(kwargs):
        return CapsuleSuspensionEnv(render_mode=render_mode, **kwargs)
    return DeclaredVehicleEnv(render_mode=render_mode, **kwargs)


def runs_compiled_kwargs(kwargs: dict[str, Any]) -> bool:
    """Whether env options ``kwargs`` name a vehicle the quarter-car's kernels run (an unknown
    name too: the quarter-car env names it in its error)."""
    name = kwargs.get("vehicle", "quarter_car")
    return not (isinstance(name, str) and name in names()) or _runs_compiled(name, kwargs)


def _runs_compiled(name: str, kwargs: dict[str, Any]) -> bool:
    """Whether the quarter-car's kernels run vehicle ``name``: its form at its defaults
    (overrides are then the quarter-car env's to check, and to refuse by name if they change
    the form); at the overrides for a vehicle of another form (a bad one is left for
    :class:`DeclaredVehicleEnv` to name)."""
    model = model_named(name)
    if runs_compiled(model):
        return True
    try:
        params = _params(model, dict(kwargs.get("vehicle_params") or {}))
    except (ValueError, TypeError):
        return False
    return runs_compiled(model, params)
