"""Where the half-car's lanes kernel spends its time: the kernel, and copies of it with one part
knocked out (their numbers are wrong: timing only), in alternating windows in one process.

    NUMBA_NUM_THREADS=1 python benchmarks/bench_half_car_parts.py --windows 11

Each row: ms per step of ``CapsuleHalfRide-v0``'s 1024 vehicles (zero actions, after 30 steps),
the median and the least of the windows (the least: the window the other processes on a shared
machine disturbed least), and what the part costs (the kernel's median and least less the
copy's); the
first row is the env's whole step (the kernel, the sensing, the reward, the observations). The
copies are written to a fixed folder in the temporary directory, so numba's disk cache keeps
their compiled code between runs.
"""

from __future__ import annotations

import argparse
import functools
import importlib
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import capsule_env  # noqa: F401  (registers the tasks)

SOURCE = Path(__file__).resolve().parents[1] / "capsule_env" / "plant" / "declared_lanes.py"
_COPY = "        for s in range(ns):\n            for i in range(na):\n                out[s, i] = z[s, i]\n        return\n"  # fmt: skip
#: (part, the text of the kernel replaced, by what)
PARTS = (
    ("tanh (glibc_tanh, vectorised)", "tmp[2, i] = glibc_tanh(tmp[0, i])", "tmp[2, i] = tmp[0, i]"),
    ("hysteretic update, all of it",
     "        if hysteretic and g[8][0] == 1:\n            _advance_z_split(f, g, na, z, xs, u0, out)\n            return\n",  # noqa: E501
     _COPY),
    ("guideway lookups (held)", "        _elevations(plant, route, na, veh, t, 0.5, h, zg[1])\n"
                                "        _elevations(plant, route, na, veh, t, 1.0, h, zg[2])\n",
     "        for c in range(nk):\n            for i in range(na):\n"
     "                zg[1, c, i] = zg[2, c, i] = zg[0, c, i]\n"),
    ("springs and dashpots", "        for e in range(ne):\n            dash",
     "        for e in range(0):\n            dash"),
    ("damper forces", "                f, y_dot = model_force(m, p, x, v, xs[2 * nc + s, i], z[s, i], ic[s, i],\n"  # noqa: E501
                      "                                       pre[s, i])  # fmt: skip",
     "                f, y_dot = x, v"),
    ("dampers' prepare (1 / (c0 + c1))", "pre[j, s, i] = model_prepare(m, p, ic[j, s, i])",
     "pre[j, s, i] = ic[j, s, i]"),
)  # fmt: skip


def _modules() -> dict[str, Any]:
    folder = Path(tempfile.gettempdir()) / "capsule_env_bench_half_car_parts"
    folder.mkdir(exist_ok=True)
    sys.path.insert(0, str(folder))
    source = SOURCE.read_text()
    texts = {"the kernel": source}
    for name, old, new in PARTS:
        if old not in source:
            raise SystemExit(f"bench_half_car_parts.py: error: the kernel changed: no {old!r}")
        texts[f"without: {name}"] = source.replace(old, new)
    modules = {}
    for j, (name, text) in enumerate(texts.items()):
        path = folder / f"lanes_part_{j}.py"
        if not path.exists() or path.read_text() != text:
            path.write_text(text)
        modules[name] = importlib.import_module(path.stem)
    return modules


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--windows", type=int, default=11, help="alternating windows of 10 steps")
    args = p.parse_args()
    if args.windows < 1:
        raise SystemExit(f"bench_half_car_parts.py: error: --windows must be >= 1, got {args.windows}")  # fmt: skip
    n = 1024
    env = gym.make_vec("CapsuleHalfRide-v0", num_envs=n, vectorization_mode="vector_entry_point")
    env.reset(seed=0)
    actions = np.zeros(env.action_space.shape, dtype=np.float32)
    for _ in range(30):
        env.step(actions)
    b = env.unwrapped.batch
    kernels = {name: m.lanes_step_parallel(b.damper.code, m.plant_form(b.plant))
               for name, m in _modules().items()}  # fmt: skip
    runs = {"the env step, all of it": lambda: env.step(actions)}
    for name, step in kernels.items():
        runs[name] = functools.partial(step, n, b.plant, b.state.copy(), b.command, b.route,
                                       b.dt, b.out.copy())  # fmt: skip
    times: dict[str, list[float]] = {name: [] for name in runs}
    for _ in range(args.windows + 1):  # the first: compile or load, not counted
        for name, run in runs.items():
            start = time.perf_counter()
            for _ in range(10):
                run()
            times[name].append((time.perf_counter() - start) / 10 * 1e3)
    base = statistics.median(times["the kernel"][1:]), min(times["the kernel"][1:])
    print(f"{time.strftime('%Y-%m-%d %H:%M')}, N = {n}, {args.windows} windows of 10 steps")
    print(f"{'ms per step':40s} {'median':>7s} {'least':>7s}  {'the kernel less it':>18s}")
    for name, t in times.items():
        med, least = statistics.median(t[1:]), min(t[1:])
        print(f"{name:40s} {med:7.3f} {least:7.3f}  {base[0] - med:8.3f} {base[1] - least:9.3f}")


if __name__ == "__main__":
    main()
