"""Gain scheduling on the trip task: the scheduled clipped LQR against the fixed-gain one.

    python experiments/scheduled_lqr.py --episodes 50 --json docs/figures/scheduled_lqr.json
    python experiments/scheduled_lqr.py --episodes 10 --retune-fixed   # + the fixed LQR re-tuned

Rows, each on the same held-out episodes of ``CapsuleTrip-v0`` (the EVALUATION bank,
``guideway_seed`` 2026, episode seeds 1000.., ``hils``): the passive damper; the fixed-gain
clipped LQR with its shipped weights (tuned at 810 km/h); the gain-scheduled LQR with its
shipped weights (tuned on the trip task's TRAINING bank); the scheduled LQR with the fixed
law's weights (what scheduling alone does); with ``--retune-fixed``, the fixed LQR with
weights searched on the trip task's training bank exactly as the scheduled law's were (what
re-tuning alone does; the search, :mod:`capsule_env.agents.controllers.tuning`, takes a few minutes; its
weights are printed, not shipped). Printed: Wk (m/s^2) mean over the episodes, its ratio to
the fixed LQR's and the spread of the per-episode ratios, the worst max |stroke|.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from capsule_env.agents.controllers.classical import make_controller  # noqa: E402
from capsule_env.agents.controllers.tuning import TuningSettings, tune  # noqa: E402
from capsule_env.agents.learning import search_space  # noqa: E402

from capsule_env import metrics  # noqa: E402
from capsule_env.common.cli import ArgumentParser  # noqa: E402
from capsule_env.common.safe_io import atomic_write_text, check_writable_file  # noqa: E402
from capsule_env.evaluation.episodes import EVALUATION_GUIDEWAY_SEED, run_episodes  # noqa: E402
from capsule_env.tasks import task_named  # noqa: E402

TASK = "CapsuleTrip-v0"
FIXED, SCHEDULED = "lqr-clipped-biexp-meas", "lqr-sched-biexp-meas"
WEIGHTS = ("q_stroke", "q_levitation", "r_force")


def retuned_fixed_weights() -> dict[str, float]:
    """The fixed LQR's weights searched on the trip task's training bank (the shipped
    search's settings), without writing the gains file."""
    space = search_space.SEARCH_SPACES[FIXED]
    search_space.SEARCH_SPACES[FIXED] = dataclasses.replace(space, task=TASK)
    try:
        entry = tune(FIXED, TuningSettings(), log=sys.stdout)
    finally:
        search_space.SEARCH_SPACES[FIXED] = space
    gains = entry["gains"]
    return {w: float(next(v for k, v in gains.items() if k.startswith(w + "_"))) for w in WEIGHTS}


def rows(retune: bool) -> dict[str, Any]:
    """The controllers of the comparison, by row name."""
    fixed = make_controller(FIXED)
    out = {
        "passive": make_controller("passive"),
        FIXED: fixed,
        SCHEDULED: make_controller(SCHEDULED),
        f"{SCHEDULED} (fixed law's weights)": make_controller(
            SCHEDULED, **{w: float(getattr(fixed, w)) for w in WEIGHTS}
        ),
    }
    if retune:
        out[f"{FIXED} (re-tuned on the trip)"] = make_controller(FIXED, **retuned_fixed_weights())
    return out


def measure(
    ctrl: Any, episodes: int, seed: int, speed_kmh: float | None = None
) -> tuple[np.ndarray, float]:
    """Per-episode Wk (m/s^2) and the worst max |stroke| (m) on the held-out episodes; with
    ``speed_kmh``, on a trip that stays at that speed (lift-off = cruise: the task's plant at
    one operating point, the speed column still there)."""
    env = {**task_named(TASK).kwargs, **ctrl.env_kwargs, "guideway_seed": EVALUATION_GUIDEWAY_SEED}
    if speed_kmh is not None:
        env["trip_params"] = {"cruise_speed_kmh": speed_kmh, "lift_off_speed_kmh": speed_kmh}
    roll = run_episodes(ctrl, env, episodes, seed, 10.0)
    wk = metrics.wk_weighted_rms(roll.signals["car_body_acceleration_m_s2"], roll.dt_s)
    return wk, float(np.abs(roll.signals["stroke_m"]).max())


def compare(
    ctrls: dict[str, Any], episodes: int, seed: int, speed_kmh: float | None = None
) -> dict[str, Any]:
    """Each row's figures (printed, and returned by row name), the ratios to the fixed LQR's
    on the same episodes."""
    out: dict[str, Any] = {}
    reference = None
    for name, ctrl in ctrls.items():
        wk, stroke = measure(ctrl, episodes, seed, speed_kmh)
        reference = wk if name == FIXED else reference
        row = {"wk_rms_body_acc_m_s2": float(wk.mean()), "max_stroke_m": stroke,
               "gains": ctrl.gains()}  # fmt: skip
        extra = ""
        if reference is not None:
            ratio = wk / reference
            row["ratio_to_fixed"] = float(wk.mean() / reference.mean())
            row["episode_ratio_range"] = [float(ratio.min()), float(ratio.max())]
            extra = (f"  x{row['ratio_to_fixed']:.4f} of the fixed LQR (episodes "
                     f"{ratio.min():.3f}..{ratio.max():.3f})")  # fmt: skip
        out[name] = row
        print(f"{name:48s} Wk {wk.mean():.4f} m/s^2  max stroke {1e3 * stroke:5.1f} mm{extra}",
              flush=True)  # fmt: skip
    return out


def main(argv: list[str] | None = None) -> int:
    p = ArgumentParser(prog="experiments/scheduled_lqr.py", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    p.add_argument("--episodes", type=int, default=50, help="held-out episodes (>= 1)")
    p.add_argument("--seed", type=int, default=1000, help="first episode seed (>= 0)")
    p.add_argument("--retune-fixed", action="store_true",
                   help="also the fixed LQR re-tuned on the trip's training bank (slow)")  # fmt: skip
    p.add_argument("--speeds", default="",
                   help="comma-separated speeds (km/h, >= 150): also each row at each constant "
                   "speed")  # fmt: skip
    p.add_argument("--json", type=Path, help="write the figures to this JSON file")
    args = p.parse_args(argv)
    if args.episodes < 1 or args.seed < 0:
        p.error(f"--episodes must be >= 1 and --seed >= 0, got {args.episodes}, {args.seed}")
    if args.json is not None:
        try:
            check_writable_file(args.json, "--json")
        except (ValueError, OSError) as exc:
            p.error(str(exc))
    try:
        speeds = [float(v) for v in args.speeds.split(",") if v.strip()]
    except ValueError:
        p.error(f"--speeds must be comma-separated numbers (km/h), got {args.speeds!r}")
    if any(not 150.0 <= v <= 2000.0 for v in speeds):
        p.error(f"--speeds must lie in [150, 2000] km/h (lift-off and up), got {args.speeds!r}")
    results: dict[str, Any] = {"task": TASK, "guideway_seed": EVALUATION_GUIDEWAY_SEED,
                               "seeds": [args.seed, args.seed + args.episodes - 1],
                               "trip": compare(rows(args.retune_fixed), args.episodes, args.seed)}  # fmt: skip
    ctrls = rows(False)
    for v in speeds:
        print(f"-- at a constant {v:g} km/h")
        results[f"{v:g}_kmh"] = compare(ctrls, args.episodes, args.seed, v)
    if args.json is not None:
        atomic_write_text(args.json, json.dumps(results, indent=2) + "\n")
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
