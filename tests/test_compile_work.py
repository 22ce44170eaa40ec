"""What a first step compiles (issue 40: the first ``make`` + ``step`` on an empty numba cache).

Facts checked in a fresh interpreter with an empty ``NUMBA_CACHE_DIR`` (one subprocess for the
module), counting numba's type inference of every function compiled by the default env's first
step:

- no function of the package is typed twice for the same argument types (numba's inlining of
  an overload types it again at every call site: the damper's affine form was typed four
  times);
- a noise-free env without a reward filter compiles neither the noise generator nor the filter
  (they were compiled into every kernel and skipped at run time);
- numba's typing work, counted in typed variables, stays under a budget: 4,957 before these
  cuts (numba 0.68), 3,638 after.

And the sensing compiled for a configuration (``env_kernel.sense_flags``) gives the numbers of
the sensing that decides everything at run time (``SENSE_ALL``), bit for bit, and the
observation columns are their quantities clipped to the observation space.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from capsule_env.engine.batch import CapsuleBatch
from capsule_env.engine.config import EnvConfig, observation_bounds
from capsule_env.engine.env_kernel import (
    SENSE_ALL,
    SENSE_FILTER,
    SENSE_NOISE,
    command_path,
    sense_flags,
)
from capsule_env.engine.kernels import ENV, BatchedKernel
from capsule_env.engine.layout import SIGNAL_NAMES
from capsule_env.engine.observations import OBSERVATION_NAMES, QUANTITIES

#: numba's typing work of the default env's first step, in typed variables (4,957 before
#: issue 40, 3,638 after, numba 0.68).
TYPED_VARIABLES_BUDGET = 4_300

_PROBE = """
import json
from numba.core import typed_passes

typings, variables = {}, [0]
infer = typed_passes.type_inference_stage

def counting(typingctx, targetctx, interp, args, *rest, **options):
    result = infer(typingctx, targetctx, interp, args, *rest, **options)
    fid = interp.func_id
    key = f"{fid.modname}:{fid.func_qualname}{tuple(args)}"
    typings[key] = typings.get(key, 0) + 1
    variables[0] += len(result.typemap)
    return result

typed_passes.type_inference_stage = counting

import gymnasium as gym
import capsule_env
from capsule_env.engine import env_kernel
from capsule_env._fastmath import fast_log

env = gym.make("CapsuleSuspension-v0")
env.reset(seed=0)
env.step(env.action_space.sample())
unused = {f.__name__: len(f.signatures) for f in (env_kernel._draw_noise,
          env_kernel._noise_lanes, env_kernel._filter_reward_acceleration, fast_log)}
print(json.dumps({"typings": typings, "variables": variables[0], "unused": unused}))
"""


@pytest.fixture(scope="module")
def first_step(tmp_path_factory) -> dict:
    """The probe's counts for the default env's first step on an empty numba cache."""
    cache = tmp_path_factory.mktemp("numba-cache")
    out = subprocess.run(
        [sys.executable, "-c", _PROBE],
        env=dict(os.environ, NUMBA_CACHE_DIR=str(cache)),
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_no_function_of_the_package_is_typed_twice(first_step):
    twice = {
        k: n for k, n in first_step["typings"].items() if k.startswith("capsule_env") and n > 1
    }
    assert twice == {}


def test_a_noise_free_unfiltered_env_compiles_no_noise_or_filter(first_step):
    assert first_step["unused"] == {
        "_draw_noise": 0,
        "_noise_lanes": 0,
        "_filter_reward_acceleration": 0,
        "fast_log": 0,
    }


def test_typing_work_of_a_first_step_within_budget(first_step):
    assert first_step["variables"] <= TYPED_VARIABLES_BUDGET, first_step["variables"]


def _trajectory(options: dict, sense: int | None, steps: int = 120) -> dict[str, np.ndarray]:
    """Observations, rewards and signals of 3 vehicles under fixed random actions; with
    ``sense``, the batch's kernel replaced by the one compiled with those sensing flags."""
    batch = CapsuleBatch(EnvConfig(**options), 3)
    if sense is not None:
        batch._kernel = BatchedKernel(
            ENV, batch.plant.code, batch.kernel_mode, 3,
            command_path(batch.params.current_mode, batch.params.inverse_code),
            preview=batch.config.preview_points > 0, envelope=batch.envelope.flags, sense=sense,
        )  # fmt: skip
    batch.seed(4)
    batch.reset()
    actions = np.random.default_rng(1).uniform(-1.0, 1.0, (steps, 3))
    record: dict[str, list] = {"obs": [], "reward": [], "signals": []}
    for a in actions:
        batch.step(a)
        record["obs"].append(batch.obs.copy())
        record["reward"].append(batch.reward.copy())
        record["signals"].append(batch.signals.copy())
    return {k: np.stack(v) for k, v in record.items()}


@pytest.mark.parametrize(
    ("options", "flags"),
    [
        ({}, 0),
        ({"setting": "hils", "observation": "measured"}, SENSE_NOISE),
        ({"reward_acceleration_filter": "wk", "observation": "full_state"}, SENSE_FILTER),
    ],
)
def test_sensing_variant_gives_the_run_time_sensing_bit_for_bit(options, flags):
    batch = CapsuleBatch(EnvConfig(**options), 1)
    assert sense_flags(batch.params) == flags
    variant, general = _trajectory(options, None), _trajectory(options, SENSE_ALL)
    for key in variant:
        np.testing.assert_array_equal(variant[key], general[key], err_msg=key)


@pytest.mark.parametrize("observation", ["sensors", "full_state", "measured"])
def test_noise_free_observation_is_its_quantities_clipped(observation):
    config = EnvConfig(observation=observation)
    batch = CapsuleBatch(config, 2)
    batch.seed(2)
    batch.reset()
    low, high = (b.astype(np.float64) for b in observation_bounds(config, config.max_current_a))
    signal_of = {q.name: q.signal for q in QUANTITIES}
    for a in np.random.default_rng(3).uniform(-1.0, 1.0, (60, 2)):
        batch.step(a)
        sig = dict(zip(SIGNAL_NAMES, batch.signals))
        for j, name in enumerate(OBSERVATION_NAMES[observation]):
            if name == "levitation_gap_m":
                value = sig["bogie_displacement_m"] - sig["guideway_elevation_m"]
            else:
                value = sig[signal_of[name]]
            expected = np.minimum(np.maximum(value, low[j]), high[j]).astype(np.float32)
            np.testing.assert_array_equal(batch.obs[:, j], expected, err_msg=name)
