"""Run a declared study (training seeds x hyperparameters, classical gain grids, oracle
episodes) as Ray Tune trials, or one after another without Ray.

    python -m capsule_env.sweep study.yml                 # local Ray, all cores
    python -m capsule_env.sweep study.yml --address auto  # the Ray cluster this node is in
    python -m capsule_env.sweep study.yml --no-ray        # no Ray: same trials, same table
    python -m capsule_env.sweep study.yml --check         # check the file, list the trials
    python -m capsule_env.sweep study.yml --block sac     # only the block named sac

The study file (YAML or JSON; :mod:`capsule_env.sweep.study`)::

    name: ppo-lr
    trials:
      - kind: train                 # train.py's train(Args)
        replicates: 2               # independent seeds per grid point
        params: {total_timesteps: 2048, num_envs: 4, hp.n_steps: 64}
        grid: {hp.learning_rate: [0.001, 0.0003]}
      - kind: gains                 # a classical controller with given gains
        params: {controller: skyhook-cont-biexp, episodes: 4, episode_length_s: 4}
        grid: {gain.c_sky: [3000, 10000, 30000]}

The kinds and their parameters: :mod:`capsule_env.sweep.kinds`. Output (``--out``, default
``runs/sweep/<name>``): ``results.csv`` and ``results.json`` (one row per trial: status, seed,
parameters, metrics, attempts, error), ``summary.png``, ``trials/<trial>/`` (each trial's
files and ``output.log``), ``tune/`` (the Ray Tune experiment) and ``study.json``. Running the
same command again continues the study: finished trials are never run again (a trial's
``result.json`` is the source of truth, with Ray too, whatever Tune's ``Tuner.restore``
restores), failed ones are run again unless ``--no-retry-failed``; a study file that only
gained blocks or grid points continues in the same folder. The whole study file is
checked before any trial starts (``--check`` runs only that). Exit status 0 when every trial
finished, 1 when some did not (each failed trial is listed with its error), 2 for a bad
study file (one line naming the key and what it accepts).
"""

from __future__ import annotations

from capsule_env.sweep.kinds import KINDS, Kind, register_kind
from capsule_env.sweep.runner import Outcome, run_ray, run_serial, run_trial, write_results
from capsule_env.sweep.study import Study, StudyError, Trial, build_study, load_study

__all__ = [
    "KINDS",
    "Kind",
    "Outcome",
    "Study",
    "StudyError",
    "Trial",
    "build_study",
    "load_study",
    "register_kind",
    "run_ray",
    "run_serial",
    "run_trial",
    "write_results",
]
