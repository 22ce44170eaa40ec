"""What the semi-active MPC's design choices are worth: each variant's Wk beside the clipped
laws it competes with, on the same episodes.

    python experiments/mpc_variants.py                      # training bank, 10 x 10 s, hils
    python experiments/mpc_variants.py --bank evaluation    # the held-out seeds 1000..1009
    python experiments/mpc_variants.py --episodes 4 --length 5 --json out.json

The variants (each the shipped ``mpc-biexp-meas`` / ``preview-mpc-biexp-meas`` weights, one
option changed): the horizon (1 step: Giorgetti et al. 2006's clipped LQ on the delay- and
lag-aware model), the number of intervals under the band (3, the default; all 10), the band's
slope (tangent; a secant over 0.05 m/s), no coil lag or delay in the model, and the
Wk-weighted cost. Prints one line per row: mean Wk, worst max |stroke|, fallback steps and
solves per step.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from capsule_env.agents.controllers.classical import make_controller

from capsule_env import metrics
from capsule_env.common.safe_io import atomic_write_text, check_writable_file
from capsule_env.evaluation.episodes import EVALUATION_GUIDEWAY_SEED, run_episodes

#: Variant name -> the options changed from the shipped law.
VARIANTS: dict[str, dict[str, Any]] = {
    "shipped (horizon 10, band on 3)": {},
    "horizon 1 (clipped LQ, Giorgetti)": {"horizon_steps": 1},
    "band on all 10, tangent": {"solver": {"constrained_steps": 0}},
    "band on all 10, secant 0.05 m/s": {"solver": {"constrained_steps": 0, "secant_m_s": 0.05}},
    "horizon 20, band on all, secant": {"horizon_steps": 20, "solver": {
        "constrained_steps": 0, "secant_m_s": 0.05, "max_passes": 4}},
    "no coil lag in the model": {"coil_time_constant_s": 0.0},
    "no delay in the model": {"delay_steps": 0},
    "Wk-weighted cost": {"wk_cost": True},
}  # fmt: skip
REFERENCES = {"": "lqr-clipped-biexp-meas", "preview-": "preview-lq-biexp-meas"}


def run(ctrl: Any, seeds: list[int], guideway_seed: int, length_s: float) -> dict[str, Any]:
    """``ctrl`` on the episodes: mean Wk, worst max |stroke|, the MPC's counters."""
    t0 = time.perf_counter()
    env_kwargs = {**ctrl.env_kwargs, "setting": "hils", "guideway_seed": guideway_seed}
    roll = run_episodes(ctrl, env_kwargs, episode_length_s=length_s, seeds=seeds,
                        recorded=("car_body_acceleration_m_s2", "stroke_m"))  # fmt: skip
    wk = metrics.wk_weighted_rms(roll.signals["car_body_acceleration_m_s2"], roll.dt_s)
    out = {"wk_rms_body_acc_m_s2": float(wk.mean()),
           "max_stroke_m": float(np.abs(roll.signals["stroke_m"]).max()),
           "wall_s": time.perf_counter() - t0}  # fmt: skip
    counters = getattr(ctrl, "counters", None)
    if counters:
        out["fallback_steps"] = counters["fallback_steps"]
        out["solves_per_step"] = counters["solves"] / max(1, counters["vehicle_steps"])
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    p.add_argument("--bank", choices=["training", "evaluation"], default="training")
    p.add_argument("--episodes", type=int, default=10)
    p.add_argument("--length", type=float, default=10.0, help="seconds per episode")
    p.add_argument("--preview", action="store_true", help="the preview law's variants")
    p.add_argument("--json", type=Path)
    args = p.parse_args(argv)
    if args.episodes < 1 or not args.length >= 0.5:
        sys.exit("mpc_variants.py: error: --episodes must be >= 1 and --length >= 0.5 s")
    if args.json is not None:
        try:
            check_writable_file(args.json, "--json")
        except (ValueError, OSError) as exc:
            sys.exit(f"mpc_variants.py: error: {exc}")
    if args.bank == "training":
        guideway_seed, seeds = 0, list(range(args.episodes))
    else:  # evaluate.py's held-out episodes
        guideway_seed = EVALUATION_GUIDEWAY_SEED
        seeds = list(range(1000, 1000 + args.episodes))
    prefix = "preview-" if args.preview else ""
    rows: dict[str, Any] = {}
    reference = REFERENCES[prefix]
    rows[reference] = run(make_controller(reference), seeds, guideway_seed, args.length)
    for label, change in VARIANTS.items():
        ctrl = make_controller(f"{prefix}mpc-biexp-meas", **change)
        rows[label] = run(ctrl, seeds, guideway_seed, args.length)
    base = rows[reference]["wk_rms_body_acc_m_s2"]
    for label, r in rows.items():
        extra = (f"  fallback {r['fallback_steps']:4d}  solves/step {r['solves_per_step']:.2f}"
                 if "fallback_steps" in r else "")  # fmt: skip
        print(f"{label:<36} Wk {r['wk_rms_body_acc_m_s2']:.4f} ({r['wk_rms_body_acc_m_s2'] / base:.3f} x)"
              f"  max stroke {1e3 * r['max_stroke_m']:5.2f} mm{extra}")  # fmt: skip
    if args.json is not None:
        data = {"bank": args.bank, "guideway_seed": guideway_seed, "seeds": seeds,
                "episode_length_s": args.length, "rows": rows}  # fmt: skip
        atomic_write_text(args.json, json.dumps(data, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
