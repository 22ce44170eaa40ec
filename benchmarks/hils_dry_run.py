"""A HILS dry run: an exported policy in a fixed-rate 200 Hz loop against the env.

    python benchmarks/hils_dry_run.py ppo-measured                   # export, then 10 s in C
    python benchmarks/hils_dry_run.py out/ppo-measured.contract.json --runtime onnx --seconds 60
    python benchmarks/hils_dry_run.py residual-ppo-mpc --json run.json

Takes the artifacts beside a contract (``python -m capsule_env.export ... --out DIR``; their
SHA-256 are checked against it) or exports a policy into a temporary folder, then runs the
contract's env (``hils``: sensor noise, coil lag, the one-step delay) for ``--seconds`` of
control steps at the contract's period (5 ms), on an absolute schedule: step ``k`` wakes at
``t0 + k T`` (sleep, then spin for the last 0.5 ms; ``--busy-wait``: spin throughout), reads the observation, computes the action
with the artifact (``--runtime c``: ``NAME.c`` compiled and called through ctypes; ``onnx``:
onnxruntime, one thread), and steps the env, which stands in for the rig. A step whose action is
ready after ``t0 + (k + 1) T`` (the next tick, where the delayed command is applied) **misses its
deadline**; one whose env step also ends after it **overruns** (the next step starts late: the
schedule does not slip, it catches up). A residual policy runs with its law: in C when the C file
has it (``capsule_control``), else the Python law of the registry (the MPC: needs the ``mpc``
extra) plus the combination, inside the timed computation.

Reports the steps, the deadlines missed, the overruns, the compute time (median, 99th
percentile, max, us), the wake-up lateness and the episode's RMS car-body acceleration.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

SPIN_S = 0.0005  # the last part of each wait is spent spinning, not sleeping
WARMUP_STEPS = 20


def check_artifacts(contract_path: Path) -> dict[str, Any]:
    """The contract at ``contract_path``; ``ValueError`` when an artifact it lists is missing or
    differs from its recorded SHA-256."""
    card = json.loads(contract_path.read_text())
    for file_name, digest in card["artifacts"].items():
        path = contract_path.parent / file_name
        if not path.is_file():
            raise ValueError(f"{path} is missing (listed in {contract_path.name})")
        if hashlib.sha256(path.read_bytes()).hexdigest() != digest["sha256"]:
            raise ValueError(f"{path} is not the file {contract_path.name} records (SHA-256)")
    return card


def _law_step(card: dict[str, Any]) -> Callable[[np.ndarray, bool], float] | None:
    """The Python law of a residual policy whose C file lacks it: ``(obs, start) -> action``."""
    res = card.get("residual")
    if res is None:
        return None
    from capsule_env.agents.controllers.classical import make_controller

    law = make_controller(res["law"])
    law.reset()

    def step(obs: np.ndarray, start: bool) -> float:
        action, _ = law.predict(obs[None], episode_start=np.array([start]), deterministic=True)
        return float(action[0, 0])

    return step


def actor(card: dict[str, Any], folder: Path, runtime: str) -> Callable[[np.ndarray, bool], float]:
    """``(obs, episode_start) -> action`` of the artifacts in ``folder`` (module docstring)."""
    name, res = card["name"], card.get("residual")
    if runtime == "c":
        from capsule_env.export.c_build import CPolicy, build_shared

        lib = CPolicy(build_shared(folder / f"{name}.c", folder), card["observation"]["size"])
        if lib.has_control:
            return lambda obs, start: float(lib.control(obs)[0, 0])
        network: Callable[[np.ndarray], float] = lambda obs: float(lib.policy(obs)[0, 0])  # noqa: E731
    else:
        import onnxruntime as ort

        options = ort.SessionOptions()
        options.intra_op_num_threads = options.inter_op_num_threads = 1
        session = ort.InferenceSession(str(folder / f"{name}.onnx"), options,
                                       providers=["CPUExecutionProvider"])  # fmt: skip
        network = lambda obs: float(session.run(None, {"obs": obs[None]})[0][0, 0])  # noqa: E731
    law = _law_step(card)
    if law is None or res is None:
        return lambda obs, start: network(obs)
    scale = float(res["scale"])
    return lambda obs, start: float(np.clip(law(obs, start) + scale * network(obs), -1.0, 1.0))


def wait_until(t: float, spin_s: float = SPIN_S) -> float:
    """Sleep, then spin for the last ``spin_s``, until ``time.perf_counter() >= t``; returns
    the wake-up time."""
    remaining = t - time.perf_counter()
    if remaining > spin_s:
        time.sleep(remaining - spin_s)
    while (now := time.perf_counter()) < t:
        pass
    return now


def run_loop(card: dict[str, Any], act: Callable[[np.ndarray, bool], float], seconds: float,
             seed: int, spin_s: float = SPIN_S) -> dict[str, Any]:  # fmt: skip
    """The fixed-rate loop (module docstring); returns its counts and timings."""
    from capsule_env.envs import CapsuleSuspensionEnv

    period = float(card["control"]["period_s"])
    env = CapsuleSuspensionEnv(**{**card["env_kwargs"], "episode_length_s": seconds + 1.0,
                                  "guideway_seed": 3})  # fmt: skip
    for _ in range(WARMUP_STEPS):  # numba loads its kernels, the runtime its caches: untimed
        obs, _ = env.reset(seed=seed)
        env.step(np.array([act(np.asarray(obs, np.float32), True)], np.float32))
    obs, _ = env.reset(seed=seed)
    steps = int(round(seconds / period))
    compute, late_wake, acc = np.empty(steps), np.empty(steps), np.empty(steps)
    missed = overruns = 0
    t0 = time.perf_counter() + 0.05
    for k in range(steps):
        tick = t0 + k * period
        woke = wait_until(tick, spin_s)
        action = act(np.asarray(obs, np.float32), k == 0)
        ready = time.perf_counter()
        obs, _, terminated, truncated, info = env.step(np.array([action], np.float32))
        done = time.perf_counter()
        compute[k], late_wake[k] = ready - woke, woke - tick
        acc[k] = float(info["car_body_acceleration_m_s2"])
        missed += ready > tick + period
        overruns += done > tick + period
        if terminated or truncated:
            steps = k + 1
            break
    us = compute[:steps] * 1e6
    return {"steps": steps, "period_s": period, "deadlines_missed": int(missed),
            "overruns": int(overruns), "compute_median_us": float(np.median(us)),
            "compute_p99_us": float(np.percentile(us, 99)), "compute_max_us": float(us.max()),
            "wake_late_p99_us": float(np.percentile(late_wake[:steps] * 1e6, 99)),
            "wake_late_max_us": float(late_wake[:steps].max() * 1e6),
            "rms_body_acc_m_s2": float(np.sqrt(np.mean(acc[:steps] ** 2)))}  # fmt: skip


def dry_run(source: str, runtime: str, seconds: float, seed: int,
            spin_s: float = SPIN_S) -> dict[str, Any]:  # fmt: skip
    """Export ``source`` (or take the artifacts beside a contract) and run the loop."""
    with tempfile.TemporaryDirectory() as tmp:
        if source.endswith(".contract.json"):
            contract_path = Path(source)
            if not contract_path.is_file():
                raise ValueError(f"contract {source!r} does not exist")
            card = check_artifacts(contract_path)
            folder = contract_path.parent
            if runtime == "c":  # the build goes to the temporary folder, not beside the files
                for suffix in (".c", ".h"):
                    (Path(tmp) / f"{card['name']}{suffix}").write_bytes(
                        (folder / f"{card['name']}{suffix}").read_bytes())  # fmt: skip
                folder = Path(tmp)
        else:
            from capsule_env.export import export_policy

            files = export_policy(source, tmp)
            card = json.loads(next(p for f, p in files.items() if f.endswith(".contract.json"))
                              .read_text())  # fmt: skip
            folder = Path(tmp)
        needed = f"{card['name']}.{'c' if runtime == 'c' else 'onnx'}"
        if needed not in card["artifacts"]:
            raise ValueError(f"the contract lists no {needed}: export with --format {runtime}")
        result = run_loop(card, actor(card, folder, runtime), seconds, seed, spin_s)
    return {"policy": card["name"], "runtime": runtime, "seconds": seconds,
            "busy_wait": spin_s > 1.0, **result}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawTextHelpFormatter)  # fmt: skip
    p.add_argument("source", metavar="POLICY_OR_CONTRACT",
                   help="a shipped policy's name, a policy's .zip, or an export's NAME.contract.json")  # fmt: skip
    p.add_argument("--runtime", choices=("c", "onnx"), default="c")
    p.add_argument("--seconds", type=float, default=10.0, help="control time to run (s)")
    p.add_argument("--seed", type=int, default=40, help="the episode's seed")
    p.add_argument("--busy-wait", action="store_true",
                   help="spin through the whole wait instead of sleeping (keeps the core and its "
                        "caches warm; takes one core)")  # fmt: skip
    p.add_argument("--json", help="also write the result to this JSON file")
    args = p.parse_args(argv)
    from capsule_env.common.safe_io import atomic_write_text, check_writable_file

    try:
        if not 0.0 < args.seconds <= 3600.0:
            raise ValueError(f"--seconds must be in (0, 3600], got {args.seconds:g}")
        if args.json is not None:
            check_writable_file(args.json, "--json")
        spin_s = float("inf") if args.busy_wait else SPIN_S
        res = dry_run(args.source, args.runtime, args.seconds, args.seed, spin_s)
    except (ValueError, RuntimeError, ImportError, OSError) as exc:
        print(f"hils_dry_run.py: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 1
    print(f"{res['policy']} ({res['runtime']}): {res['steps']} steps of {res['period_s'] * 1e3:g} "
          f"ms: {res['deadlines_missed']} deadlines missed, {res['overruns']} overruns; compute "
          f"median {res['compute_median_us']:.1f} us, p99 {res['compute_p99_us']:.1f} us, max "
          f"{res['compute_max_us']:.1f} us; wake-up late p99 {res['wake_late_p99_us']:.1f} us; "
          f"RMS body acceleration {res['rms_body_acc_m_s2']:.4f} m/s^2")  # fmt: skip
    if args.json is not None:
        atomic_write_text(args.json, json.dumps(res, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
