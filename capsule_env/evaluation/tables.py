"""The evaluation's tables: the printed Tables 5 and 6 analogues and their Markdown form.

:func:`format_tables` prints what ``python evaluate.py`` shows; :func:`format_markdown` writes
the results page's tables (docs/results.md) from the same results dictionary
(:func:`capsule_env.evaluation.evaluate.evaluate`'s, or its ``--json``). Rows are grouped by the
observation set each controller reads; the paper's published figures stand beside ours.
"""

from __future__ import annotations

import textwrap
from typing import Any

from capsule_env.agents.controllers.base import OBSERVATION_GROUPS
from capsule_env.agents.controllers.classical import PAPER_FIXED
from capsule_env.evaluation.condition import headline, table_notes
from capsule_env.evaluation.table_key import column_footer, key_lines, on_off_note

#: The paper's published vibration-reduction effects (per cent) that survived extraction
#: (docs/model.md 12): the rest of Tables 5 and 6 was lost. Text-only statements are in ``PAPER_TEXT``.
PAPER_VRE = {
    ("sim", "skyhook-biexp", "body_mode1"): 72.33,
    ("sim", "skyhook-csdc", "body_mode1"): 41.66,
}
PAPER_TEXT = {
    "sim": "paper: Bi-exponential 72.33 % vs Bouc-Wen 41.66 % at the body's first mode; "
    "Bi-exponential also far better at the second mode.",
    "hils": "paper: Bi-exponential about 10 points better than Bouc-Wen at the body's first "
    "mode; neither effective at the second mode (Bouc-Wen no reduction of the bogie's).",
}
#: The tables' groups, in order: the observation set a controller reads (its header says
#: what the group may read: ``capsule_env.agents.controllers.base.OBSERVATION_GROUPS``).
GROUP_ORDER = ("none", "measured", "measured+preview", "sensors", "full_state",
               "full_state+preview", "oracle+preview")  # fmt: skip
NAME_WIDTH = 24

#: The tables' columns after the controller's name: (header with the unit, width), and the
#: number format of each. The json (``--json``) holds the same figures in SI units.
COLUMNS = [
    ("body m1 %", 11), ("paper %", 9), ("body m2 %", 11), ("bogie m1 %", 12), ("bogie m2 %", 12),
    ("Wk m/s^2", 10), ("rms m/s^2", 11), ("stroke mm", 11), ("I A", 8), ("trk rel", 9),
    ("Wz", 6), ("N_v", 6), ("headroom", 10),
]  # fmt: skip
FORMATS = [".2f"] * 5 + [".4f", ".4f", ".1f", ".3f", ".3f", ".2f", ".2f", ".0%"]


def _values(setting: str, name: str, m: dict) -> list:
    """A row's figures in :data:`COLUMNS` order (None where a figure does not apply)."""
    vre = m.get("vre_pct", {})  # absent for passive, the reference
    return [
        vre.get("body_mode1"), PAPER_VRE.get((setting, name, "body_mode1")),
        vre.get("body_mode2"), vre.get("bogie_mode1"), vre.get("bogie_mode2"),
        m["wk_rms_body_acc_m_s2"], m["rms_body_acc_m_s2"], 1000.0 * m["max_stroke_m"],
        m["mean_current_a"], m.get("force_tracking_error_rel"), m.get("sperling_ride_index"),
        m.get("en12299_comfort_index"), m.get("oracle_headroom_captured_rel"),
    ]  # fmt: skip


def _columns(results: dict) -> list[int]:
    """The indices of :data:`COLUMNS` to print: all, except ``headroom`` when no row has one
    (a run without ``--oracle``)."""
    has_headroom = any(
        "oracle_headroom_captured_rel" in m
        for block in results["settings"].values()
        for m in block["controllers"].values()
    )
    return [k for k, (title, _) in enumerate(COLUMNS) if has_headroom or title != "headroom"]


def _cell(value: Any, k: int, width: int = 0) -> str:
    """One figure of column ``k``: its format, or a dash (blank for ``paper %``)."""
    if value is None:
        return f"{'' if COLUMNS[k][0] == 'paper %' else '-':>{width}}"
    return f"{value:{width}{FORMATS[k]}}"


def _row(setting: str, name: str, m: dict, columns: list[int]) -> str:
    values = _values(setting, name, m)
    return f"{name:<{NAME_WIDTH}}" + "".join(_cell(values[k], k, COLUMNS[k][1]) for k in columns)


def group_of(entry: dict) -> str:
    """A controller's table group: its observation set, ``+preview`` if it reads the guideway
    ahead."""
    return entry.get("observation", "unknown") + ("+preview" if entry.get("preview") else "")


def _grouped(controllers: dict) -> list[tuple[str, list[str]]]:
    """The rows in table order: ``(group, names)`` in :data:`GROUP_ORDER`, then any other."""
    seen = [group_of(m) for m in controllers.values()]
    groups = [*GROUP_ORDER, *sorted(set(seen) - set(GROUP_ORDER))]
    rows = [(g, [n for n, s in zip(controllers, seen) if s == g]) for g in groups]
    return [(g, names) for g, names in rows if names]


def _bands(results: dict) -> str:
    """The mode bands with their unit: ``mode1 1.0-3.0 Hz, mode2 4.5-7.0 Hz``."""
    return ", ".join(f"{k} {lo:g}-{hi:g} Hz" for k, (lo, hi) in results["bands_hz"].items())


def format_tables(results: dict) -> str:
    """The tables, one per setting, rows grouped by the observation set each controller reads
    (a header line per group says what the group may read), each followed by the on-off
    Skyhook note when its figures show it (:func:`capsule_env.evaluation.table_key.on_off_note`); then
    the key to the controller names and the columns. The ``headroom`` column only with
    ``--oracle``."""
    columns = _columns(results)
    f1, f2 = results["natural_frequencies_hz"]
    lines = [
        f"Undamped modes of the plant: {f1:.2f} Hz (body), {f2:.2f} Hz (bogie)",
        f"{results['episodes']} guideway seeds per controller ({results['seeds'][0]}.."
        f"{results['seeds'][1]}); mode bands of the VRE: {_bands(results)}",
    ]
    condition_line = headline(results)
    if condition_line:
        lines += _wrap(condition_line, 100, "  ")
    for setting, block in results["settings"].items():
        table = "5" if setting == "sim" else "6"
        lines += [
            "",
            f"== {setting}: vibration reduction effect, % (paper Table {table} analogue) ==",
        ]
        header = "".join(f"{COLUMNS[k][0]:>{COLUMNS[k][1]}}" for k in columns)
        controllers = block["controllers"]
        for note in table_notes(controllers, results.get("gains_tuned_env_kwargs", {})):
            lines += _wrap(note, NAME_WIDTH + len(header), "  ")
        lines += [f"{'controller':<{NAME_WIDTH}}{header}", "-" * (NAME_WIDTH + len(header))]
        for group, names in _grouped(controllers):
            lines.append(f"[{OBSERVATION_GROUPS.get(group, group)}]")
            lines.extend(_row(setting, n, controllers[n], columns) for n in names)
        lines.append(PAPER_TEXT[setting])
        on_off = on_off_note(controllers)
        if on_off:
            lines += _wrap(on_off, NAME_WIDTH + len(header), "  ")
    if results.get("policies"):
        lines += [
            "",
            "policies: " + "; ".join(f"{n} = {p}" for n, p in results["policies"].items()),
        ]
    every = {  # every row once, in table order
        n: block["controllers"][n]
        for block in results["settings"].values()
        for _, names in _grouped(block["controllers"])
        for n in names
    }
    title, *key = key_lines(every, results.get("policies", {}), NAME_WIDTH)
    lines += ["", *_wrap(title, 100), *key, ""]
    headroom = "headroom" in [COLUMNS[k][0] for k in columns]
    lines += _wrap(column_footer(headroom, PAPER_FIXED), 100)
    return "\n".join(lines)


def _wrap(text: str, width: int, indent: str = "") -> list[str]:
    """``text`` in lines of at most ``width`` characters, broken at spaces only (names such
    as ``skyhook-biexp`` stay whole), continuation lines indented by ``indent``."""
    return textwrap.wrap(text, width, subsequent_indent=indent, break_on_hyphens=False)


#: The Markdown tables' short group names (what the rows read).
MARKDOWN_GROUPS = {
    "none": "open loop", "measured": "measured", "measured+preview": "measured + preview",
    "sensors": "sensors", "full_state": "ideal sensors", "full_state+preview":
    "ideal sensors + preview", "oracle+preview": "oracle",
}  # fmt: skip


def format_markdown(results: dict) -> str:
    """The tables as Markdown (the results page's), two per setting: the VRE columns, and the
    comfort, stroke and effort columns; rows in the printed tables' order."""
    columns = _columns(results)
    parts = [[k for k in columns if k < 5], [k for k in columns if k >= 5]]
    titles = ("vibration reduction effect (%)", "comfort, stroke and effort")
    lines: list[str] = []
    for setting, block in results["settings"].items():
        controllers = block["controllers"]
        for title, part in zip(titles, parts):
            heads = ["controller", "reads", *(COLUMNS[k][0] for k in part)]
            lines += [f"**`{setting}`: {title}**", "", "| " + " | ".join(heads) + " |"]
            lines.append("| --- | --- |" + " ---: |" * len(part))
            for group, names in _grouped(controllers):
                for n in names:
                    values = _values(setting, n, controllers[n])
                    cells = [f"`{n}`", MARKDOWN_GROUPS.get(group, group)]
                    cells += [_cell(values[k], k).replace("%", " %") for k in part]
                    lines.append("| " + " | ".join(cells) + " |")
            lines.append("")
    return "\n".join(lines)
