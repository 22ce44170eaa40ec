"""Environment speed, side by side with Gymnasium's own envs, in one run.

    python benchmarks/bench_env.py                 # prints the table
    python benchmarks/bench_env.py --json out.json # and writes it as JSON
    python benchmarks/bench_env.py --quick         # fewer steps (smoke test)

Measures (pre-sampled actions, the same machine, the same process):
1. single env through ``gymnasium.make`` vs Pendulum-v1 and CartPole-v1 (steps/s, ratio);
2. native vector env at N = 1, 64, 1024, 4096 vs CartPole's native vector env, in ``sim``
   and ``hils`` (env-steps/s, ratio);
3. the SB3 VecEnv alone (N = 64, 1024);
4. real-time factor (simulated seconds per wall second) of one vehicle, ``sim`` and ``hils``;
5. memory per vehicle in the vector env, import time, first-step (numba compile/cache load) time.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
import tracemalloc

import numpy as np


def _rate(step, n_steps: int, batch: int = 1, repeats: int = 3) -> float:
    """Best of ``repeats`` timings of ``n_steps`` calls of ``step(k)``: items per second."""
    best = 0.0
    for _ in range(repeats):
        t0 = time.perf_counter()
        for k in range(n_steps):
            step(k)
        best = max(best, n_steps * batch / (time.perf_counter() - t0))
    return best


def single_env(env_id: str, n_steps: int, **kwargs) -> float:
    import gymnasium as gym

    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    space = env.action_space
    space.seed(0)
    actions = [space.sample() for _ in range(n_steps)]
    for k in range(50):
        _, _, terminated, truncated, _ = env.step(actions[k])
        if terminated or truncated:
            env.reset()

    def step(k):
        _, _, terminated, truncated, _ = env.step(actions[k])
        if terminated or truncated:
            env.reset()

    return _rate(step, n_steps)


def vector_env(env_id: str, num_envs: int, n_steps: int, **kwargs) -> float:
    import gymnasium as gym

    env = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)
    env.reset(seed=0)
    env.action_space.seed(0)
    actions = [env.action_space.sample() for _ in range(min(n_steps, 200))]
    env.step(actions[0])
    return _rate(lambda k: env.step(actions[k % len(actions)]), n_steps, batch=num_envs)


def sb3_vec_env(num_envs: int, n_steps: int, **kwargs) -> float:
    from capsule_env.sb3 import CapsuleSuspensionSB3VecEnv

    env = CapsuleSuspensionSB3VecEnv(num_envs, **kwargs)
    env.seed(0)
    env.reset()
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (200, num_envs, 1)).astype(np.float32)
    env.step(actions[0])
    return _rate(lambda k: env.step(actions[k % 200]), n_steps, batch=num_envs)


def memory_per_env(num_envs: int, **kwargs) -> float:
    """Bytes allocated by numpy for a vector env of ``num_envs`` vehicles, per vehicle
    (guideway bank excluded: it is shared, see ``bank_bytes``)."""
    from capsule_env.envs import CapsuleSuspensionVectorEnv

    tracemalloc.start()
    env = CapsuleSuspensionVectorEnv(num_envs=num_envs, **kwargs)
    env.reset(seed=0)
    env.step(np.zeros((num_envs, 1)))
    current, _ = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    bank = env.batch.profiles.nbytes
    return (current - bank) / num_envs, bank


def import_and_first_step() -> dict[str, float]:
    """Fresh interpreters: import time of ``capsule_env`` and the first reset+step (numba
    compile, or loading the cache) of the single env."""
    code = (
        "import time; t0 = time.perf_counter(); import capsule_env; t1 = time.perf_counter();"
        "import gymnasium as gym; env = gym.make('CapsuleSuspension-v0', setting='hils');"
        "env.reset(seed=0); env.step(env.action_space.sample()); t2 = time.perf_counter();"
        "print(t1 - t0, t2 - t1)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    imp, first = (float(x) for x in out.stdout.split())
    return {"import_s": imp, "first_step_s": first}


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    parser.add_argument("--json", help="also write the results to this JSON file")
    parser.add_argument("--quick", action="store_true", help="few steps: a smoke test")
    args = parser.parse_args(argv)
    scale = 0.05 if args.quick else 1.0
    n_single = max(200, int(20_000 * scale))
    import capsule_env  # noqa: F401  (registers the env)

    res: dict = {"machine": machine(), "date": time.strftime("%Y-%m-%d"), "single": {},
                 "vector": {}, "sb3": {}, "realtime": {}}  # fmt: skip
    res["startup"] = import_and_first_step()
    res["single"]["Pendulum-v1"] = single_env("Pendulum-v1", n_single)
    res["single"]["CartPole-v1"] = single_env("CartPole-v1", n_single)
    for setting in ("sim", "hils"):
        res["single"][f"capsule-{setting}"] = single_env(
            "CapsuleSuspension-v0", n_single, setting=setting
        )
    for n in (1, 64, 1024, 4096):
        steps = max(20, int(scale * min(20_000, 2_000_000 // n)))
        res["vector"][f"CartPole-v1/N={n}"] = vector_env("CartPole-v1", n, steps)
        for setting in ("sim", "hils"):
            res["vector"][f"capsule-{setting}/N={n}"] = vector_env(
                "CapsuleSuspension-v0", n, steps, setting=setting
            )
    for n in (64, 1024):
        steps = max(20, int(scale * 200_000 // n))
        for setting in ("sim", "hils"):
            res["sb3"][f"capsule-{setting}/N={n}"] = sb3_vec_env(n, steps, setting=setting)
    dt = 1.0 / 200.0
    for setting in ("sim", "hils"):
        res["realtime"][setting] = res["single"][f"capsule-{setting}"] * dt
    per_env, bank = memory_per_env(1024, setting="hils")
    res["memory"] = {"bytes_per_env": per_env, "guideway_bank_bytes": bank}

    print(f"machine: {res['machine']}  date: {res['date']}")
    print(f"import capsule_env: {res['startup']['import_s']:.2f} s; first reset+step "
          f"(compile or cache load): {res['startup']['first_step_s']:.2f} s")  # fmt: skip
    print("\nsingle env through gymnasium.make (steps/s)")
    pend = res["single"]["Pendulum-v1"]
    for name, rate in res["single"].items():
        print(f"  {name:<22}{rate:>14,.0f}   x{rate / pend:5.2f} Pendulum-v1")
    print("\nnative vector env (env-steps/s)")
    for n in (1, 64, 1024, 4096):
        cart = res["vector"][f"CartPole-v1/N={n}"]
        line = f"  N={n:<6} CartPole {cart:>14,.0f}"
        for setting in ("sim", "hils"):
            rate = res["vector"][f"capsule-{setting}/N={n}"]
            line += f" | {setting} {rate:>13,.0f} (x{rate / cart:4.2f})"
        print(line)
    print("\nSB3 VecEnv (env-steps/s)")
    for name, rate in res["sb3"].items():
        print(f"  {name:<22}{rate:>14,.0f}")
    print("\nreal-time factor of one vehicle (simulated s per wall s)")
    for setting, rtf in res["realtime"].items():
        print(f"  {setting:<6}{rtf:10.0f}")
    print(f"\nmemory: {res['memory']['bytes_per_env'] / 1024:.1f} KiB per vehicle "
          f"(+ shared guideway bank {res['memory']['guideway_bank_bytes'] / 2**20:.1f} MiB)")  # fmt: skip
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(res, fh, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
