"""Does DAQP's warm start change the semi-active MPC's answer, or only its speed?

    python experiments/mpc_warm_start.py              # 400 steps of each MPC, hils, seed 40
    python experiments/mpc_warm_start.py --steps 100

Runs ``mpc-biexp-meas`` and ``preview-mpc-biexp-meas`` in closed loop (one vehicle, guideway
bank 3, episode seed 40, the ``hils`` setting) and solves each warm-started QP again without
the warm start. Prints per law: the warm-started solves, how many cold solutions differ from
the warm one, the largest difference over the solution's largest entry, and the mean DAQP
iterations cold and warm.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from capsule_env.agents.controllers import mpc_solver
from capsule_env.agents.controllers.classical import make_controller

from capsule_env.envs import CapsuleSuspensionVectorEnv

LAWS = ("mpc-biexp-meas", "preview-mpc-biexp-meas")


def compare(name: str, steps: int) -> dict[str, float]:
    """Run ``name`` for ``steps`` steps, re-solving each warm-started QP cold."""
    rows: list[tuple[float, int, int]] = []  # (relative difference, cold, warm iterations)
    solve = mpc_solver.BandQP._daqp

    def spy(problem, q, a, lower, upper):  # type: ignore[no-untyped-def]
        start = None if problem._last is None else problem._last.copy()
        out = solve(problem, q, a, lower, upper)
        if start is not None and out[0] is not None:
            args = (problem.hessian, q, a, np.minimum(upper, mpc_solver._BIG),
                    np.maximum(lower, -mpc_solver._BIG))  # fmt: skip
            cold, _, _, info = problem.backend.solve(*args, iter_limit=problem.options.max_iter)
            _, _, _, warm = problem.backend.solve(*args, primal_start=start,
                                                  iter_limit=problem.options.max_iter)  # fmt: skip
            diff = np.max(np.abs(cold - problem._last)) / np.max(np.abs(cold))
            rows.append((float(diff), int(info["iterations"]), int(warm["iterations"])))
        return out

    mpc_solver.BandQP._daqp = spy  # type: ignore[method-assign]
    try:
        law = make_controller(name)
        env = CapsuleSuspensionVectorEnv(num_envs=1, guideway_seed=3, setting="hils",
                                         episode_length_s=steps * 0.005 + 1.0, **law.env_kwargs)  # fmt: skip
        obs, _ = env.reset(seed=[40])
        for _ in range(steps):
            obs, *_ = env.step(law.predict(obs)[0])
        env.close()
    finally:
        mpc_solver.BandQP._daqp = solve  # type: ignore[method-assign]
    table = np.array(rows)
    return {"warm_solves": len(rows), "differ": int(np.sum(table[:, 0] > 0)),
            "max_rel_diff": float(table[:, 0].max()), "iterations_cold": float(table[:, 1].mean()),
            "iterations_warm": float(table[:, 2].mean())}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=400, help="control steps (10..4000)")
    args = parser.parse_args(argv)
    if not 10 <= args.steps <= 4000:
        print(f"--steps must be 10..4000, got {args.steps}", file=sys.stderr)
        return 2
    if not mpc_solver.solver_available():
        print("DAQP is not installed: pip install 'capsule-env[mpc]'", file=sys.stderr)
        return 2
    for name in LAWS:
        r = compare(name, args.steps)
        print(f"{name}: {r['warm_solves']} warm-started solves, {r['differ']} differ from a cold "
              f"start, by at most {r['max_rel_diff']:.1e} of the largest entry; iterations "
              f"{r['iterations_cold']:.1f} cold, {r['iterations_warm']:.1f} warm")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
