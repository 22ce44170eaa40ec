"""How low could any controller push the Wk-weighted body acceleration in ``hils``?

    python experiments/clairvoyant_bound.py                       # 5 episodes of 4 s
    python experiments/clairvoyant_bound.py --episodes 10 --duration 4 --json out.json

Issue 6 asks for a policy with at most 0.9 x the best Skyhook's ISO Wk-weighted RMS car-body
acceleration in ``hils``. This script asks what a *clairvoyant* controller could do: one that
knows the whole guideway in advance and sets the applied coil current at every step freely
in [0, i_max] (no sensor noise, no delay, no inverse model to get in its way). For each
held-out evaluation episode (the seeds ``evaluate.py`` uses, 1000, 1001, ...) it:

1. runs continuous Skyhook (``skyhook-cont-biexp``, the best Skyhook variant in ``hils``) and
   the passive damper through the env, recording what they did;
2. replays Skyhook's applied currents open loop through the plant kernel (a check that the
   replay is the env's plant: the body accelerations must agree);
3. searches the applied-current sequence that minimises the Wk-weighted RMS body acceleration
   over the episode with L-BFGS-B, starting from Skyhook's sequence and from zero current.
   Gradients are finite differences: one batched kernel call per gradient advances ``N + 1``
   copies of the vehicle, copy ``j + 1`` with step ``j``'s current nudged. The search uses a
   fixed 5 substeps per step (the adaptive rule's maximum: no substep count switching under
   the finite differences); the optimum is then re-evaluated with the env's adaptive rule.

What the numbers mean: the clairvoyant optimum is a lower bound for every controller on the
plant (causal controllers see less), but a local search only finds an *upper* bound on that
optimum. A result above the bar (0.9 x Skyhook) is evidence, not proof, that the bar is out of
reach; a result below it shows the plant has room and that what a controller knows (no
preview, noisy sensors, 5 ms delay, coil lag) is the limit.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from agents.classical import classical_controllers  # noqa: E402
from capsule_env import metrics  # noqa: E402
from capsule_env.envs.capsule_suspension import CapsuleSuspensionVectorEnv  # noqa: E402
from capsule_env.evaluation import (  # noqa: E402
    EVALUATION_GUIDEWAY_SEED,
    episode_metrics,
    run_episodes,
)
from capsule_env.layout import N_PLANT_OUTPUTS  # noqa: E402
from capsule_env.plant import Route, make_plant_params, step_batch  # noqa: E402

SKYHOOK = "skyhook-cont-biexp"


class Episode:
    """One evaluation episode's plant and guideway, replayed open loop for many current
    sequences at once (one vehicle per sequence, the env's kernel via ``step_batch``)."""

    def __init__(self, batch, k: int, n_steps: int) -> None:
        self.code = batch.plant.code
        self.dp, self.vp = batch.damper_params[k], batch.vehicle_params[k]
        self.state0 = batch.state[k].copy()
        self.profiles, self.spacing = batch.profiles, batch.spacing
        self.profile_index = int(batch.profile_index[k])
        self.start, self.speed, self.gain = (
            float(batch.start_position[k]), float(batch.speed[k]), float(batch.gain[k])
        )  # fmt: skip
        self.dt, self.table, self.i_max = batch.dt, batch.sub_table[k], batch.i_max
        self.n_steps = n_steps

    def replay(self, currents: np.ndarray, substeps: int | np.ndarray | None = None):
        """Applied currents (M, N) -> body acceleration, body displacement, stroke (M, N)."""
        m = currents.shape[0]
        tile = lambda row: np.ascontiguousarray(np.tile(row, (m, 1)))  # noqa: E731
        table = self.table if substeps is None else substeps
        plant = make_plant_params(self.code, tile(self.dp), tile(self.vp), table,
                                  self.profiles, self.spacing, self.dt)  # fmt: skip
        route = Route(np.full(m, self.profile_index, dtype=np.int64), np.full(m, self.start),
                      np.full(m, self.speed), np.full(m, self.gain))  # fmt: skip
        state = tile(self.state0)
        out = np.empty((m, N_PLANT_OUTPUTS))
        acc, disp, stroke = (np.empty((m, self.n_steps)) for _ in range(3))
        cmd = np.empty(m)
        for t in range(self.n_steps):
            cmd[:] = currents[:, t]
            step_batch(self.code, plant, state, cmd, route, self.dt, out)
            acc[:, t], disp[:, t], stroke[:, t] = out[:, 1], state[:, 0], state[:, 0] - state[:, 2]
        return acc, disp, stroke

    def wk(self, currents: np.ndarray, substeps=None) -> np.ndarray:
        return metrics.wk_weighted_rms(self.replay(currents, substeps)[0], self.dt)

    def objective(self, u: np.ndarray, delta: float = 1e-3) -> tuple[float, np.ndarray]:
        """Wk-weighted RMS body acceleration of sequence ``u`` and its finite-difference
        gradient (forward, or backward at the upper bound), one batched replay."""
        n = u.size
        nudges = np.where(u + delta <= self.i_max, delta, -delta)
        batch = np.repeat(u[None, :], n + 1, axis=0)
        batch[np.arange(1, n + 1), np.arange(n)] += nudges
        wk = self.wk(batch, substeps=FIXED_SUBSTEPS)
        return float(wk[0]), (wk[1:] - wk[0]) / nudges


FIXED_SUBSTEPS = 5


def applied_from_commands(commands: np.ndarray, delay_steps: int) -> np.ndarray:
    """The env's control delay: the current applied at step t is the command of t - delay."""
    applied = np.zeros_like(commands)
    applied[:, delay_steps:] = commands[:, : commands.shape[1] - delay_steps]
    return applied


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--episodes", type=int, default=5)
    p.add_argument("--seed", type=int, default=1000, help="first evaluation seed")
    p.add_argument("--duration", type=float, default=4.0, help="episode length (s)")
    p.add_argument("--max-iter", type=int, default=300, help="L-BFGS-B iterations per start")
    p.add_argument("--ftol", type=float, default=1e-12, help="L-BFGS-B relative tolerance")
    p.add_argument("--json", help="write the results here")
    args = p.parse_args(argv)

    controllers = classical_controllers()
    sky, passive = controllers[SKYHOOK], controllers["passive"]
    kwargs = {**sky.env_kwargs, "setting": "hils"}
    roll_sky = run_episodes(sky, kwargs, args.episodes, args.seed, args.duration)
    roll_pas = run_episodes(passive, {**passive.env_kwargs, "setting": "hils"}, args.episodes,
                            args.seed, args.duration)  # fmt: skip
    env = CapsuleSuspensionVectorEnv(
        num_envs=args.episodes, episode_length_s=args.duration,
        guideway_seed=EVALUATION_GUIDEWAY_SEED, **kwargs,
    )  # fmt: skip
    env.reset(seed=[args.seed + k for k in range(args.episodes)])  # as run_episodes
    batch, n_steps = env.batch, env.batch.max_steps
    delay = env.config.effective_control_delay_steps
    applied_sky = applied_from_commands(roll_sky.signals["current_command_a"], delay)
    sky_metrics = episode_metrics(roll_sky, roll_pas)
    print(f"{SKYHOOK} in hils over {args.episodes} episodes of {args.duration:g} s (seeds "
          f"{args.seed}..{args.seed + args.episodes - 1}): Wk "
          f"{sky_metrics['wk_rms_body_acc_m_s2']:.4f} m/s^2, first-mode VRE "
          f"{sky_metrics['vre_pct']['body_mode1']:.1f} %", flush=True)  # fmt: skip

    rows = []
    for k in range(args.episodes):
        ep = Episode(batch, k, n_steps)
        acc_replay = ep.replay(applied_sky[k : k + 1])[0][0]
        acc_env = roll_sky.signals["car_body_acceleration_m_s2"][k]
        replay_error = float(np.max(np.abs(acc_replay - acc_env)) / np.max(np.abs(acc_env)))
        wk_sky = float(metrics.wk_weighted_rms(acc_env, ep.dt))
        best_u, best_wk, t0, iterations = None, np.inf, time.perf_counter(), 0
        for start in (applied_sky[k], np.zeros(n_steps)):
            res = minimize(ep.objective, start, jac=True, method="L-BFGS-B",
                           bounds=[(0.0, ep.i_max)] * n_steps,
                           options={"maxiter": args.max_iter, "ftol": args.ftol,
                                    "gtol": 1e-12})  # fmt: skip
            iterations += int(res.nit)
            if res.fun < best_wk:
                best_u, best_wk = res.x, float(res.fun)
        acc_opt, disp_opt, stroke_opt = (a[0] for a in ep.replay(best_u[None, :]))
        wk_opt = float(metrics.wk_weighted_rms(acc_opt, ep.dt))  # the env's adaptive substeps
        vre_opt = float(
            metrics.vibration_reduction_effect(
                roll_pas.signals["car_body_displacement_m"][k], disp_opt, ep.dt,
                metrics.DEFAULT_BANDS_HZ["mode1"],
            )
        )  # fmt: skip
        row = {
            "seed": args.seed + k,
            "wk_skyhook_m_s2": wk_sky,
            "wk_clairvoyant_m_s2": wk_opt,
            "ratio": wk_opt / wk_sky,
            "vre_body_mode1_clairvoyant_pct": vre_opt,
            "max_stroke_m": float(np.max(np.abs(stroke_opt))),
            "mean_current_a": float(np.mean(best_u)),
            "replay_error_rel": replay_error,
            "iterations": iterations,
            "time_s": time.perf_counter() - t0,
        }
        rows.append(row)
        print(f"seed {row['seed']}: Skyhook Wk {wk_sky:.4f}, clairvoyant {wk_opt:.4f} "
              f"(x{row['ratio']:.3f}), first-mode VRE {vre_opt:.1f} %, max stroke "
              f"{1e3 * row['max_stroke_m']:.1f} mm, replay error {replay_error:.1e}, "
              f"{iterations} iterations, {row['time_s']:.0f} s", flush=True)  # fmt: skip
    wk_s = np.mean([r["wk_skyhook_m_s2"] for r in rows])
    wk_c = np.mean([r["wk_clairvoyant_m_s2"] for r in rows])
    summary = {
        "episodes": args.episodes,
        "duration_s": args.duration,
        "wk_skyhook_mean_m_s2": float(wk_s),
        "wk_clairvoyant_mean_m_s2": float(wk_c),
        "ratio_of_means": float(wk_c / wk_s),
        "bar": 0.9,
        "vre_body_mode1_skyhook_pct": sky_metrics["vre_pct"]["body_mode1"],
        "vre_body_mode1_clairvoyant_mean_pct": float(
            np.mean([r["vre_body_mode1_clairvoyant_pct"] for r in rows])
        ),
        "episodes_detail": rows,
    }
    print(f"mean Wk: Skyhook {wk_s:.4f}, clairvoyant {wk_c:.4f} (x{wk_c / wk_s:.3f}; the bar "
          f"is x0.9); first-mode VRE: Skyhook {summary['vre_body_mode1_skyhook_pct']:.1f} %, "
          f"clairvoyant {summary['vre_body_mode1_clairvoyant_mean_pct']:.1f} %")  # fmt: skip
    if args.json:
        Path(args.json).write_text(json.dumps(summary, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
