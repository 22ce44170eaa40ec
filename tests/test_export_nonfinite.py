"""The export's rule for a non-finite observation, as a rig builds and feeds the files.

A residual policy's C ``capsule_policy`` gives the residual 0 on a row holding a NaN or inf
(:mod:`capsule_env.export.c_export`). Rigs often build with ``-ffast-math`` (``-Ofast``), under
which the compiler may assume every float finite and drop C99's ``isfinite``: the rule must hold
there too. GCC links such a library with ``crtfastmath.o``, whose constructor turns on
flush-to-zero and denormals-are-zero for the whole process that loads it: the library is loaded
in a child process, so the rest of the test session keeps IEEE arithmetic (loading it here made
two later tests of ``glibc_tanh`` on subnormals fail).
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from conftest import NO_SB3

pytest.importorskip("stable_baselines3", reason=NO_SB3)

from capsule_env.agents.learning.sb3_policy import PRETRAINED_DIR, SB3Policy  # noqa: E402

from capsule_env.export import export_policy  # noqa: E402
from capsule_env.export.c_build import C_FLAGS, build_shared, c_compiler  # noqa: E402

NAME = "residual-ppo-mpc"


@pytest.mark.parametrize("flag", ["-ffast-math", "-Ofast"])
def test_the_c_residual_is_0_on_a_non_finite_row_under_fast_math(flag, tmp_path):
    if c_compiler() is None:
        pytest.skip("no C compiler on this machine (cc, gcc, clang or $CC)")
    files = export_policy(NAME, tmp_path / "out", "c")
    library = build_shared(files[f"{NAME}.c"], tmp_path, (*C_FLAGS, flag))
    obs = np.zeros((5, 9), np.float32)
    obs[:, 2] = np.linspace(-0.01, 0.01, 5)  # strokes: the network's residual is not 0 there
    obs[1, 2], obs[2, 0], obs[3, 8] = np.nan, np.inf, -np.inf
    bad = ~np.all(np.isfinite(obs), axis=1)
    network = SB3Policy.load(PRETRAINED_DIR / f"{NAME}.zip")
    expected, _ = network.predict(obs[~bad], deterministic=True)
    assert np.all(np.abs(expected) > 1e-3)  # a dropped rule would not give 0 by chance
    got = _policy_in_a_child(library, obs, tmp_path)
    assert np.all(got[bad] == 0.0), got[bad]
    np.testing.assert_allclose(got[~bad], expected, rtol=0, atol=1e-4)


def _policy_in_a_child(library, obs: np.ndarray, folder) -> np.ndarray:
    """``CPolicy(library).policy(obs)`` run in a fresh Python process (module docstring: a
    fast-math library changes the loading process's floating-point mode)."""
    np.save(folder / "obs.npy", obs)
    code = ("import sys, numpy as np; from capsule_env.export.c_build import CPolicy; "
            "obs = np.load(sys.argv[2]); "
            "np.save(sys.argv[3], CPolicy(sys.argv[1], obs.shape[1]).policy(obs))")  # fmt: skip
    out = folder / "got.npy"
    subprocess.run([sys.executable, "-c", code, str(library), str(folder / "obs.npy"), str(out)],
                   check=True, timeout=120)  # fmt: skip
    return np.load(out)


def test_a_fast_math_library_is_loaded_out_of_this_process(tmp_path):
    """The arithmetic of this process after the fast-math test: 5e-324 * 1 is still the
    subnormal (with denormals-are-zero it would be 0), and the smallest normal halved is not
    flushed."""
    tiny = np.finfo(np.float64).tiny
    assert np.float64(5e-324) * np.float64(1.0) > 0.0
    assert np.float64(tiny) / np.float64(2.0) > 0.0


HALF_CAR = "residual-ppo-mpc-half-car"


def _half_car_rows(steps: int = 12) -> np.ndarray:
    """Observations of the half-car task's env (guideway bank 3, seed 40), passive damper."""
    from capsule_env.envs.declared_vector import DeclaredVectorEnv

    env = DeclaredVectorEnv(1, guideway_seed=3, episode_length_s=1.0, vehicle="half_car",
                            setting="hils", observation="measured", action_mode="force")  # fmt: skip
    obs, _ = env.reset(seed=[40])
    rows = []
    for _ in range(steps):
        rows.append(obs.copy())
        obs, *_ = env.step(np.zeros((1, 2), np.float32))
    env.close()
    return np.concatenate(rows)


def test_a_half_car_contract_states_its_law_on_a_non_finite_observation(tmp_path):
    """The half-car MPC's block says what the law does with a NaN or inf (the quarter-car's
    says it too), and it is what the law rebuilt from the block does: 0 on both slots whatever
    measured column holds it (an acceleration it does not feed its state included); the
    per-bogie LQR's block says it has no rule: a NaN in a slot's state column makes that slot's
    action NaN, a NaN elsewhere changes nothing."""
    import json

    from capsule_env.agents.controllers.mpc_solver import solver_available

    from capsule_env.export.base_law import rebuild_base_law

    from conftest import residual_copy

    if not solver_available("daqp"):
        pytest.skip("the half-car MPC's QP solver DAQP is not installed (the mpc extra)")
    card = json.loads(export_policy(HALF_CAR, tmp_path / "mpc", "c")
                      [f"{HALF_CAR}.contract.json"].read_text())  # fmt: skip
    block = card["residual"]["base_law"]
    assert "0 N on both slots" in block["nonfinite"]
    law, rows = rebuild_base_law(block), _half_car_rows()
    for k, column in enumerate((2, 0, 13), start=3):  # an acceleration, a stroke, a velocity
        rows[k, column] = np.nan
    rows[9, 4] = np.inf
    actions = np.concatenate([law.predict(rows[t : t + 1], episode_start=np.array([t == 0]))[0]
                              for t in range(rows.shape[0])])  # fmt: skip
    bad = ~np.all(np.isfinite(rows), axis=1)
    assert np.all(actions[bad] == 0.0)
    assert np.all(np.abs(actions[~bad][1:]).max(axis=1) > 1e-3)  # (row 0: at rest)

    lqr_zip = residual_copy(tmp_path, HALF_CAR, "lqr-clipped-biexp-meas", "res-lqr")
    lqr_card = json.loads(export_policy(str(lqr_zip), tmp_path / "lqr", "c")
                          ["res-lqr.contract.json"].read_text())  # fmt: skip
    lqr_block = lqr_card["residual"]["base_law"]
    assert "no special handling" in lqr_block["nonfinite"]
    lqr, row = rebuild_base_law(lqr_block), _half_car_rows(2)[1:].copy()
    row[0, lqr_block["state_columns"][0][0]["index"]] = np.nan  # slot 0's stroke
    row[0, 10] = np.nan  # the rear's upper acceleration: in no slot's state
    action = lqr.predict(row)[0][0]
    assert np.isnan(action[0]) and np.isfinite(action[1])
    assert "an inf one" in lqr_block["nonfinite"]
    row[0, lqr_block["state_columns"][0][0]["index"]] = np.inf  # the clip saturates it
    assert abs(lqr.predict(row)[0][0, 0]) == 1.0
