"""What every offline baseline shares: the dataset it learns from and the evaluation of its
networks like every other row.

:class:`Evaluation` (the options ``--dataset-root``, ``--seeds``, ``--eval-*``, ``--json``)
names the dataset and how the trained networks are judged: each drives the dataset's env on
the evaluation bank (``recover_environment(eval_env=True)``'s options with
``guideway_seed=2026``, whatever bank that env names; a dataset recorded on a bank held out
from training, the evaluation, validation or selection bank, is refused), episodes
``eval_seed .. eval_seed + eval_episodes - 1`` of ``eval_episode_length_s`` (as
``evaluate.py``: 1000..1009, 10 s), through :func:`~capsule_env.evaluation.episodes.run_episodes`;
the row's figure is the Wk-weighted RMS car-body acceleration of
:func:`~capsule_env.evaluation.episodes.episode_metrics`. The passive damper and the dataset's
demonstrator (when its metadata names a classical law) run on the same episodes; the ratio of
the method's Wk to the demonstrator's is given with a 95 % bootstrap interval over the training
seeds and the episodes (:func:`~capsule_env.evaluation.rl_statistics.paired_ratio_interval`,
the IQM over the seeds), and with the seeds alone resampled.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from capsule_env import metrics
from capsule_env.common.cli import ArgumentParser, add_dataclass_options, dataclass_values

__all__ = ["Evaluation", "Transitions", "check_ranges", "NetworkPolicy", "transitions", "load",
           "evaluation_env_kwargs", "evaluate", "run_offline", "offline_main"]  # fmt: skip


_MAX_SEED = 2**63
#: The guideway banks held out from training (evaluation.episodes): a dataset recorded on one
#: of them is refused.
_HELD_OUT_BANKS = {"EVALUATION_GUIDEWAY_SEED": "evaluation", "VALIDATION_GUIDEWAY_SEED":
                   "validation", "SELECTION_GUIDEWAY_SEED": "selection"}  # fmt: skip


@dataclass
class Evaluation:
    dataset_root: str = ""
    """the datasets root the dataset was recorded into (capsule-datasets --out)"""
    dataset_id: str = ""
    """the dataset's id (default: the one dataset under --dataset-root)"""
    seeds: int = 5
    """training seeds, one network each (>= 2: the interval resamples them)"""
    first_seed: int = 0
    """training seed of the first network (then +1 each)"""
    eval_episodes: int = 10
    """evaluation episodes (>= 2), on the evaluation bank"""
    eval_seed: int = 1000
    """seed of the first evaluation episode (evaluate.py's default)"""
    eval_episode_length_s: float = 10.0
    """seconds per evaluation episode"""
    json: str = ""
    """write the results to this JSON file (atomically)"""


def check_evaluation(ev: Evaluation) -> None:
    """``ValueError`` naming the option for a value out of range."""
    if not ev.dataset_root:
        raise ValueError("--dataset-root is required: the folder capsule-datasets --out wrote")
    if ev.seeds < 2 or ev.eval_episodes < 2:
        raise ValueError(f"--seeds and --eval-episodes must be >= 2 (the interval resamples "
                         f"both), got {ev.seeds} and {ev.eval_episodes}")  # fmt: skip
    for option, first, count in (("--first-seed", ev.first_seed, ev.seeds),
                                 ("--eval-seed", ev.eval_seed, ev.eval_episodes)):  # fmt: skip
        if not 0 <= first <= _MAX_SEED - count:
            raise ValueError(f"{option} must be in 0..{_MAX_SEED - count} (2**63 minus the "
                             f"count: seeds are {option} + k, 64-bit), got {first}")  # fmt: skip
    if not (np.isfinite(ev.eval_episode_length_s) and ev.eval_episode_length_s > 0):
        raise ValueError(f"--eval-episode-length-s must be positive, got "
                         f"{ev.eval_episode_length_s}")  # fmt: skip


def check_ranges(args: Any, counts: Sequence[str],
                 open_intervals: Mapping[str, tuple[float, float]]) -> None:  # fmt: skip
    """The fields ``counts`` of the dataclass ``args`` are >= 1 and those of
    ``open_intervals`` strictly between their bounds; ``ValueError`` naming the option
    (``--field-name``) otherwise."""
    option = lambda name: "--" + name.replace("_", "-")  # noqa: E731
    for name in counts:
        if getattr(args, name) < 1:
            raise ValueError(f"{option(name)} must be >= 1, got {getattr(args, name)}")
    for name, (lo, hi) in open_intervals.items():
        if not lo < getattr(args, name) < hi:
            raise ValueError(f"{option(name)} must be in ({lo:g}, {hi:g}), got "
                             f"{getattr(args, name)}")  # fmt: skip


@dataclass
class Transitions:
    """Every transition of a dataset, float32 arrays of one row each (each episode's last
    observation, which has no action, appears only as a ``next_observations`` row)."""

    observations: np.ndarray  # (N, obs_dim)
    actions: np.ndarray  # (N, action_dim)
    rewards: np.ndarray  # (N,)
    next_observations: np.ndarray  # (N, obs_dim)
    terminations: np.ndarray  # (N,) bool: the bump stop
    truncations: np.ndarray  # (N,) bool: the episode's end


def transitions(dataset: Any) -> Transitions:
    """The transitions of a Minari dataset (:class:`Transitions`)."""
    parts: dict[str, list[np.ndarray]] = {k: [] for k in Transitions.__dataclass_fields__}
    for episode in dataset.iterate_episodes():
        obs = np.asarray(episode.observations, dtype=np.float32)
        steps = len(episode.rewards)
        parts["observations"].append(obs[:-1])
        parts["next_observations"].append(obs[1:])
        parts["actions"].append(np.asarray(episode.actions, dtype=np.float32).reshape(steps, -1))
        parts["rewards"].append(np.asarray(episode.rewards, dtype=np.float32))
        parts["terminations"].append(np.asarray(episode.terminations, dtype=bool))
        parts["truncations"].append(np.asarray(episode.truncations, dtype=bool))
    return Transitions(**{k: np.concatenate(v) for k, v in parts.items()})


class NetworkPolicy:
    """A torch network ``observation -> action`` with SB3's ``predict`` (deterministic,
    clipped to ``[-1, 1]``)."""

    def __init__(self, net: Any, name: str) -> None:
        self.net, self.name = net, name

    def predict(self, observation: np.ndarray, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, Any]:  # fmt: skip
        import torch

        with torch.no_grad():
            x = torch.as_tensor(np.atleast_2d(np.asarray(observation, dtype=np.float32)))
            action = self.net(x).numpy()
        return np.clip(action, -1.0, 1.0).astype(np.float32), state


def load(ev: Evaluation) -> tuple[Any, str]:
    """The dataset ``ev`` names, and its id; ``ValueError`` when there is none or several."""
    from capsule_env.datasets.minari_store import datasets_root, load_dataset, minari_module

    ident = ev.dataset_id
    if not ident:
        if not Path(ev.dataset_root).is_dir():
            raise ValueError(f"--dataset-root {ev.dataset_root!r} is not a folder")
        with datasets_root(ev.dataset_root):
            found = list(minari_module().list_local_datasets())
        if len(found) != 1:
            raise ValueError(f"--dataset-root {ev.dataset_root!r} holds {len(found)} datasets "
                             f"({', '.join(found) or 'none'}): give --dataset-id")  # fmt: skip
        ident = found[0]
    try:
        return load_dataset(ev.dataset_root, ident), ident
    except (FileNotFoundError, ValueError) as exc:
        raise ValueError(f"no dataset {ident!r} under --dataset-root {ev.dataset_root!r} "
                         f"({exc})") from None  # fmt: skip


def evaluate(policy: Any, env_kwargs: dict[str, Any], ev: Evaluation) -> tuple[np.ndarray, dict]:
    """Per-episode Wk (m/s^2) of ``policy`` on the evaluation episodes, and
    :func:`~capsule_env.evaluation.episodes.episode_metrics` of the run."""
    from capsule_env.evaluation.episodes import episode_metrics, run_episodes

    roll = run_episodes(policy, env_kwargs, ev.eval_episodes, ev.eval_seed,
                        ev.eval_episode_length_s)  # fmt: skip
    wk = np.asarray(metrics.wk_weighted_rms(roll.signals["car_body_acceleration_m_s2"],
                                            roll.dt_s), dtype=float)  # fmt: skip
    summary = episode_metrics(roll, None)
    if abs(float(np.mean(wk)) - summary["wk_rms_body_acc_m_s2"]) > 1e-12:
        raise RuntimeError("per-episode Wk and episode_metrics disagree")
    return wk, summary


def evaluation_env_kwargs(dataset: Any, ident: str, ev: Evaluation) -> dict[str, Any]:
    """The options of the env the networks are judged in: the dataset's evaluation env's
    (``recover_environment(eval_env=True)``) on the evaluation bank, whatever bank that env
    names (Minari's evaluation env is the recording env when the dataset names none).
    ``ValueError`` when the dataset is not of this package's env, was recorded on a bank held
    out from training, or ``--eval-episode-length-s`` or ``--eval-episodes`` is refused there
    (too short, more than the memory holds)."""
    from capsule_env.engine.config import EnvConfig
    from capsule_env.evaluation import episodes

    recorded = dataset.spec.env_spec
    if recorded is None or not str(recorded.entry_point).startswith("capsule_env."):
        raise ValueError(f"dataset {ident!r} was not recorded in a capsule_env env "
                         f"({getattr(recorded, 'id', None)!r})")  # fmt: skip
    bank = recorded.kwargs.get("guideway_seed", EnvConfig().guideway_seed)
    held_out = {getattr(episodes, k): v for k, v in _HELD_OUT_BANKS.items()}
    if bank in held_out:
        raise ValueError(f"dataset {ident!r} was recorded on the {held_out[bank]} guideway "
                         f"bank (guideway_seed={bank}), held out from training: record it "
                         f"on the training bank")  # fmt: skip
    eval_env = dataset.recover_environment(eval_env=True)
    kwargs = {k: v for k, v in eval_env.spec.kwargs.items() if k != "episode_length_s"}
    eval_env.close()
    kwargs["guideway_seed"] = episodes.EVALUATION_GUIDEWAY_SEED
    try:
        config = EnvConfig.from_kwargs(**kwargs, episode_length_s=ev.eval_episode_length_s)
        config.check_memory(ev.eval_episodes)  # the evaluation's vector env
    except (ValueError, TypeError) as exc:
        raise ValueError(f"--eval-episodes / --eval-episode-length-s on the dataset's env: "
                         f"{exc}") from None  # fmt: skip
    return kwargs


def _references(dataset: Any, env_kwargs: dict[str, Any], ev: Evaluation) -> dict[str, np.ndarray]:
    """Per-episode Wk of the passive damper and of the dataset's demonstrator (when its
    metadata names a classical law) on the evaluation episodes."""
    from capsule_env.agents.controllers.classical import FACTORIES, make_controller

    block = dataset.storage.metadata.get("capsule_env", {}).get("controller", {})
    names = ["passive"] + ([block["name"]] if block.get("kind") == "classical" else [])
    out = {}
    for name in dict.fromkeys(n for n in names if n in FACTORIES):
        law = make_controller(name)
        out[name] = evaluate(law, {**env_kwargs, **law.env_kwargs}, ev)[0]
    return out


#: ``train(data, seed) -> (network, final losses)``: one network of a method from one seed.
Trainer = Callable[[Transitions, int], tuple[Any, dict[str, float]]]


def run_offline(method: str, train: Trainer, ev: Evaluation, options: Any) -> dict[str, Any]:
    """Train ``ev.seeds`` networks of ``method`` (``train``, with ``options`` recorded) on the
    dataset of ``ev``, evaluate them and the references (module docstring); the results as a
    JSON-ready dict."""
    from capsule_env.evaluation.rl_statistics import paired_ratio_interval

    check_evaluation(ev)
    dataset, ident = load(ev)
    data = transitions(dataset)
    env_kwargs = evaluation_env_kwargs(dataset, ident, ev)
    runs, t0 = [], time.perf_counter()
    for seed in range(ev.first_seed, ev.first_seed + ev.seeds):
        net, losses = train(data, seed)
        wk, summary = evaluate(NetworkPolicy(net, method), env_kwargs, ev)
        runs.append({"seed": seed, "final_losses": losses, "wk_per_episode_m_s2": wk.tolist(),
                     "wk_rms_body_acc_m_s2": summary["wk_rms_body_acc_m_s2"],
                     "terminated_episodes": summary["terminated_episodes"]})  # fmt: skip
    seconds = time.perf_counter() - t0
    references = _references(dataset, env_kwargs, ev)
    results: dict[str, Any] = {
        "method": method, "dataset_id": ident, "transitions": int(len(data.rewards)),
        "evaluation": asdict(ev), "options": asdict(options), "eval_env_kwargs": env_kwargs,
        "train_and_eval_time_s": seconds, "runs": runs,
        "references_wk_per_episode_m_s2": {k: v.tolist() for k, v in references.items()},
        "references_wk_m_s2": {k: float(v.mean()) for k, v in references.items()},
    }  # fmt: skip
    group = np.array([r["wk_per_episode_m_s2"] for r in runs])
    for law in (k for k in references if k != "passive"):
        for resample in ("both", "seeds"):
            est = paired_ratio_interval(group, references[law], resample=resample)
            results[f"ratio_to_{law}_{resample}"] = {"iqm": est.value, "low": est.low,
                                                     "high": est.high}  # fmt: skip
    return results


def offline_main(prog: str, doc: str, options_cls: type, method: str,
                 make_trainer: Callable[[Any], Trainer], argv: list[str] | None) -> int:  # fmt: skip
    """A baseline's command line: :class:`Evaluation`'s options and ``options_cls``'s, then
    :func:`run_offline`; bad input is one line on stderr and exit status 1 (2 for syntax),
    Ctrl-C one line and exit status 130."""
    # each option's help already ends with its default (add_dataclass_options)
    parser = ArgumentParser(prog=prog, description=doc.split("\n\n")[0])
    add_dataclass_options(parser, Evaluation)
    add_dataclass_options(parser, options_cls)
    given = parser.parse_args(argv)
    ev = Evaluation(**dataclass_values(given, Evaluation))
    options = options_cls(**dataclass_values(given, options_cls))
    try:
        if ev.json:
            from capsule_env.common.safe_io import check_writable_file

            check_writable_file(ev.json, "--json")
        results = run_offline(method, make_trainer(options), ev, options)
    except (ValueError, ImportError, OSError) as exc:
        print(f"{prog}: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"{prog}: interrupted: nothing written (the results are written at the end)",
              file=sys.stderr)  # fmt: skip
        return 130
    text = json.dumps(results, indent=2)
    if ev.json:
        from capsule_env.common.safe_io import atomic_write_text

        atomic_write_text(Path(ev.json), text + "\n")
    print(text)
    return 0
