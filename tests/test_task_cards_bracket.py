"""The task cards' bracket [floor, oracle]: the certified floor of the results where it was
run, else 0 (below every Wk), and each row's share of the gap passive -> floor."""

from __future__ import annotations

import copy
from pathlib import Path

from capsule_env.evaluation.task_cards import load_results, task_cards

FIGURES = Path(__file__).resolve().parents[1] / "docs" / "figures"


def _row(card: str, name: str) -> list[str]:
    line = next(x for x in card.splitlines() if x.startswith(f"| `{name}` |"))
    return [c.strip() for c in line.strip("|").split("|")]


def _card(text: str, env_id: str) -> str:
    return text.split(f"## `{env_id}`")[1].split("\n## ")[0]


def test_without_a_floor_block_the_bracket_starts_at_zero():
    results = load_results(FIGURES)
    card = _card(task_cards(results), "CapsuleRide-v0")
    rows = results["evaluation.json"]["settings"]["hils"]["controllers"]
    passive, oracle = (rows[n]["wk_rms_body_acc_m_s2"] for n in ("passive", "oracle"))
    assert f"[0.0000, {oracle:.4f}]" in card
    share = (passive - rows["oracle"]["wk_rms_body_acc_m_s2"]) / passive
    assert _row(card, "oracle")[-1] == f"{share:.3f}"


def test_a_floor_block_sets_the_lower_end_and_the_shares():
    results = copy.deepcopy(load_results(FIGURES))
    block = results["evaluation.json"]["settings"]["hils"]
    block["floor"] = {"wk_rms_body_acc_m_s2": 0.1}
    card = _card(task_cards(results), "CapsuleRide-v0")
    rows = block["controllers"]
    passive, oracle = (rows[n]["wk_rms_body_acc_m_s2"] for n in ("passive", "oracle"))
    assert f"[0.1000, {oracle:.4f}]" in card and "the certified floor" in card
    assert _row(card, "oracle")[-1] == f"{(passive - oracle) / (passive - 0.1):.3f}"
    assert _row(card, "passive")[-1] == "0.000"


def test_the_cards_command_refuses_a_missing_page_in_one_line(tmp_path, capsys):
    import pytest

    from capsule_env.evaluation.task_cards import main

    with pytest.raises(SystemExit) as err:
        main([str(tmp_path / "nope" / "tasks.md")])
    assert err.value.code == 2
    message = capsys.readouterr().err.strip().splitlines()[-1]
    assert "does not exist" in message and "Traceback" not in message
    assert not (tmp_path / "nope").exists()
