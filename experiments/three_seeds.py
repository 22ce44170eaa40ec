"""Train PPO with several seeds and compare every run with Skyhook on held-out guideways.

    python experiments/three_seeds.py                     # seeds 0 1 2, default train.py
    python experiments/three_seeds.py --seeds 0 1 2 --train-args "--env reward_velocity_weight=0.2"

For each seed: ``python train.py --seed S --output-dir runs/three-seeds/seedS <train-args>``,
then ``evaluate.py`` in ``hils`` on seeds 1000..1009 of the held-out guideway bank with the
classical controllers and that run's ``best_model``. Prints a table with the mean and spread
of the ISO Wk-weighted RMS car-body acceleration and the car-body first-mode vibration
reduction, against the best Skyhook variant (the issue's bar: Wk <= 0.9 x Skyhook's and a
higher first-mode reduction), and writes ``runs/three-seeds/summary.json``.
"""

from __future__ import annotations

import argparse
import json
import shlex
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from capsule_env.common.safe_io import atomic_write_text

SKYHOOKS = ("skyhook-biexp", "skyhook-csdc", "skyhook-tanh", "skyhook-cont-biexp")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    p.add_argument("--train-args", default="", help="extra arguments for train.py")
    p.add_argument("--root", type=Path, default=Path("runs/three-seeds"))
    p.add_argument("--skip-training", action="store_true", help="evaluate existing runs only")
    args = p.parse_args(argv)
    bad = [s for s in args.seeds if not 0 <= s < 2**32] or sorted(
        {s for s in args.seeds if args.seeds.count(s) > 1})  # fmt: skip
    if bad:  # before any folder or training, not a train.py failure and a traceback after
        sys.exit(f"three_seeds.py: error: --seeds must be distinct integers in 0..{2**32 - 1} "
                 f"(train.py's --seed), got {bad[0]}")  # fmt: skip
    args.root.mkdir(parents=True, exist_ok=True)
    runs = {}
    for seed in args.seeds:
        out = args.root / f"seed{seed}"
        if not args.skip_training:
            t0 = time.perf_counter()
            cmd = [sys.executable, "train.py", "--seed", str(seed), "--output-dir", str(out),
                   "--no-progress", *shlex.split(args.train_args)]  # fmt: skip
            if subprocess.run(cmd).returncode != 0:  # train.py said why, in one line
                sys.exit(f"three_seeds.py: error: train.py failed for seed {seed}")
            print(f"seed {seed}: trained in {time.perf_counter() - t0:.0f} s", flush=True)
        evaluation = out / "evaluation.json"
        evaluated = subprocess.run(
            [sys.executable, "evaluate.py", "--setting", "hils", "--no-shipped-policy",
             "--controllers", ",".join(("passive", *SKYHOOKS)), "--policy",
             str(out / "best_model.zip"), "--json", str(evaluation)],
            stdout=subprocess.DEVNULL,
        )  # fmt: skip
        if evaluated.returncode != 0:  # evaluate.py said why, in one line
            sys.exit(f"three_seeds.py: error: evaluate.py failed for seed {seed}")
        runs[seed] = json.loads(evaluation.read_text())["settings"]["hils"]["controllers"]
    first = next(iter(runs.values()))
    best_sky = min(SKYHOOKS, key=lambda n: first[n]["wk_rms_body_acc_m_s2"])
    sky_wk = first[best_sky]["wk_rms_body_acc_m_s2"]
    sky_vre = first[best_sky]["vre_pct"]["body_mode1"]
    policies = {
        s: [n for n in r if n not in SKYHOOKS and n != "passive"][0] for s, r in runs.items()
    }
    wk = np.array([r[policies[s]]["wk_rms_body_acc_m_s2"] for s, r in runs.items()])
    vre = np.array([r[policies[s]]["vre_pct"]["body_mode1"] for s, r in runs.items()])
    print(f"\nhils, 10 held-out guideway seeds; best Skyhook by Wk: {best_sky} "
          f"(Wk {sky_wk:.4f} m/s^2, VRE body m1 {sky_vre:.2f} %), passive Wk "
          f"{first['passive']['wk_rms_body_acc_m_s2']:.4f}")  # fmt: skip
    for seed, r in runs.items():
        m = r[policies[seed]]
        wk_m = m["wk_rms_body_acc_m_s2"]
        print(f"  seed {seed}: Wk {wk_m:.4f} ({wk_m / sky_wk:.3f} x Skyhook), VRE body m1 "
              f"{m['vre_pct']['body_mode1']:.2f} %")  # fmt: skip
    print(f"  mean +- std: Wk {wk.mean():.4f} +- {wk.std():.4f} ({wk.mean() / sky_wk:.3f} x), "
          f"VRE {vre.mean():.2f} +- {vre.std():.2f} %")  # fmt: skip
    bar = bool(np.all(wk <= 0.9 * sky_wk) and np.all(vre > sky_vre))
    print(f"  bar (every seed: Wk <= 0.9 x Skyhook and higher VRE): {'met' if bar else 'NOT met'}")
    summary = {"best_skyhook": best_sky, "skyhook_wk_m_s2": sky_wk,
               "skyhook_vre_body_mode1_pct": sky_vre, "policy_wk_m_s2": wk.tolist(),
               "policy_vre_body_mode1_pct": vre.tolist(), "bar_met": bar,
               "seeds": args.seeds, "train_args": args.train_args}  # fmt: skip
    atomic_write_text(args.root / "summary.json", json.dumps(summary, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
