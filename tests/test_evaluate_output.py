"""What evaluate.py prints for a reader: the key to the controller names, the units of the mode
bands, the headroom column only with --oracle, the on-off Skyhook note, and the results page's
Markdown tables (which must be the printed tables of docs/figures/evaluation.json)."""

from __future__ import annotations

import json
import re
from pathlib import Path

from capsule_env.agents import classical_controllers

from capsule_env.evaluation import evaluate
from capsule_env.evaluation.table_key import DESCRIPTIONS

ROOT = Path(__file__).resolve().parent.parent
FIGURES = ROOT / "docs" / "figures"


def entry(observation: str, wk: float, vre: float | None = None, **extra) -> dict:
    """A results entry with made-up figures (the keys evaluate.py's JSON holds)."""
    m = {"observation": observation, "preview": False, "wk_rms_body_acc_m_s2": wk,
         "rms_body_acc_m_s2": 1.3 * wk, "max_stroke_m": 0.009, "mean_current_a": 0.2, **extra}  # fmt: skip
    if vre is not None:
        m["vre_pct"] = dict.fromkeys(
            ("body_mode1", "body_mode2", "bogie_mode1", "bogie_mode2"), vre
        )
    return m


def results(controllers: dict, policies: dict | None = None) -> dict:
    return {"natural_frequencies_hz": [1.3, 5.42], "episodes": 2, "seeds": [1000, 1001],
            "bands_hz": {"mode1": [1.0, 3.0], "mode2": [4.5, 7.0]},
            "policies": policies or {}, "settings": {"hils": {"controllers": controllers}}}  # fmt: skip


ROWS = {
    "passive": entry("none", 0.26),
    "skyhook-biexp": entry("full_state", 0.31, 60.0),
    "sh-add-meas": entry("measured", 0.245, 35.0),
    "preview-lq-biexp-meas": entry("measured", 0.228, 50.0, preview=True),
    "ppo-measured": entry("measured", 0.238, 45.0),
    "my-law": entry("measured", 0.25, 30.0),
}


def header(printed: str) -> str:
    return next(line for line in printed.splitlines() if line.startswith("controller "))


def test_key_says_what_each_row_is_and_reads():
    printed = evaluate.format_tables(results(ROWS, {"ppo-measured": "x/ppo-measured.zip"}))
    key = {line.split()[0]: line for line in printed.splitlines() if line.startswith("  ")}
    assert set(ROWS) <= set(key)
    assert key["passive"].endswith("[reads: nothing]") and "15 kN s/m" in key["passive"]
    assert "mixed Skyhook-ADD" in key["sh-add-meas"]
    assert key["sh-add-meas"].endswith("[reads: on-board sensors]")
    assert key["skyhook-biexp"].endswith("[reads: ideal sensors (true states)]")
    assert "Bi-exponential" in key["skyhook-biexp"] and "on-off" in key["skyhook-biexp"]
    assert key["preview-lq-biexp-meas"].endswith("[reads: on-board sensors + the guideway ahead]")
    assert "learned policy" in key["ppo-measured"]
    assert "a controller given in Python" in key["my-law"]


def test_every_classical_controller_has_a_description():
    # the registry is the independent list: a new controller must get a key line
    assert set(classical_controllers()) <= set(DESCRIPTIONS)


def test_mode_bands_printed_with_their_unit():
    printed = evaluate.format_tables(results(ROWS))
    assert "mode1 1-3 Hz, mode2 4.5-7 Hz" in printed
    assert "{'mode1'" not in printed  # not the raw dict


def test_headroom_column_only_with_the_oracle():
    assert "headroom" not in evaluate.format_tables(results(ROWS))
    with_oracle = {name: {**m, "oracle_headroom_captured_rel": 0.5} for name, m in ROWS.items()}
    with_oracle["oracle"] = entry("oracle", 0.21, 50.0, preview=True,
                                  oracle_headroom_captured_rel=1.0)  # fmt: skip
    printed = evaluate.format_tables(results(with_oracle))
    assert header(printed).endswith("headroom")
    assert re.search(r"^oracle .* 100%$", printed, flags=re.M)
    assert "headroom: the share of the Wk gap" in printed


def test_on_off_skyhook_note_only_when_the_figures_show_it():
    printed = evaluate.format_tables(results(ROWS))
    note = printed[printed.index("Note: on-off Skyhook") :].split("\n\n")[0]
    assert "skyhook-biexp 60.0 % / 0.3100" in note and "0.2600" in note
    # an on-off Skyhook that is better than passive by Wk: no note
    calm = {**ROWS, "skyhook-biexp": entry("full_state", 0.25, 60.0)}
    assert "Note: on-off Skyhook" not in evaluate.format_tables(results(calm))


def test_results_page_tables_are_the_evaluation_json_tables():
    # The results page shows docs/figures/evaluation.json as Markdown tables, verbatim.
    data = json.loads((FIGURES / "evaluation.json").read_text())
    page = (ROOT / "docs" / "results.md").read_text()
    start, end = "<!-- tables: begin -->\n", "<!-- tables: end -->"
    assert page[page.index(start) + len(start) : page.index(end)].strip() == (
        evaluate.format_markdown(data).strip()
    )
    for setting in ("sim", "hils"):  # every row of each setting, in both of its tables
        for name in data["settings"][setting]["controllers"]:
            assert page.count(f"| `{name}` |") >= 2, name


def test_fair_comparison_table_is_evaluation_json():
    # docs/fair-comparison.md's hils table, written by hand, against the run's JSON: Wk, its
    # ratio to the clipped LQR (the column's name), first-mode VRE, stroke, Wz, N_v, headroom.
    hils = json.loads((FIGURES / "evaluation.json").read_text())["settings"]["hils"]
    ctrls = hils["controllers"]
    lqr = ctrls["lqr-clipped-biexp-meas"]["wk_rms_body_acc_m_s2"]
    page = (ROOT / "docs" / "fair-comparison.md").read_text().splitlines()
    start = page.index(next(line for line in page if line.startswith("| group | controller |")))
    stop = next(k for k in range(start, len(page)) if not page[k].startswith("|"))
    rows = page[start + 2 : stop]
    seen = set()
    for line in rows:
        cells = [c.strip().strip("*") for c in line.strip("|").split("|")]
        name = cells[1].split()[0]
        m = ctrls[name]
        vre = m.get("vre_pct", {}).get("body_mode1")
        wk = m["wk_rms_body_acc_m_s2"]
        assert cells[2:] == [
            f"{wk:.4f}", f"{wk / lqr:.3f}", "(ref.)" if vre is None else f"{vre:.1f} %",
            f"{1e3 * m['max_stroke_m']:.1f} mm", f"{m['sperling_ride_index']:.2f}",
            f"{m['en12299_comfort_index']:.2f}", f"{100 * m['oracle_headroom_captured_rel']:.0f} %",
        ], name  # fmt: skip
        seen.add(name)
    assert len(seen) == 15  # the table's rows, each found in the JSON


def test_results_page_figures_read_back_from_the_json():
    # Independent of format_markdown: read each comfort table's Wk and stroke cells and each
    # VRE table's body m1 cell back, and compare them with the JSON's figures.
    data = json.loads((FIGURES / "evaluation.json").read_text())["settings"]
    lines = (ROOT / "docs" / "results.md").read_text().splitlines()
    checked = 0
    for k, line in enumerate(lines):
        title = re.fullmatch(r"\*\*`(\w+)`: (.+)\*\*", line)
        if not title:
            continue
        heads = [c.strip() for c in lines[k + 2].strip("|").split("|")]
        for row in lines[k + 4 :]:
            if not row.startswith("| `"):
                break
            cells = dict(zip(heads, (c.strip() for c in row.strip("|").split("|"))))
            m = data[title[1]]["controllers"][cells["controller"].strip("`")]
            if "Wk m/s^2" in cells:
                assert cells["Wk m/s^2"] == f"{m['wk_rms_body_acc_m_s2']:.4f}"
                assert cells["stroke mm"] == f"{1e3 * m['max_stroke_m']:.1f}"
            elif "vre_pct" in m:
                assert cells["body m1 %"] == f"{m['vre_pct']['body_mode1']:.2f}"
            checked += 1
    assert checked == 2 * sum(len(block["controllers"]) for block in data.values())
