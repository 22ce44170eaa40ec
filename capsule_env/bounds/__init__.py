"""A certified floor: per episode, a proven lower bound on the Wk-weighted RMS body
acceleration (:func:`capsule_env.metrics.wk_weighted_rms`, what evaluate.py reports) that no
controller of the plant's damper can go below on that guideway.

    from capsule_env.bounds import certified_floor, floor_row
    result = certified_floor({"setting": "sim"}, seeds=range(1000, 1010), episode_length_s=1.0)
    result.floor_wk_m_s2          # (episodes,) m/s^2
    floor_row(result)             # a results row (certified: True)

How (docs/fair-comparison.md, "A certified floor"): the simulator's RK4 integration lifted over
the episode (:mod:`.lifted`: every force evaluation a variable, the motion affine in them,
the simulator's arithmetic in another order: its J agrees with the compiled env's to about
1e-14 relative, which the bound does not cover), quadratic constraints that every force the
damper model can produce satisfies (:mod:`.relaxation`), and the Lagrangian dual of the ride metric under
them (:mod:`.dual`), maximised over the multipliers by L-BFGS-B. Any multipliers give a valid
bound; the search only tightens it. Option ``branch_nodes=K`` adds a branch and bound over the
sign of the stroke rate (:mod:`.branch`: convex cuts per sign, Clarabel QPs certified by weak
duality) and reports the larger floor; on the ``sim`` plant it has not certified more than 0
yet (docs/fair-comparison.md). Episodes are those of evaluate.py's guideway bank unless
``env_kwargs`` names a ``guideway_seed``. Supported plants: the Bi-exponential damper (the ``sim``
setting) and the passive linear damper; the ``hils`` plant (Spencer's hysteretic model) is
refused with a ValueError.

Dense linear algebra (an ``N + 1`` square Cholesky per dual evaluation, ``N = T (4 n_sub +
1)``, 1801 for a 1 s episode of the ``sim`` setting): on a machine shared by several jobs set
``OPENBLAS_NUM_THREADS=1`` (threads oversubscribed made it 40 times slower here).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from capsule_env.bounds.dual import DualProblem, DualSolution, maximise
from capsule_env.bounds.lifted import LiftedEpisode, check_liftable, lift_episode
from capsule_env.bounds.relaxation import (
    constraint_matrices,
    constraint_names,
    damper_envelope,
)
from capsule_env.engine.config import check_seed

__all__ = [
    "DEFAULT_OPTIONS",
    "MAX_FORCES",
    "FloorResult",
    "certified_floor",
    "check_floor",
    "floor_row",
    "verify",
]

#: Most force evaluations per episode (the dual's dense Hessian is ``N + 1`` square; 4000 is
#: 2.2 s of the ``sim`` setting, about 130 MB per matrix and seconds per Cholesky).
MAX_FORCES = 4000

#: ``max_iterations``: L-BFGS-B iterations per episode; ``lam_scale``: the multipliers'
#: scale (the optimiser's variables are ``lam / lam_scale``); ``lam_start``: the start, per
#: constraint of :func:`~capsule_env.bounds.relaxation.constraint_names` (a positive definite
#: one: the rate part's magnitude above the maximum slope and the offset's band).
#: ``branch_nodes``: when > 0, also a branch and bound over the stroke rate's sign with at
#: most this many node QPs per episode (:mod:`.branch`); the floor is the larger of the two.
DEFAULT_OPTIONS: dict[str, Any] = {
    "max_iterations": 30,
    "branch_nodes": 0,
    "lam_scale": 1e-6,
    "lam_start": tuple(
        1e-7 if n in ("rate_part_above_max_slope", "offset_band") else 0.0
        for n in constraint_names()
    ),
}


@dataclass(frozen=True)
class FloorResult:
    """What :func:`certified_floor` found.

    floor_wk_m_s2 : (E,) the certified floors (m/s^2); ``mean_wk_m_s2`` their mean.
    dual_value : (E,) ``g`` at the certificate's multipliers ((m/s^2)^2; without branching
    the floor is ``sqrt(max(g, 0))``). branch : per episode, the branch and bound's summary
    (``floor_j`` its bound on ``J``; the floor is then ``sqrt(max(g, floor_j, 0))``), empty
    when ``branch_nodes`` is 0. multipliers : per episode, (N, K) ``lam`` (the certificate: with
    the env, the seeds and the length, :func:`verify` recomputes ``g`` from them).
    """

    env_kwargs: dict
    seeds: tuple[int, ...]
    episode_length_s: float
    floor_wk_m_s2: np.ndarray
    dual_value: np.ndarray
    multipliers: tuple[np.ndarray, ...]
    options: dict
    runtime_s: float
    evaluations: tuple[int, ...]
    constraints: tuple[str, ...] = field(default_factory=constraint_names)
    method: str = "lifted-RK4 Shor/Lagrangian dual, L-BFGS-B over the multipliers"
    branch: tuple[dict, ...] = ()

    @property
    def mean_wk_m_s2(self) -> float:
        return float(np.mean(self.floor_wk_m_s2))

    def summary(self) -> dict[str, Any]:
        """A JSON-ready summary (no multipliers)."""
        return {
            "method": self.method,
            "env_kwargs": dict(self.env_kwargs),
            "seeds": list(self.seeds),
            "episode_length_s": self.episode_length_s,
            "floor_wk_m_s2": [float(v) for v in self.floor_wk_m_s2],
            "mean_wk_m_s2": self.mean_wk_m_s2,
            "dual_value": [float(v) for v in self.dual_value],
            "constraints": list(self.constraints),
            "options": {
                k: (list(v) if isinstance(v, tuple) else v) for k, v in self.options.items()
            },  # fmt: skip
            "dual_evaluations": list(self.evaluations),
            "runtime_s": self.runtime_s,
            **({"branch": [dict(b) for b in self.branch]} if self.branch else {}),
        }


def _options(options: Mapping[str, Any]) -> dict[str, Any]:
    unknown = set(options) - set(DEFAULT_OPTIONS)
    if unknown:
        raise TypeError(f"certified_floor: unknown options {sorted(unknown)}; accepted: "
                        f"{sorted(DEFAULT_OPTIONS)}")  # fmt: skip
    out = {**DEFAULT_OPTIONS, **options}
    for name in ("max_iterations", "branch_nodes"):
        it = out[name]
        if isinstance(it, bool) or not isinstance(it, int) or it < 0:
            raise ValueError(f"{name} must be an integer >= 0, got {it!r}")
    scale = out["lam_scale"]
    if not isinstance(scale, (int, float)) or not 0.0 < float(scale) < math.inf:
        raise ValueError(f"lam_scale must be a finite number > 0, got {scale!r}")
    start = np.asarray(out["lam_start"], dtype=float)
    if start.shape != (len(constraint_names()),) or np.any(~(start >= 0.0)):
        raise ValueError(f"lam_start must be {len(constraint_names())} numbers >= 0 (one per "
                         f"constraint {constraint_names()}), got {out['lam_start']!r}")  # fmt: skip
    out["lam_start"] = tuple(float(v) for v in start)
    return out


_SEEDS = "a non-empty list, tuple, range or 1-D numpy array of integers in [0, 2**63)"


def _check_seeds(seeds: Any) -> tuple[int, ...]:
    """``seeds`` as ints, as :func:`capsule_env.oracle.clairvoyant_bound` takes them (numpy
    integers and integer arrays too), each checked as the env checks a seed."""
    if isinstance(seeds, (str, bytes)) or not isinstance(seeds, Sequence | np.ndarray):
        raise TypeError(f"seeds must be {_SEEDS}, got {seeds!r}")
    if isinstance(seeds, np.ndarray) and seeds.ndim != 1:
        raise TypeError(f"seeds must be {_SEEDS}, got an array of shape {seeds.shape}")
    if len(seeds) == 0:
        raise ValueError(f"seeds must be {_SEEDS}, got an empty one")
    return tuple(check_seed(f"seeds[{k}]", s) for k, s in enumerate(seeds))


def _check(seeds: Any, episode_length_s: float) -> tuple[tuple[int, ...], float]:
    out = _check_seeds(seeds)
    if isinstance(episode_length_s, bool) or not isinstance(episode_length_s, int | float):
        raise TypeError(f"episode_length_s must be a number of seconds in (0, 10], got "
                        f"{episode_length_s!r}")  # fmt: skip
    length = float(episode_length_s)
    if not 0.0 < length <= 10.0:
        raise ValueError(f"episode_length_s must be in (0, 10] s, got {episode_length_s!r}")
    return out, length


def _problem(episodes: Any, k: int) -> tuple[LiftedEpisode, DualProblem]:
    lifted = lift_episode(episodes, k)
    mats = constraint_matrices(damper_envelope(episodes.code, episodes.damper_params[k]))
    return lifted, DualProblem(lifted, mats)


def evaluation_kwargs(env_kwargs: Mapping[str, Any]) -> dict[str, Any]:
    """``env_kwargs`` with evaluate.py's guideway bank (``guideway_seed`` 2026) unless it names
    one: the episodes evaluate.py and the oracle (``clairvoyant_bound``) run for these seeds."""
    from capsule_env.evaluation.episodes import EVALUATION_GUIDEWAY_SEED

    return {"guideway_seed": EVALUATION_GUIDEWAY_SEED, **env_kwargs}


def check_floor(
    env_kwargs: Mapping[str, Any], seeds: Sequence[int] | np.ndarray, episode_length_s: float
) -> tuple[Any, tuple[int, ...], float]:
    """Check that :func:`certified_floor` can run these episodes (a supported plant damper,
    one substep count at every current, at most :data:`MAX_FORCES` force evaluations per
    episode) before anything long runs; returns the episodes
    (:class:`~capsule_env.oracle.plant.OracleEpisodes`), the seeds and the length. ValueError
    naming what fails (an ``episode_length_s`` in ``env_kwargs`` other than the argument too);
    ``seeds``: a non-empty list, tuple, range or 1-D numpy array of integers (numpy integers
    too), each in ``[0, 2**63)`` as the env's ``reset(seed=...)`` takes; TypeError or ValueError
    naming ``seeds`` (``seeds[k]``) and that range otherwise, TypeError for a length that is not
    a number."""
    from capsule_env.oracle.plant import OracleEpisodes

    seeds_t, length = _check(seeds, episode_length_s)
    own = dict(env_kwargs).get("episode_length_s", length)
    if own != length:  # OracleEpisodes would run the env's, the result name the argument's
        raise ValueError(f"env_kwargs['episode_length_s'] ({own!r}) contradicts episode_length_s "
                         f"({length:g} s): give the length once, as episode_length_s")  # fmt: skip
    episodes = OracleEpisodes(evaluation_kwargs(env_kwargs), seeds_t, length)
    for k in range(len(seeds_t)):
        damper_envelope(episodes.code, episodes.damper_params[k])
        n_forces = episodes.n_steps * (4 * check_liftable(episodes, k) + 1)
        if n_forces > MAX_FORCES:
            raise ValueError(
                f"episode_length_s {length:g} s needs {n_forces} force evaluations per episode; "
                f"the certified floor takes at most {MAX_FORCES} (about "
                f"{MAX_FORCES / n_forces * length:.2g} s here)"
            )
    return episodes, seeds_t, length


def certified_floor(
    env_kwargs: Mapping[str, Any],
    seeds: Sequence[int] | np.ndarray,
    episode_length_s: float,
    **options: Any,
) -> FloorResult:
    """Per episode (the env's episode for each seed, as evaluate.py runs them), a certified
    lower bound on the Wk-weighted RMS body acceleration that any controller reaches:
    :class:`FloorResult`. ``options``: :data:`DEFAULT_OPTIONS`. ValueError for a plant with
    no relaxation (``hils``: Spencer's hysteretic damper) or bad arguments."""
    opts = _options(options)
    t0 = time.perf_counter()
    # refuse before any long computation
    episodes, seeds_t, length = check_floor(env_kwargs, seeds, episode_length_s)
    floors, values, lams, evals, branch = [], [], [], [], []
    for k in range(len(seeds_t)):
        lifted, problem = _problem(episodes, k)
        lam0 = np.tile(np.array(opts["lam_start"]), (lifted.n_forces, 1))
        sol: DualSolution = maximise(problem, lam0, opts["max_iterations"], opts["lam_scale"])
        g = sol.point.value
        values.append(g)
        if opts["branch_nodes"] > 0:
            branch.append(_branch(episodes, k, lifted, opts["branch_nodes"]))
            g = max(g, branch[-1]["floor_j"])
        floors.append(math.sqrt(max(g, 0.0)))
        lams.append(sol.lam)
        evals.append(sol.evaluations)
    method = FloorResult.method + (BRANCH_METHOD if branch else "")
    return FloorResult(
        evaluation_kwargs(env_kwargs), seeds_t, length, np.array(floors), np.array(values),
        tuple(lams),
        opts, time.perf_counter() - t0, tuple(evals), method=method, branch=tuple(branch),
    )  # fmt: skip


BRANCH_METHOD = "; and branch and bound over the stroke rate's sign (Clarabel QPs, dual-certified)"


def _branch(episodes: Any, k: int, lifted: LiftedEpisode, max_nodes: int) -> dict[str, Any]:
    """The branch and bound of episode ``k`` (:func:`.branch.branch_and_bound`), summarised."""
    from capsule_env.bounds.branch import BranchProblem, branch_and_bound

    env = damper_envelope(episodes.code, episodes.damper_params[k])
    res = branch_and_bound(BranchProblem(lifted, env), max_nodes)
    budgets = [b for b in (1, 10, 100, 1000, 10000) if b <= res.nodes]
    return {"floor_j": res.floor_j, "root_j": res.root_j, "nodes": res.nodes,
            "floor_j_at_nodes": {str(b): res.floor_j_at(b) for b in budgets},
            "open_nodes": res.open_nodes, "complete": res.complete,
            "runtime_s": res.runtime_s}  # fmt: skip


def verify(result: FloorResult) -> np.ndarray:
    """Recompute every episode's ``g`` from the certificate's multipliers (independently of
    the search): (E,) values; the floors are ``sqrt(max(g, 0))``. The dual's certificate only:
    a floor raised by the branch and bound (``branch_nodes`` > 0, ``branch[k]["floor_j"]``
    above ``g``) is certified node by node as it runs (:meth:`.branch.BranchProblem.certify`)
    but its open nodes' multipliers are not stored, so it is not re-checked here."""
    from capsule_env.oracle.plant import OracleEpisodes

    episodes = OracleEpisodes(result.env_kwargs, result.seeds, result.episode_length_s)
    out = []
    for k, lam in enumerate(result.multipliers):
        _, problem = _problem(episodes, k)
        out.append(problem.evaluate(lam).value)
    return np.array(out)


def floor_row(result: FloorResult) -> dict[str, Any]:
    """A results row, as evaluate.py's: ``wk_rms_body_acc_m_s2`` the mean over episodes and
    ``std`` its spread (as :func:`~capsule_env.evaluation.episodes.episode_metrics`),
    ``per_episode`` the values, ``certified: True``, ``method``, the search's summary."""
    return {
        "wk_rms_body_acc_m_s2": result.mean_wk_m_s2,
        "std": {"wk_rms_body_acc_m_s2": float(np.std(result.floor_wk_m_s2))},
        "per_episode": {"wk_rms_body_acc_m_s2": [float(v) for v in result.floor_wk_m_s2]},
        "certified": True,
        "method": result.method,
        "floor": {k: v for k, v in result.summary().items() if k != "floor_wk_m_s2"},
    }
