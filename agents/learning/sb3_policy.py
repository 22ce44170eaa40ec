"""Load a saved stable-baselines3 model (and its VecNormalize statistics) as a controller."""

from __future__ import annotations

import copy
import json
import pickle
from pathlib import Path
from typing import Any

import numpy as np
from capsule_env.agents.controllers.base import Controller
from capsule_env.agents.learning.algorithms import ALGORITHMS as ALGORITHM_CLASSES
from capsule_env.agents.learning.algorithms import algorithm_class
from capsule_env.agents.learning.policy_files import (
    digests_problem,
    readable_stem,
    recorded_digests,
    sibling,
)

import capsule_env

PRETRAINED_DIR = Path(capsule_env.__file__).resolve().parent / "pretrained"
ALGORITHMS = tuple(ALGORITHM_CLASSES)


#: The env options a controller declares about how it reads and acts
#: (:attr:`Controller.env_kwargs`) and those the evaluation chooses: a shipped policy's own
#: values of these never keep it out of an evaluation (it runs with them).
READING_OPTIONS = ("setting", "guideway_seed", "episode_length_s", "observation", "action_mode",
                   "inverse_model", "max_force_n", "damper", "preview_points",
                   "preview_horizon_s")  # fmt: skip


def fits_condition(own: dict[str, Any], condition: dict[str, Any]) -> bool:
    """Whether a policy trained with the env options ``own`` belongs in the default evaluation
    of an env with the options ``condition`` (``{}``: the paper's env).

    True when (1) every option of ``own`` other than :data:`READING_OPTIONS` has the value the
    condition gives it (the env's default where the condition names none), i.e. the policy
    runs in the physics it is evaluated for, and (2) the env it runs in (the condition with
    ``own`` over it, as ``evaluate.py`` runs every controller) gives the observation columns
    it was trained on. So ``ppo-trip`` (trained on ``CapsuleTrip-v0``) is evaluated on that
    task and not in the paper's env, and ``ppo-measured`` on the paper's env (and any speed
    or payload given with ``--env``) but not on the trip task, whose observation has two more
    columns. Options that are not valid together count as not fitting."""
    from capsule_env.engine.config import EnvConfig

    setting = {"setting": own.get("setting", condition.get("setting", "sim"))}
    reads = {k: v for k, v in own.items() if k in READING_OPTIONS}
    try:
        asked = EnvConfig.from_kwargs(**{**condition, **reads, **setting})
        runs_in = EnvConfig.from_kwargs(**{**condition, **own, **setting})
        trained = EnvConfig.from_kwargs(**own)
    except (ValueError, TypeError):
        return False
    return asked == runs_in and runs_in.observation_names == trained.observation_names


def _training_options(zip_path: Path) -> dict[str, Any]:
    """The env options a saved policy was trained with (its ``.json``'s ``env_kwargs``)."""
    meta_path = sibling(readable_stem(zip_path), ".json")
    if not meta_path.is_file():
        return {}
    return dict(json.loads(meta_path.read_text()).get("env_kwargs", {}))


def missing_solver(zip_path: str | Path) -> str:
    """The residual law a saved policy needs whose QP solver (DAQP, the ``mpc`` extra) is not
    installed (``""`` when it needs none or the solver is there): read from its ``.json``'s
    ``residual`` block, without loading the model."""
    meta_path = Path(sibling(Path(zip_path), ".json"))
    block = json.loads(meta_path.read_text()).get("residual") if meta_path.is_file() else None
    law = str(block.get("law", "")) if isinstance(block, dict) else ""
    if "mpc" not in law.split("-"):
        return ""
    from capsule_env.agents.controllers.mpc_solver import solver_available

    return "" if solver_available() else law


def runnable(paths: list[str]) -> tuple[list[str], dict[str, str]]:
    """``paths`` split into those that can run here and, by file stem, the residual law of each
    one left out because its QP solver is missing (:func:`missing_solver`)."""
    laws = {path: missing_solver(path) for path in paths}
    return [p for p in paths if not laws[p]], {Path(p).stem: law for p, law in laws.items() if law}


def shipped_policy_paths(env_kwargs: dict[str, Any] | None = None) -> list[str]:
    """The pretrained policies shipped with the package (may be empty); with ``env_kwargs``
    (an evaluated env's options, ``{}`` for the paper's env), only those that belong in its
    default evaluation (:func:`fits_condition`)."""
    paths = sorted(PRETRAINED_DIR.glob("*.zip"))
    if env_kwargs is not None:
        paths = [p for p in paths if fits_condition(_training_options(p), env_kwargs)]
    return [str(p) for p in paths]


def shipped_policies() -> dict[str, Controller]:
    """The pretrained policies shipped with the package, loaded, by name (``ppo-hils``,
    ``ppo-measured``, ``ppo-preview``, ``ppo-trip``, ``residual-ppo-mpc`` and
    ``residual-ppo-mpc-trip`` (the trip task's) and ``residual-ppo-mpc-half-car`` (the half-car
    task's, on its wheelbase-preview MPC, two actions):
    :class:`~capsule_env.agents.learning.residual.ResidualPolicy`, the MPC plus its learned correction).
    Each carries the env arguments it was trained with (``env_kwargs``: pass them to
    ``gymnasium.make``) and acts through ``predict``. Needs the ``rl`` extra; a residual on
    the MPC is left out without the ``mpc`` extra (its QP solver)."""
    use_one_torch_thread()
    policies = [load_policy(path) for path in runnable(shipped_policy_paths())[0]]
    return {str(policy.name): policy for policy in policies}


def load_policy(path: str | Path, require_normalization: bool = True) -> Controller:
    """A saved policy as a controller: :meth:`SB3Policy.load`, wrapped as a
    :class:`~capsule_env.agents.learning.residual.ResidualPolicy` of its law when its metadata has a
    ``residual`` block (``{"law": NAME, "scale": S}``, written by ``train.py --residual``): the
    saved network is the correction added to the law's request, so it only acts right with it;
    a declared vehicle's policy (its ``env_kwargs`` name a ``vehicle``) rides on that vehicle's
    law (:func:`declared_law`). ``ValueError`` for an unknown law or a bad scale in the
    metadata, or a law whose QP solver (the ``mpc`` extra) is not installed."""
    policy = SB3Policy.load(path, require_normalization=require_normalization)
    block = policy.meta.get("residual")
    if block is None:
        return policy
    from capsule_env.agents.controllers.classical import FACTORIES, make_controller
    from capsule_env.agents.learning.residual import ResidualPolicy

    law_name = block.get("law") if isinstance(block, dict) else None
    vehicle = str(policy.env_kwargs.get("vehicle", "quarter_car"))
    if vehicle != "quarter_car":  # a declared vehicle's policy rides on that vehicle's law
        law = declared_law(str(law_name), vehicle, path)
    elif law_name not in FACTORIES:
        raise ValueError(f"{path}: its residual law {law_name!r} is not a classical controller; "
                         f"accepted: {', '.join(sorted(FACTORIES))}")  # fmt: skip
    elif missing_solver(path):
        raise ValueError(f"{path}: its residual law {law_name} needs a QP solver: "
                         "pip install 'capsule-env[mpc]'")  # fmt: skip
    else:
        law = make_controller(law_name)
    residual = ResidualPolicy(law, policy, block.get("scale", 0.5), name=str(policy.name))
    residual.env_kwargs = dict(policy.env_kwargs)
    residual.meta, residual.path = policy.meta, getattr(policy, "path", None)
    return residual


#: The laws a declared vehicle's residual policy may ride on, by the name its metadata's
#: ``residual`` block gives: the per-slot law of the half-car task's card, and the half-car's
#: wheelbase-preview MPC (its tuned weights; DAQP, the ``mpc`` extra).
DECLARED_LAWS = ("lqr-clipped-biexp-meas", "wheelbase-mpc-biexp-meas")


def declared_law(name: str, vehicle: str, path: str | Path) -> Controller:
    """The law ``name`` of a residual policy trained on the declared vehicle ``vehicle``:
    ``lqr-clipped-biexp-meas`` is one tuned quarter-car clipped LQR per damper slot
    (:class:`~capsule_env.agents.controllers.declared_lqr.IndependentClippedLQR`), and
    ``wheelbase-mpc-biexp-meas`` the half-car's semi-active MPC with the wheelbase preview at
    the weights of the task's card
    (:data:`capsule_env.evaluation.half_car.TUNED_MPC`), the laws
    ``experiments/half_car_ppo.py --residual --law NAME`` trains on. ``ValueError`` naming the
    file for another name or a vehicle without that law."""
    from capsule_env.agents.controllers.declared_lqr import IndependentClippedLQR

    if name not in DECLARED_LAWS:
        raise ValueError(f"{path}: its residual law {name!r} is not one a {vehicle} policy rides "
                         f"on; accepted: {', '.join(DECLARED_LAWS)}")  # fmt: skip
    if name == "wheelbase-mpc-biexp-meas":
        if vehicle != "half_car":
            raise ValueError(f"{path}: its residual law {name} is the half_car's; its vehicle "
                             f"is {vehicle!r}")  # fmt: skip
        from capsule_env.agents.controllers.mpc_solver import solver_available

        from capsule_env.evaluation.half_car import tuned_mpc

        if not solver_available():
            raise ValueError(f"{path}: its residual law {name} needs a QP solver: "
                             "pip install 'capsule-env[mpc]'")  # fmt: skip
        return tuned_mpc(name)
    try:
        return IndependentClippedLQR(vehicle)
    except (KeyError, ValueError) as exc:
        raise ValueError(f"{path}: its vehicle {vehicle!r} has no {name}: {exc}") from None


def use_one_torch_thread() -> None:
    """Run PyTorch on one thread: an evaluation's batches are a few observations (10 per
    step), for which the thread pool costs more than it gives (the shipped policy's 10
    episodes: 2.1 s on one thread, 6.4 s on two, on the 2-core machine under load)."""
    import torch

    torch.set_num_threads(1)


#: ``(obs_rms, clip_obs, epsilon)`` of a policy that acts on raw observations.
_RAW_OBSERVATIONS: tuple[Any, float, float] = (None, 10.0, 1e-8)


def _statistics(vec_normalize: Any) -> tuple[Any, float, float]:
    """``(obs_rms or None, clip_obs, epsilon)`` of a ``VecNormalize`` (a copy of the running
    statistics: the policy keeps them as they are now)."""
    norm_obs = bool(getattr(vec_normalize, "norm_obs", True))
    obs_rms = copy.deepcopy(vec_normalize.obs_rms) if norm_obs else None
    return obs_rms, float(vec_normalize.clip_obs), float(vec_normalize.epsilon)


def _checked_meta(path: Path, stem: Path, meta_path: Path) -> dict:
    """The policy's ``.json`` metadata (empty when absent), its digests by role checked against
    the set's files present, whatever their names
    (:func:`capsule_env.agents.learning.policy_files.digests_problem`); ``ValueError`` naming the role and the
    files otherwise."""
    meta: dict = {}
    if meta_path.is_file():
        try:
            meta = json.loads(meta_path.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ValueError(f"policy metadata {meta_path} is not readable JSON: {exc}") from None
        if not isinstance(meta, dict):
            raise ValueError(f"policy metadata {meta_path} is not a JSON object")
    recorded = recorded_digests(meta)
    if recorded is not None:  # a missing .pkl is dealt with by the caller
        problem = digests_problem(stem, recorded, optional=("normaliser", "replay_buffer"))
        if problem:
            raise ValueError(f"policy {path} does not match {meta_path.name}: {problem}")
    meta.setdefault("name", stem.name)
    return meta


class SB3Policy(Controller):
    """A trained SB3 policy with the observation normalisation it was trained with.

    Files: ``NAME.zip`` (the SB3 model), and next to it ``NAME.vecnormalize.pkl`` (SB3's
    ``VecNormalize`` statistics; required unless ``load(..., require_normalization=False)``)
    and ``NAME.json`` (metadata written by ``train.py``: algorithm, the env arguments it was
    trained with and the digests of the other two files by role; optional): :meth:`load`. During
    training, :meth:`from_model` wraps the model in memory with its ``VecNormalize``, so that
    ``train.py``'s evaluations see the policy as ``evaluate.py`` will.
    """

    def __init__(self, model: Any, obs_rms: Any, clip_obs: float, epsilon: float, meta: dict):
        self.model = model
        self.obs_rms = obs_rms
        self.clip_obs = clip_obs
        self.epsilon = epsilon
        self.meta = meta
        self.path: Path | None = None  # the .zip, when loaded from a file
        self.name = meta.get("name", "policy")
        env_kwargs = dict(meta.get("env_kwargs", {}))
        # chosen by the evaluation, not the policy
        for key in ("setting", "guideway_seed", "episode_length_s"):
            env_kwargs.pop(key, None)
        self.env_kwargs = env_kwargs

    @classmethod
    def load(cls, path: str | Path, require_normalization: bool = True) -> SB3Policy:
        """Load ``path`` (a ``.zip``) with the files next to it.

        ``require_normalization``: the ``.vecnormalize.pkl`` statistics must be there (a policy
        trained on normalised observations acts on raw ones without them, far worse than the
        passive damper); False runs a policy without them on raw observations.

        The files are ``NAME.vecnormalize.pkl`` and ``NAME.json`` for ``NAME.zip``, a dotted
        ``NAME`` included (:func:`capsule_env.agents.learning.policy_files.sibling`); a save cut off after its
        commit is read from its commit folder
        (:func:`capsule_env.agents.learning.policy_files.readable_stem`). When the ``.json`` records the sizes
        and SHA-256 of the model and its statistics by role (``digests``; ``train.py`` writes
        it last, as the mark of a complete save), those present are checked, whatever the
        files are named now: a set copied or renamed whole loads, one mixed from two saves is
        refused.
        Raises ``ValueError`` naming the file and the reason for a missing, empty, corrupt,
        inconsistent or mismatched file.
        """
        path = Path(path)
        stem = readable_stem(path) if path.suffix == ".zip" else path
        zip_path, meta_path = sibling(stem, ".zip"), sibling(stem, ".json")
        if path.suffix != ".zip" or not zip_path.is_file():
            raise ValueError(f"policy path must be an existing SB3 .zip file, got {path}")
        if zip_path.stat().st_size == 0:
            raise ValueError(f"policy file {path} is empty")
        meta = _checked_meta(path, stem, meta_path)
        algo = meta.get("algo", "ppo")
        if algo not in ALGORITHMS:
            raise ValueError(f"unknown algo {algo!r} in {meta_path}; accepted: {ALGORITHMS}")
        try:
            model = algorithm_class(algo).load(str(zip_path), device="cpu")
        except Exception as exc:  # a corrupt zip raises many types (BadZipFile, KeyError, ...)
            reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise ValueError(
                f"cannot load {path} as an SB3 {algo.upper()} model: {reason}"
            ) from None
        norm_path = sibling(stem, ".vecnormalize.pkl")
        statistics = _RAW_OBSERVATIONS
        if norm_path.is_file():
            try:
                with norm_path.open("rb") as fh:
                    statistics = _statistics(pickle.load(fh))
            except Exception as exc:  # unpickling garbage raises many types
                raise ValueError(
                    f"cannot read the normalisation statistics {norm_path}: {exc!r}"
                ) from None
        elif require_normalization:
            raise ValueError(
                f"policy {path} has no normalisation statistics {norm_path.name} next to it: "
                "it would act on raw observations (allow that explicitly with "
                "require_normalization=False, evaluate.py --allow-unnormalized)"
            )
        obs_rms = statistics[0]
        space = getattr(model, "observation_space", None)
        if obs_rms is not None and space is not None and obs_rms.mean.shape != space.shape:
            raise ValueError(
                f"{norm_path.name} holds statistics of observations of shape "
                f"{obs_rms.mean.shape}, but the model {path} takes shape {space.shape}"
            )
        policy = cls(model, *statistics, meta)
        policy.path = path
        return policy

    @classmethod
    def from_model(cls, model: Any, vec_normalize: Any, meta: dict | None = None) -> SB3Policy:
        """The in-memory ``model`` with a snapshot of the statistics of ``vec_normalize`` (the
        ``VecNormalize`` it trains on, or None for raw observations): what :meth:`load` gives
        for the files ``train.py`` would save now. Later updates of ``vec_normalize`` do not
        change the policy (``train.py`` evaluates during training with it)."""
        statistics = _RAW_OBSERVATIONS if vec_normalize is None else _statistics(vec_normalize)
        return cls(model, *statistics, dict(meta or {}))

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
        obs = np.atleast_2d(np.asarray(observation, dtype=np.float32))
        shape = getattr(getattr(self.model, "observation_space", None), "shape", None)
        if shape is not None and len(shape) == 1 and obs.shape[-1] != shape[0]:
            raise ValueError(f"observation must have {shape[0]} columns, the env's it was "
                             f"trained on ({self.env_kwargs}), got shape {obs.shape}")  # fmt: skip
        obs = self.normalize(obs)
        action, state = self.model.predict(
            obs, state=state, episode_start=episode_start, deterministic=deterministic
        )
        return np.clip(np.asarray(action, dtype=np.float32), -1.0, 1.0), state
