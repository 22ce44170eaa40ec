"""Does the half-car's reward rank policies as its comfort metric does? A check of the cause
``docs/half-car.md`` names for the learned policies' drift (trained on the reward, judged on Wk).

    python experiments/half_car_reward_check.py --runs runs/half_car_residual --residual \
        --out runs/half_car_reward_check.json
    python experiments/half_car_reward_check.py --runs runs/half_car_residual --residual \
        --bank validation --checkpoints --out runs/half_car_reward_curve.json

Read top to bottom: each saved seed of ``experiments/half_car_ppo.py`` (its deterministic
policy) and the per-bogie clipped LQR it rides on run the same held-out episodes (evaluation
bank 2026, episodes 1000..1009, 10 s); for each, the episode's return (the env's reward summed
over the episode, undiscounted) split into its three cost terms (``info['cost_*']``: the floor
points' unweighted accelerations, the strokes, the coil currents) and the Wk headline. If a
policy earns more reward than the law while riding worse on Wk, the reward and the metric
disagree on that pair; the output counts such pairs, episode by episode. ``--checkpoints``
adds every saved checkpoint of each seed (``step_<n>``, the learning curve); ``--bank
validation`` runs the validation bank (guideway seed 7, episodes 5000..5009) instead, the bank
for looking at a learning curve without touching the evaluation bank.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

TERMS = ("cost_acceleration", "cost_stroke", "cost_energy")
#: The residual's scale (``experiments/half_car_ppo.py``'s ``RESIDUAL_SCALE``).
RESIDUAL_SCALE = 0.5


BANKS = {"evaluation": (2026, 1000), "validation": (7, 5000)}  # guideway seed, first episode


class Saved:
    """A saved checkpoint's deterministic action (its normaliser inside); with ``residual``
    the per-bogie law's action plus half of it, clipped (``half_car_ppo.py``'s residual)."""

    def __init__(self, stem: Path, residual: bool) -> None:
        import pickle

        from stable_baselines3 import PPO

        self.model = PPO.load(f"{stem}.zip", device="cpu")
        with open(f"{stem}.vecnormalize.pkl", "rb") as f:
            self.norm = pickle.load(f)
        self.law = Law() if residual else None

    def predict(self, obs: np.ndarray) -> tuple[np.ndarray, None]:
        action, _ = self.model.predict(self.norm.normalize_obs(obs), deterministic=True)
        if self.law is not None:
            base = self.law.predict(obs)[0]
            action = np.clip(base + RESIDUAL_SCALE * action, -1.0, 1.0)
        return action, None


class Law:
    """The per-bogie clipped LQR the residual rides on (memoryless)."""

    def __init__(self) -> None:
        from capsule_env.agents.controllers.declared_lqr import IndependentClippedLQR

        self.law = IndependentClippedLQR()

    def predict(self, obs: np.ndarray) -> tuple[np.ndarray, None]:
        return self.law.act(np.asarray(obs, dtype=np.float64)), None


def run(policy: Any, episodes: list[int], guideway_seed: int) -> dict[str, np.ndarray]:
    """Per episode: the return, its cost terms (summed over steps) and the Wk headline."""
    from capsule_env.envs.declared_vector import DeclaredVectorEnv
    from capsule_env.evaluation.half_car import TASK_KWARGS
    from capsule_env.metrics import wk_weighted_rms

    env = DeclaredVectorEnv(len(episodes), guideway_seed=guideway_seed,
                            episode_length_s=10.0, **TASK_KWARGS)  # fmt: skip
    obs, _ = env.reset(seed=episodes)
    sums = {k: np.zeros(len(episodes)) for k in ("return", *TERMS)}
    acc = []
    for _ in range(env.batch.max_steps):
        obs, reward, _, _, info = env.step(policy.predict(obs)[0])
        sums["return"] += reward
        for k in TERMS:
            sums[k] += info[k]
        acc.append(info["comfort_acceleration_m_s2"])
    wk = wk_weighted_rms(np.stack(acc, axis=2), env.batch.dt).mean(axis=1)
    return {**sums, "wk_rms_body_acc_m_s2": wk}


def _stems(runs: Path, checkpoints: bool) -> dict[str, Path]:
    """``seed<k>`` (its final policy) and, with ``checkpoints``, ``seed<k>/step_<n>``."""
    stems = {}
    for folder in sorted(runs.glob("seed*")):
        if (folder / "final.zip").exists():
            saved = sorted(folder.glob("step_*.zip"), key=lambda p: int(p.stem[5:]))
            for p in saved if checkpoints else []:
                stems[f"{folder.name}/{p.stem}"] = p.with_suffix("")
            stems[folder.name] = folder / "final"
    return stems


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", required=True, type=Path, help="a half_car_ppo.py run folder")
    p.add_argument("--residual", action="store_true", help="the run is a residual on the law")
    p.add_argument("--bank", choices=tuple(BANKS), default="evaluation")
    p.add_argument("--checkpoints", action="store_true", help="every saved checkpoint too")
    p.add_argument("--out", required=True, type=Path)
    a = p.parse_args(argv)
    stems = _stems(a.runs, a.checkpoints)
    if not stems:
        p.exit(2, f"error: --runs must hold seed<k>/final.zip, got {a.runs}\n")
    guideway_seed, first = BANKS[a.bank]
    episodes = list(range(first, first + 10))
    rows = {"lqr-clipped-biexp-meas": run(Law(), episodes, guideway_seed)}
    for name, stem in stems.items():
        rows[name] = run(Saved(stem, a.residual), episodes, guideway_seed)
    law = rows["lqr-clipped-biexp-meas"]
    out: dict[str, Any] = {"command": "python experiments/half_car_reward_check.py "
                           + " ".join(argv or sys.argv[1:]), "guideway_seed": guideway_seed,
                           "episodes": episodes}  # fmt: skip
    for name, r in rows.items():
        out[name] = {k: float(v.mean()) for k, v in r.items()}
        if r is not law:  # the episodes on which the reward and Wk rank it against the law apart
            more_reward = r["return"] > law["return"]
            worse_wk = r["wk_rms_body_acc_m_s2"] > law["wk_rms_body_acc_m_s2"]
            out[name]["episodes_more_reward_and_worse_wk"] = int(np.sum(more_reward & worse_wk))
            out[name]["episodes_less_reward_and_better_wk"] = int(np.sum(~more_reward & ~worse_wk))
        print(name, {k: round(v, 5) for k, v in out[name].items()})
    with tempfile.NamedTemporaryFile("w", dir=a.out.parent, suffix=".tmp", delete=False) as f:
        json.dump(out, f, indent=1)
    os.replace(f.name, a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
