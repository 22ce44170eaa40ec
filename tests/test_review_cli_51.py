"""Review 51: the command lines given bad input (one line on stderr, a non-zero exit, no
traceback, nothing on disk) and the paths they write."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

from capsule_env.common.safe_io import check_creatable_dir

#: A folder that cannot be made on Linux whoever runs (root passes ``os.access`` on /proc).
UNMAKEABLE = Path("/proc/review-51-no-such-folder/run")
linux_only = pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux /proc")


def _one_line(text: str) -> str:
    lines = [line for line in text.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in text, text
    return lines[0]


# ----------------------------------------------------------------------------- safe_io
@linux_only
def test_check_creatable_dir_refuses_a_folder_that_cannot_be_made() -> None:
    with pytest.raises(ValueError, match="--out '/proc/review-51.*' is not a writable folder"):
        check_creatable_dir(UNMAKEABLE, "--out")
    assert not UNMAKEABLE.parent.exists()


def test_check_creatable_dir_makes_nothing_for_a_folder_that_can_be_made(tmp_path: Path) -> None:
    target = tmp_path / "a" / "b"
    assert check_creatable_dir(target, "--out") == target
    assert list(tmp_path.iterdir()) == []  # the probe file is gone again, no folder made


# ----------------------------------------------------------------------------- train.py
def _train_args(argv: list[str]) -> object:
    from capsule_env.agents.learning.train import parse_args

    return parse_args(argv)


def test_train_refuses_an_unknown_device_in_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        _train_args(["--device", "nope"])
    assert exc.value.code == 2
    line = _one_line(capsys.readouterr().err)
    assert "--device" in line and "'nope'" in line and "cpu" in line


def test_train_accepts_the_devices_sb3_accepts() -> None:
    for device in ("cpu", "auto", "cuda:1"):
        assert _train_args(["--device", device]).device == device


def test_train_refuses_residual_scale_without_a_residual(
    capsys: pytest.CaptureFixture[str],
) -> None:
    with pytest.raises(SystemExit) as exc:
        _train_args(["--residual-scale", "0.3"])
    assert exc.value.code == 2
    line = _one_line(capsys.readouterr().err)
    assert "--residual-scale" in line and "--residual LAW" in line
    given = _train_args(["--residual", "lqr-clipped-biexp-meas", "--residual-scale", "0.3"])
    assert given.residual_scale == 0.3
    resumed = _train_args(["--resume", "auto", "--residual-scale", "0.3"])  # checked on resume
    assert resumed.residual_scale == 0.3


def _train_refused(args: object, capsys: pytest.CaptureFixture[str]) -> str:
    from capsule_env.agents.learning.train import train

    with pytest.raises(SystemExit) as exc:
        train(args)  # type: ignore[arg-type]
    message = str(exc.value.code)
    assert "\n" not in message and message.startswith("train.py: error:"), message
    return message


def test_train_refuses_too_many_vehicles_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = _train_args(["--num-envs", str(10**10), "--output-dir", str(tmp_path / "run")])
    message = _train_refused(args, capsys)
    assert "memory" in message and "num_envs" in message
    assert not (tmp_path / "run").exists()


@linux_only
def test_train_refuses_an_unmakeable_tensorboard_folder_leaving_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    argv = ["--output-dir", str(run), "--tensorboard", str(UNMAKEABLE), "--num-envs", "1",
            "--total-timesteps", "64"]  # fmt: skip
    message = _train_refused(_train_args(argv), capsys)
    assert "--tensorboard" in message
    assert not run.exists()  # the run folder used to be made before the refusal


# ----------------------------------------------------------------------------- sweep
STUDY = """name: review51
trials:
  - kind: gains
    params: {controller: passive, episodes: 1, episode_length_s: 0.5}
"""


@pytest.mark.parametrize("out", ["a-file", "unmakeable"])
def test_sweep_refuses_an_out_that_is_not_a_folder(
    out: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from capsule_env.sweep.__main__ import main

    if out == "unmakeable" and not Path("/proc/self").is_dir():
        pytest.skip("needs Linux /proc")
    study = tmp_path / "study.yml"
    study.write_text(STUDY)
    target = tmp_path / "a-file" if out == "a-file" else UNMAKEABLE
    if out == "a-file":
        target.write_text("not a folder")
    before = sorted(tmp_path.rglob("*"))
    assert main([str(study), "--out", str(target), "--no-ray"]) == 2
    line = _one_line(capsys.readouterr().err)
    assert line.startswith("sweep: error: --out") and "folder" in line
    assert sorted(tmp_path.rglob("*")) == before


# ----------------------------------------------------------------------------- half-car
def test_half_car_usage_errors_are_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    from capsule_env.evaluation import half_car

    with pytest.raises(SystemExit) as exc:
        half_car.main(["--episodes", "abc"])
    assert exc.value.code == 2
    line = _one_line(capsys.readouterr().err)
    assert "--episodes" in line and "'abc'" in line


def test_half_car_checks_out_before_the_evaluation(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--out`` naming a folder used to fail in the final write, a minute of evaluation
    lost, with a traceback."""
    from capsule_env.evaluation import half_car

    def must_not_run(*args: object, **kwargs: object) -> None:
        raise AssertionError("ran before checking --out")

    monkeypatch.setattr(half_car, "evaluate", must_not_run)
    assert half_car.main(["--out", str(tmp_path), "--episodes", "2"]) == 2
    line = _one_line(capsys.readouterr().err)
    assert "--out" in line and "folder" in line
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------- bounds
def test_bounds_usage_errors_are_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    from capsule_env.bounds.__main__ import main

    with pytest.raises(SystemExit) as exc:
        main(["--seed", "abc"])
    assert exc.value.code == 2
    line = _one_line(capsys.readouterr().err)
    assert "--seed" in line and "'abc'" in line


# ----------------------------------------------------------------------------- docs tools
DOCS = Path(__file__).resolve().parents[1] / "docs"


def _interrupt_renames(monkeypatch: pytest.MonkeyPatch) -> None:
    """A Ctrl-C at the rename that puts a saved file in place (``os.replace``)."""

    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "replace", interrupted)


def test_envelope_report_refuses_a_missing_page_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from capsule_env.envelope.report import main

    assert main([str(tmp_path / "nope.md")]) == 2
    line = _one_line(capsys.readouterr().err)
    assert "nope.md" in line and "No such file" in line
    assert main(["--help"]) == 0 and "usage" in capsys.readouterr().out
    assert list(tmp_path.iterdir()) == []


def test_envelope_report_interrupted_save_keeps_the_page(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A Ctrl-C while the page is saved leaves it as it was (it was rewritten in place)."""
    from capsule_env.envelope.report import BEGIN, END, main

    (tmp_path / "figures").mkdir()
    (tmp_path / "figures" / "envelope.json").write_bytes(
        (DOCS / "figures/envelope.json").read_bytes()
    )
    page = tmp_path / "envelope.md"
    old = f"# Envelope\n\n{BEGIN}\nstale\n{END}\n"
    page.write_text(old)

    _interrupt_renames(monkeypatch)
    with pytest.raises(KeyboardInterrupt):
        main([str(page)])
    assert page.read_text() == old
    assert sorted(p.name for p in tmp_path.iterdir()) == ["envelope.md", "figures"]


def test_published_checks_the_figure_path_first(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from capsule_env.envelope.published import main

    with pytest.raises(SystemExit) as exc:
        main(["--figure", str(tmp_path)])
    assert exc.value.code == 2
    out, err = capsys.readouterr()
    assert "--figure" in _one_line(err) and out == ""  # refused before the tables
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("content", ["not json", '{"settings": {}}', "[1]"])
def test_half_car_figure_refuses_a_wrong_json_in_one_line(
    content: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from capsule_env.evaluation.half_car_figure import main

    result = tmp_path / "r.json"
    result.write_text(content)
    assert main([str(result), str(tmp_path / "out" / "f.png")]) == 2
    assert "r.json" in _one_line(capsys.readouterr().err)
    assert [p.name for p in tmp_path.iterdir()] == ["r.json"]


def test_task_cards_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from capsule_env.evaluation.task_cards import main

    with pytest.raises(SystemExit) as exc:
        main([str(tmp_path / "tasks.md")])
    assert exc.value.code == 2
    assert "tasks.md does not exist" in _one_line(capsys.readouterr().err)


# ----------------------------------------------------------------------------- evaluate.py
@pytest.mark.parametrize("option", ["--json", "--plots"])
def test_evaluate_refuses_an_empty_output_path(
    option: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--plots ''`` was the current folder: the run went ahead and wrote its figures there."""
    from capsule_env.evaluation.evaluate import parse_args

    with pytest.raises(SystemExit) as exc:
        parse_args([option, ""])
    assert exc.value.code == 2
    line = _one_line(capsys.readouterr().err)
    assert option in line and "empty path" in line


def test_task_cards_interrupted_save_keeps_the_readme(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A Ctrl-C while the README's table is saved leaves the README as it was (it was
    rewritten in place: a cut-off write truncated the README)."""
    from capsule_env.evaluation.task_cards import README_BEGIN, README_END, sync_readme

    readme = tmp_path / "README.md"
    old = f"# capsule-env\n\n{README_BEGIN}\nstale\n{README_END}\nthe rest of the README\n"
    readme.write_text(old)

    _interrupt_renames(monkeypatch)
    with pytest.raises(KeyboardInterrupt):
        sync_readme(readme, DOCS / "figures")
    assert readme.read_text() == old
    assert [p.name for p in tmp_path.iterdir()] == ["README.md"]


# ----------------------------------------------------------------------------- figures
def test_an_interrupted_figure_save_keeps_the_earlier_figure(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """evaluate.py --plots and identify --plots save through plots._save: a Ctrl-C during the
    save used to leave a cut-off PNG under the figure's own name."""
    from capsule_env.plots import _pyplot, _save

    plt = _pyplot()
    target = tmp_path / "figure.png"
    target.write_bytes(b"the earlier figure")
    fig = plt.figure()
    _interrupt_renames(monkeypatch)
    with pytest.raises(KeyboardInterrupt):
        _save(fig, target, plt)
    assert target.read_bytes() == b"the earlier figure"
    assert [p.name for p in tmp_path.iterdir()] == ["figure.png"]
    monkeypatch.undo()
    _save(plt.figure(), target, plt)
    assert target.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# ----------------------------------------------------------------------------- benchmarks
@pytest.mark.parametrize(
    ("argv", "named"),
    [
        (["--num-envs", "-1"], "--num-envs"),
        (["--minutes", "nan"], "--minutes"),
        (["--minutes", "-1"], "--minutes"),
        (["--json", "DIR"], "--json"),
    ],  # fmt: skip
)
def test_soak_refuses_bad_input_before_soaking(
    argv: list[str],
    named: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """--num-envs -1 was a traceback, --minutes -1 a run of nothing reported as a pass, and
    --json naming a folder a traceback after the whole soak (its counts lost)."""
    from conftest import load_script

    soak = load_script("benchmarks/soak.py")

    def must_not_run(*args: object, **kwargs: object) -> None:
        raise AssertionError("soaked before checking the arguments")

    monkeypatch.setattr(soak, "soak", must_not_run)
    with pytest.raises(SystemExit) as exc:
        soak.main([a.replace("DIR", str(tmp_path)) for a in argv])
    assert exc.value.code == 2
    assert named in _one_line(capsys.readouterr().err)
    assert list(tmp_path.iterdir()) == []


def test_soak_interrupted_json_save_leaves_no_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The counts were written with open(..., "w"): a Ctrl-C there left a cut-off JSON."""
    from conftest import load_script

    soak = load_script("benchmarks/soak.py")
    counts = {"vehicle_steps": 16, "bump_stop_episodes": 0, "non_finite": 0, "out_of_space": 0}
    monkeypatch.setattr(soak, "soak", lambda *args, **kwargs: dict(counts))
    _interrupt_renames(monkeypatch)
    with pytest.raises(KeyboardInterrupt):
        soak.main(["--quick", "--json", str(tmp_path / "soak.json")])
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------- experiments
def test_pareto_checks_the_episode_length_before_anything(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--episode-length -1 was a traceback from the first episode, after --out's folder was
    made."""
    from conftest import load_script

    pareto = load_script("experiments/pareto.py")
    out = tmp_path / "figures" / "pareto.png"
    with pytest.raises(SystemExit) as exc:
        pareto.main(["--episode-length", "-1", "--out", str(out), "--no-shipped-policy"])
    message = str(exc.value.code)
    assert message.startswith("pareto.py: error: --episode-length") and "\n" not in message
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("seeds", [["-1"], ["3", "3"], [str(2**32)]])
def test_three_seeds_checks_the_seeds_before_training(seeds: list[str], tmp_path: Path) -> None:
    """--seeds -1 made the root folder, ran train.py (refused) and ended in a
    CalledProcessError traceback; a seed given twice trained one run folder twice."""
    from conftest import load_script

    three_seeds = load_script("experiments/three_seeds.py")
    root = tmp_path / "root"
    with pytest.raises(SystemExit) as exc:
        three_seeds.main(["--seeds", *seeds, "--root", str(root)])
    message = str(exc.value.code)
    assert message.startswith("three_seeds.py: error: --seeds") and "\n" not in message
    assert not root.exists()


@pytest.mark.parametrize(
    "argv",
    [["--seed", "-1"], ["--episode-length", "nan"], ["--max-wavelength", "nan"]],
)
def test_spectrum_peak_refuses_a_bad_seed_or_nan_in_one_line(argv: list[str]) -> None:
    """--seed -1 was a traceback from the first episode; a nan length passed the check."""
    from conftest import load_script

    spectrum_peak = load_script("experiments/spectrum_peak.py")
    with pytest.raises(SystemExit) as exc:
        spectrum_peak.main(argv)
    message = str(exc.value.code)
    assert message.startswith("spectrum_peak.py: error:") and "\n" not in message
    assert argv[0] in message


@pytest.mark.parametrize(
    ("argv", "named"),
    [
        (["--seed", "-1"], "--seed"),
        (["--episodes", "0"], "--episodes"),
        (["--episode-length", "-1"], "--episode-length"),
        (["--controllers", "nope"], "nope"),
    ],  # fmt: skip
)
def test_biexp_defaults_refit_checks_its_arguments_first(
    argv: list[str], named: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Each was a traceback after the refit, from the first episode."""
    from conftest import load_script

    refit = load_script("experiments/biexp_defaults_refit.py")

    def must_not_run() -> None:
        raise AssertionError("refitted before checking the arguments")

    monkeypatch.setattr(refit, "refit_params", must_not_run)
    with pytest.raises(SystemExit) as exc:
        refit.main(argv)
    message = str(exc.value.code)
    assert message.startswith("biexp_defaults_refit.py: error:") and "\n" not in message
    assert named in message


@pytest.mark.parametrize("option", ["--num-envs", "--repeats"])
def test_bench_half_car_refuses_a_count_below_one(
    option: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """--num-envs -1 was a traceback from gym.make_vec; --repeats -1 timed no window at all
    after compiling (then failed on an empty median)."""
    from conftest import load_script

    bench = load_script("benchmarks/bench_half_car.py")

    def must_not_run(*args: object, **kwargs: object) -> None:
        raise AssertionError("made an env before checking the arguments")

    monkeypatch.setattr(bench.gym, "make_vec", must_not_run)
    monkeypatch.setattr(sys, "argv", ["bench_half_car.py", option, "-1"])
    with pytest.raises(SystemExit) as exc:
        bench.main()
    message = str(exc.value.code)
    assert message.startswith("bench_half_car.py: error:") and option in message


# ----------------------------------------------------------------------------- messages
def test_format_bytes_keeps_a_huge_request_short() -> None:
    """``evaluate.py --episode-length 1e300`` printed a memory need of 290 digits."""
    from capsule_env.common.validation import format_bytes

    assert format_bytes(192.2 * 2**30) == "192.2 GiB"
    assert format_bytes(3 * 2**20) == "3.0 MiB"
    huge = format_bytes(1e300)
    assert (
        huge.endswith(" GiB")
        and len(huge) < 16
        and float(huge.split()[0]) == pytest.approx(1e300 / 2**30, rel=1e-2)
    )


def test_wheelbase_active_refuses_no_window_in_one_line() -> None:
    """--windows 0 or -1 was a traceback from random_profile (length_m must be > 0)."""
    from conftest import load_script

    wheelbase = load_script("experiments/wheelbase_active.py")
    for windows in ("0", "-1"):
        with pytest.raises(SystemExit) as exc:
            wheelbase.main(["--windows", windows])
        assert (
            str(exc.value.code)
            == f"wheelbase_active.py: error: --windows must be >= 1, got {windows}"
        )


# ----------------------------------------------------------------------------- Ctrl-C
def _interrupt(*args: object, **kwargs: object) -> None:
    raise KeyboardInterrupt


@pytest.mark.parametrize(
    ("module", "work", "argv"),
    [
        ("capsule_env.evaluation.evaluate", "evaluate", ["--controllers", "passive"]),
        ("capsule_env.bounds.__main__", "certified_floor", ["--episodes", "1"]),
        ("capsule_env.agents.controllers.tuning", "tune_all", ["--quick", "--out", "OUT/g.json"]),
        ("capsule_env.identification.cli", "identify_reference", []),
        ("capsule_env.export.artifacts", "export_policy", ["ppo-measured", "--out", "OUT"]),
    ],
)
def test_a_ctrl_c_ends_a_command_in_one_line(
    module: str,
    work: str,
    argv: list[str],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """A Ctrl-C in the work was a KeyboardInterrupt traceback of 20 to 120 lines (probed with
    SIGINT); now one line and exit status 130, as train.py and the sweep end."""
    import importlib

    monkeypatch.setattr(importlib.import_module(module), work, _interrupt)
    cli = {"capsule_env.export.artifacts": "capsule_env.export.__main__"}.get(module, module)
    main = importlib.import_module(cli).main
    try:
        status = main([a.replace("OUT", str(tmp_path)) for a in argv])
    except KeyboardInterrupt:
        pytest.fail("the Ctrl-C escaped main as a KeyboardInterrupt (a traceback)")
    assert status == 130
    line = _one_line(capsys.readouterr().err)
    assert line.endswith("interrupted; the files it wrote are complete, the rest were not written")
