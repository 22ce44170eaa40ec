"""Golden trajectories: save today's, compare a later checkout's, bit for bit.

A refactoring of the kernels (issue 26) promises that no trajectory moves. This script runs a
fixed set of cases through every public path (the plant open loop for each damper model, the
single env, the native vector env with autoreset, the SB3 VecEnv) and stores every array it
sees; ``--compare`` runs the same cases and reports, per array, whether it is bit-identical
(``np.array_equal``, NaN equal to NaN) and otherwise the largest absolute difference.

Bit-identity is a promise about our kernels on one machine (same CPU, same numba); compare on
the machine that saved the baseline. Keys present on one side only are listed, not failures
(a new info signal is allowed; a missing one is reported).

Usage::

    python benchmarks/golden.py --save /tmp/golden_base      # on the baseline checkout
    python benchmarks/golden.py --compare /tmp/golden_base   # on the changed checkout

Exit status 0 when every shared array is identical and none is missing, 1 otherwise.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

CASES_ENV = {
    "sim_default": {},
    "sim_current": {"action_mode": "current"},
    "sim_csdc": {"inverse_model": "csdc"},
    "sim_tanh_full": {"inverse_model": "tanh", "observation": "full_state"},
    "hils_measured": {"setting": "hils", "observation": "measured"},
    "hils_preview": {"setting": "hils", "observation": "measured", "preview_points": 8},
    "hils_wk_random": {
        "setting": "hils",
        "reward_acceleration_filter": "wk",
        "vehicle_randomization": 0.1,
        "speed_range_kmh": (500.0, 1000.0),
        "observation": "full_state",
    },
    "sim_sine": {"guideway": "sine", "episode_length_s": 1.0},
}


def plant_cases() -> dict[str, np.ndarray]:
    """Open-loop plant runs, one per damper model, under a varying current."""
    from capsule_env import DAMPER_NAMES, make_damper, random_profile
    from capsule_env.engine.simulate import simulate

    out = {}
    rng = np.random.default_rng(7)
    spacing = 0.25
    profile = random_profile(600.0, spacing, seed=3)
    commands = rng.uniform(0.0, 1.6, size=400)
    for name in DAMPER_NAMES:
        run = simulate(make_damper(name), profile, spacing, 225.0, commands, 2.0)
        for key, values in run.items():
            out[f"plant/{name}/{key}"] = values
    return out


def _record(out: dict, prefix: str, step: int, obs, reward, term, trunc, info) -> None:
    out.setdefault(f"{prefix}/obs", []).append(np.asarray(obs, float))
    out.setdefault(f"{prefix}/reward", []).append(np.asarray(reward, float))
    out.setdefault(f"{prefix}/done", []).append(np.asarray(term, float) + 2 * np.asarray(trunc))
    for key, value in sorted(info.items()):
        if key.startswith("_") or isinstance(value, dict):
            continue
        arr = np.asarray(value)
        if arr.dtype.kind in "fiub":
            out.setdefault(f"{prefix}/info/{key}", []).append(arr.astype(float))


def env_cases() -> dict[str, np.ndarray]:
    """The single env and the native vector env (autoreset) on every case, random actions."""
    import gymnasium as gym

    import capsule_env  # noqa: F401

    out: dict = {}
    for case, kwargs in CASES_ENV.items():
        env = gym.make("CapsuleSuspension-v0", **kwargs)
        obs, _ = env.reset(seed=11)
        env.action_space.seed(5)
        out.setdefault(f"single/{case}/obs", []).append(np.asarray(obs, float))
        for step in range(260):
            obs, r, te, tr, info = env.step(env.action_space.sample())
            _record(out, f"single/{case}", step, obs, r, te, tr, info)
            if te or tr:
                obs, _ = env.reset()
        env.close()
        for n in (3, 300):
            venv = gym.make_vec("CapsuleSuspension-v0", num_envs=n,
                                vectorization_mode="vector_entry_point", **kwargs)  # fmt: skip
            obs, _ = venv.reset(seed=23)
            venv.action_space.seed(9)
            for step in range(40 if n > 10 else 230):
                obs, r, te, tr, info = venv.step(venv.action_space.sample())
                _record(out, f"vector{n}/{case}", step, obs, r, te, tr, info)
            venv.close()
    return {k: np.stack(v) for k, v in out.items()}


def sb3_cases() -> dict[str, np.ndarray]:
    """The SB3 VecEnv over the compiled kernel (skipped without stable-baselines3)."""
    try:
        from capsule_env.envs.sb3 import CapsuleSuspensionSB3VecEnv
    except ImportError:
        return {}
    out: dict = {}
    venv = CapsuleSuspensionSB3VecEnv(num_envs=4, setting="hils", observation="measured")
    venv.seed(4)
    obs = venv.reset()
    rng = np.random.default_rng(2)
    for _ in range(230):
        obs, r, d, _infos = venv.step(rng.uniform(-1, 1, size=(4, 1)).astype(np.float32))
        out.setdefault("sb3/obs", []).append(np.asarray(obs, float))
        out.setdefault("sb3/reward", []).append(np.asarray(r, float))
        out.setdefault("sb3/done", []).append(np.asarray(d, float))
    return {k: np.stack(v) for k, v in out.items()}


def run_all() -> dict[str, np.ndarray]:
    return {**plant_cases(), **env_cases(), **sb3_cases()}


def compare(base: dict[str, np.ndarray], new: dict[str, np.ndarray]) -> int:
    bad = 0
    for key in sorted(base):
        if key not in new:
            print(f"MISSING  {key}")
            bad += 1
            continue
        a, b = base[key], new[key]
        if a.shape == b.shape and np.array_equal(a, b, equal_nan=True):
            continue
        diff = np.nanmax(np.abs(a - b)) if a.shape == b.shape else float("nan")
        print(f"DIFFERS  {key}  shape {a.shape} vs {b.shape}  max |diff| {diff:.3g}")
        bad += 1
    for key in sorted(set(new) - set(base)):
        print(f"new      {key}")
    same = sum(1 for k in base if k in new and np.array_equal(base[k], new[k], equal_nan=True))
    print(f"{same}/{len(base)} arrays bit-identical, {bad} differ or missing")
    return 1 if bad else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--save", type=Path, help="folder to write the baseline into")
    group.add_argument("--compare", type=Path, help="baseline folder to compare against")
    args = parser.parse_args(argv)
    results = run_all()
    if args.save:
        args.save.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(args.save / "golden.npz", **results)
        print(f"saved {len(results)} arrays to {args.save / 'golden.npz'}")
        return 0
    path = args.compare / "golden.npz"
    if not path.is_file():
        print(f"golden.py: error: --compare: no baseline at {path}", file=sys.stderr)
        return 2
    with np.load(path) as base:
        return compare(dict(base), results)


if __name__ == "__main__":
    sys.exit(main())
