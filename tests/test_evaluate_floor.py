"""evaluate.py --floor: the certified floor (capsule_env.bounds) as a block of each setting,
below the oracle and every controller on the same episodes; refused, in one line and before
anything runs, where the floor does not cover the plant or the length."""

from __future__ import annotations

import json

import pytest

from capsule_env.evaluation.evaluate import main


def test_floor_block_lies_below_the_oracle_and_every_controller(tmp_path, monkeypatch):
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "1")
    out = tmp_path / "floor.json"
    argv = ["--setting", "sim", "--controllers", "passive,mr-0A,lqr-clipped-biexp-meas",
            "--no-shipped-policy", "--episodes", "1", "--episode-length", "0.4",
            "--oracle", "--floor", "--json", str(out)]  # fmt: skip
    assert main(argv) == 0
    block = json.loads(out.read_text())["settings"]["sim"]
    floor = block["floor"]
    assert floor["certified"] is True
    assert len(floor["per_episode"]["wk_rms_body_acc_m_s2"]) == 1
    rows = block["controllers"]
    assert floor["wk_rms_body_acc_m_s2"] >= 0.0
    for name, row in rows.items():  # the oracle and every controller ran the same episode
        assert floor["wk_rms_body_acc_m_s2"] <= row["wk_rms_body_acc_m_s2"], name
    assert floor["floor_to_oracle"] == pytest.approx(
        floor["wk_rms_body_acc_m_s2"] / rows["oracle"]["wk_rms_body_acc_m_s2"]
    )


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--task", "CapsuleRide-v0", "--episode-length", "0.5"], "'reference'"),
        (["--setting", "sim"], "at most 4000"),
        (["--task", "CapsuleHalfRide-v0"], "--floor is not supported"),
    ],
)
def test_floor_refused_in_one_line_before_anything_runs(argv, needle, tmp_path, capsys):
    out = tmp_path / "never.json"
    with pytest.raises(SystemExit) as err:
        main([*argv, "--floor", "--json", str(out)])
    message = str(err.value.code) if err.value.code not in (2,) else capsys.readouterr().err
    assert needle in message and "--floor" in message
    assert message.strip().count("\n") == 0 or message.strip().startswith("usage")
    assert not out.exists()


@pytest.mark.parametrize(
    "argv",
    [
        ["--episodes", "1", "--episode-length", "0.1"],  # refused by the controllers' check
        ["--policy", "/nonexistent/policy.zip"],
    ],
)
def test_a_refused_run_creates_no_output_folder(argv, tmp_path):
    out = tmp_path / "new" / "sub" / "results.json"
    with pytest.raises(SystemExit) as err:
        main([*argv, "--json", str(out)])
    assert str(err.value.code).startswith("evaluate.py: error: ")
    assert not (tmp_path / "new").exists()


def test_floor_nodes_reach_the_branch_and_bound(tmp_path, monkeypatch):
    """``--floor N`` passes N node QPs to the branch and bound; bare ``--floor`` passes 0."""
    import capsule_env.bounds as bounds

    seen: list[int] = []

    def fake(env_kwargs, seeds, length_s, **options):
        seen.append(options["branch_nodes"])
        raise RuntimeError("stop after the call")

    monkeypatch.setattr(bounds, "certified_floor", fake)
    base = ["--setting", "sim", "--controllers", "passive", "--no-shipped-policy",
            "--episodes", "1", "--episode-length", "0.4"]  # fmt: skip
    for given, nodes in ((["--floor", "7"], 7), (["--floor"], 0)):
        with pytest.raises(RuntimeError, match="stop"):
            main([*base, *given, "--json", str(tmp_path / "x.json")])
        assert seen[-1] == nodes


def test_negative_floor_nodes_refused_in_one_line(tmp_path):
    out = tmp_path / "never.json"
    with pytest.raises(SystemExit) as err:
        main(["--setting", "sim", "--episode-length", "0.1", "--floor", "-1", "--json", str(out)])
    message = str(err.value.code)
    assert "--floor NODES" in message and ">= 0" in message and "\n" not in message.strip()
    assert not out.exists()
