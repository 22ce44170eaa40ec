"""Evaluate controllers on the half-car task ``CapsuleHalfRide-v0`` (a declared vehicle).

The comfort metric: the ISO 2631-1 Wk-weighted RMS vertical acceleration of the car body's floor
at three points, over the front bogie, at the centre of mass and over the rear bogie (Wk: the
weighting for vertical vibration of a seated or standing person, as on the quarter-car tasks);
the headline ``wk_rms_body_acc_m_s2`` is their mean, the name the quarter-car tasks' evaluation
uses, so tables compare across tasks. Beside it: the pitch acceleration's We-weighted RMS
(rad/s^2; ISO 2631-1's weighting for rotational vibration; the standard's factor k = 0.40 for
pitch at a seat surface is not applied), ``pitch = (a_front - a_rear) / (a + b)``.

Episodes: the evaluation bank (``guideway_seed`` 2026), episode seeds 1000.. (the quarter-car
tasks'); the coupled law's weights are tuned on the training bank (``guideway_seed`` 0, episode
seeds 0..9). Intervals: 95 % bootstrap over the episodes (paired for ratios), seeded.

    python -m capsule_env.evaluation.half_car --out docs/figures/evaluation-CapsuleHalfRide-v0.json
    python -m capsule_env.evaluation.evaluate --task CapsuleHalfRide-v0 --oracle --json F  # the same

``--tune`` re-tunes the coupled law's weights (about a minute); ``--oracle-iterations N`` adds
the oracle (started from the best law's own currents, so never worse than it; ``evaluate.py
--oracle``: :data:`ORACLE_ITERATIONS`). The shipped policies trained on the task
(``capsule_env/pretrained``, e.g. ``residual-ppo-mpc-half-car``) are rows too unless
``--no-shipped-policy``. The JSON has ``evaluate.py``'s layout (:func:`evaluation_results`):
each row under ``settings.hils.controllers`` with the headline ``wk_rms_body_acc_m_s2`` and what
the row reads, so that the task cards and tables read every task's file alike.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import sys
import tempfile
from typing import Any

import numpy as np

from capsule_env.common.cli import ArgumentParser
from capsule_env.common.safe_io import check_writable_file
from capsule_env.engine.config import check_seed
from capsule_env.envs.declared_vector import DeclaredVectorEnv
from capsule_env.metrics import we_weighted_rms, wk_weighted_rms

__all__ = ["TASK_KWARGS", "tuned_mpc", "rollout", "episode_metrics", "tune_coupled", "shipped_policies",
           "evaluate", "evaluation_results", "layout", "format_rows", "run_cli", "main"]  # fmt: skip

#: The task evaluated here, and its options (``capsule_env.tasks.DECLARED_TASKS``).
TASK_ID = "CapsuleHalfRide-v0"
TASK_KWARGS: dict[str, Any] = {"vehicle": "half_car", "setting": "hils", "observation": "measured"}
EVALUATION_GUIDEWAY_SEED, TRAINING_GUIDEWAY_SEED = 2026, 0
#: The coupled law's weights when not re-tuned: ``--tune``'s result (``docs/half-car.md``).
TUNED_COUPLED = {"q_stroke": 0.001, "q_levitation": 0.1, "r_force": 3e-8}
#: The oracle's L-BFGS-B iterations with ``evaluate.py --oracle`` (the page's figures').
ORACLE_ITERATIONS = 30
_GRID = {"q_stroke": (0.001, 0.01, 0.1, 1.0), "q_levitation": (0.1, 1.0, 10.0, 100.0),
         "r_force": (1e-8, 3e-8, 1e-7)}  # fmt: skip
#: The half-car MPCs' weights, :func:`tune_mpc`'s result on the training bank over
#: :data:`MPC_GRID` (``docs/half-car.md``).
TUNED_MPC = {"mpc-coupled-biexp-meas": {"q_stroke": 0.001, "q_levitation": 0.1, "r_force": 7e-8},
             "wheelbase-mpc-biexp-meas": {"q_stroke": 0.001, "q_levitation": 0.1,
                                          "r_force": 5e-8}}  # fmt: skip
MPC_GRID = {"q_stroke": (0.001, 1.0), "q_levitation": (0.1, 10.0),
            "r_force": (1e-8, 2e-8, 3e-8, 4e-8, 5e-8, 7e-8, 1e-7, 3e-7)}  # fmt: skip


def rollout(policy: Any, seeds: list[int], guideway_seed: int, length_s: float = 10.0) -> dict:
    """``policy`` (``predict(obs) -> (actions, state)``, or None: the passive damper) on the
    episodes ``seeds``: the comfort points' accelerations (E, 3, T), the applied currents
    (E, T, slots), the strokes' largest magnitude (E,) and whether each ended at the bump stop."""
    episodes = _check_seeds(seeds)
    kwargs = dict(TASK_KWARGS, **(policy.env_kwargs if policy is not None else {}))
    if policy is None:
        kwargs["damper"] = "passive"
    env = DeclaredVectorEnv(len(episodes), guideway_seed=guideway_seed, episode_length_s=length_s,
                            **{k: v for k, v in kwargs.items() if k != "vehicle_params"})  # fmt: skip
    obs, _ = env.reset(seed=episodes)
    if hasattr(policy, "reset"):  # a law with memory (the wheelbase window) starts afresh
        policy.reset()
    steps = env.batch.max_steps
    acc, currents = [], []
    stroke = np.zeros(len(episodes))
    ended = np.zeros(len(episodes), dtype=bool)
    for _ in range(steps):
        actions = (
            np.zeros((len(episodes), env.batch.n_slots))
            if policy is None
            else policy.predict(obs)[0]
        )
        obs, _, terminated, _, info = env.step(actions)
        acc.append(info["comfort_acceleration_m_s2"])
        currents.append(env.batch.command.copy())
        stroke = np.maximum(stroke, np.abs(info["stroke_m"]).max(axis=1))
        ended |= terminated
    values = env.batch.values
    return {"acc": np.stack(acc, axis=2), "currents": np.stack(currents, axis=1),
            "max_stroke_m": stroke, "terminated": ended, "dt_s": env.batch.dt,
            "wheelbase_m": values["front_bogie_position_m"] - values["rear_bogie_position_m"]}  # fmt: skip


def _check_seeds(seeds: Any) -> list[int]:
    """``seeds`` as a list of ints; ``TypeError``/``ValueError`` naming ``seeds`` unless a
    non-empty list (tuple, range, array) of integer episode seeds in ``[0, 2**63)``."""
    if not isinstance(seeds, (list, tuple, range, np.ndarray)) or len(seeds) == 0:
        raise ValueError(f"seeds must be a non-empty list of episode seeds (integers in "
                         f"[0, 2**63)), got {seeds!r}")  # fmt: skip
    return [check_seed(f"seeds[{k}]", s) for k, s in enumerate(seeds)]


def episode_metrics(roll: dict) -> dict[str, np.ndarray]:
    """Per episode: Wk at each floor point, their mean (the headline), the pitch's We."""
    wk = wk_weighted_rms(roll["acc"], roll["dt_s"])  # (E, 3)
    pitch = (roll["acc"][:, 0] - roll["acc"][:, 2]) / roll["wheelbase_m"]
    return {"wk_rms_body_acc_m_s2": wk.mean(axis=1), "wk_front_m_s2": wk[:, 0],
            "wk_centre_m_s2": wk[:, 1], "wk_rear_m_s2": wk[:, 2],
            "we_rms_pitch_rad_s2": we_weighted_rms(pitch, roll["dt_s"]),
            "max_stroke_m": roll["max_stroke_m"],
            "terminated": roll["terminated"].astype(float)}  # fmt: skip


def _interval(x: np.ndarray, seed: int = 0, reps: int = 10_000) -> list[float]:
    """95 % bootstrap interval of the mean over episodes."""
    rng = np.random.default_rng(seed)
    means = x[rng.integers(0, len(x), (reps, len(x)))].mean(axis=1)
    return [float(np.quantile(means, 0.025)), float(np.quantile(means, 0.975))]


def _ratio_interval(x: np.ndarray, y: np.ndarray, seed: int = 0, reps: int = 10_000) -> list:
    """95 % paired bootstrap interval of ``mean(x) / mean(y)`` over the same episodes."""
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, len(x), (reps, len(x)))
    ratios = x[idx].mean(axis=1) / y[idx].mean(axis=1)
    return [float(np.quantile(ratios, 0.025)), float(np.quantile(ratios, 0.975))]


def tune_coupled(seeds: list[int] | None = None, length_s: float = 10.0,
                 make: Any = None, grid: dict | None = None) -> dict[str, float]:  # fmt: skip
    """The weights with the lowest mean headline Wk on the training bank, on a grid (default
    :data:`_GRID`) of the law ``make(**weights)`` (default the coupled clipped LQR)."""
    from capsule_env.agents.controllers.declared_lqr import DeclaredClippedLQR

    def coupled(**weights: float) -> Any:
        return DeclaredClippedLQR("half_car", observation="measured", **weights)

    seeds = list(range(10)) if seeds is None else seeds
    grid, make = _GRID if grid is None else grid, make or coupled
    best, best_wk = dict(TUNED_COUPLED), np.inf
    for values in itertools.product(*grid.values()):
        weights = dict(zip(grid, values, strict=True))
        law = make(**weights)
        wk = float(episode_metrics(rollout(law, seeds, TRAINING_GUIDEWAY_SEED, length_s))[
            "wk_rms_body_acc_m_s2"].mean())  # fmt: skip
        if wk < best_wk:
            best, best_wk = weights, wk
    return best


def tune_mpc(name: str, seeds: list[int] | None = None) -> dict[str, float]:
    """The weights of the half-car MPC ``name`` (a key of :data:`TUNED_MPC`) on the training
    bank, over :data:`MPC_GRID` (32 runs of the 10 training episodes; about 15 minutes)."""
    from capsule_env.agents.controllers.half_car_mpc import HalfCarMPC

    if not isinstance(name, str) or name not in TUNED_MPC:
        raise ValueError(f"name must be one of {', '.join(TUNED_MPC)}, got {name!r}")
    preview = name.startswith("wheelbase")
    return tune_coupled(seeds, make=lambda **w: HalfCarMPC(**w, preview=preview), grid=MPC_GRID)


def tuned_mpc(name: str) -> Any:
    """The half-car MPC ``name`` (a key of :data:`TUNED_MPC`) at its tuned weights: what the
    task's rows, the residual policies trained on it and their loader run."""
    from capsule_env.agents.controllers.half_car_mpc import HalfCarMPC

    if not isinstance(name, str) or name not in TUNED_MPC:
        raise ValueError(f"name must be one of {', '.join(TUNED_MPC)}, got {name!r}")
    w = TUNED_MPC[name]
    law = HalfCarMPC(w["q_stroke"], w["q_levitation"], w["r_force"],
                     preview=name.startswith("wheelbase"))  # fmt: skip
    law.gains_tuned = True
    return law


def _mpc_laws() -> dict[str, Any]:
    """The half-car MPCs with their tuned weights (:data:`TUNED_MPC`)."""
    return {name: tuned_mpc(name) for name in TUNED_MPC}


def _solver_figures(name: str, law: Any) -> dict[str, float]:
    """An MPC row's solver figures over its evaluation: QP solves per vehicle-step and the
    steps that fell back to the LQ law (in the row); the plans' wall time per vehicle-step,
    which depends on the machine and its load, on stderr only."""
    c = law.counters
    steps = max(c["vehicle_steps"], 1)
    print(f"{name}: {c['solves'] / steps:.2f} QP solves and {1e6 * c['solve_time_s'] / steps:.0f}"
          f" us of planning per vehicle-step, {c['fallback_steps']} fallbacks in "
          f"{c['vehicle_steps']} vehicle-steps", file=sys.stderr)  # fmt: skip
    return {"solves_per_step": c["solves"] / steps, "fallback_steps": int(c["fallback_steps"]),
            "vehicle_steps": int(c["vehicle_steps"])}  # fmt: skip


def _own_shipped() -> dict[str, str]:
    """The files of the shipped policies trained on this task (their metadata's
    ``env_kwargs`` are the task's options, the action mode aside), by name."""
    from capsule_env.agents.learning.sb3_policy import shipped_policy_paths

    own = {}
    for path in shipped_policy_paths():
        with open(path[: -len(".zip")] + ".json") as f:
            meta = json.load(f)
        kwargs = {k: v for k, v in meta.get("env_kwargs", {}).items() if k != "action_mode"}
        if kwargs == TASK_KWARGS:
            own[str(meta.get("name", os.path.basename(path)[: -len(".zip")]))] = path
    return own


def shipped_policies() -> dict[str, Any]:
    """The shipped policies trained on this task, loaded, by name (a residual one with the
    law it rides on)."""
    from capsule_env.agents.learning.sb3_policy import load_policy, use_one_torch_thread

    own = _own_shipped()
    if own:
        use_one_torch_thread()
    return {name: load_policy(path) for name, path in own.items()}


def _describe(law: Any, name: str) -> dict[str, Any]:
    """What a row reads (as ``evaluate.py``'s rows say it): its observation set, whether that
    includes unmeasured signals, whether it previews the surveyed guideway, its gains, and
    the env options it ran with (the policies' file beside a shipped one)."""
    if name == "oracle":
        return {"observation": "oracle", "uses_unmeasured_signals": True, "preview": True,
                "gains": {}, "gains_tuned": False, "env_kwargs": dict(TASK_KWARGS)}  # fmt: skip
    if law is None:  # passive
        return {"observation": "none", "uses_unmeasured_signals": False, "preview": False,
                "gains": {}, "gains_tuned": False,
                "env_kwargs": dict(TASK_KWARGS, damper="passive")}  # fmt: skip
    return {"observation": law.observation,
            "uses_unmeasured_signals": bool(law.uses_unmeasured_signals),
            "preview": bool(law.preview), "gains": law.gains(),
            "gains_tuned": name in ("lqr-clipped-biexp-meas", "lqr-coupled-biexp-meas")
            or bool(getattr(law, "gains_tuned", False)),
            "env_kwargs": {**TASK_KWARGS, **law.env_kwargs}}  # fmt: skip


def evaluate(seeds: list[int], coupled: dict[str, float], oracle_iterations: int = 0,
             shipped: bool = True, survey_laws: dict[str, Any] | None = None) -> dict:  # fmt: skip
    """Every row's metrics (means and intervals over the episodes ``seeds``) and what it
    reads; the shipped policies trained on the task among them when ``shipped``;
    ``survey_laws`` (name -> law, on ``CapsuleHalfRidePreview-v0``) rows after the laws."""
    from capsule_env.agents.controllers.declared_lqr import (
        DeclaredClippedLQR,
        IndependentClippedLQR,
    )
    from capsule_env.agents.controllers.wheelbase import (
        WheelbaseExactPreviewLQ,
        WheelbasePreviewLQ,
    )

    w = (coupled["q_stroke"], coupled["q_levitation"], coupled["r_force"])
    laws: dict[str, Any] = {"passive": None, "lqr-clipped-biexp-meas": IndependentClippedLQR(),
            "lqr-coupled-biexp-meas": DeclaredClippedLQR("half_car", observation="measured",
                                                         **coupled),
            "lq-discrete-biexp-meas": WheelbasePreviewLQ(*w, preview=False),
            "wheelbase-lq-biexp-meas": WheelbasePreviewLQ(*w),
            "wheelbase-lq-biexp-exact": WheelbaseExactPreviewLQ(*w), **_mpc_laws()}  # fmt: skip
    laws.update(survey_laws or {})
    classical = list(laws)
    if shipped:
        laws.update(shipped_policies())
    rolls = {name: rollout(law, seeds, EVALUATION_GUIDEWAY_SEED) for name, law in laws.items()}
    metrics = {name: episode_metrics(r) for name, r in rolls.items()}
    if oracle_iterations:
        starts = {n: rolls[n] for n in classical}  # the oracle starts from a law's currents
        metrics["oracle"] = _oracle(seeds, starts, metrics, oracle_iterations,
                                    set(survey_laws or ()))  # fmt: skip
    reference = metrics["lqr-clipped-biexp-meas"]["wk_rms_body_acc_m_s2"]
    rows = {}
    for name, m in metrics.items():
        head = m["wk_rms_body_acc_m_s2"]
        rows[name] = {k: float(np.mean(v)) for k, v in m.items()}
        rows[name].update(_describe(laws.get(name), name))
        rows[name]["wk_rms_body_acc_m_s2_ci95"] = _interval(head)
        rows[name]["ratio_to_independent_lqr"] = float(head.mean() / reference.mean())
        rows[name]["ratio_to_independent_lqr_ci95"] = _ratio_interval(head, reference)
        rows[name]["per_episode_wk_m_s2"] = head.tolist()
        if "solve_time_s" in getattr(laws.get(name), "counters", {}):  # an MPC's
            rows[name]["solver"] = _solver_figures(name, laws[name])
    return rows


def _oracle(seeds: list[int], rolls: dict, metrics: dict, iterations: int,
            survey: set[str] | frozenset[str] = frozenset()) -> dict:  # fmt: skip
    """The oracle's metrics (its applied currents replayed on the plant), started from the
    best law's own applied currents (so never worse than it) and, when the best law is one of
    ``survey`` (the preview task's), also from the best law's without it: the search of
    ``CapsuleHalfRide-v0``'s oracle on the same plant and episodes (the survey changes what a
    law reads, not the plant), so the preview task's oracle is never above that one either."""
    from capsule_env.oracle.declared import DeclaredEpisodes, declared_oracle

    def best_of(names: list[str]) -> str:
        return min(names, key=lambda n: metrics[n]["wk_rms_body_acc_m_s2"].mean())

    laws = [n for n in rolls if n != "passive" and not n.endswith("-exact")]
    starts = list(dict.fromkeys([best_of([n for n in laws if n not in survey]), best_of(laws)]))
    kwargs = dict(TASK_KWARGS, guideway_seed=EVALUATION_GUIDEWAY_SEED)
    result = declared_oracle(kwargs, seeds, starts=[rolls[n]["currents"] for n in starts],
                             max_iterations=iterations)  # fmt: skip
    best = starts[0]
    episodes = DeclaredEpisodes(kwargs, seeds)
    states, outs = episodes.run(np.arange(len(seeds)), result.currents)
    limit = episodes.objective.max_stroke_m
    roll = {"acc": episodes.comfort_acc(outs), "max_stroke_m": result.max_stroke_m,
            "terminated": result.max_stroke_m > limit, "dt_s": episodes.dt_s,
            "wheelbase_m": rolls[best]["wheelbase_m"]}  # fmt: skip
    return episode_metrics(roll)


def evaluation_results(seeds: list[int], oracle_iterations: int = 0, shipped: bool = True,
                       command: str = "", tune: bool = False) -> dict[str, Any]:  # fmt: skip
    """The evaluation of the episodes ``seeds`` in ``evaluate.py``'s layout (:func:`layout`),
    and the half-car's own: the guideway bank and the coupled law's weights."""
    coupled = tune_coupled() if tune else dict(TUNED_COUPLED)
    rows = evaluate(seeds, coupled, oracle_iterations, shipped)
    return layout(TASK_ID, TASK_KWARGS, seeds, rows, command, coupled, shipped)


def layout(task_id: str, task_kwargs: dict[str, Any], seeds: list[int], rows: dict,
           command: str, coupled: dict[str, float], shipped: bool) -> dict[str, Any]:  # fmt: skip
    """``evaluate.py``'s JSON layout of a half-car task's ``rows``: ``condition``, ``episodes``
    (their number), ``seeds`` (first and last), ``policies`` (each shipped policy's file) and
    ``settings.hils.controllers`` (a row per law, policy and the oracle), with the guideway
    bank and the coupled law's weights."""
    from capsule_env.agents.learning.policy_files import shown_path

    policies = _own_shipped() if shipped else {}
    return {"task": task_id, "command": command,
            "condition": {"task": task_id, "task_env_kwargs": dict(task_kwargs),
                          "env_overrides": {}, "env_kwargs": dict(task_kwargs),
                          "settings": ["hils"], "episode_length_s": 10.0},
            "episodes": len(seeds), "seeds": [seeds[0], seeds[-1]],
            "guideway_seed": EVALUATION_GUIDEWAY_SEED, "coupled_weights": coupled,
            "policies": {name: shown_path(path) for name, path in policies.items()},
            "settings": {"hils": {"controllers": rows}}}  # fmt: skip


def format_rows(results: dict[str, Any]) -> str:
    """The rows of :func:`evaluation_results` as a Markdown table (Wk with its interval, the
    ratio to the per-bogie LQR, the three points, the pitch)."""
    lines = ["| row | Wk mean of 3 points (m/s²) [95 % CI] | x per-bogie LQR | "
             "front / centre / rear | pitch We (rad/s²) |", "| --- | --- | --- | --- | --- |"]  # fmt: skip
    for name, r in results["settings"]["hils"]["controllers"].items():
        low, high = r["wk_rms_body_acc_m_s2_ci95"]
        lines.append(f"| {name} | {r['wk_rms_body_acc_m_s2']:.4f} [{low:.4f}, {high:.4f}] | "
                     f"{r['ratio_to_independent_lqr']:.4f} | {r['wk_front_m_s2']:.3f} / "
                     f"{r['wk_centre_m_s2']:.3f} / {r['wk_rear_m_s2']:.3f} | "
                     f"{r['we_rms_pitch_rad_s2']:.4f} |")  # fmt: skip
    return "\n".join(lines)


def write_json(path: str, text: str) -> None:
    """``text`` into ``path``, atomically (the folder must exist)."""
    folder = os.path.dirname(os.path.abspath(path))
    with tempfile.NamedTemporaryFile("w", dir=folder, delete=False, suffix=".tmp") as f:
        try:
            f.write(text)
            f.close()
            os.replace(f.name, path)
        except BaseException:  # nothing left behind; the old file, if any, as it was
            if os.path.exists(f.name):
                os.unlink(f.name)
            raise


def main(argv: list[str] | None = None) -> int:
    return run_cli(argv, "half_car", __doc__.split("\n\n")[0], evaluation_results,
                   "re-tune the coupled law's weights")  # fmt: skip


def run_cli(argv: list[str] | None, module: str, description: str, results: Any,
            tune_help: str) -> int:  # fmt: skip
    """A half-car task's evaluation on the command line (``python -m
    capsule_env.evaluation.<module>``): ``results`` (:func:`evaluation_results`'s signature)
    as a table, into ``--out`` as JSON. Bad input: one line on stderr, exit status 2."""
    prog = f"python -m capsule_env.evaluation.{module}"
    p = ArgumentParser(prog=prog, description=description)  # usage errors: one line, exit 2
    p.add_argument("--out", default="", help="JSON file to write (atomically)")
    p.add_argument("--episodes", type=int, default=10, help="evaluation episodes (>= 2)")
    p.add_argument("--tune", action="store_true", help=tune_help)
    p.add_argument("--oracle-iterations", type=int, default=0, help="L-BFGS-B iterations (0: none)")
    p.add_argument("--no-shipped-policy", action="store_true", help="no shipped policy's row")
    args = p.parse_args(argv)
    problem = _args_problem(args)
    if problem:
        print(f"{prog}: error: {problem}", file=sys.stderr)
        return 2
    command = f"{prog} " + " ".join(argv or sys.argv[1:])
    result = results(list(range(1000, 1000 + args.episodes)), args.oracle_iterations,
                     not args.no_shipped_policy, command, args.tune)  # fmt: skip
    print(format_rows(result))  # first: a failed write below still shows the results
    if args.out:
        try:
            write_json(args.out, json.dumps(result, indent=1))
        except OSError as exc:
            print(f"{prog}: error: cannot write --out {args.out} ({exc.strerror or exc})",
                  file=sys.stderr)  # fmt: skip
            return 1
    return 0


def _args_problem(args: argparse.Namespace) -> str | None:
    """Why ``run_cli``'s arguments cannot run (one line), checked before the minutes of the
    evaluation: the counts' ranges, and ``--out`` a writable file in an existing folder."""
    if args.episodes < 2 or args.oracle_iterations < 0:
        return (f"--episodes must be >= 2 and --oracle-iterations >= 0, got {args.episodes} "
                f"and {args.oracle_iterations}")  # fmt: skip
    if args.out and not os.path.isdir(os.path.dirname(os.path.abspath(args.out))):
        return f"--out's folder must exist, got {args.out!r}"
    if args.out:
        try:
            check_writable_file(args.out, "--out")
        except ValueError as exc:
            return str(exc)
    return None


if __name__ == "__main__":
    sys.exit(main())
