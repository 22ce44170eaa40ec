"""What the wheelbase preview could give without a damper's limits: the half-car's
wheelbase-preview LQ (``agents/controllers/wheelbase.py``) on the *linear* plant with an ideal
active actuator (no clipping, no sensor noise), exact front rises, against the same design
without the window, over random guideway windows.

    python experiments/wheelbase_active.py            # prints the ratios per weight set

For each weight set: the Wk at the floor's front, centre and rear with the preview over without
it (the mean over ``--windows`` 10 s windows of one random profile at 810 km/h).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from capsule_env.agents.controllers.wheelbase import _sampled, wheelbase_gains

from capsule_env.guideway import random_profile
from capsule_env.metrics import wk_weighted_rms
from capsule_env.vehicles import model_named

WEIGHTS = ((0.1, 10.0, 3e-8), (1.0, 100.0, 3e-9), (0.1, 10.0, 1e-9))


def comfort(gains, a, b, e, c, d, rises_front, rises_rear) -> np.ndarray:
    """Wk (3,) of the comfort points under the linear closed loop (one step of delay)."""
    x, in_flight = np.zeros(a.shape[0]), np.zeros(b.shape[1])
    window = np.zeros(gains.k_p.shape[1])
    acc = []
    for k in range(len(rises_front)):
        force = -(gains.k_x @ x + gains.k_u @ in_flight + gains.k_p @ window)
        applied, in_flight = in_flight, force
        acc.append(c @ x + d @ applied)
        x = a @ x + b @ applied + e[:, 0] * rises_front[k] + e[:, 1] * rises_rear[k]
        if len(window):
            window[:-1], window[-1] = window[1:], rises_front[k]
    return wk_weighted_rms(np.array(acc).T, 0.005)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--windows", type=int, default=5, help="10 s windows averaged (>= 1)")
    args = p.parse_args(argv)
    if args.windows < 1:  # was a traceback from random_profile (a profile of length 0)
        sys.exit(f"wheelbase_active.py: error: --windows must be >= 1, got {args.windows}")
    model = model_named("half_car")
    dt, speed, steps = 0.005, 225.0, 2000
    a, b, e, c, d = _sampled(model, model.params(), dt)
    spacing = 0.25
    profile = random_profile(speed * steps * dt * (args.windows + 1), spacing, 7, peak_m=None)
    grid = np.arange(len(profile)) * spacing
    for weights in WEIGHTS:
        ratios = []
        for w in range(args.windows):
            t = np.arange(steps + 1) * dt
            start = 50.0 + w * speed * steps * dt
            rises = [np.diff(np.interp(start + off + speed * t, grid, profile))
                     for off in (0.0, -20.0)]  # fmt: skip
            with_p = comfort(
                wheelbase_gains("half_car", dt, speed, *weights), a, b, e, c, d, *rises
            )
            without = comfort(wheelbase_gains("half_car", dt, speed, *weights, preview=False),
                              a, b, e, c, d, *rises)  # fmt: skip
            ratios.append(with_p / without)
        front, centre, rear = np.mean(ratios, axis=0)
        print(f"weights {weights}: preview / none  front {front:.4f}  centre {centre:.4f}  "
              f"rear {rear:.4f}")  # fmt: skip


if __name__ == "__main__":
    main()
