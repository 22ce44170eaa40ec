"""CPU time per vehicle-step of the env kernel's parts, for A/B runs of two checkouts on a busy
machine (wall-clock rates swing by 2-10x when other processes share the cores; the CPU time
of one thread much less).

    NUMBA_NUM_THREADS=1 python benchmarks/bench_kernel_cpu.py LABEL [key=value ...]
    cd /other/checkout && NUMBA_NUM_THREADS=1 PYTHONPATH=$PWD python \
        /this/checkout/benchmarks/bench_kernel_cpu.py LABEL [key=value ...]

``key=value`` are ``EnvConfig`` options (strings; e.g. ``setting=hils``). Prints one JSON line:
ns per vehicle-step (best of 15 windows, ``time.process_time``) of ``env_sense`` alone, of the
serial and the parallel kernel at N = 1024, and of ``CapsuleBatch.step`` at N = 1024.
Alternate the two checkouts a few times and compare the minima.
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np
from numba import njit

import capsule_env.engine.env_kernel as env_kernel
from capsule_env.engine.batch import CapsuleBatch
from capsule_env.engine.config import EnvConfig
from capsule_env.engine.env_kernel import EnvOutputs, env_sense

N = 1024
#: env_sense's scratch.
SHAPE = env_kernel.SENSE_SCRATCH_SHAPE


@njit
def _sense_loop(reps, n, params, plant, state, out, scratch):
    for _ in range(reps):
        for b in range(0, n, 64):
            env_sense(b, min(n, b + 64), params, plant, state, out, scratch)


def _best_ns(call, reps: int) -> float:
    best = float("inf")
    for _ in range(15):
        t0 = time.process_time()
        call()
        best = min(best, (time.process_time() - t0) / (reps * N) * 1e9)
    return round(best, 2)


def main(argv: list[str]) -> int:
    label, options = argv[0], dict(a.split("=", 1) for a in argv[1:])
    batch = CapsuleBatch(EnvConfig(**options), N)
    batch.seed(0)
    batch.reset()
    actions = np.zeros(N)
    for _ in range(5):
        batch.step(actions)
    out = EnvOutputs(batch.obs, batch.reward, batch.terminated, batch.signals, batch.plant_out)
    scratch = np.empty(SHAPE)
    sense_args = (batch.params, batch.plant_params, batch.env_state, out, scratch)
    _sense_loop(1, N, *sense_args)
    # the batch's own kernels (those of its configuration: its sensing flags since issue 40)
    serial, parallel = batch._kernel.serial, batch._kernel.parallel
    args = (batch._action_buf, batch._signals_buf, batch._env_args)
    serial(0, N, *args)
    parallel(N, *args)
    result = {
        "label": label,
        "options": options,
        "env_sense": _best_ns(lambda: _sense_loop(200, N, *sense_args), 200),
        "serial_kernel": _best_ns(lambda: [serial(0, N, *args) for _ in range(50)], 50),
        "parallel_kernel": _best_ns(lambda: [parallel(N, *args) for _ in range(50)], 50),
        "batch_step": _best_ns(lambda: [batch.step(actions) for _ in range(50)], 50),
    }
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:] or ["run"]))
