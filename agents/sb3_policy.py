"""Load a saved stable-baselines3 model (and its VecNormalize statistics) as a controller."""

from __future__ import annotations

import json
import pickle
from pathlib import Path
from typing import Any

import numpy as np

from agents.base import Controller

PRETRAINED_DIR = Path(__file__).resolve().parent.parent / "capsule_env" / "pretrained"
ALGORITHMS = ("ppo", "sac", "td3")


def shipped_policy_paths() -> list[str]:
    """The pretrained policies shipped with the package (may be empty)."""
    return [str(p) for p in sorted(PRETRAINED_DIR.glob("*.zip"))]


class SB3Policy(Controller):
    """A trained SB3 policy with the observation normalisation it was trained with.

    Files: ``NAME.zip`` (the SB3 model), and next to it ``NAME.vecnormalize.pkl`` (SB3's
    ``VecNormalize`` statistics, optional) and ``NAME.json`` (metadata written by
    ``train.py``: algorithm and the env arguments it was trained with, optional).
    """

    def __init__(self, model: Any, obs_rms: Any, clip_obs: float, epsilon: float, meta: dict):
        self.model = model
        self.obs_rms = obs_rms
        self.clip_obs = clip_obs
        self.epsilon = epsilon
        self.meta = meta
        self.name = meta.get("name", "policy")
        env_kwargs = dict(meta.get("env_kwargs", {}))
        # chosen by the evaluation, not the policy
        for key in ("setting", "guideway_seed", "episode_length_s"):
            env_kwargs.pop(key, None)
        self.env_kwargs = env_kwargs
        self.uses_unmeasured_signals = env_kwargs.get("observation") == "full_state"

    @classmethod
    def load(cls, path: str | Path) -> SB3Policy:
        """Load ``path`` (a ``.zip``); raises ``ValueError`` with the reason if it is not one."""
        path = Path(path)
        if path.suffix != ".zip" or not path.is_file():
            raise ValueError(f"policy path must be an existing SB3 .zip file, got {path}")
        stem = path.with_suffix("")
        meta_path = stem.with_suffix(".json")
        meta = json.loads(meta_path.read_text()) if meta_path.is_file() else {}
        meta.setdefault("name", stem.name)
        algo = meta.get("algo", "ppo")
        if algo not in ALGORITHMS:
            raise ValueError(f"unknown algo {algo!r} in {meta_path}; accepted: {ALGORITHMS}")
        import stable_baselines3 as sb3

        model = getattr(sb3, algo.upper()).load(str(path), device="cpu")
        norm_path = Path(str(stem) + ".vecnormalize.pkl")
        obs_rms, clip_obs, eps = None, 10.0, 1e-8
        if norm_path.is_file():
            with norm_path.open("rb") as fh:
                vec_normalize = pickle.load(fh)
            if getattr(vec_normalize, "norm_obs", True):
                obs_rms = vec_normalize.obs_rms
            clip_obs = float(vec_normalize.clip_obs)
            eps = float(vec_normalize.epsilon)
        return cls(model, obs_rms, clip_obs, eps, meta)

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        if self.obs_rms is None:
            return obs
        scaled = (obs - self.obs_rms.mean) / np.sqrt(self.obs_rms.var + self.epsilon)
        return np.clip(scaled, -self.clip_obs, self.clip_obs).astype(np.float32)

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        obs = self.normalize(np.atleast_2d(np.asarray(observation, dtype=np.float32)))
        action, state = self.model.predict(
            obs, state=state, episode_start=episode_start, deterministic=deterministic
        )
        return np.clip(np.asarray(action, dtype=np.float32), -1.0, 1.0), state
