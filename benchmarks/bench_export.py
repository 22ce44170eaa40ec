"""What one inference of an exported policy costs, against the 5 ms of a 200 Hz control step.

    python benchmarks/bench_export.py                      # ppo-measured, the table
    python benchmarks/bench_export.py --policy ppo-trip --json out.json
    python benchmarks/bench_export.py --quick              # a smoke test (seconds)

Exports the policy (``python -m capsule_env.export``: ONNX and C) into a temporary folder, takes
the observations of a rollout of the policy (one vehicle, ``hils``), and times one inference at
batch 1, call by call, cycling through them (after a warm-up):

- ``sb3``: ``SB3Policy.predict`` (the normalisation in numpy, SB3's ``predict`` in torch on one
  thread, the clip): the policy as ``evaluate.py`` runs it;
- ``onnxruntime``: ``InferenceSession.run`` of ``NAME.onnx`` on the CPU provider, one thread;
- ``c``: ``capsule_policy`` of ``NAME.c`` compiled with ``cc -std=c99 -O2``, timed in C by a small
  harness (``clock_gettime(CLOCK_MONOTONIC)`` around each call): what a rig's loop sees;
- ``c-ctypes``: the same library called from Python through ctypes (the HILS dry run's path).

Reports the median, the 99th percentile and the maximum (microseconds) and the share of calls
over the 5 ms period, with the machine (``lscpu``'s model name) and the load average.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

PERIOD_S = 0.005  # one control interval at 200 Hz
WARMUP = 200
HARNESS = r"""#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "@NAME@.h"

int main(int argc, char **argv)
{
    long repeats, rows, k;
    float *obs, action[CAPSULE_POLICY_ACTION_SIZE], sink = 0.0f;
    long long *ns;
    FILE *in, *out;
    struct timespec t0, t1;
    if (argc != 4) return 1;
    repeats = atol(argv[3]);
    in = fopen(argv[1], "rb");
    out = fopen(argv[2], "wb");
    if (in == NULL || out == NULL) return 2;
    fseek(in, 0, SEEK_END);
    rows = ftell(in) / (long)(sizeof(float) * CAPSULE_POLICY_OBS_SIZE);
    rewind(in);
    obs = malloc(sizeof(float) * CAPSULE_POLICY_OBS_SIZE * rows);
    ns = malloc(sizeof(long long) * repeats);
    if (obs == NULL || ns == NULL || rows < 1) return 3;
    if (fread(obs, sizeof(float) * CAPSULE_POLICY_OBS_SIZE, rows, in) != (size_t)rows) return 4;
    for (k = -@WARMUP@; k < repeats; ++k) {
        const float *row = obs + ((k + @WARMUP@) % rows) * CAPSULE_POLICY_OBS_SIZE;
        clock_gettime(CLOCK_MONOTONIC, &t0);
        capsule_policy(row, action);
        clock_gettime(CLOCK_MONOTONIC, &t1);
        sink += action[0];
        if (k >= 0) ns[k] = (t1.tv_sec - t0.tv_sec) * 1000000000LL + (t1.tv_nsec - t0.tv_nsec);
    }
    fwrite(ns, sizeof(long long), repeats, out);
    printf("%g\n", sink);
    return 0;
}
"""


def stats_us(times_s: np.ndarray) -> dict[str, Any]:
    """Median, 99th percentile and maximum (us) of per-call times, and the share over 5 ms."""
    us = np.asarray(times_s, dtype=np.float64) * 1e6
    return {"calls": int(us.size), "median_us": float(np.median(us)),
            "p99_us": float(np.percentile(us, 99)), "max_us": float(us.max()),
            "over_period_pct": float(100.0 * np.mean(us > PERIOD_S * 1e6))}  # fmt: skip


def time_calls(call: Any, rows: np.ndarray, repeats: int) -> np.ndarray:
    """Seconds of each of ``repeats`` calls ``call(row)`` (rows cycled, after a warm-up)."""
    for k in range(WARMUP):
        call(rows[k % len(rows)])
    times = np.empty(repeats)
    clock = time.perf_counter
    for k in range(repeats):
        row = rows[k % len(rows)]
        t0 = clock()
        call(row)
        times[k] = clock() - t0
    return times


def rollout(policy: Any, env_kwargs: dict[str, Any], steps: int) -> np.ndarray:
    """Observations (batch-1 rows, float32) of one vehicle that ``policy`` drives."""
    from capsule_env.envs import CapsuleSuspensionVectorEnv

    env = CapsuleSuspensionVectorEnv(num_envs=1, guideway_seed=3, episode_length_s=10.0,
                                     **env_kwargs)  # fmt: skip
    obs, _ = env.reset(seed=[40])
    policy.reset()
    rows = []
    for _ in range(steps):
        rows.append(obs.astype(np.float32))
        action, _ = policy.predict(obs, deterministic=True)
        obs, *_ = env.step(np.asarray(action, np.float32))
    return np.stack(rows)  # (steps, 1, n_obs)


def _run(cmd: list[str]) -> None:
    """Run ``cmd``; ``RuntimeError`` with the end of its stderr when it fails."""
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"{cmd[0]} failed ({done.returncode}): {done.stderr.strip()[-500:]}")


def time_c_harness(folder: Path, name: str, rows: np.ndarray, repeats: int) -> np.ndarray:
    """Seconds per ``capsule_policy`` call, timed in C (module docstring)."""
    from capsule_env.export.c_build import C_FLAGS, c_compiler

    source = folder / "harness.c"
    source.write_text(HARNESS.replace("@NAME@", name).replace("@WARMUP@", str(WARMUP)))
    binary, obs_file, out_file = folder / "harness", folder / "obs.bin", folder / "ns.bin"
    flags = [f for f in C_FLAGS if f != "-pedantic"]
    cmd = [str(c_compiler()), *flags, str(source), str(folder / f"{name}.c"), "-o", str(binary),
           "-lm"]  # fmt: skip
    _run(cmd)
    rows.reshape(len(rows), -1).astype(np.float32).tofile(obs_file)
    _run([str(binary), str(obs_file), str(out_file), str(repeats)])
    return np.fromfile(out_file, dtype=np.int64) * 1e-9


def onnx_session(path: Path) -> Any:
    import onnxruntime as ort

    options = ort.SessionOptions()
    options.intra_op_num_threads = options.inter_op_num_threads = 1
    options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    return ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])


def measure(name: str, repeats: int, steps: int) -> dict[str, Any]:
    """Every runtime's timings of the policy ``name`` (module docstring)."""
    from capsule_env.agents.learning.sb3_policy import load_policy, use_one_torch_thread

    from capsule_env.export import export_policy
    from capsule_env.export.c_build import CPolicy, build_shared

    use_one_torch_thread()
    policy = load_policy(name if name.endswith(".zip") else _shipped(name))
    network = getattr(policy, "policy", policy)  # a residual's network: what the files compute
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        files = export_policy(name, folder)
        stem = next(f[: -len(".contract.json")] for f in files if f.endswith(".contract.json"))
        card = json.loads(files[f"{stem}.contract.json"].read_text())
        rows = rollout(policy, {**card["env_kwargs"], "setting": "hils"}, steps)
        session = onnx_session(files[f"{stem}.onnx"])
        clib = CPolicy(build_shared(files[f"{stem}.c"], folder), rows.shape[-1])
        results = {
            "sb3": time_calls(lambda r: network.predict(r, deterministic=True), rows, repeats),
            "onnxruntime": time_calls(lambda r: session.run(None, {"obs": r}), rows, repeats),
            "c": time_c_harness(folder, stem, rows, repeats * 10),
            "c-ctypes": time_calls(clib.policy, rows, repeats),
        }
    return {"policy": stem, "repeats": repeats, "observations": int(len(rows)),
            "runtimes": {k: stats_us(v) for k, v in results.items()}}  # fmt: skip


def _shipped(name: str) -> str:
    from capsule_env.agents.learning.sb3_policy import PRETRAINED_DIR

    return str(PRETRAINED_DIR / f"{name}.zip")


def machine() -> dict[str, Any]:
    """The machine: ``lscpu``'s model name, cores, Python and the library versions, the load."""
    from importlib.metadata import version

    try:
        lscpu = subprocess.run(["lscpu"], capture_output=True, text=True, timeout=30).stdout
        model = next((line.split(":", 1)[1].strip() for line in lscpu.splitlines()
                      if line.startswith("Model name")), platform.processor())  # fmt: skip
    except OSError:
        model = platform.processor()
    return {"cpu": model, "cores": os.cpu_count(), "platform": platform.platform(),
            "python": platform.python_version(), "torch": version("torch"),
            "onnxruntime": version("onnxruntime"), "load_average": list(os.getloadavg()),
            "date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime())}  # fmt: skip


def report(res: dict[str, Any]) -> str:
    m = res["machine"]
    lines = [f"{res['policy']}: one inference at batch 1, {res['repeats']} calls each (C in C: "
             f"x10), on {m['cpu']} ({m['cores']} cores), load {m['load_average'][0]:.2f}, "
             f"{m['date_utc']} UTC", "",
             "| runtime | median (us) | 99th percentile (us) | max (us) | calls over 5 ms |",
             "| --- | --- | --- | --- | --- |"]  # fmt: skip
    for name, s in res["runtimes"].items():
        lines.append(f"| {name} | {s['median_us']:.2f} | {s['p99_us']:.2f} | {s['max_us']:.1f} "
                     f"| {s['over_period_pct']:.3f} % |")  # fmt: skip
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawTextHelpFormatter)  # fmt: skip
    p.add_argument("--policy", default="ppo-measured", help="a shipped name or a policy's .zip")
    p.add_argument("--repeats", type=int, default=20000, help="timed calls per runtime")
    p.add_argument("--json", help="also write the results to this JSON file")
    p.add_argument("--quick", action="store_true", help="a smoke test: seconds, not minutes")
    args = p.parse_args(argv)
    from capsule_env.common.safe_io import atomic_write_text, check_writable_file

    try:
        if args.json is not None:
            check_writable_file(args.json, "--json")
        if args.repeats < 100:
            raise ValueError(f"--repeats must be at least 100, got {args.repeats}")
        repeats, steps = (200, 50) if args.quick else (args.repeats, 400)
        res = measure(args.policy, repeats, steps)
    except (ValueError, RuntimeError) as exc:
        print(f"bench_export.py: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 1
    res["machine"] = machine()
    print(report(res))
    if args.json is not None:
        atomic_write_text(args.json, json.dumps(res, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
