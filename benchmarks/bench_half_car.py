"""The half-car's speed beside the quarter-car's, in one run (issue 42's bar: the half-car vector
env with 1024 vehicles at >= 0.4x ``CapsuleRide-v0``'s vehicle-steps per second).

    python benchmarks/bench_half_car.py            # prints the table
    python benchmarks/bench_half_car.py --quick    # short windows (a smoke test)
    NUMBA_NUM_THREADS=1 python benchmarks/bench_half_car.py --repeats 5   # one core each

On a loaded machine the all-core figures measure the threads' wait at every step's barrier,
not the kernels (every row of one run near 0.05-0.1 M vehicle-steps/s on the shared 2-core VM
at load 9): compare kernels there with ``NUMBA_NUM_THREADS=1``.

Measures, alternating windows of each (``--repeats``, 3 by default; the median), zero actions:

1. ``CapsuleRide-v0`` and ``CapsuleHalfRide-v0`` native vector envs at N = 1024 (vehicle-steps
   per second, and their ratio);
2. ``CapsuleHalfRide-v0`` as it ran before the lanes kernel (the declared plant one vehicle at a
   time, :func:`capsule_env.plant.declared.declared_step`, and the sensing in numpy: kept below
   as :func:`_step_before`), the same numbers bit for bit (``tests/test_declared_lanes.py``);
3. each plant alone at N = 1024 (the run's threads), one vehicle at a time and in lanes
   (:mod:`capsule_env.plant.declared_lanes`): on the quarter-car's declaration (beside the
   first row: what the generic loops cost on the quarter-car's physics) and on the half-car;
4. with ``--kernel-from PATH`` (another version of ``declared_lanes.py``, e.g. ``git show
   a560d78:capsule_env/plant/declared_lanes.py > /tmp/lanes_a560d78.py``), the half-car env
   and its lanes plant with that file's kernel, in the same alternating windows;
5. with ``--step-from REV`` (a git revision of this repository, e.g. ``acacaf2``), the half-car
   env with that revision's ``declared_vector.py`` and ``declared_batch.py`` (the env's step
   outside the kernel as it was then; the package's kernel), in the same windows.

Row 2's env steps with :func:`_step_before`, then the package's reward and observations.
"""

from __future__ import annotations

import argparse
import importlib
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numba
import numpy as np

import capsule_env  # noqa: F401  (registers the tasks)
from capsule_env.engine import declared_batch
from capsule_env.engine.declared_batch import N_SLOT_CHANNELS, PARALLEL_THRESHOLD
from capsule_env.engine.declared_sensing import normals as _normals
from capsule_env.plant.declared import declared_step_parallel
from capsule_env.plant.declared_lanes import VECTOR_TANH, plant_form

ROOT = Path(__file__).resolve().parents[1]


def _env_rate(env: Any, steps: int) -> float:
    actions = np.zeros(env.action_space.shape, dtype=np.float32)
    start = time.perf_counter()
    for _ in range(steps):
        env.step(actions)
    return env.num_envs * steps / (time.perf_counter() - start)


def _plant_rate(batch: Any, steps: int, lanes: bool, module: Any = None) -> float:
    code = batch.damper.code
    lanes_mod = module or declared_batch
    step = lanes_mod.lanes_step_parallel(code, lanes_mod.plant_form(batch.plant)) if lanes else (
        declared_step_parallel(code))  # fmt: skip
    start = time.perf_counter()
    for _ in range(steps):
        step(batch.num_envs, batch.plant, batch.state, batch.command, batch.route, batch.dt,
             batch.out)  # fmt: skip
    return batch.num_envs * steps / (time.perf_counter() - start)


def _median_windows(funcs: dict[str, Any], repeats: int) -> dict[str, float]:
    rates: dict[str, list[float]] = {name: [] for name in funcs}
    for _ in range(repeats):
        for name, f in funcs.items():  # alternating: the same machine state for each
            rates[name].append(f())
    return {name: statistics.median(r) for name, r in rates.items()}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help="short windows")
    p.add_argument("--num-envs", type=int, default=1024)
    p.add_argument("--repeats", type=int, default=3, help="alternating windows (the median)")
    p.add_argument("--kernel-from", metavar="PATH", help="another declared_lanes.py to time beside")
    p.add_argument(
        "--step-from", metavar="REV", help="a git revision whose env step to time beside"
    )
    args = p.parse_args()
    if args.num_envs < 1 or args.repeats < 1:  # a traceback from the env, or no window timed
        raise SystemExit(f"bench_half_car.py: error: --num-envs and --repeats must be >= 1, "
                         f"got {args.num_envs} and {args.repeats}")  # fmt: skip
    if args.kernel_from and not os.path.isfile(args.kernel_from):
        raise SystemExit(f"bench_half_car.py: error: --kernel-from: no file {args.kernel_from}")
    step_files = _step_files(args.step_from) if args.step_from else None
    n, steps = args.num_envs, (20 if args.quick else 300)
    if args.quick:
        args.repeats = 1
    ride = gym.make_vec("CapsuleRide-v0", num_envs=n, vectorization_mode="vector_entry_point")
    half = gym.make_vec("CapsuleHalfRide-v0", num_envs=n, vectorization_mode="vector_entry_point")
    for env in (ride, half):
        env.reset(seed=0)
        _env_rate(env, 3)  # compile
    before = gym.make_vec("CapsuleHalfRide-v0", num_envs=n,
                          vectorization_mode="vector_entry_point")  # fmt: skip
    batch_before = before.unwrapped.batch
    batch_before.step_scored = lambda actions: _scored(
        batch_before, _step_before(batch_before, actions)
    )
    before.reset(seed=0)
    _env_rate(before, 3)
    qd = _declared_batch(n)
    qd.reset()
    half_batch = half.unwrapped.batch
    for lanes in (False, True):
        _plant_rate(qd, 2, lanes), _plant_rate(half_batch, 2, lanes)
    funcs = {
        "CapsuleRide-v0 env": lambda: _env_rate(ride, steps),
        "CapsuleHalfRide-v0 env": lambda: _env_rate(half, steps // 2),
        "CapsuleHalfRide-v0 env, before": lambda: _env_rate(before, steps // 4),
        "declared plant, quarter_car": lambda: _plant_rate(qd, steps // 2, False),
        "lanes plant, quarter_car": lambda: _plant_rate(qd, steps, True),
        "declared plant, half_car": lambda: _plant_rate(half_batch, steps // 4, False),
        "lanes plant, half_car": lambda: _plant_rate(half_batch, steps // 2, True),
    }  # fmt: skip
    if args.kernel_from:
        funcs.update(_kernel_from(args.kernel_from, n, steps, half_batch))
    if step_files:
        funcs.update(_step_from(step_files, n, steps))
    rates = _median_windows(funcs, args.repeats)
    cpu = _cpu()
    print(f"{time.strftime('%Y-%m-%d %H:%M')}, {cpu}, {platform.python_version()}, N = {n}, "
          f"{numba.get_num_threads()} thread(s), load {os.getloadavg()[0]:.1f}")  # fmt: skip
    print(f"{'what':32s} {'vehicle-steps/s':>16s}")
    for name, rate in rates.items():
        print(f"{name:32s} {rate:16.4g}")
    ratio = rates["CapsuleHalfRide-v0 env"] / rates["CapsuleRide-v0 env"]
    gain = rates["CapsuleHalfRide-v0 env"] / rates["CapsuleHalfRide-v0 env, before"]
    print(f"half-car / ride: {ratio:.3f} (bar: >= 0.4); half-car now / before: {gain:.2f}")
    if args.kernel_from:
        env_file, plant_file = "CapsuleHalfRide-v0 env, file's", "lanes plant, half_car, file's"
        file_ratio = rates[env_file] / rates["CapsuleRide-v0 env"]
        env_gain = rates["CapsuleHalfRide-v0 env"] / rates[env_file]
        plant_gain = rates["lanes plant, half_car"] / rates[plant_file]
        print(f"with {args.kernel_from}'s kernel: half-car / ride {file_ratio:.3f}; now / it: "
              f"env {env_gain:.2f}, plant {plant_gain:.2f}")  # fmt: skip
    if step_files:
        rev_rate = rates["CapsuleHalfRide-v0 env, rev's"]
        print(f"with {args.step_from}'s step: half-car / ride "
              f"{rev_rate / rates['CapsuleRide-v0 env']:.3f}; now / it: env "
              f"{rates['CapsuleHalfRide-v0 env'] / rev_rate:.2f}")  # fmt: skip
    vector_tanh = plant_form(half_batch.plant) // VECTOR_TANH % 2 == 1
    print(f"the hysteretic update's tanh: {'glibc_tanh, vectorised' if vector_tanh else 'libm'}")


def _kernel_from(path: str, n: int, steps: int, half_batch: Any) -> dict[str, Any]:
    """The rows of ``--kernel-from``: the half-car env and lanes plant with ``path``'s kernel."""
    folder, name = os.path.split(os.path.abspath(path))
    sys.path.insert(0, folder)  # imported by name: numba's disk cache finds it again
    module = importlib.import_module(os.path.splitext(name)[0])
    env = gym.make_vec("CapsuleHalfRide-v0", num_envs=n, vectorization_mode="vector_entry_point")
    batch = env.unwrapped.batch
    batch._advance = lambda actions: _step_with(batch, actions, module)
    env.reset(seed=0)
    _env_rate(env, 3)
    _plant_rate(half_batch, 2, True, module)
    return {
        "CapsuleHalfRide-v0 env, file's": lambda: _env_rate(env, steps // 2),
        "lanes plant, half_car, file's": lambda: _plant_rate(half_batch, steps // 2, True, module),
    }


def _step_with(batch: Any, actions: np.ndarray, module: Any) -> None:
    """``DeclaredBatch._advance`` (the commands and the plant) with ``module``'s lanes kernel."""
    saved = declared_batch.lanes_step_parallel, declared_batch.plant_form
    declared_batch.lanes_step_parallel, declared_batch.plant_form = (
        module.lanes_step_parallel, module.plant_form)  # fmt: skip
    try:
        declared_batch.DeclaredBatch._advance(batch, actions)
    finally:
        declared_batch.lanes_step_parallel, declared_batch.plant_form = saved


def _scored(batch: Any, sig: dict[str, np.ndarray]) -> tuple:
    """``DeclaredBatch.step_scored``'s answer for the signals ``sig`` of a step."""
    reward, hit, costs = batch.reward(sig)
    return sig, reward, hit, costs, batch.observe(sig)


def _step_files(rev: str) -> Path:
    """``declared_vector.py`` and ``declared_batch.py`` at git revision ``rev``, written as
    modules of their own to a folder in the temporary directory (numba's disk cache keeps their
    compiled code between runs); its path."""
    tag = "".join(c if c.isalnum() else "_" for c in rev)
    folder = Path(tempfile.gettempdir()) / f"capsule_env_bench_step_{tag}"
    folder.mkdir(exist_ok=True)
    for path in ("capsule_env/envs/declared_vector.py", "capsule_env/engine/declared_batch.py"):
        shown = subprocess.run(["git", "show", f"{rev}:{path}"], cwd=ROOT, capture_output=True,
                               text=True, check=False)  # fmt: skip
        if shown.returncode != 0:
            raise SystemExit(f"bench_half_car.py: error: --step-from: no {path} at {rev!r}")
        target = folder / f"{Path(path).stem}_{tag}.py"
        if not target.exists() or target.read_text() != shown.stdout:
            target.write_text(shown.stdout)
    return folder


def _step_from(folder: Path, n: int, steps: int) -> dict[str, Any]:
    """The row of ``--step-from``: the half-car env with the revision's env and batch classes
    (the batch built as now, then given the revision's class: the same attributes)."""
    sys.path.insert(0, str(folder))
    tag = folder.name.removeprefix("capsule_env_bench_step_")
    vector = importlib.import_module(f"declared_vector_{tag}")
    batch = importlib.import_module(f"declared_batch_{tag}")
    env = vector.DeclaredVectorEnv(n, **gym.spec("CapsuleHalfRide-v0").kwargs)
    env.batch.__class__ = batch.DeclaredBatch
    env.reset(seed=0)
    _env_rate(env, 3)
    return {"CapsuleHalfRide-v0 env, rev's": lambda: _env_rate(env, steps // 2)}


def _step_before(batch: Any, actions: np.ndarray) -> dict[str, np.ndarray]:
    """``DeclaredBatch.step`` as it was before the lanes kernel (commit 42ef846): the declared
    plant one vehicle at a time, the sensing in numpy (its ``_measure`` and ``_estimate``)."""
    batch.requested[:] = batch.commands(actions)
    if batch.delay_steps:
        batch.command[:] = batch.delay[:, 0]
        batch.delay[:, :-1] = batch.delay[:, 1:]
        batch.delay[:, -1] = batch.requested
    else:
        batch.command[:] = batch.requested
    assert batch.num_envs >= PARALLEL_THRESHOLD  # noqa: S101 - the threaded kernel
    declared_step_parallel(batch.damper.code)(batch.num_envs, batch.plant, batch.state,
                                              batch.command, batch.route, batch.dt, batch.out)  # fmt: skip
    batch.step_count += 1
    sig = _signals_before(batch)
    n, ns = batch.num_envs, batch.n_slots
    ends = sig["slot_end_acceleration_m_s2"].reshape(n, ns, 2)
    true = np.stack([sig["stroke_m"], sig["stroke_rate_m_s"], ends[..., 0], ends[..., 1],
                     sig["gap_m"]], axis=-1).reshape(n, -1)  # fmt: skip
    if batch.noise_level > 0.0:
        normals = np.empty((n, true.shape[1] + 1))
        _normals(batch.noise_key, batch.step_count, normals)
        true = true + batch._noise_std * normals[:, : true.shape[1]]
    batch.measured[:] = true
    acc = true.reshape(n, ns, N_SLOT_CHANNELS)[:, :, 2:4]
    b0, b1, b2, a1, a2 = batch._estimator
    s1, s2 = batch._estimator_state[..., 0], batch._estimator_state[..., 1]
    y = b0 * acc + s1
    s1[...] = b1 * acc - a1 * y + s2
    s2[...] = b2 * acc - a2 * y
    batch.estimates[:] = y
    return sig


def _combine_before(x: np.ndarray, rows: np.ndarray) -> np.ndarray:
    out = np.zeros((x.shape[0], rows.shape[0]))
    for j in range(rows.shape[1]):
        out += x[:, j, None] * rows[None, :, j]
    return out


def _signals_before(batch: Any) -> dict[str, np.ndarray]:
    """``DeclaredBatch.signals`` with its sums in numpy, as before."""
    ns, nc = batch.n_slots, batch.n_coords
    q, v = batch.positions_rates()
    acc, zg = batch.out[:, ns : ns + nc], batch.out[:, ns + nc :]
    return {
        "stroke_m": _combine_before(q, batch.stroke_rows),
        "stroke_rate_m_s": _combine_before(v, batch.stroke_rows),
        "damper_force_n": batch.out[:, :ns].copy(),
        "coil_current_a": batch.state[:, 2 * nc + 2 : 2 * nc + 3 * ns : 3].copy(),
        "current_command_a": batch.requested.copy(),
        "comfort_acceleration_m_s2": _combine_before(acc, batch.comfort_rows),
        "slot_end_acceleration_m_s2": _combine_before(acc, batch.end_rows),
        "guideway_elevation_m": zg.copy(),
        "gap_m": _combine_before(q, batch.gap_rows) - _combine_before(zg, batch.gap_contacts),
    }


def _declared_batch(n: int) -> Any:
    """The declared plant on the quarter-car's declaration, the ride task's hils damper."""
    from capsule_env.envs.declared_vector import DeclaredVectorEnv

    env = DeclaredVectorEnv(n, vehicle="quarter_car", setting="hils", observation="sensors")
    return env.batch


def _cpu() -> str:
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, check=False).stdout
        for line in out.splitlines():
            if line.startswith("Model name:"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


if __name__ == "__main__":
    main()
