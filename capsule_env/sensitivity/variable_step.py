"""Closed-loop episodes of the paper's on-off Skyhook pairs on the variable-step plant.

The env's episodes (guideway bank, seeds, routes) are reused as they are: an env is built and
reset with the same seeds, and each vehicle's route (profile, start, speed, gain) and start
state are read from it; then every control step the controller reads the true states (the
``full_state`` set, as ``sim`` gives it), turns its force request into a current through the
inverse, and :class:`~capsule_env.plant.reference_solver.VariableStepPlant` advances the plant
with that current held. The result is a :class:`~capsule_env.evaluation.episodes.Rollout`, so that
:func:`~capsule_env.evaluation.episodes.episode_metrics` scores it like an env rollout.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from capsule_env.dampers import BiExponentialDamper, BoucWenDamper, LinearDamper
from capsule_env.dampers.inverse import bi_exponential_inverse
from capsule_env.engine.layout import BODY_DISP
from capsule_env.envs.capsule_suspension import CapsuleSuspensionVectorEnv
from capsule_env.evaluation.episodes import EVALUATION_GUIDEWAY_SEED, Rollout
from capsule_env.plant.reference_solver import VariableStepPlant
from capsule_env.sensitivity.csdc_variants import CSDCVariant

__all__ = ["variable_step_rollout"]

SIGNALS = ("car_body_displacement_m", "bogie_displacement_m", "car_body_acceleration_m_s2",
           "stroke_m", "coil_current_a", "damper_force_n", "desired_force_n")  # fmt: skip


def _routes(env_kwargs: dict[str, Any], seeds: Sequence[int], episode_length_s: float) -> dict:
    """The env's routes and start elevations for ``seeds`` (as run_episodes would make them)."""
    kwargs = {"guideway_seed": EVALUATION_GUIDEWAY_SEED, **env_kwargs}
    env = CapsuleSuspensionVectorEnv(num_envs=len(seeds), episode_length_s=episode_length_s,
                                     **kwargs)  # fmt: skip
    env.reset(seed=[int(s) for s in seeds])
    b = env.batch
    out = {"profiles": b.profiles[b.profile_index].copy(), "start_m": b.start_position.copy(),
           "speed_mps": b.speed.copy(), "gain": b.gain.copy(), "zg0": b.state[:, BODY_DISP].copy(),
           "spacing_m": float(b.spacing), "dt_s": float(b.dt), "steps": int(b.max_steps),
           "vehicle": env.config.vehicle_parameters}  # fmt: skip
    env.close()
    return out


def variable_step_rollout(
    pair: str,
    damper: BoucWenDamper | BiExponentialDamper | LinearDamper,
    seeds: Sequence[int],
    episode_length_s: float = 10.0,
    c_max: float = 7.0e4,
    max_force_n: float = 8000.0,
    method: str = "RK45",
    rtol: float = 1e-3,
    env_kwargs: dict[str, Any] | None = None,
) -> Rollout:
    """One pair's episodes on :class:`VariableStepPlant` (the plant is ``damper``).

    ``pair``: ``"passive"`` (``damper`` a LinearDamper, no control), ``"biexp"`` (on-off
    Skyhook through the closed-form Bi-exponential inverse of ``damper``) or ``"csdc"`` (through
    the exact-observer continuous CSDC of ``damper``). ``env_kwargs`` choose the guideway as the
    env's do (``sim`` setting). Returns the recorded signals as a :class:`Rollout`."""
    if pair not in ("passive", "biexp", "csdc"):
        raise ValueError(f"pair must be 'passive', 'biexp' or 'csdc', got {pair!r}")
    r = _routes({"setting": "sim", **(env_kwargs or {})}, seeds, episode_length_s)
    n, steps, dt = len(seeds), r["steps"], r["dt_s"]
    record = {name: np.zeros((n, steps)) for name in SIGNALS}
    for k in range(n):
        plant = VariableStepPlant(damper, r["profiles"][k], r["spacing_m"], r["speed_mps"][k],
                                  r["start_m"][k], r["gain"][k], r["vehicle"], method, rtol)  # fmt: skip
        plant.state[0] = plant.state[2] = r["zg0"][k]
        csdc = CSDCVariant(damper, 1, dt_s=dt) if pair == "csdc" else None
        if csdc is not None:
            csdc.reset(0.0)
        for t in range(steps):
            zc, vc, zb, vb, _, _, ic = plant.state
            x, v = np.array([zc - zb]), np.array([vc - vb])
            f_d = np.clip(np.where(vc * v > 0.0, c_max * v, 0.0), -max_force_n, max_force_n)
            if pair == "biexp":
                i_cmd = float(bi_exponential_inverse(damper, f_d, x, v)[0])
            elif pair == "csdc":
                i_cmd = float(csdc(f_d, x, v, np.array([ic]))[0])
            else:
                i_cmd, f_d = 0.0, np.zeros(1)
            plant.step(i_cmd, dt)
            force, acc_body, _, _ = plant.outputs(i_cmd)
            s = plant.state
            row = (s[0], s[2], acc_body, s[0] - s[2], s[6], force, float(f_d[0]))
            for name, value in zip(SIGNALS, row):
                record[name][k, t] = value
    return Rollout(record, dt, np.zeros(n, dtype=bool), "current")
