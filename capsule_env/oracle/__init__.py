"""The clairvoyant oracle: per episode, the lowest Wk-weighted RMS body acceleration that a
multi-start local search finds for a controller knowing the whole guideway in advance. An
achievable, not a certified, reference: an upper bound on the clairvoyant optimum and a lower
bound on nothing (the name ``clairvoyant_bound`` is historical).

    from capsule_env.oracle import clairvoyant_bound
    result = clairvoyant_bound({"setting": "hils"}, seeds=range(1000, 1010))
    result.wk_rms_body_acc_m_s2          # (episodes,) m/s^2
    episode_metrics(result.rollout, passive_rollout)   # any metric, as for a controller

What is searched: the applied coil-current sequence ``u_t`` in ``[0, i_max]`` of each episode
(``T`` control steps), set directly on the plant: no sensor noise, no control delay, no
inverse model (the coil's lag, where the setting has one, stays: it is physics). It is a
reference for the semi-active damper on that guideway, not a controller: every causal
controller reads less (noisy sensors, 5 ms late, no knowledge of the guideway ahead or of the
vehicle's own state beyond its estimates), but the search is local, so no causal controller is
proven unable to reach a lower figure.

The method (:mod:`capsule_env.oracle.plant`, :mod:`capsule_env.oracle.search`):

- the episodes are the env's own (vehicle, damper, route, start state drawn as ``CapsuleBatch``
  draws them at the reset) and are stepped with the env's compiled plant kernel;
- exact-to-rounding gradients by an adjoint: every control step of a trajectory is
  linearised at once (forward differences of single steps, all ``T (n_x + 1)`` of them in one
  batched kernel call), then one backward recursion gives ``dF/du_t`` for every ``t``: the cost
  of about ``n_x + 2`` open-loop runs per gradient, independent of ``T`` (the finite
  differences over the whole sequence that this replaced cost ``T + 1`` runs: ~1.5 min per 4 s
  episode; now ~20 s for a 4 s episode with three starts);
- L-BFGS-B with bounds, from several starts (zero current, 10 % of ``i_max``, on-off Skyhook
  on the true state, or any given sequence such as a controller's own), the searches of all
  episodes and starts in lockstep (one kernel call per step for all of them), then restart
  rounds from the best sequence smoothed (:mod:`capsule_env.oracle.starts`,
  :mod:`capsule_env.oracle.lockstep`);
- ``candidates``: named sequences, e.g. the applied currents of every controller evaluated on
  the same plant (``evaluate.py --oracle`` passes them): each is replayed on its episode (the
  replay is the env's own run, :func:`applied_currents`), kept where it is the best sequence
  tried, and the best ``searched_candidates`` of each episode are searched from too. So the
  oracle is never above any of those controllers, episode by episode, by construction, and
  :attr:`OracleResult.best_start` names the start that won each episode;
- the search integrates with each episode's finest substep count (no switching under the
  finite differences); every reported figure is re-measured with the env's adaptive substeps.

How far from the global optimum: the problem is not convex (the damper force is a nonlinear,
hysteretic function of the current and the motion), so a local search gives an *upper* bound
on the clairvoyant optimum, and a lower bound on no controller (the certified floor of
:mod:`capsule_env.bounds` covers short episodes of the ``sim`` plant only, and proves 0 there).
:class:`OracleResult` reports
how much the answer depends on the start (``spread_m_s2``, the range over the starts of what
each reached) and what the restarts added (``restart_gain_m_s2``); docs/fair-comparison.md
quotes both for the evaluation seeds. A spread of a few per cent means the true optimum may lie a few per cent
lower still; read fractions of the "headroom" with that margin.
"""

from capsule_env.oracle.plant import OracleEpisodes, RideObjective, adjoint_gradient
from capsule_env.oracle.search import (
    DEFAULT_STARTS,
    EVALUATION_SEEDS,
    START_NAMES,
    OracleResult,
    applied_currents,
    clairvoyant_bound,
)

__all__ = [
    "DEFAULT_STARTS",
    "EVALUATION_SEEDS",
    "START_NAMES",
    "OracleEpisodes",
    "OracleResult",
    "RideObjective",
    "adjoint_gradient",
    "applied_currents",
    "clairvoyant_bound",
]
