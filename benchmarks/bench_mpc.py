"""What the semi-active MPC costs per control step, against the 5 ms of a 200 Hz step.

    python benchmarks/bench_mpc.py                   # the table (about 5 minutes)
    python benchmarks/bench_mpc.py --json out.json   # and the JSON
    python benchmarks/bench_mpc.py --quick           # a smoke test (seconds; 3 rows timed)

Measures, on this machine, in ``hils`` on the evaluation bank's first episodes:

1. per control step of one vehicle (the law's whole ``predict``: the state, the plan, every
   OSQP solve, the fallback): median, 99th percentile and maximum (ms) and the share of steps
   over 5 ms, for ``mpc-biexp-meas`` and ``preview-mpc-biexp-meas`` (the first 20 steps left
   out: numba compiles there), beside the clipped LQR and preview LQ laws they compete with;
   the solves per step and the fallback steps;
2. the time of the default evaluation's runs (``evaluate.py``'s classical controllers, 10
   episodes of 10 s, ``hils`` only; the shipped policies left out) with and without the MPC
   rows.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from typing import Any

import numpy as np

BUDGET_S = 0.005  # one control interval at 200 Hz
LAWS = ("mpc-biexp-meas", "preview-mpc-biexp-meas", "lqr-clipped-biexp-meas",
        "preview-lq-biexp-meas")  # fmt: skip
WARMUP_STEPS = 20


class _Timed:
    """A controller whose every ``predict`` is timed."""

    def __init__(self, ctrl: Any) -> None:
        self.ctrl, self.times_s = ctrl, []
        self.env_kwargs = ctrl.env_kwargs

    def reset(self) -> None:
        self.ctrl.reset()

    def predict(self, *args: Any, **kwargs: Any) -> Any:
        t0 = time.perf_counter()
        out = self.ctrl.predict(*args, **kwargs)
        self.times_s.append(time.perf_counter() - t0)
        return out


def step_times(name: str, episodes: int, length_s: float) -> dict[str, Any]:
    """Per-step cost of law ``name`` on one vehicle (``episodes`` runs of ``length_s``)."""
    from capsule_env.agents.controllers.classical import make_controller

    from capsule_env.evaluation.episodes import run_episodes

    times: list[float] = []
    ctrl = make_controller(name)
    for k in range(episodes):
        timed = _Timed(ctrl)
        run_episodes(timed, {**ctrl.env_kwargs, "setting": "hils"}, 1, 1000 + k, length_s)
        times += timed.times_s[WARMUP_STEPS:]
    ms = 1e3 * np.asarray(times)
    out = {"steps": len(ms), "median_ms": float(np.median(ms)),
           "p99_ms": float(np.percentile(ms, 99)), "max_ms": float(ms.max()),
           "over_budget_rel": float(np.mean(ms > 1e3 * BUDGET_S))}  # fmt: skip
    counters = getattr(ctrl, "counters", None)
    if counters:
        out["solves_per_step"] = counters["solves"] / max(1, counters["vehicle_steps"])
        out["fallback_steps"] = counters["fallback_steps"]
        out["failed_solves"] = counters["failed_solves"]
    return out


def evaluation_time(episodes: int, length_s: float, names: list[str]) -> dict[str, Any]:
    """Seconds of each controller's run (``hils``; ``names`` or [] for the default
    evaluation's classical controllers), and the totals with and without the MPC rows."""
    from capsule_env.agents.controllers.classical import make_controller

    from capsule_env.evaluation.episodes import run_episodes
    from capsule_env.evaluation.evaluate import DEFAULT_CONTROLLERS

    per: dict[str, float] = {}
    for name in dict.fromkeys(["passive", *(names or DEFAULT_CONTROLLERS)]):
        ctrl = make_controller(name)
        t0 = time.perf_counter()
        run_episodes(ctrl, {**ctrl.env_kwargs, "setting": "hils"}, episodes, 1000, length_s)
        per[name] = time.perf_counter() - t0
    mpc = [n for n in per if "mpc" in n]
    return {"per_controller_s": per, "with_mpc_s": sum(per.values()),
            "without_mpc_s": sum(v for n, v in per.items() if n not in mpc)}  # fmt: skip


def machine() -> dict[str, Any]:
    from importlib.metadata import version

    return {"platform": platform.platform(), "processor": platform.processor(),
            "python": platform.python_version(), "daqp": version("daqp"),
            "osqp": version("osqp"), "cpus": __import__("os").cpu_count(),
            "load_average_1min": __import__("os").getloadavg()[0]}  # fmt: skip


def report(res: dict[str, Any]) -> str:
    lines = [f"per control step, one vehicle, hils ({res['date']}, {res['machine']['cpus']} "
             f"CPUs); budget {1e3 * BUDGET_S:g} ms",
             f"{'law':<26}{'median ms':>10}{'p99 ms':>9}{'max ms':>9}{'> 5 ms':>8}"
             f"{'solves':>8}{'fallback':>9}"]  # fmt: skip
    for name, r in res["step"].items():
        lines.append(f"{name:<26}{r['median_ms']:10.3f}{r['p99_ms']:9.3f}{r['max_ms']:9.2f}"
                     f"{r['over_budget_rel']:8.2%}{r.get('solves_per_step', 0):8.2f}"
                     f"{r.get('fallback_steps', 0):9d}")  # fmt: skip
    ev = res["evaluation"]
    lines.append(f"default evaluation's runs (hils, classical rows): {ev['with_mpc_s']:.1f} s "
                 f"with the MPC rows, {ev['without_mpc_s']:.1f} s without")  # fmt: skip
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawTextHelpFormatter)  # fmt: skip
    p.add_argument("--json", help="also write the results to this JSON file")
    p.add_argument("--quick", action="store_true", help="a smoke test: seconds, not minutes")
    args = p.parse_args(argv)
    if args.json is not None:
        from capsule_env.common.safe_io import check_writable_file

        try:
            check_writable_file(args.json, "--json")
        except ValueError as exc:
            p.exit(2, f"bench_mpc.py: {exc}\n")
    episodes, length_s = (1, 0.5) if args.quick else (10, 10.0)
    res: dict[str, Any] = {"machine": machine(), "date": time.strftime("%Y-%m-%d"), "step": {}}
    for name in LAWS:
        res["step"][name] = step_times(name, 1 if args.quick else 5, length_s)
    quick_rows = ["lqr-clipped-biexp-meas", "mpc-biexp-meas"] if args.quick else []
    res["evaluation"] = evaluation_time(episodes, length_s, quick_rows)
    print(report(res))
    if args.json is not None:
        from capsule_env.common.safe_io import atomic_write_text

        atomic_write_text(args.json, json.dumps(res, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
