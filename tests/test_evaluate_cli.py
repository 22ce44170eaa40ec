"""``evaluate.py --env KEY=VALUE`` and ``--task ID`` (issue 28, section 3).

The overridden env is checked against a rollout made without evaluate.py (``gymnasium.make``
with the same options, one env per seed, the passive law's action); a task against the same
options given as ``--env`` items written here by hand; bad input against the project's rule
(one line on stderr, exit status 2). Tiny budgets: 2 episodes of 1 s.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from capsule_env import metrics
from capsule_env.evaluation import condition as eval_condition
from capsule_env.evaluation import evaluate
from capsule_env.tasks import DECLARED_TASKS, TASKS, Task

ROOT = Path(__file__).resolve().parent.parent
#: Two 1 s episodes on the evaluation bank's first seeds, no shipped policy (seconds per run).
QUICK = ["--episodes", "2", "--seed", "1000", "--no-shipped-policy"]


def run(tmp_path: Path, name: str, *argv: str) -> tuple[dict, str]:
    """evaluate.py's JSON and printed tables for ``argv`` (after :data:`QUICK`)."""
    out = tmp_path / f"{name}.json"
    assert evaluate.main([*QUICK, *argv, "--json", str(out)]) == 0
    return json.loads(out.read_text()), out.name


def direct_passive_wk(seeds: list[int], **env_kwargs) -> float:
    """Mean Wk-weighted RMS body acceleration of the passive damper, each episode a single
    ``gym.make`` env seeded ``seed`` on the evaluation bank (2026), stepped with the passive
    law's action (0: the action is ignored by the passive damper) to its end."""
    values = []
    for seed in seeds:
        env = gym.make("CapsuleSuspension-v0", damper="passive", action_mode="current",
                       guideway_seed=2026, **env_kwargs)  # fmt: skip
        env.reset(seed=seed)
        acc, done = [], False
        while not done:
            _, _, terminated, truncated, info = env.step(np.zeros(1, dtype=np.float32))
            acc.append(info["car_body_acceleration_m_s2"])
            done = terminated or truncated
        env.close()
        dt_s = 1.0 / env.unwrapped.config.control_rate_hz
        values.append(float(metrics.wk_weighted_rms(np.asarray(acc, dtype=float), dt_s)))
    return float(np.mean(values))


def test_env_override_changes_the_env_of_every_controller(tmp_path, capsys):
    names = "passive,skyhook-cont-biexp-meas"
    base, _ = run(tmp_path, "base", "--setting", "sim", "--episode-length", "1",
                  "--controllers", names)  # fmt: skip
    fast, _ = run(tmp_path, "slow", "--setting", "sim", "--env", "speed_kmh=400",
                  "--env", "episode_length_s=1", "--controllers", names)  # fmt: skip
    printed = capsys.readouterr().out
    wk = {k: r["settings"]["sim"]["controllers"]["passive"]["wk_rms_body_acc_m_s2"]
          for k, r in (("base", base), ("fast", fast))}  # fmt: skip
    # 400 km/h excites the modes with other wavelengths of the same guideway: another ride
    assert abs(wk["fast"] - wk["base"]) > 0.01 * wk["base"]
    # the same figure from gym.make on the same seeds, without evaluate.py's plumbing (the
    # vector env's vehicle k is the single env seeded k: equal to rounding)
    direct = direct_passive_wk([1000, 1001], speed_kmh=400, setting="sim", episode_length_s=1.0)
    assert wk["fast"] == pytest.approx(direct, rel=1e-9)
    for name, entry in fast["settings"]["sim"]["controllers"].items():
        assert entry["env_kwargs"]["speed_kmh"] == 400, name
        assert entry["own_options_kept"] == {}
    assert fast["condition"]["env_overrides"] == {"speed_kmh": 400, "episode_length_s": 1}
    assert fast["condition"]["task"] is None and fast["condition"]["episode_length_s"] == 1.0
    assert base["condition"]["env_overrides"] == {}
    assert "overrides (--env, --setting): speed_kmh=400, episode_length_s=1" in printed.replace(
        "\n  ", " "
    )


def test_task_equals_its_options_given_as_env_items(tmp_path, capsys):
    names = ["--controllers", "passive,skyhook-cont-biexp-meas,skyhook-cont-biexp"]
    task, _ = run(tmp_path, "task", "--task", "CapsuleRide-v0", "--env", "episode_length_s=1",
                  *names)  # fmt: skip
    items, _ = run(tmp_path, "items", "--env", "setting=hils", "--env", "observation=measured",
                   "--episode-length", "1", *names)  # fmt: skip
    printed = capsys.readouterr().out
    assert list(task["settings"]) == ["hils"] == list(items["settings"])  # the task's setting
    for name, entry in task["settings"]["hils"]["controllers"].items():
        other = items["settings"]["hils"]["controllers"][name]
        assert entry["wk_rms_body_acc_m_s2"] == other["wk_rms_body_acc_m_s2"], name
        assert entry.get("vre_pct") == other.get("vre_pct"), name
        assert entry["env_kwargs"] == other["env_kwargs"], name
    assert task["condition"]["task"] == "CapsuleRide-v0"
    assert task["condition"]["task_env_kwargs"] == {"setting": "hils", "observation": "measured"}
    # a law on ideal sensors keeps what it reads, and the results say so
    kept = task["settings"]["hils"]["controllers"]["skyhook-cont-biexp"]["own_options_kept"]
    assert kept == {"observation": {"controller": "full_state", "condition": "measured"}}
    assert "own options kept over the evaluated env's: observation='full_state' " in printed
    # the tuned gains were tuned in hils: no note on this condition
    assert "tuned gains (agents/controllers/tuned_gains.json) were tuned at" not in printed


def test_tuned_gains_are_kept_and_the_condition_change_is_stated(tmp_path, capsys):
    from capsule_env.agents import classical_controllers

    shipped = classical_controllers()["skyhook-cont-biexp-meas"].gains()
    result, _ = run(tmp_path, "tuned", "--setting", "hils", "--env", "speed_kmh=400",
                    "--episode-length", "1", "--controllers", "skyhook-cont-biexp-meas")  # fmt: skip
    printed = capsys.readouterr().out
    entry = result["settings"]["hils"]["controllers"]["skyhook-cont-biexp-meas"]
    assert entry["gains_tuned"] and entry["gains"] == shipped
    assert entry["tuned_condition_differs"] == {"speed_kmh": {"tuned": 810.0, "evaluated": 400}}
    note = printed.replace("\n  ", " ")
    assert "were tuned at setting='hils'" in note and "speed_kmh=400 (tuned: 810.0)" in note


def test_a_law_tuned_on_a_task_is_compared_with_that_task(tmp_path):
    """The scheduled LQR was searched in CapsuleTrip-v0's options (its gains-file entry's
    ``task``): on that task its env is the one it was tuned in; the fixed LQR's is not."""
    result, _ = run(tmp_path, "trip", "--task", "CapsuleTrip-v0", "--episode-length", "1",
                    "--controllers", "lqr-sched-biexp-meas,lqr-clipped-biexp-meas")  # fmt: skip
    rows = result["settings"]["hils"]["controllers"]
    assert rows["lqr-sched-biexp-meas"]["gains_tuned"]
    assert rows["lqr-sched-biexp-meas"]["tuned_condition_differs"] == {}
    assert "spans" in rows["lqr-clipped-biexp-meas"]["tuned_condition_differs"]


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--task", "CapsuleNope-v0"], "CapsuleSuspension-v0, CapsuleRide-v0"),
        (["--env", "speed_mph=400"], "'speed_mph' is not an env option; accepted: "),
        (["--env", "speed_kmh=-4"], "speed_kmh must be in [0.001, 10000.0], got -4"),
        (["--env", "speed_kmh"], "--env expects KEY=VALUE, got 'speed_kmh'"),
        (["--env", "setting=both"], "--env setting must be one of sim, hils"),
        (["--env", "setting=lab"], "setting"),
        (["--env", "setting=sim", "--setting", "hils"], "contradicts --setting 'hils'"),
        (["--env", "episode_length_s=2", "--episode-length", "3"], "contradicts --episode-length"),
        (["--task", "CapsuleRide-v0", "--env", "vehicle_params=[1]"], "vehicle_params must be"),
        (["--env", "observation=ideal"], "observation"),
        (["--env", "episode_length_s=0.001"], "--env episode_length_s 0.001 s is shorter than"),
        (["--env", "episode_length_s=0.2"], "--env episode_length_s 0.2 s (40 control steps) is"),
    ],
)
def test_bad_task_or_env_is_one_line_and_exit_2(argv, needle, capsys):
    with pytest.raises(SystemExit) as stop:
        evaluate.main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("evaluate.py: error: ") and err.count("\n") == 1, err
    assert needle in err


def test_the_script_itself_says_one_line_without_traceback():
    proc = subprocess.run([sys.executable, "evaluate.py", "--task", "Capsule-v9"], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)  # fmt: skip
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr == (
        "evaluate.py: error: --task must be one of "
        + ", ".join(t.env_id for t in TASKS + DECLARED_TASKS)
        + ", got 'Capsule-v9'\n"
    )


def test_settings_and_episode_length_resolution():
    def condition(*argv: str) -> eval_condition.Condition:
        return evaluate.parse_args(list(argv)).condition

    assert condition().settings == ("sim", "hils") and condition().is_default
    assert condition("--env", "speed_kmh=600").settings == ("sim", "hils")
    assert condition("--task", "CapsuleSuspension-v0").settings == ("sim",)  # env's default
    assert condition("--task", "CapsuleRide-v0").settings == ("hils",)
    ride_sim = condition("--task", "CapsuleRide-v0", "--setting", "sim")
    assert ride_sim.settings == ("sim",) and ride_sim.env_kwargs == {"observation": "measured"}
    # --setting over a task's own is a change of the task, named as one (it was labelled as
    # the bare task in the header and the --plots folder)
    assert ride_sim.env_overrides == {"setting": "sim"} and not ride_sim.is_default
    assert ride_sim.label() == "CapsuleRide-v0+setting=sim"
    assert condition("--task", "CapsuleRide-v0", "--setting", "hils").env_overrides == {}
    both = condition("--task", "CapsuleSuspension-v0", "--setting", "both")
    assert both.settings == ("sim", "hils") and both.env_overrides == {"setting": "both"}
    assert "overrides (--env, --setting): setting='both'" in eval_condition.headline(
        {"condition": both.describe()}
    )
    assert condition("--env", "setting=hils", "--setting", "hils").settings == ("hils",)
    assert condition().episode_length_s == 10.0
    assert condition("--env", "episode_length_s=2.5").episode_length_s == 2.5
    args = evaluate.parse_args(["--env", "episode_length_s=2.5"])
    assert args.episode_length == 2.5
    # a later item of the same key wins, as in train.py
    assert condition("--env", "speed_kmh=500", "--env", "speed_kmh=700").env_kwargs == {
        "speed_kmh": 700
    }
    # values read as train.py reads them: numbers, bools, JSON objects, bare words
    parsed = condition("--env", 'vehicle_params={"car_body_mass_kg": 7000}', "--env",
                       "guideway=random", "--env", "preview_points=4").env_kwargs  # fmt: skip
    assert parsed == {"vehicle_params": {"car_body_mass_kg": 7000}, "guideway": "random",
                      "preview_points": 4}  # fmt: skip


def test_plots_go_to_a_sub_folder_named_after_the_condition(tmp_path):
    def folder(*argv: str) -> Path:
        return evaluate.plots_dir(evaluate.parse_args([*argv, "--plots", str(tmp_path)]))

    assert folder() == tmp_path  # the paper's run: the folder itself
    assert folder("--task", "CapsuleRide-v0") == tmp_path / "CapsuleRide-v0"
    assert folder("--env", "speed_kmh=400", "--env", "setting=hils") == (
        tmp_path / "CapsuleSuspension-v0+speed_kmh=400+setting=hils"
    )
    odd = folder("--task", "CapsuleRide-v0", "--env", 'vehicle_params={"car_body_mass_kg": 7e3}')
    assert odd.parent == tmp_path
    assert odd.name == "CapsuleRide-v0+vehicle_params=__car_body_mass_kg__7000.0_"
    long = folder("--env", "survey_offset_m=0.001", "--env", "velocity_estimator_damping=0.8",
                  "--env", "velocity_estimator_corner_hz=0.2", "--env", "position_error_m=0.1",
                  "--env", "reward_stroke_weight=0.2")  # fmt: skip
    whole = ("CapsuleSuspension-v0+survey_offset_m=0.001+velocity_estimator_damping=0.8+"
             "velocity_estimator_corner_hz=0.2+position_error_m=0.1+reward_stroke_weight=0.2")  # fmt: skip
    assert len(long.name) == eval_condition.MAX_LABEL_CHARS and long.parent == tmp_path
    assert long.name.startswith(whole[:80])
    assert long.name.endswith(hashlib.sha256(whole.encode()).hexdigest()[:12])


def test_a_task_registered_later_needs_no_edit(monkeypatch):
    """A task added to capsule_env.tasks (and registered) is evaluated with its registered
    kwargs, read from Gymnasium's registry."""
    from gymnasium.envs.registration import register, registry

    from capsule_env.tasks import ENTRY_POINT

    task = Task("CapsuleTestSlow-v0", "a test task", "sensors", {"speed_kmh": 600.0})
    monkeypatch.setattr(eval_condition, "TASKS", (*TASKS, task))
    register(id=task.env_id, entry_point=ENTRY_POINT, kwargs={"speed_kmh": 600.0})
    try:
        got = eval_condition.build_condition(task.env_id, ["reward_stroke_weight=0.2"], None, None)
    finally:
        del registry[task.env_id]
    assert got.env_kwargs == {"speed_kmh": 600.0, "reward_stroke_weight": 0.2}
    assert got.settings == ("sim",)


def test_a_controllers_own_physics_is_stated_where_the_condition_left_the_default():
    # a law made for trips (its own options: a trip, EDS levitation) on the paper's task runs
    # its own physics: the results say so, naming the env's defaults it replaced; what a law
    # reads and how it acts (observation, inverse model, force limit) is never such a change
    from capsule_env.evaluation.condition import controller_env

    own = {"observation": "measured", "inverse_model": "bi_exponential", "max_force_n": 8000.0,
           "speed_profile": "trip", "levitation": "eds"}  # fmt: skip
    env, kept = controller_env({}, own, "hils")
    assert env["speed_profile"] == "trip" and env["setting"] == "hils"
    assert kept == {"speed_profile": {"controller": "trip", "condition": "constant"},
                    "levitation": {"controller": "eds", "condition": "fixed"}}  # fmt: skip
    # on the trip task the same options are the condition's: nothing kept
    task = {"levitation": "eds", "speed_profile": "trip", "spans": "continuous"}
    assert controller_env(task, own, "hils")[1] == {}
    # an option given at the env's default changes nothing
    assert controller_env({}, {"speed_kmh": 810.0, "levitation": "fixed"}, "hils")[1] == {}


@pytest.mark.parametrize(
    ("argv", "needle"),
    [  # issue 40: each was caught after the run had started, or not at all
        (["--seed", str(2**63)], "--seed must be in 0..9223372036854775798 (2**63 - --episodes"),
        (["--seed", str(2**63 - 5), "--episodes", "10"], "--seed must be in 0.."),
        (["--seed", "-1"], "--seed must be in 0.."),
        (["--controllers", ""], "--controllers names no controller (got '')"),
        (["--controllers", " , "], "--controllers names no controller"),
    ],
)
def test_bad_seed_or_empty_controllers_stop_before_the_run(argv, needle, capsys, tmp_path):
    out = tmp_path / "out.json"
    with pytest.raises(SystemExit) as stop:
        evaluate.main([*argv, "--no-shipped-policy", "--json", str(out)])
    err = stop.value.code  # sys.exit(message): the interpreter prints it, exit status 1
    assert isinstance(err, str) and err.startswith("evaluate.py: error: "), err
    assert "\n" not in err and needle in err and not out.exists()


def test_the_last_seed_the_kernels_take_runs():
    args = evaluate.parse_args(["--seed", str(2**63 - 2), "--episodes", "2"])
    evaluate.check_args(args)  # episode seeds 2**63 - 2 and 2**63 - 1: both in range


def test_a_task_s_own_laws_join_its_default_run():
    # the trip task's law, the gain-scheduled LQR, was left out of --task CapsuleTrip-v0
    trip = evaluate.parse_args(["--task", "CapsuleTrip-v0", "--no-shipped-policy"])
    assert "lqr-sched-biexp-meas" in evaluate.prepare(trip)
    ride = evaluate.parse_args(["--task", "CapsuleRide-v0", "--no-shipped-policy"])
    assert "lqr-sched-biexp-meas" not in evaluate.prepare(ride)
    named = evaluate.parse_args(["--task", "CapsuleTrip-v0", "--no-shipped-policy",
                                 "--controllers", "passive,mpc-biexp-meas"])  # fmt: skip
    assert list(evaluate.prepare(named)) == ["passive", "mpc-biexp-meas"]


def test_a_cold_cache_is_announced_on_stderr(tmp_path, capsys, monkeypatch):
    for _ in range(2):  # the first may compile (a cold or stale cache) and then say so
        capsys.readouterr()
        run(tmp_path, "warm", "--setting", "sim", "--episode-length", "1", "--controllers",
            "passive")  # fmt: skip
    assert evaluate.kernels_cached()  # those runs compiled or loaded the kernels
    assert "compiling" not in capsys.readouterr().err
    monkeypatch.setattr(evaluate, "kernels_cached", lambda: False)
    run(tmp_path, "cold", "--setting", "sim", "--episode-length", "1", "--controllers",
        "passive")  # fmt: skip
    captured = capsys.readouterr()
    assert "compiling the numba kernels" in captured.err
    assert "compiling" not in captured.out


def test_a_cold_or_stale_cache_is_told_from_a_warm_one(tmp_path):
    """In a fresh interpreter whose numba caches in an empty folder: not cached; after numba
    compiled a function of capsule_env.engine.kernels (it writes its index there): cached; with
    that index older than kernels.py, as after an edit of the module, which numba compiles
    again: not cached (it read as cached, issue 40)."""
    code = textwrap.dedent("""
        import os
        from pathlib import Path
        from capsule_env.evaluation import evaluate
        from capsule_env.engine import kernels
        print(evaluate.kernels_cached())
        kernels.work_item_size(4)
        print(evaluate.kernels_cached())
        for index in Path(os.environ["NUMBA_CACHE_DIR"]).rglob("*.nbi"):
            os.utime(index, (0, 0))
        print(evaluate.kernels_cached())
    """)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.split() == ["False", "True", "False"]
    assert list((tmp_path / "cache").rglob("kernels.work_item_size*.nbi"))


def test_the_help_calls_the_oracle_a_search_not_a_bound(capsys):
    # issue 40: "--oracle: also search the clairvoyant bound"; it is a multi-start local search
    with pytest.raises(SystemExit):
        evaluate.parse_args(["--help"])
    texts = {"--help": capsys.readouterr().out, "add_oracle": evaluate.add_oracle.__doc__}
    texts.update(module=evaluate.__doc__, evaluate=evaluate.evaluate.__doc__)
    for name, text in texts.items():
        flat = " ".join(text.split()).lower()
        assert "clairvoyant bound" not in flat and "bound's" not in flat, name
    assert "multi-start local search" in " ".join(texts["--help"].split())
    assert "not a proven limit" in " ".join(texts["--help"].split())
