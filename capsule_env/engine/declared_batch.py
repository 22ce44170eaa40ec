"""``N`` vehicles of any declared form, stepped by the declared plant
(:mod:`capsule_env.plant.declared`): the episodes, the commands, the reward and the
observations of :class:`capsule_env.envs.declared_vehicle.DeclaredVehicleEnv` (no Gym import).

The episode is drawn as ``CapsuleBatch`` draws it (the same stream per vehicle, the same draws
in the same order: a profile of the bank, a start along it, the speed), so a vehicle declared
with the quarter-car's form meets the guideway the quarter-car env meets for the same seed. The
vehicle starts at rest in static equilibrium over its contacts' first elevations (``K q = K_g
z_g``: every body at the guideway's elevation for one contact).

The reward generalises the quarter-car's (``reward_velocity_weight`` and the reward filter are
not offered)::

    r = -( w_acc mean_p (a_p / a_ref)^2 + w_stroke mean_s (x_s / x_ref)^2
           + w_energy mean_s (i_s / i_max)^2 ) - penalty [any |x_s| > stroke_limit]

over the comfort points ``p`` and the damper slots ``s``: for one point and one slot it is the
quarter-car env's reward term for term.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from capsule_env.dampers.inverse import INVERSE_CODES, affine_in_current, invert_affine
from capsule_env.dampers.registry import model_of_code
from capsule_env.engine.batch import vehicle_streams
from capsule_env.engine.config import EnvConfig
from capsule_env.guideway import make_profile, random_profile
from capsule_env.plant.declared import declared_step
from capsule_env.plant.declared_build import (
    declared_output_names,
    declared_plant,
    declared_state_names,
)
from capsule_env.plant.params import Route
from capsule_env.plant.substeps import MAX_AUTO_SUBSTEPS
from capsule_env.vehicles.declaration import VehicleModel
from capsule_env.vehicles.linear import absolute_model, mechanical_matrices

__all__ = ["DeclaredBatch", "DECLARED_OBSERVATIONS"]

#: Observation sets of a declared vehicle: ``full_state`` (every coordinate and rate, each
#: slot's stroke and stroke rate, each comfort point's acceleration and each contact's
#: elevation) and ``sensors`` (each slot's stroke, stroke rate and the accelerations of its two
#: ends: what a bogie's own sensors read). No noise.
DECLARED_OBSERVATIONS = ("full_state", "sensors")


class DeclaredBatch:
    """``N`` vehicles of ``model`` with the common options of ``config`` (an
    :class:`EnvConfig` whose vehicle options are ignored: ``model`` and ``params`` are the
    vehicle)."""

    def __init__(self, config: EnvConfig, model: VehicleModel, params: Any, num_envs: int = 1):
        self.config, self.model, self.num_envs = config, model, int(num_envs)
        self.params = params
        self.values = model.values(params)
        self.damper = config.plant_damper
        self.inverse = config.inverse_damper
        self.i_max, self.dt = config.max_current_a, config.dt_s
        self.max_steps = config.max_episode_steps
        self.guideway = config.guideway_spec
        self.n_slots, self.n_coords = len(model.dampers), len(model.coordinates)
        self.profiles = _bank(config)
        speed = config.speed_m_s
        rate = float(np.asarray(config.input_rate_rad_s(speed)).reshape(-1)[0])
        self.plant = declared_plant(model, [self.values] * self.num_envs, self.damper,
                                    self.profiles, self.guideway.spacing_m, self.dt,
                                    substeps=config.substeps, input_rate_rad_s=rate)  # fmt: skip
        need = int(self.plant.substeps.max())
        if need > MAX_AUTO_SUBSTEPS:
            raise ValueError(f"vehicle {model.name!r} needs {need} RK4 substeps per control step "
                             f"(more than {MAX_AUTO_SUBSTEPS}): too stiff for control_rate_hz="
                             f"{config.control_rate_hz:g}; raise it or set substeps")  # fmt: skip
        self.state_names = declared_state_names(model)
        self.output_names = declared_output_names(model)
        n = self.num_envs
        self.state = np.zeros((n, len(self.state_names)))
        self.out = np.zeros((n, len(self.output_names)))
        self.command = np.zeros((n, self.n_slots))
        self.route = Route(np.zeros(n, np.int64), np.zeros(n), np.full(n, speed), np.ones(n))
        self.step_count = np.zeros(n, dtype=np.int64)
        self.rngs = vehicle_streams(None, n)
        self._geometry()

    def _geometry(self) -> None:
        """The rows the observations and the reward read, and the static equilibrium."""
        lin = absolute_model(self.model, self.params)
        self.stroke_rows = np.array([lin.stroke[s][0::2] for s in range(self.n_slots)])
        values, model = self.values, self.model
        self.comfort_rows = np.array([model.point_row(p, values) for p in model.comfort_points])
        ends = [(model.point_row(d.upper, values), model.point_row(d.lower, values))
                for d in model.dampers]  # fmt: skip
        self.end_rows = np.array([row for pair in ends for row in pair]).reshape(-1, self.n_coords)
        m, k, _ = mechanical_matrices(model, self.params)
        k_g = lin.e[1::2] * np.diag(m)[:, None]  # lin.e: K_g over the inertias
        self._equilibrium = np.linalg.solve(k, k_g)  # q at rest = this @ z_g
        # a contact behind the reference point reads the bank from its first sample on
        offsets = self.plant.contact_offsets_m
        self._lead_m = max(0.0, -float(offsets.min(initial=0.0)))
        length_m = self._lead_m + max(0.0, float(offsets.max(initial=0.0)))
        self._length_samples = int(math.ceil(length_m / self.guideway.spacing_m))

    # ------------------------------------------------------------------ episodes
    def seed(self, seed: Any) -> None:
        self.rngs = vehicle_streams(seed, self.num_envs)

    def reset(self, n: int) -> None:
        """A new episode for vehicle ``n`` (the quarter-car env's draws, in its order)."""
        cfg, rng = self.config, self.rngs[n]
        k = int(rng.integers(self.profiles.shape[0]))
        u_offset, _ = rng.random(2)
        rng.uniform(-1.0, 1.0, 4)  # the quarter-car's vehicle randomisation draw (unused)
        rng.integers(0, 2**63 - 1)  # its noise key (no noise here)
        spacing = self.guideway.spacing_m
        window = int(math.ceil(cfg.window_m / spacing)) + 1
        self.route.profile[n] = k
        if self.guideway.kind == "random":
            j0 = int(u_offset * (self.profiles.shape[1] - window - self._length_samples))
            self.route.start_m[n] = j0 * spacing + self._lead_m
            seg = self.profiles[k, j0 : j0 + window]
            peak = self.guideway.peak_m
            self.route.gain[n] = 1.0 if peak is None else peak / np.max(np.abs(seg))
        else:
            self.route.start_m[n], self.route.gain[n] = self._lead_m, 1.0
        self.state[n] = 0.0
        zg = self._contact_elevations(n, 0.0)
        self.state[n, : self.n_coords] = self._equilibrium @ zg
        self.command[n] = 0.0
        self.step_count[n] = 0
        self.out[n] = 0.0
        self.out[n, self.n_slots + self.n_coords :] = zg

    def _contact_elevations(self, n: int, t: float) -> np.ndarray:
        pos = self.route.start_m[n] + self.route.speed_mps[n] * t + self.plant.contact_offsets_m[n]
        grid = np.arange(self.profiles.shape[1]) * self.guideway.spacing_m
        return self.route.gain[n] * np.interp(pos, grid, self.profiles[self.route.profile[n]])

    # ------------------------------------------------------------------ stepping
    def commands(self, n: int, action: np.ndarray) -> np.ndarray:
        """Coil-current commands (A) of vehicle ``n`` for ``action`` in [-1, 1] per slot:
        directly (current mode) or through the inverse model on each slot's true stroke and
        stroke rate (force mode: the action times ``max_force_n`` is the force asked for)."""
        if self.config.action_mode == "current":
            return 0.5 * (action + 1.0) * self.i_max
        code = INVERSE_CODES[self.config.inverse_model]
        p = self.inverse.as_array()
        q, v = self.positions_rates(n)
        out = np.empty(self.n_slots)
        for s in range(self.n_slots):
            x, xd = float(self.stroke_rows[s] @ q), float(self.stroke_rows[s] @ v)
            f0, slope = affine_in_current(code, p, x, xd, 0.0)
            out[s] = invert_affine(float(action[s]) * self.config.max_force_n, f0, slope, xd,
                                   self.i_max)  # fmt: skip
        return out

    def positions_rates(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        nc = self.n_coords
        return self.state[n, :nc], self.state[n, nc : 2 * nc]

    def step(self, n: int, action: np.ndarray) -> None:
        self.command[n] = self.commands(n, action)
        declared_step(self.damper.code, n, n + 1, self.plant, self.state, self.command,
                      self.route, self.dt, self.out)  # fmt: skip
        self.step_count[n] += 1

    # ------------------------------------------------------------------ signals
    def signals(self, n: int) -> dict[str, np.ndarray]:
        """The physical signals of vehicle ``n`` now, by name (arrays per slot or point)."""
        ns, nc = self.n_slots, self.n_coords
        q, v = self.positions_rates(n)
        acc = self.out[n, ns : ns + nc]
        currents = self.state[n, 2 * nc + 2 :: 3][:ns]
        return {
            "stroke_m": self.stroke_rows @ q,
            "stroke_rate_m_s": self.stroke_rows @ v,
            "damper_force_n": self.out[n, :ns].copy(),
            "coil_current_a": currents.copy(),
            "current_command_a": self.command[n].copy(),
            "comfort_acceleration_m_s2": self.comfort_rows @ acc,
            "slot_end_acceleration_m_s2": self.end_rows @ acc,
            "guideway_elevation_m": self.out[n, ns + nc :].copy(),
        }

    def reward(self, sig: dict[str, np.ndarray]) -> tuple[float, bool, dict[str, float]]:
        cfg = self.config
        acc = sig["comfort_acceleration_m_s2"] / cfg.acceleration_scale_m_s2
        stroke = sig["stroke_m"] / cfg.stroke_scale_m
        current = sig["coil_current_a"] / self.i_max if self.i_max > 0.0 else 0.0 * stroke
        costs = {
            "cost_acceleration": cfg.reward_acceleration_weight * float(np.mean(acc * acc)),
            "cost_stroke": cfg.reward_stroke_weight * float(np.mean(stroke * stroke)),
            "cost_energy": cfg.reward_energy_weight * float(np.mean(current * current)),
        }
        hit = bool(np.any(np.abs(sig["stroke_m"]) > cfg.stroke_limit_m))
        reward = -(costs["cost_acceleration"] + costs["cost_stroke"] + costs["cost_energy"])
        return reward - (cfg.bump_stop_penalty if hit else 0.0), hit, costs

    def observation_names(self) -> tuple[str, ...]:
        m = self.model
        slots = [d.name for d in m.dampers]
        if self.config.observation == "sensors":
            return tuple(f"{s}_{part}" for s in slots for part in (
                "stroke_m", "stroke_rate_m_s", "upper_acceleration_m_s2",
                "lower_acceleration_m_s2"))  # fmt: skip
        return (*m.state_names, *(f"{s}_stroke_m" for s in slots),
                *(f"{s}_stroke_rate_m_s" for s in slots),
                *(f"{p}_acceleration_m_s2" for p in m.comfort_points),
                *(f"{c.name}_elevation_m" for c in m.contacts))  # fmt: skip

    def observe(self, n: int, sig: dict[str, np.ndarray]) -> np.ndarray:
        if self.config.observation == "sensors":
            ends = sig["slot_end_acceleration_m_s2"].reshape(self.n_slots, 2)
            cols = np.column_stack([sig["stroke_m"], sig["stroke_rate_m_s"], ends])
            return cols.reshape(-1).astype(np.float32)
        q, v = self.positions_rates(n)
        qv = np.column_stack([q, v]).reshape(-1)
        return np.concatenate([qv, sig["stroke_m"], sig["stroke_rate_m_s"],
                               sig["comfort_acceleration_m_s2"],
                               sig["guideway_elevation_m"]]).astype(np.float32)  # fmt: skip


def _bank(cfg: EnvConfig) -> np.ndarray:
    """The guideway bank: ``CapsuleBatch``'s (the same seeds, lengths and spectra)."""
    gw = cfg.guideway_spec
    if gw.kind == "random":
        seeds = np.random.SeedSequence(cfg.guideway_seed).generate_state(cfg.guideway_bank_size)
        bank = [random_profile(4.0 * cfg.window_m, gw.spacing_m, int(s), peak_m=None,
                               min_wavelength_m=gw.min_wavelength_m,
                               max_wavelength_m=gw.max_wavelength_m, psd=gw.psd)
                for s in seeds]  # fmt: skip
        return np.ascontiguousarray(np.stack(bank))
    profile = make_profile(gw, cfg.window_m / cfg.speed_m_s, extend_m=0.0)
    return np.ascontiguousarray(profile[None, :])


def inverse_is_algebraic(name: str) -> bool:
    """Whether the inverse model ``name`` inverts in closed form (force mode needs it here)."""
    return model_of_code(INVERSE_CODES[name]).affine is not None
