"""What the half-car MPCs' figures are made of (``docs/half-car.md``): the design choices on
the TRAINING bank, the discrete LQ twins with the MPCs' force weight, and, on the held-out
bank, each MPC against its twin at the same weights (paired, 95 % bootstrap).

    python experiments/half_car_mpc_check.py --out runs/half_car_mpc_check.json

1. Training bank (guideway seed 0, episodes 0..9): each tuned MPC (``TUNED_MPC``) with one
   option changed: a horizon of 1 interval (the clipped LQ law of the model with the coil lag
   and the delay), no coil lag in the model, the band on all 10 intervals (edges as secants
   over 0.05 m/s).
2. Training bank: the discrete LQ twins (``lq-discrete-biexp-meas``,
   ``wheelbase-lq-biexp-meas``) over ``r_force`` at the tuned state weights.
3. Held-out bank (guideway seed 2026, episodes 1000..1009): each MPC over its LQ twin at the
   MPC's own weights, and the twin over the per-bogie clipped LQR.
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from capsule_env.evaluation.half_car import (
    EVALUATION_GUIDEWAY_SEED,
    TRAINING_GUIDEWAY_SEED,
    TUNED_MPC,
    _ratio_interval,
    episode_metrics,
    rollout,
    write_json,
)

VARIANTS = {"shipped": {}, "horizon 1": {"horizon_steps": 1},
            "no coil lag in the model": {"coil_time_constant_s": 0.0},
            "band on all 10, secants 0.05 m/s": {"solver": {"constrained_steps": 0,
                                                            "secant_m_s": 0.05}}}  # fmt: skip
TWIN_FORCE_WEIGHTS = (3e-8, 5e-8, 7e-8, 1e-7)


def wk(law, seeds: list[int], guideway_seed: int) -> np.ndarray:  # type: ignore[no-untyped-def]
    """The headline Wk per episode."""
    return episode_metrics(rollout(law, seeds, guideway_seed))["wk_rms_body_acc_m_s2"]


def main(argv: list[str] | None = None) -> int:
    from capsule_env.agents.controllers.declared_lqr import IndependentClippedLQR
    from capsule_env.agents.controllers.half_car_mpc import HalfCarMPC
    from capsule_env.agents.controllers.wheelbase import WheelbasePreviewLQ

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default="", help="JSON file to write (atomically)")
    args = p.parse_args(argv)
    train, held = list(range(10)), list(range(1000, 1010))
    out: dict = {"variants_training_wk": {}, "twins_training_wk": {}, "held_out": {}}
    base = wk(IndependentClippedLQR(), held, EVALUATION_GUIDEWAY_SEED)
    for name, weights in TUNED_MPC.items():
        preview = name.startswith("wheelbase")
        for variant, options in VARIANTS.items():
            law = HalfCarMPC(**weights, preview=preview, **options)
            value = float(wk(law, train, TRAINING_GUIDEWAY_SEED).mean())
            out["variants_training_wk"][f"{name}: {variant}"] = value
            print(f"training  {name}: {variant}: {value:.5f}", flush=True)
        for r_force in TWIN_FORCE_WEIGHTS:
            twin = WheelbasePreviewLQ(weights["q_stroke"], weights["q_levitation"], r_force,
                                      preview=preview)  # fmt: skip
            value = float(wk(twin, train, TRAINING_GUIDEWAY_SEED).mean())
            out["twins_training_wk"][f"{twin.name} r_force={r_force:g}"] = value
            print(f"training  {twin.name} r_force={r_force:g}: {value:.5f}", flush=True)
        twin = WheelbasePreviewLQ(*weights.values(), preview=preview)
        mine = wk(HalfCarMPC(**weights, preview=preview), held, EVALUATION_GUIDEWAY_SEED)
        theirs = wk(twin, held, EVALUATION_GUIDEWAY_SEED)
        out["held_out"][name] = {
            "twin": twin.name, "weights": weights, "mpc_wk": float(mine.mean()),
            "twin_wk": float(theirs.mean()), "mpc_over_twin": float(mine.mean() / theirs.mean()),
            "mpc_over_twin_ci95": _ratio_interval(mine, theirs),
            "twin_over_per_bogie_lqr": float(theirs.mean() / base.mean()),
            "twin_over_per_bogie_lqr_ci95": _ratio_interval(theirs, base),
        }  # fmt: skip
        print(f"held-out  {json.dumps(out['held_out'][name])}", flush=True)
    if args.out:
        write_json(args.out, json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
