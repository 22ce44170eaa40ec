"""experiments/envelope.py and capsule_env/envelope/report.py: a point's Wk is evaluate.py's on
the same options, a rerun skips what is done, bad arguments are one line (exit 2), the page's
tables are the JSON's and say what did not run."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from capsule_env.envelope import report as envelope_report
from capsule_env.evaluation.evaluate import evaluate, parse_args

ROOT = Path(__file__).resolve().parents[1]
SPANS_30 = "spans/continuous/30m/L3000"


@pytest.fixture(scope="module")
def envelope():
    """The script as a module, registered in ``sys.modules`` (its dataclasses need it)."""
    spec = importlib.util.spec_from_file_location("envelope_script", ROOT / "experiments" /
                                                  "envelope.py")  # fmt: skip
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop(spec.name, None)


def _point(envelope, key):
    return next(p for p in envelope.envelope_points() if p.key == key)


def test_point_runner_gives_evaluate_py_wk(envelope):
    """The runner on the 30 m spans point (EDS, 810 km/h), 2 seeds of 0.5 s, against
    ``evaluate.py --env ...`` with the options written out by hand."""
    from capsule_env.agents import classical_controllers

    name = "lqr-clipped-biexp-meas"
    entry = envelope.run_point(_point(envelope, SPANS_30), classical_controllers()[name],
                               [1000, 1001], 0.5)  # fmt: skip
    args = parse_args(["--setting", "hils", "--env", "observation=measured", "--env",
                       "levitation=eds", "--env", "speed_kmh=810", "--env", "spans=continuous",
                       "--env", 'span_params={"span_m": 30, "sag_m": 0.01}', "--controllers",
                       name, "--no-shipped-policy", "--episodes", "2", "--episode-length",
                       "0.5"])  # fmt: skip
    direct = evaluate(args)["settings"]["hils"]["controllers"][name]
    assert entry["wk_rms_body_acc_m_s2"] == pytest.approx(direct["wk_rms_body_acc_m_s2"],
                                                          rel=1e-12)  # fmt: skip
    assert len(entry["wk_per_episode_m_s2"]) == 2
    # the spans point records the PSD: 0.5 Hz lines (2 s segments, here the 0.5 s record) to 40 Hz
    assert entry["psd_frequency_hz"][-1] <= 40.0 and len(entry["psd_m2_s4_per_hz"]) > 1


def _argv(tmp_path, controllers="passive"):
    return ["--json", str(tmp_path / "e.json"), "--figures", "", "--page", "",
            "--only", "payload/+0.40", "--sweeps", "payload", "--controllers", controllers,
            "--policies", "", "--oracle", "", "--episodes", "2", "--episode-length", "0.5"]  # fmt: skip


def test_rerun_skips_done_pairs(envelope, tmp_path, monkeypatch):
    calls = []
    real = envelope.run_point

    def counting(point, ctrl, seeds, length):
        calls.append((point.key, ctrl.name))
        return real(point, ctrl, seeds, length)

    monkeypatch.setattr(envelope, "run_point", counting)
    assert envelope.main(_argv(tmp_path)) == 0
    first = json.loads((tmp_path / "e.json").read_text())
    assert calls == [("payload/+0.40", "passive")]
    assert envelope.main(_argv(tmp_path)) == 0  # all done: nothing runs, the file is the same
    assert calls == [("payload/+0.40", "passive")]
    assert json.loads((tmp_path / "e.json").read_text()) == first
    assert envelope.main(_argv(tmp_path, "passive,skyhook-meas")) == 0  # only the new one
    assert calls[1:] == [("payload/+0.40", "skyhook-meas")]
    done = json.loads((tmp_path / "e.json").read_text())["points"]["payload/+0.40"]
    assert (
        done["controllers"]["passive"] == first["points"]["payload/+0.40"]["controllers"]["passive"]
    )
    # another episode count: the JSON is refused, one line, exit 2
    assert envelope.main([*_argv(tmp_path), "--episodes", "3"]) == 2


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["--episodes", "0"], "--episodes must be >= 1"),
        (["--sweeps", "speed,altitude"], "--sweeps must be names among"),
        (["--oracle", "speed/eds/99"], "--oracle: unknown point"),
        (["--episode-length", "0.1"], "--episode-length"),
        (["--seed", "-1"], "--seed must be >= 0"),
        (["--controllers", "nope", "--page", "", "--figures", ""], "--controllers: unknown"),
    ],
)
def test_bad_argument_is_one_line_exit_2(envelope, tmp_path, capsys, argv, needle):
    full = ["--json", str(tmp_path / "e.json"), *argv]
    try:
        status = envelope.main(full)
    except SystemExit as exc:
        status = exc.code
    err = capsys.readouterr().err
    assert status == 2
    assert needle in err and err.count("\n") == 1 and err.startswith("envelope.py: error:")


def test_policy_of_another_observation_is_not_run(envelope):
    trip = _point(envelope, "trip")
    policy = SimpleNamespace(
        model=SimpleNamespace(observation_space=SimpleNamespace(shape=(9,))),
        env_kwargs={"observation": "measured", "action_mode": "force"},
    )
    entry = envelope.run_point(trip, policy, [1000], 0.5)
    assert "speed_m_s, longitudinal_acceleration_m_s2" in entry["skipped"]
    assert envelope.observation_mismatch(policy, {"observation": "measured"}) is None


def _hand_written() -> dict:
    def ctrls(**wk):
        return {n.replace("_", "-"): ({"wk_rms_body_acc_m_s2": v} if isinstance(v, float)
                                      else {"skipped": v}) for n, v in wk.items()}  # fmt: skip

    point = {"sweep": "payload", "env_kwargs": {}}
    return {
        "config": {"episodes": 2, "seed": 1000, "episode_length_s": 0.5, "guideway_seed": 2026,
                   "setting": "hils"},
        "runtime_s": 60.0,
        "points": {
            "payload/-0.30": {**point, "label": "", "value": -0.3,
                              "controllers": ctrls(passive=0.2, lqr=0.15, ppo="not run: x",
                                                  oracle=0.1)},
            "payload/+0.40": {**point, "label": "", "value": 0.4,
                              "controllers": ctrls(passive=0.3, lqr=0.28, ppo=0.27)},
        },
    }  # fmt: skip


def test_tables_from_a_hand_written_json():
    text = envelope_report.tables(_hand_written())
    lines = text.splitlines()
    assert "| controller | -30 % | +40 % |" in lines
    assert "| `passive` | 0.2000 | 0.3000 |" in lines
    assert "| `lqr` | **0.1500** | 0.2800 |" in lines
    assert "| `ppo` | – | **0.2700** |" in lines
    assert "| best / passive | 0.750 | 0.900 |" in lines
    assert "- `ppo` at `payload/-0.30`: not run: x" in lines
    assert "| `oracle` | 0.1000 | – |" in lines  # a reference, never bold, last
    # the oracle is a local search: an achievable reference, never called a bound or a limit
    assert "a bound" not in lines[0] and "a clairvoyant local search" in lines[0]
    assert lines.index("| `oracle` | 0.1000 | – |") == lines.index("| `ppo` | – | **0.2700** |") + 1
    assert "| headroom closed | 0.50 | – |" in lines  # (0.2 - 0.15) / (0.2 - 0.1)


def test_a_controller_that_never_ran_in_a_table_is_one_note_not_a_row():
    data = _hand_written()
    for p in data["points"].values():
        p["controllers"]["sched"] = {"skipped": "not run: its own options set trip"}
    lines = envelope_report.tables(data).splitlines()
    assert not any(line.startswith("| `sched`") for line in lines)
    assert (
        "- `sched` at `payload/-0.30`, `payload/+0.40`: not run: its own options set trip" in lines
    )


def test_a_controller_that_never_ran_has_each_points_own_reason():
    # the note had given every point the first point's reason (the page said "(the point:
    # (-0.3, -0.3))" of the +40 % payload, and no spans mismatch at the simply supported one)
    data = _hand_written()
    data["points"]["payload/-0.30"]["controllers"]["trip"] = {"skipped": "not run: a (-0.3)"}
    data["points"]["payload/+0.40"]["controllers"]["trip"] = {"skipped": "not run: a (0.4)"}
    lines = envelope_report.tables(data).splitlines()
    assert "- `trip` at `payload/-0.30`: not run: a (-0.3)" in lines
    assert "- `trip` at `payload/+0.40`: not run: a (0.4)" in lines


def test_a_law_made_for_trips_runs_only_where_the_point_is_a_trip(envelope):
    own = {"observation": "measured", "speed_profile": "trip", "levitation": "eds"}
    reason = envelope.physics_mismatch(_point(envelope, "speed/fixed/810").env_kwargs, own)
    assert reason == ("not run: its own options set speed_profile='trip' (the point: "
                      "'constant'), levitation='eds' (the point: 'fixed')")  # fmt: skip
    assert "levitation" not in envelope.physics_mismatch(
        _point(envelope, "speed/eds/810").env_kwargs, own)  # fmt: skip
    assert envelope.physics_mismatch(_point(envelope, "trip").env_kwargs, own) is None
    # reading and acting options are the controller's own, never a mismatch
    assert envelope.physics_mismatch({}, {"observation": "sensors", "action_mode": "force"}) is None


def test_every_option_of_the_plants_physics_is_a_mismatch_and_only_those(envelope):
    """Not only the envelope's own options: a controller whose options set the speed range,
    the vehicle, its randomisation or the guideway bank would run other episodes than the
    point's (they were let through); an option at its default value, what a controller reads
    or how it acts, and the passive row's damper are not refused."""
    eds400 = _point(envelope, "speed/eds/400").env_kwargs
    cases = {
        "speed_range_kmh": ((700.0, 900.0), "None"),
        "vehicle_params": ({"car_body_mass_kg": 8400.0}, "{}"),
        "vehicle_randomization": (0.2, "0.0"),
        "guideway_seed": (0, "2026"),  # the training bank, not the evaluation's
        "guideway_params": ({"peak_m": None}, "{}"),
        "stroke_limit_m": (0.01, "0.06"),
    }
    for key, (value, there) in cases.items():
        assert envelope.physics_mismatch(eds400, {key: value}) == (
            f"not run: its own options set {key}={value!r} (the point: {there})"
        ), key
    trip = _point(envelope, "trip").env_kwargs
    assert envelope.physics_mismatch(trip, {"speed_range_kmh": (700.0, 900.0)}).startswith(
        "not run: its own options set speed_range_kmh=(700.0, 900.0) (the point: None; "
        "refused there: speed_range_kmh must be None"
    )
    assert "cruise_speed_kmh" in envelope.physics_mismatch(trip, {"trip_params": {
        "cruise_speed_kmh": 900.0}})  # fmt: skip
    not_physics = [
        {"trip_params": {"cruise_speed_kmh": 1000.0}},  # the default, spelled out
        {"speed_profile": "trip", "levitation": "eds", "payload_range": [-0.3, 0.4]},
        {"observation": "measured", "preview_points": 32, "preview_horizon_s": 1.0,
         "sensor_noise": 2.0, "control_delay_steps": 2, "control_rate_hz": 400.0,
         "inverse_model": "csdc", "max_force_n": 5000.0, "setting": "sim"},
        {"damper": "passive"},  # the passive row: the damper is its actuator
    ]  # fmt: skip
    for own in not_physics:
        assert envelope.physics_mismatch(trip, own) is None, own


def test_page_in_sync_with_the_json():
    page = (ROOT / "docs" / "envelope.md").read_text()
    data = json.loads((ROOT / "docs" / "figures" / "envelope.json").read_text())
    assert envelope_report.tables(data) in page
    assert data["config"] == {"episodes": 10, "seed": 1000, "episode_length_s": 10.0,
                              "guideway_seed": 2026, "setting": "hils"}  # fmt: skip


def test_stored_points_agree_with_the_stored_evaluation():
    """A committed run of another code path on the same options: the fixed-levitation 810
    km/h point is evaluate.py's hils run (docs/figures/evaluation.json, measured-signal rows).
    Both were measured on one machine from the same kernels; 1e-9 relative leaves room for the
    JSON's float text only."""
    data = json.loads((ROOT / "docs" / "figures" / "envelope.json").read_text())["points"]
    pairs = (("speed/fixed/810", "evaluation.json"),)
    for key, name in pairs:
        other = json.loads((ROOT / "docs" / "figures" / name).read_text())
        theirs = other["settings"]["hils"]["controllers"]
        ours = data[key]["controllers"]
        shared = [
            n for n in ours if n in theirs and theirs[n]["observation"] in ("none", "measured")
        ]
        assert "passive" in shared and "lqr-clipped-biexp-meas" in shared
        for n in shared:
            assert ours[n]["wk_rms_body_acc_m_s2"] == pytest.approx(
                theirs[n]["wk_rms_body_acc_m_s2"], rel=1e-9), (key, n)  # fmt: skip


def test_law_that_refuses_the_point_is_recorded_not_run(envelope):
    class NeedsATrip:
        name, env_kwargs = "needs-a-trip", {"observation": "measured"}

        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            raise ValueError("speed column missing: run it on a trip")

    entry = envelope.run_point(_point(envelope, "payload/+0.20"), NeedsATrip(), [1000], 0.5)
    assert entry["skipped"] == "not run: speed column missing: run it on a trip"
