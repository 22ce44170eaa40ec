"""Environment speed, side by side with Gymnasium's own envs, in one run.

    python benchmarks/bench_env.py                 # prints the table
    python benchmarks/bench_env.py --json out.json # and writes it as JSON
    python benchmarks/bench_env.py --quick         # fewer steps (smoke test)
    python benchmarks/bench_env.py --cold-demo     # also the README demo with an empty cache
    python benchmarks/bench_env.py --substep-ceiling  # also the vector env, substeps forced

Measures (pre-sampled actions, the same machine, the same process):
1. single env through ``gymnasium.make`` vs Pendulum-v1 and CartPole-v1 (steps/s, ratio);
2. native vector env at N = 1, 64, 1024, 4096 vs CartPole's native vector env, in ``sim``
   and ``hils`` (env-steps/s, ratio);
3. the SB3 VecEnv alone (N = 64, 1024);
4. real-time factor (simulated seconds per wall second) of one vehicle, ``sim`` and ``hils``;
5. memory per vehicle in the vector env, import time, first-step (numba compile/cache load) time;
6. long windows (the figures the targets are judged on): the native vector env at N = 1024 in
   ``sim`` and ``hils`` vs CartPole's native vector env, and the single env vs Pendulum-v1;
   windows of 1500 steps (the single env: 10 x 1500), ours and the reference alternating,
   3 repeats: the median rate of each and their ratio (short best-of-3 windows flatter a
   threaded kernel on a shared machine);
7. with ``--substep-ceiling``: what the integrator costs. The native vector env at N = 1024 in
   ``sim`` and ``hils`` with the automatic substeps and with the substeps forced to 1 and 2
   (accuracy ignored: RK4 at 2 substeps misses the force bound by far in ``hils``), long
   windows interleaved with CartPole's, and the mean substeps each configuration took per
   vehicle-step (counted in a separate, untimed pass by the kernel's rule: the table bin of the
   interval's highest current). Forcing 2 substeps gives what an integrator of the stiff damper
   that kept the accuracy bound at 2 substeps could reach at RK4's cost (docs/model.md 7.4);
8. cold start: a fresh interpreter with ``NUMBA_CACHE_DIR`` an empty folder, ``import
   capsule_env`` + ``gym.make("CapsuleSuspension-v0")`` + reset + first step (wall and CPU
   seconds: compiling is single-threaded, so the CPU time is what an idle machine's wall time
   would be); with ``--cold-demo`` also ``python evaluate.py`` (the README demo) the same way.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path

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
    from capsule_env.envs.sb3 import CapsuleSuspensionSB3VecEnv

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


def _children_cpu_s() -> float:
    """User + system CPU seconds of this process's finished children so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _run_cold(argv: list[str], cwd: Path | None = None) -> tuple[subprocess.CompletedProcess, dict]:
    """Run ``argv`` with ``NUMBA_CACHE_DIR`` an empty temporary folder (removed after): the
    completed process, and its wall and CPU (user + system) seconds."""
    with tempfile.TemporaryDirectory(prefix="numba-cold-") as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        cpu0, t0 = _children_cpu_s(), time.perf_counter()
        out = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True)
        wall, cpu = time.perf_counter() - t0, _children_cpu_s() - cpu0
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(argv)} failed:\n{out.stderr[-3000:]}")
    return out, {"process_wall_s": wall, "process_cpu_s": cpu}


#: The cold first step, timed inside the fresh interpreter: each phase's wall and CPU seconds.
_COLD_CODE = """
import json, sys, time
def now():
    return time.perf_counter(), time.process_time()
marks = {"start": now()}
import capsule_env
marks["import"] = now()
import gymnasium as gym
import numpy as np
env = gym.make("CapsuleSuspension-v0", **json.loads(sys.argv[1]))
marks["make"] = now()
env.reset(seed=0)
marks["reset"] = now()
env.step(np.zeros(1, dtype=np.float32))
marks["first_step"] = now()
names = list(marks)
out = {}
for a, b in zip(names, names[1:]):
    out[b + "_wall_s"] = marks[b][0] - marks[a][0]
    out[b + "_cpu_s"] = marks[b][1] - marks[a][1]
out["total_wall_s"] = marks[names[-1]][0] - marks["start"][0]
out["total_cpu_s"] = marks[names[-1]][1] - marks["start"][1]
print(json.dumps(out))
"""


def cold_first_step(**kwargs) -> dict[str, float]:
    """Empty numba cache, fresh interpreter: ``import capsule_env`` + ``gym.make`` (with
    ``kwargs``) + reset + first step; wall and CPU seconds of each phase, of the four together
    (``total_*``) and of the whole process (``process_*``: interpreter start-up and exit too)."""
    load = os.getloadavg()[0]
    out, process = _run_cold([sys.executable, "-c", _COLD_CODE, json.dumps(kwargs)])
    return {**json.loads(out.stdout.strip().splitlines()[-1]), **process, "load_before": load}


def cold_demo(root: Path | None = None) -> dict[str, float]:
    """Empty numba cache: ``python evaluate.py`` of the checkout ``root`` (default this one; the
    README demo: both settings, every default controller, the shipped policy), wall and CPU
    seconds of the process, and the load average before it (the machine is shared)."""
    root = Path(__file__).resolve().parents[1] if root is None else Path(root)
    load = os.getloadavg()[0]
    _, process = _run_cold([sys.executable, "evaluate.py"], cwd=root)
    return {**process, "load_before": load}


def interleaved(runs: dict[str, Callable[[], float]], repeats: int) -> dict[str, list[float]]:
    """``runs``: name -> a function timing one window (items per second). Each repeat runs
    every window once, in turn (ours and the reference alternate: a slow spell of the shared
    machine hits both); returns each name's rates."""
    rates: dict[str, list[float]] = {name: [] for name in runs}
    for _ in range(repeats):
        for name, window in runs.items():
            rates[name].append(window())
    return rates


def _window(step, n_steps: int, batch: int):
    def run() -> float:
        t0 = time.perf_counter()
        for k in range(n_steps):
            step(k)
        return n_steps * batch / (time.perf_counter() - t0)

    return run


def _vector_stepper(env_id: str, num_envs: int, **kwargs):
    import gymnasium as gym

    env = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)
    env.reset(seed=0)
    env.action_space.seed(0)
    actions = [env.action_space.sample() for _ in range(200)]
    for k in range(20):  # compiled (or loaded), threads started, caches warm
        env.step(actions[k])

    def step(k):
        env.step(actions[k % 200])

    step.env, step.actions = env, actions
    return step


def _single_stepper(env_id: str, **kwargs):
    import gymnasium as gym

    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    space = env.action_space
    space.seed(0)
    actions = [space.sample() for _ in range(1000)]

    def step(k):
        _, _, terminated, truncated, _ = env.step(actions[k % 1000])
        if terminated or truncated:
            env.reset()

    for k in range(50):
        step(k)
    return step


def long_windows(window_steps: int = 1500, repeats: int = 3, num_envs: int = 1024) -> dict:
    """The long-window comparison (module docstring, item 6): per comparison, each side's
    window rates, their medians and ``ratio = median(ours) / median(reference)``; the load
    average before and after (the machine is shared)."""
    res: dict = {"window_steps": window_steps, "repeats": repeats, "num_envs": num_envs,
                 "load_before": list(os.getloadavg())}  # fmt: skip
    cart = _vector_stepper("CartPole-v1", num_envs)
    for setting in ("sim", "hils"):
        ours = _vector_stepper("CapsuleSuspension-v0", num_envs, setting=setting)
        rates = interleaved(
            {"capsule": _window(ours, window_steps, num_envs),
             "CartPole-v1": _window(cart, window_steps, num_envs)}, repeats,
        )  # fmt: skip
        res[f"vector-{setting}/N={num_envs}"] = _compare(rates, "capsule", "CartPole-v1")
    single_steps = 10 * window_steps  # one step is ~10 us: 1500 would be a 15 ms window
    pend = _single_stepper("Pendulum-v1")
    for setting in ("sim", "hils"):
        ours = _single_stepper("CapsuleSuspension-v0", setting=setting)
        rates = interleaved(
            {"capsule": _window(ours, single_steps, 1),
             "Pendulum-v1": _window(pend, single_steps, 1)}, repeats,
        )  # fmt: skip
        res[f"single-{setting}"] = _compare(rates, "capsule", "Pendulum-v1")
    res["load_after"] = list(os.getloadavg())
    return res


def mean_substeps(env, actions: list, steps: int = 200) -> float:
    """Mean RK4 substeps per vehicle-step of a native vector env over ``steps`` further steps:
    each vehicle's substep-table bin of the highest current its interval can see (the command,
    and with coil lag the current at the start; ``plant/block.py``)."""
    from capsule_env.engine.layout import COIL_CURRENT, COIL_TAU, I_MAX

    batch = env.unwrapped.batch
    i_max, tau = batch.damper_params[:, I_MAX], batch.damper_params[:, COIL_TAU]
    bins = batch.sub_table.shape[1]
    rows = np.arange(len(i_max))
    total = 0
    for k in range(steps):
        i_start = batch.state[:, COIL_CURRENT].copy()
        env.step(actions[k % len(actions)])
        command = np.clip(batch.applied_current, 0.0, i_max)
        i_high = np.where(tau > 0.0, np.maximum(command, i_start), command)
        b = np.clip((i_high / np.where(i_max > 0.0, i_max, 1.0) * bins).astype(int), 0, bins - 1)
        total += int(batch.sub_table[rows, b].sum())
    return total / (steps * len(rows))


def substep_ceiling(window_steps: int = 1500, repeats: int = 3, num_envs: int = 1024) -> dict:
    """Item 7 of the module docstring: each configuration's window rates, median and ratio to
    CartPole's median, all windows of one repeat run in turn."""
    runs = {
        "CartPole-v1": _window(_vector_stepper("CartPole-v1", num_envs), window_steps, num_envs)
    }
    substeps_taken = {}
    for setting in ("sim", "hils"):
        for substeps in ("auto", 1, 2):
            name = f"{setting}/substeps={substeps}"
            kwargs = {"setting": setting} | ({} if substeps == "auto" else {"substeps": substeps})
            stepper = _vector_stepper("CapsuleSuspension-v0", num_envs, **kwargs)
            runs[name] = _window(stepper, window_steps, num_envs)
            env, actions = stepper.env, stepper.actions
            substeps_taken[name] = mean_substeps(env, actions)
    res: dict = {"window_steps": window_steps, "repeats": repeats, "num_envs": num_envs,
                 "load_before": list(os.getloadavg())}  # fmt: skip
    rates = interleaved(runs, repeats)
    cart = statistics.median(rates["CartPole-v1"])
    res["runs"] = {name: {"rates": r, "median": statistics.median(r),
                          "ratio": statistics.median(r) / cart} for name, r in rates.items()}  # fmt: skip
    for name, mean in substeps_taken.items():
        res["runs"][name]["mean_substeps"] = mean
    res["load_after"] = list(os.getloadavg())
    return res


def _compare(rates: dict[str, list[float]], ours: str, ref: str) -> dict:
    med = {name: statistics.median(r) for name, r in rates.items()}
    return {"rates": rates, "median": med, "reference": ref, "ratio": med[ours] / med[ref]}


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


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line; an unwritable ``--json`` path is refused now, not after minutes of
    measuring (one line, exit status 2)."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    parser.add_argument("--json", help="also write the results to this JSON file")
    parser.add_argument(
        "--quick", action="store_true", help="few steps: a smoke test (no cold start unless --cold)"
    )
    parser.add_argument(
        "--cold", action="store_true", help="with --quick: measure the cold first step all the same"
    )
    parser.add_argument(
        "--cold-demo",
        action="store_true",
        help="also time `python evaluate.py` with an empty numba cache (minutes)",
    )
    parser.add_argument(
        "--substep-ceiling",
        action="store_true",
        help="also the vector env at N=1024 with the substeps forced to 1 and 2 (minutes)",
    )
    args = parser.parse_args(argv)
    if args.json is not None:
        from capsule_env.common.safe_io import check_writable_file

        try:
            check_writable_file(args.json, "--json")
        except ValueError as exc:
            parser.exit(2, f"bench_env.py: {exc}\n")
    return args


def measure_speeds(scale: float) -> dict:
    """Single env, native vector env, SB3 VecEnv, real-time factor and memory, ``scale`` times
    the full number of steps."""
    n_single = max(200, int(20_000 * scale))
    res: dict = {"single": {}, "vector": {}, "sb3": {}, "realtime": {}}
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
    return res


def measure(args: argparse.Namespace) -> dict:
    """Every measurement the options ask for, as the ``--json`` file holds them."""
    scale = 0.05 if args.quick else 1.0
    import capsule_env  # noqa: F401  (registers the env)

    res: dict = {"machine": machine(), "date": time.strftime("%Y-%m-%d")}
    res["startup"] = import_and_first_step()
    res.update(measure_speeds(scale))
    res["long_window"] = long_windows(max(20, int(1500 * scale)), num_envs=1024)
    res["substep_ceiling"] = None
    if args.substep_ceiling:
        res["substep_ceiling"] = substep_ceiling(max(20, int(1500 * scale)))
    res["cold_start"] = None
    if not args.quick or args.cold:  # the default env (sim), then hils (the other kernels)
        res["cold_start"] = {s: cold_first_step(setting=s) for s in ("sim", "hils")}
    res["cold_demo"] = cold_demo() if args.cold_demo else None
    return res


def print_speeds(res: dict) -> None:
    """The start-up, single env, vector env, SB3, real-time and memory lines."""
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


def print_windows(res: dict) -> None:
    """The long windows and, if measured, the substep ceiling."""
    lw = res["long_window"]
    print(f"\nlong windows ({lw['window_steps']} steps, the single env {10 * lw['window_steps']}; "
          f"median of {lw['repeats']} interleaved repeats; load {lw['load_before'][0]:.1f} -> "
          f"{lw['load_after'][0]:.1f})")  # fmt: skip
    for name, cmp in lw.items():
        if isinstance(cmp, dict) and "ratio" in cmp:
            ours, ref = cmp["median"]["capsule"], cmp["median"][cmp["reference"]]
            print(f"  {name:<18}{ours:>14,.0f} vs {cmp['reference']} {ref:>13,.0f}   "
                  f"x{cmp['ratio']:5.2f}")  # fmt: skip
    if res["substep_ceiling"] is not None:
        sc = res["substep_ceiling"]
        print(f"\nsubstep ceiling, N={sc['num_envs']} ({sc['window_steps']} steps, median of "
              f"{sc['repeats']} interleaved repeats; load {sc['load_before'][0]:.1f} -> "
              f"{sc['load_after'][0]:.1f})")  # fmt: skip
        for name, run in sc["runs"].items():
            taken = f"   {run['mean_substeps']:.2f} substeps" if "mean_substeps" in run else ""
            print(f"  {name:<20}{run['median']:>14,.0f}   x{run['ratio']:5.2f} CartPole-v1{taken}")


def print_cold(res: dict) -> None:
    """The empty-cache first step and demo, where measured."""
    for setting, c in (res["cold_start"] or {}).items():
        print(f"\ncold start, {setting} (empty numba cache; import + make + reset + first step): "
              f"{c['total_wall_s']:.1f} s wall, {c['total_cpu_s']:.1f} s CPU (import "
              f"{c['import_cpu_s']:.1f} s, first step {c['first_step_cpu_s']:.1f} s CPU); whole "
              f"process {c['process_wall_s']:.1f} s wall, {c['process_cpu_s']:.1f} s CPU")  # fmt: skip
    if res["cold_demo"] is not None:
        c = res["cold_demo"]
        print(f"\ncold demo (empty numba cache): python evaluate.py {c['process_wall_s']:.1f} s "
              f"wall, {c['process_cpu_s']:.1f} s CPU")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    """Measure, print, and write ``--json`` (atomically) if asked."""
    args = parse_args(argv)
    res = measure(args)
    print_speeds(res)
    print_windows(res)
    print_cold(res)
    if args.json is not None:
        from capsule_env.common.safe_io import atomic_write_text

        atomic_write_text(args.json, json.dumps(res, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
