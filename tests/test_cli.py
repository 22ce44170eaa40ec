"""The command lines' shared helper (capsule_env.common.cli): one-line usage errors with status 2,
the dataclass-to-argparse bridge, and the KEY=VALUE env items; and that each command built on
it answers a bad option with one line and status 2."""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from typing import Literal

import pytest

from capsule_env.common import cli as _cli
from capsule_env.common.cli import (
    ArgumentParser,
    add_dataclass_options,
    dataclass_values,
    field_docs,
    integer,
    parse_env_item,
    parse_env_kwargs,
)


@dataclass
class _Args:
    algo: Literal["ppo", "sac"] = "ppo"
    """the algorithm"""
    steps: int | None = None
    """env steps, all vehicles together
    (default: the file's)"""
    rate: float = 0.5
    """a rate"""
    progress: bool = False
    """show a progress bar"""
    env: list[str] = field(default_factory=list)
    """one env argument KEY=VALUE; repeatable"""
    env_kwargs: dict = field(default_factory=dict)
    """env arguments as JSON"""
    name: str = "run"
    undocumented: str = "x"


def _parser() -> ArgumentParser:
    parser = ArgumentParser(prog="prog")
    add_dataclass_options(parser, _Args)
    return parser


def _usage_error(parse, capsys) -> str:
    with pytest.raises(SystemExit) as exc:
        parse()
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    return err


def test_usage_error_is_one_line_with_status_2(capsys):
    parser = ArgumentParser(prog="prog")
    parser.add_argument("--n", type=int)
    err = _usage_error(lambda: parser.parse_args(["--n", "x"]), capsys)
    assert err.startswith("prog: error: argument --n: invalid int value: 'x'")
    err = _usage_error(lambda: parser.parse_args(["--nope"]), capsys)
    assert err == "prog: error: unrecognized arguments: --nope\n"


@pytest.mark.parametrize(
    ("text", "value"), [("3", 3), ("2e6", 2_000_000), ("-4", -4), ("1.0e2", 100)]
)
def test_integer_accepts_integers_written_as_floats(text, value):
    assert integer(text) == value and isinstance(integer(text), int)


@pytest.mark.parametrize("text", ["1.5", "x", "inf", "nan", "", "1e400"])
def test_integer_refuses_non_integers(text):
    with pytest.raises(argparse.ArgumentTypeError, match="not an integer"):
        integer(text)


def test_field_docs_reads_the_string_under_each_field():
    assert field_docs(_Args) == {
        "algo": "the algorithm",
        "steps": "env steps, all vehicles together (default: the file's)",
        "rate": "a rate",
        "progress": "show a progress bar",
        "env": "one env argument KEY=VALUE; repeatable",
        "env_kwargs": "env arguments as JSON",
    }


def test_dataclass_defaults_round_trip():
    values = dataclass_values(_parser().parse_args([]), _Args)
    assert values == {"algo": "ppo", "steps": None, "rate": 0.5, "progress": False, "env": [],
                      "env_kwargs": "{}", "name": "run", "undocumented": "x"}  # fmt: skip


def test_dataclass_options_have_their_types():
    argv = ["--algo", "sac", "--steps", "2e6", "--rate", "0.25", "--progress", "--env", "a=1",
            "--env", "b=x", "--env-kwargs", '{"c": 2}', "--name", "r2"]  # fmt: skip
    values = dataclass_values(_parser().parse_args(argv), _Args)
    assert values == {"algo": "sac", "steps": 2_000_000, "rate": 0.25, "progress": True,
                      "env": ["a=1", "b=x"], "env_kwargs": '{"c": 2}', "name": "r2",
                      "undocumented": "x"}  # fmt: skip
    assert _parser().parse_args(["--progress", "--no-progress"]).progress is False


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["--algo", "td3"], "argument --algo: invalid choice: 'td3'"),
        (["--steps", "1.5"], "argument --steps: not an integer: '1.5'"),
        (["--rate", "fast"], "argument --rate: invalid float value: 'fast'"),
    ],
)
def test_dataclass_options_refuse_bad_values(argv, expected, capsys):
    err = _usage_error(lambda: _parser().parse_args(argv), capsys)
    assert err.startswith(f"prog: error: {expected}"), err


def test_help_texts_carry_the_docs_and_defaults():
    text = _parser().format_help()
    assert "the algorithm (default: ppo)" in text
    assert "(default: the file's)" in text and "(default: the file's) (default" not in text
    assert "(default: 0.5)" in text and "(default: x)" in text


@pytest.mark.parametrize(
    ("item", "pair"),
    [
        ("setting=sim", ("setting", "sim")),
        ("speed_kmh=600", ("speed_kmh", 600)),
        (" sensor_noise = 0.5", ("sensor_noise", 0.5)),
        ("randomize=true", ("randomize", True)),
        ("damper_params={'x0': 0.01}", ("damper_params", {"x0": 0.01})),
        ("guideway_params=[1, 2]", ("guideway_params", [1, 2])),
        ("name=a=b", ("name", "a=b")),
        ("empty=", ("empty", "")),
    ],
)
def test_parse_env_item(item, pair):
    assert parse_env_item(item) == pair


@pytest.mark.parametrize("item", ["setting", "=sim", " =1"])
def test_parse_env_item_needs_key_and_value(item):
    with pytest.raises(ValueError, match="--env expects KEY=VALUE"):
        parse_env_item(item)


def test_parse_env_kwargs():
    assert parse_env_kwargs('{"speed_kmh": 600}') == {"speed_kmh": 600}
    assert parse_env_kwargs("{'setting': 'sim', 'sensor_noise': None}") == {
        "setting": "sim",
        "sensor_noise": None,
    }
    with pytest.raises(ValueError, match="must be a JSON object"):
        parse_env_kwargs("[1, 2]")
    with pytest.raises(ValueError, match="--env-kwargs: not JSON or a Python literal"):
        parse_env_kwargs("dict(a=1)")


def test_hyperparams_reexports_the_env_parsers():
    from capsule_env.agents.learning import hyperparams

    assert hyperparams.parse_env_item is _cli.parse_env_item
    assert hyperparams.parse_env_kwargs is _cli.parse_env_kwargs
    assert hyperparams.parse_literal is _cli.parse_literal


def test_tuning_command_usage_errors(tmp_path, capsys):
    from capsule_env.agents.controllers.tuning import main

    prog = "python -m capsule_env.agents.controllers.tuning: error: "
    err = _usage_error(lambda: main(["--controllers", "nope", "--quick"]), capsys)
    assert err.startswith(prog + "--controllers: no search space for ['nope']"), err
    err = _usage_error(lambda: main(["--stroke-limit-mm", "0", "--quick"]), capsys)
    assert err == prog + "--stroke-limit-mm must be > 0, got 0.0\n"
    (tmp_path / "file").write_text("")  # a file where the folder should be
    err = _usage_error(
        lambda: main(["--quick", "--out", str(tmp_path / "file" / "g.json")]), capsys
    )
    assert err.startswith(prog + "--out"), err


def test_evaluate_and_sweep_usage_errors(capsys):
    from capsule_env.evaluation import evaluate
    from capsule_env.sweep.__main__ import parse_args as sweep_args

    err = _usage_error(lambda: evaluate.parse_args(["--episodes", "x"]), capsys)
    assert err == "evaluate.py: error: argument --episodes: invalid int value: 'x'\n"
    err = _usage_error(lambda: sweep_args(["s.yml", "--num-cpus", "0"]), capsys)
    assert err == "python -m capsule_env.sweep: error: --num-cpus must be >= 1, got 0\n"
