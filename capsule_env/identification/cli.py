"""Command line: identify MR-damper models from force loops (docs/model.md, section 6).

Run ``python -m capsule_env.identification.cli --help``. Examples::

    python -m capsule_env.identification.cli                                  # reference damper, tables
    python -m capsule_env.identification.cli --json fit.json --plots figs/    # + JSON summary and PNGs
    python -m capsule_env.identification.cli --emit-defaults                  # dataclass default lines
    python -m capsule_env.identification.cli --data ../shared/data/labcontrol-mr-damper/ensaio.A.1.mat
    python -m capsule_env.identification.cli --data ../shared/data/labcontrol-mr-damper   # every file
    python -m capsule_env.identification.cli --data loops.csv         # header: time,displacement,force,...
    python -m capsule_env.identification.cli --data rig.npy --columns "time,displacement[mm],force"
    python -m capsule_env.identification.cli --data loop_0A.csv loop_0.5A.csv loop_1A.csv --together

CSV and NumPy files: columns, units, the velocity filter and the current rules are in
:mod:`capsule_env.identification.tabular` and docs/howto-identify.md.

Exit status: 0 on success, 2 for bad arguments, unreadable or unusable data, or an output
path that cannot be written (checked before fitting), with one line on stderr naming the file.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from capsule_env.common.cli import ArgumentParser, exits_on_interrupt
from capsule_env.common.safe_io import atomic_write_text, check_writable_dir, check_writable_file
from capsule_env.identification import (
    D_RULES,
    MODEL_NAMES,
    PAPER_RMSE_N,
    SUPPORTED_SUFFIXES,
    IdentificationResult,
    dataclass_default_lines,
    identify_files,
    identify_measured,
    identify_reference,
    measured_files,
    plot_fits,
)
from capsule_env.identification.plausibility import PlausibilityWarning

_LABELS = {"bi_exponential": "Bi-exponential", "bouc_wen": "Bouc-Wen", "tanh": "tanh"}
_CLASSES = {
    "bouc_wen": "BoucWenDamper",
    "tanh": "TanhDamper",
    "bi_exponential": "BiExponentialDamper",
}


def _number_type(low: float, strict: bool, what: str) -> Callable[[str], float]:
    def convert(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or value < low or (strict and value == low):
            raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}")
        return value

    return convert


def _int_type(low: int, high: int, odd: bool = False) -> Callable[[str], int]:
    what = f"an {'odd ' if odd else ''}integer in [{low}, {high}]"

    def convert(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}") from None
        if not low <= value <= high or (odd and value % 2 == 0):
            raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}")
        return value

    return convert


#: Options that only apply to measured files (--data), with their defaults.
_FILE_OPTIONS = {
    "columns": None,
    "current": None,
    "current_resolution": 0.01,
    "velocity_window": None,
    "velocity_polyorder": 3,
    "remove_force_offset": False,
    "together": False,
}


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``python -m capsule_env.identification.cli``."""
    parser = ArgumentParser(
        prog="python -m capsule_env.identification.cli",
        description=(
            "Identify the Bi-exponential, Bouc-Wen and tanh MR-damper models from force loops "
            "(docs/model.md, section 6): from loops of the reference (Spencer) damper under a "
            "sinusoidal stroke at 0 to 1.5 A (default), or from measured files: Labcontrol "
            ".mat, CSV or NumPy (.npy, .npz). Prints the Bi-exponential linear-law table (the paper's Table 2 analogue) "
            "and the RMSE of each model next to the paper's 61.8 N (Bi-exponential) and "
            "695.3 N (Bouc-Wen) at 1.5 A."
        ),
        epilog=(
            "Labcontrol files record no coil current: each is fitted on its own at i = 0 (the "
            "per-ampere coefficients are 0). A CSV or NumPy file gives its current in a "
            "'current' column, --current or its name (loop_0.75A.csv); --together fits several "
            "such files at once, with current laws. Compare RMSE relative to the peak force: "
            "the paper's damper, the reference damper and the laboratory damper differ in "
            "size. Columns, units and the velocity filter: docs/howto-identify.md."
        ),
    )
    _add_source_and_output_options(parser)
    _add_file_options(parser.add_argument_group("measured CSV and NumPy files (with --data)"))
    parser.add_argument(
        "--frequency-hz",
        type=float,
        default=1.0,
        help="reference loops: stroke frequency in Hz (default 1.0)",
    )
    parser.add_argument(
        "--amplitude-m",
        type=float,
        default=0.025,
        help="reference loops: stroke amplitude in m (default 0.025)",
    )
    return parser


def _add_source_and_output_options(parser: argparse.ArgumentParser) -> None:
    """Where the loops come from, what is written and the Bi-exponential's ``d`` rule."""
    source = parser.add_mutually_exclusive_group()
    source.add_argument(
        "--reference",
        action="store_true",
        help="fit loops of the reference damper (the default when --data is not given)",
    )
    source.add_argument(
        "--data",
        metavar="PATH",
        type=Path,
        nargs="+",
        help="measured files or folders (every .mat, .csv, .tsv, .txt, .npy and .npz file in "
        "it), each fitted on its own unless --together: Labcontrol .mat (x_F = displacement "
        "mm, velocity mm/s, force N) or CSV/NumPy with columns time, displacement, "
        "[velocity], force, [current] (SI units unless a unit is given, e.g. displacement[mm])",
    )
    parser.add_argument("--json", metavar="PATH", type=Path, help="write a JSON summary here")
    parser.add_argument(
        "--allow-poor-fit",
        action="store_true",
        help="keep a fit whose best model is off by more than 25 %% of the peak force (refused "
        "by default: such loops are noise or the wrong columns); a loop or model that does "
        "not dissipate is refused regardless",
    )
    parser.add_argument(
        "--plots", metavar="DIR", type=Path, help="write PNG figures (loops, parameter trends) here"
    )
    parser.add_argument(
        "--emit-defaults",
        action="store_true",
        help="print the dataclass default lines (5 significant digits) of BoucWenDamper, "
        "TanhDamper and BiExponentialDamper fitted to the reference damper, to paste into "
        "capsule_env/dampers.py (the shipped Bi-exponential defaults used the literal branch "
        "split and differ by up to 0.58 %%: docs/model.md 6)",
    )
    parser.add_argument(
        "--d-rule",
        choices=D_RULES,
        default="mean",
        help="Bi-exponential d per branch: 'mean' over the per-current fits (the paper's "
        "procedure, default) or 'joint' (d and the linear laws fitted to all currents at once)",
    )


def _add_file_options(files: argparse._ArgumentGroup) -> None:
    """How measured CSV and NumPy files are read (columns, current, velocity, offset)."""
    files.add_argument(
        "--columns",
        metavar="NAMES",
        help="the files' columns in order, comma-separated, overriding any header; 'skip' "
        "ignores a column; units in brackets: e.g. 'time,displacement[mm],skip,force[kN]'",
    )
    files.add_argument(
        "--current",
        metavar="A",
        type=_number_type(0.0, False, "a number >= 0 (A)"),
        help="the coil current of every file without a current column (default: the current "
        "in the file name, e.g. loop_0.75A.csv, else 0)",
    )
    files.add_argument(
        "--current-resolution",
        metavar="A",
        type=_number_type(0.0, True, "a number > 0 (A)"),
        default=0.01,
        help="a current column is rounded to this before it is split into loops at constant "
        "current (default 0.01 A)",
    )
    files.add_argument(
        "--velocity-window",
        metavar="N",
        type=_int_type(3, 10**7, odd=True),
        help="files without velocity: Savitzky-Golay window in samples (odd; default: the odd "
        "number nearest to a tenth of the stroke's period)",
    )
    files.add_argument(
        "--velocity-polyorder",
        metavar="P",
        type=_int_type(1, 9),
        default=3,
        help="files without velocity: Savitzky-Golay polynomial degree (default 3)",
    )
    files.add_argument(
        "--remove-force-offset",
        action="store_true",
        help="subtract each file's mean force (a preload); .mat files always do",
    )
    files.add_argument(
        "--together",
        action="store_true",
        help="fit the loops of all the files at once (one file per current: current laws "
        "across files) instead of each file on its own",
    )


def _fmt(value: float, width: int = 11) -> str:
    return f"{value:{width}.5g}"


def format_table(result: IdentificationResult) -> str:
    """The Bi-exponential linear-law table (the paper's Table 2 analogue) as text."""
    # b = b0 + b1 i (N s/m), i in A: b1 is in N s/m per ampere, N s/(m A)
    widths = {"a0": 11, "a1": 11, "b0": 11, "b1": 15, "c0": 11, "c1": 11, "d": 11}
    units = {"a0": "N", "a1": "N/A", "b0": "N s/m", "b1": "N s/(m A)", "c0": "N", "c1": "N/A",
             "d": "s/m"}  # fmt: skip
    head = f"{'branch':<7}" + "".join(f"{f'{k} ({units[k]})':>{widths[k]}}" for k in widths)
    lines = [
        "Bi-exponential linear laws (paper's Table 2 analogue), d rule: " + result.d_rule,
        "  F = a S_d(v) + b v + c,  S_d(v) = sign(v)(1 - exp(-d|v|)),  p = p0 + p1 i;"
        "  upper: x >= 0, lower: x < 0",
        head,
    ]
    for branch, row in result.table.items():
        lines.append(f"{branch:<7}" + "".join(_fmt(row[k], widths[k]) for k in widths))
    return "\n".join(lines)


def format_rmse(result: IdentificationResult) -> str:
    """RMSE of each model at the reporting current and per current, next to the paper's."""
    peak = result.peak_force_n
    where = (
        f"at {result.rmse_current_a:g} A"
        if len(result.bi_exponential.currents_a) > 1
        else "over the record"
    )
    lines = [
        f"RMSE {where} (peak force {peak:.1f} N)",
        f"{'model':<16}{'ours (N)':>10}{'% of peak':>11}{'paper (N)':>11}",
    ]
    for name in MODEL_NAMES:
        fit = result.models[name]
        paper = PAPER_RMSE_N.get(name)
        paper_s = f"{paper:11.1f}" if paper is not None else f"{'-':>11}"
        lines.append(
            f"{_LABELS[name]:<16}{fit.rmse_n:10.1f}{100 * fit.rmse_n / peak:11.2f}{paper_s}"
        )
    lines.append("(paper: its own damper's measured loops at 1.5 A; compare % of peak force)")
    currents = result.bi_exponential.currents_a
    if len(currents) > 1:
        lines.append("")
        lines.append("RMSE per current (N)")
        lines.append(f"{'current (A)':<12}" + "".join(f"{_LABELS[n]:>16}" for n in MODEL_NAMES))
        for i in currents:
            lines.append(
                f"{i:<12.2f}"
                + "".join(
                    f"{result.models[n].rmse_per_current_n[float(i)]:16.1f}" for n in MODEL_NAMES
                )
            )
    return "\n".join(lines)


def format_defaults(result: IdentificationResult) -> str:
    """Dataclass default lines of the three fitted models, ready to paste into dampers.py."""
    out = []
    for name in ("bouc_wen", "tanh", "bi_exponential"):
        out.append(
            f"# {_CLASSES[name]} defaults: identified from {result.source}, "
            f"{len(result.loops)} loops, {min(lp.current_a for lp in result.loops):g} to "
            f"{result.rmse_current_a:g} A (capsule_env.identification.cli --emit-defaults; RMSE "
            f"{result.models[name].rmse_n:.1f} N at {result.rmse_current_a:g} A)"
        )
        out.extend(dataclass_default_lines(result.models[name].damper))
        out.append("")
    return "\n".join(out).rstrip() + "\n"


def _report(result: IdentificationResult) -> str:
    header = f"Identification from: {result.source}"
    if not result.current_known:
        header += " (current unknown: fitted at 0 A)"
    if result.force_offset_n:
        header += f" (mean force {result.force_offset_n:.1f} N removed)"
    return "\n\n".join([header, format_table(result), format_rmse(result)])


def _summary_table(results: Sequence[IdentificationResult]) -> str:
    lines = [
        "RMSE per measured file (N, and % of the file's peak force)",
        f"{'file':<22}{'peak (N)':>10}{'offset (N)':>11}"
        + "".join(f"{_LABELS[n]:>22}" for n in MODEL_NAMES),
    ]
    for r in results:
        cells = "".join(
            f"{r.models[n].rmse_n:12.1f} ({100 * r.models[n].rmse_n / r.peak_force_n:5.1f}%)"
            for n in MODEL_NAMES
        )
        lines.append(f"{r.source:<22}{r.peak_force_n:10.1f}{r.force_offset_n:11.1f}{cells}")
    return "\n".join(lines)


def _data_files(paths: Sequence[Path]) -> list[Path]:
    """The files of ``--data``: each file as given, each folder's supported files."""
    files: list[Path] = []
    for path in paths:
        if path.is_dir():
            files += measured_files(path, SUPPORTED_SUFFIXES)
        elif path.is_file():
            files.append(path)
        else:
            raise ValueError(f"--data: no such file or folder: {str(path)!r}")
    return files


def _identify_data(args: argparse.Namespace) -> tuple[list[IdentificationResult], dict]:
    """Fit the ``--data`` files (each on its own, or all together); print the reports."""
    files = _data_files(args.data)
    options = dict(
        columns=args.columns,
        current_a=args.current,
        current_resolution_a=args.current_resolution,
        velocity_window=args.velocity_window,
        velocity_polyorder=args.velocity_polyorder,
        remove_force_offset=args.remove_force_offset,
    )
    if args.together:
        result = identify_files(
            files, d_rule=args.d_rule, allow_poor_fit=args.allow_poor_fit, **options
        )
        print(_report(result))
        return [result], result.to_json_dict()
    results = []
    for file in files:
        try:
            results.append(identify_measured(file, d_rule=args.d_rule,
                                             allow_poor_fit=args.allow_poor_fit, **options))  # fmt: skip
        except ValueError as exc:
            if str(file) in str(exc):
                raise
            raise ValueError(f"cannot identify {str(file)!r}: {exc}") from None
        print(_report(results[-1]))
        print()
    if len(results) == 1:
        return results, results[0].to_json_dict()
    print(_summary_table(results))
    source = str(args.data[0]) if len(args.data) == 1 else ", ".join(map(str, args.data))
    return results, {"source": source, "files": {r.source: r.to_json_dict() for r in results}}


def _one_line_warnings(prog: str) -> Callable[..., None]:
    """A ``warnings.showwarning`` that prints a :class:`PlausibilityWarning` as one line on
    stderr (``prog: warning: ...``) and leaves other warnings to Python's own."""
    default = warnings.showwarning

    def show(message: Warning | str, category: type[Warning], *args: Any, **kwargs: Any) -> None:
        if issubclass(category, PlausibilityWarning):
            print(f"{prog}: warning: {message}", file=sys.stderr)
        else:
            default(message, category, *args, **kwargs)

    return show


@exits_on_interrupt("python -m capsule_env.identification.cli")
def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    with warnings.catch_warnings():
        warnings.simplefilter("always", PlausibilityWarning)
        warnings.showwarning = _one_line_warnings(parser.prog)
        return _run(parser, args)


def _write_plots(results: list, folder: Path) -> None:
    """Each result's figures into ``folder`` (a prefix per file when there are several)."""
    written = []
    for r in results:
        prefix = "" if len(results) == 1 else Path(r.source).stem + "_"
        written += plot_fits(r, None, folder, prefix=prefix)
    print(f"wrote {len(written)} figures to {folder}")


def _run(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    """The work of :func:`main` once the arguments are parsed; returns the exit status."""
    if args.emit_defaults and args.data is not None:
        parser.error("--emit-defaults fits the reference damper; do not combine it with --data")
    if args.data is None:
        for key, default in _FILE_OPTIONS.items():
            if getattr(args, key) != default:
                parser.error(f"--{key.replace('_', '-')} applies to measured files: add --data")
    try:
        if args.json is not None:
            check_writable_file(args.json, "--json")
        if args.plots is not None:
            check_writable_dir(args.plots, "--plots")
        if args.data is None:
            result = identify_reference(
                frequency_hz=args.frequency_hz, amplitude_m=args.amplitude_m, d_rule=args.d_rule
            )
            results = [result]
            print(_report(result))
            payload = result.to_json_dict()
        else:
            results, payload = _identify_data(args)
        if args.emit_defaults:
            print()
            print(format_defaults(results[0]), end="")
        if args.json is not None:
            atomic_write_text(args.json, json.dumps(payload, indent=2) + "\n")
            print(f"\nwrote {args.json}")
        if args.plots is not None:
            _write_plots(results, args.plots)
    except (ValueError, OSError, TypeError) as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
