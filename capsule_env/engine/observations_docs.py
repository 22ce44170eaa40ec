"""The observation tables of the docs, generated from :mod:`capsule_env.engine.observations`.

``python -m capsule_env.engine.observations_docs docs/env.md`` rewrites every block of the file
between ``<!-- generated: KEY -->`` and ``<!-- /generated -->``, where ``KEY`` is
``observations <set>`` (a set's columns) or ``noise`` (the noise channels); a test checks that
the docs are in sync (:func:`sync_docs` leaves them unchanged).
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

from capsule_env.common.safe_io import atomic_write_text
from capsule_env.engine.observations import (
    NOISE_CHANNELS,
    OBSERVABLES,
    OBSERVATION_SETS,
    Observable,
    observables,
)

__all__ = ["docs_table", "docs_noise_table", "docs_tables", "sync_docs", "main"]

_CHANNEL_STD = {c.name: c.std for c in NOISE_CHANNELS}


def _noise_text(row: Observable) -> str:
    if row.noise is None:
        return "none"
    return f"{_CHANNEL_STD[row.noise]:g} {row.unit}"


def docs_table(observation: str) -> str:
    """The Markdown table of a set's columns (index, name, what, unit, noise at
    ``sensor_noise=1``, saturation bounds)."""
    lines = [
        "| index | name | observation | unit | noise std (`sensor_noise=1`) | bounds |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for k, row in enumerate(observables(observation)):
        lim = f"[{row.low.text()}, {row.high.text()}]"
        lines.append(
            f"| {k} | `{row.name}` | {row.what} | {row.unit} | {_noise_text(row)} | {lim} |"
        )
    return "\n".join(lines)


def docs_noise_table() -> str:
    """The Markdown table of the noise channels, in the order they are drawn."""
    units = {row.noise: row.unit for row in OBSERVABLES if row.noise}
    lines = ["| channel | name | std at `sensor_noise=1` |", "| --- | --- | --- |"]
    lines += [
        f"| {k} | `{c.name}` | {c.std:g} {units[c.name]} |" for k, c in enumerate(NOISE_CHANNELS)
    ]
    return "\n".join(lines)


def docs_tables() -> dict[str, str]:
    """Every generated docs block, by its marker's key (``observations <set>``, ``noise``)."""
    tables = {f"observations {s}": docs_table(s) for s in OBSERVATION_SETS}
    tables["noise"] = docs_noise_table()
    return tables


_BLOCK = re.compile(
    r"(<!-- generated: (?P<key>[^>]*?) -->\n)(?P<body>.*?)(<!-- /generated -->)", re.S
)


def sync_docs(text: str) -> str:
    """``text`` with every generated block rewritten from the table (a ``KeyError`` names a
    marker with no table)."""
    tables = docs_tables()

    def replace(match: re.Match) -> str:
        return f"{match.group(1)}{tables[match.group('key')]}\n{match.group(4)}"

    return _BLOCK.sub(replace, text)


def main(argv: list[str] | None = None) -> int:
    """``python -m capsule_env.engine.observations_docs FILE...``: rewrite the generated blocks."""
    paths = sys.argv[1:] if argv is None else argv
    if not paths:
        print("usage: python -m capsule_env.engine.observations_docs FILE.md ...", file=sys.stderr)
        return 2
    for name in paths:
        path = Path(name)
        try:
            text = path.read_text(encoding="utf-8")
            new = sync_docs(text)
        except (OSError, KeyError) as err:
            print(f"capsule_env.engine.observations_docs: {name}: {err}", file=sys.stderr)
            return 1
        if new != text:
            atomic_write_text(path, new)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
