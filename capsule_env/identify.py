"""Command line: identify MR-damper models from force loops (docs/model.md, section 6).

Run ``python -m capsule_env.identify --help``. Examples::

    python -m capsule_env.identify                                  # reference damper, tables
    python -m capsule_env.identify --json fit.json --plots figs/    # + JSON summary and PNGs
    python -m capsule_env.identify --emit-defaults                  # dataclass default lines
    python -m capsule_env.identify --data ../shared/data/labcontrol-mr-damper/ensaio.A.1.mat
    python -m capsule_env.identify --data ../shared/data/labcontrol-mr-damper   # every file

Exit status: 0 on success, 2 for bad arguments, unreadable or unusable data, or an output
path that cannot be written (checked before fitting), with one line on stderr naming the file.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import NoReturn

from capsule_env.identification import (
    D_RULES,
    MODEL_NAMES,
    PAPER_RMSE_N,
    IdentificationResult,
    dataclass_default_lines,
    identify_measured,
    identify_reference,
    measured_files,
    plot_fits,
)
from capsule_env.safe_io import atomic_write_text, check_writable_dir, check_writable_file

_LABELS = {"bi_exponential": "Bi-exponential", "bouc_wen": "Bouc-Wen", "tanh": "tanh"}
_CLASSES = {
    "bouc_wen": "BoucWenDamper",
    "tanh": "TanhDamper",
    "bi_exponential": "BiExponentialDamper",
}


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr (no usage block), exit 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``python -m capsule_env.identify``."""
    parser = _Parser(
        prog="python -m capsule_env.identify",
        description=(
            "Identify the Bi-exponential, Bouc-Wen and tanh MR-damper models from force loops "
            "(docs/model.md, section 6): from loops of the reference (Spencer) damper under a "
            "sinusoidal stroke at 0 to 1.5 A (default), or from measured Labcontrol .mat "
            "files. Prints the Bi-exponential linear-law table (the paper's Table 2 analogue) "
            "and the RMSE of each model next to the paper's 61.8 N (Bi-exponential) and "
            "695.3 N (Bouc-Wen) at 1.5 A."
        ),
        epilog=(
            "Measured files record no coil current: each is fitted on its own at i = 0 (the "
            "per-ampere coefficients are 0). Compare RMSE relative to the peak force: the "
            "paper's damper, the reference damper and the laboratory damper differ in size."
        ),
    )
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
        help="a measured .mat file (Labcontrol format: x_F = displacement mm, velocity mm/s, "
        "force N) or a folder: every .mat file in it, each fitted on its own",
    )
    parser.add_argument("--json", metavar="PATH", type=Path, help="write a JSON summary here")
    parser.add_argument(
        "--plots", metavar="DIR", type=Path, help="write PNG figures (loops, parameter trends) here"
    )
    parser.add_argument(
        "--emit-defaults",
        action="store_true",
        help="print the dataclass default lines (5 significant digits) of BoucWenDamper, "
        "TanhDamper and BiExponentialDamper fitted to the reference damper, to paste into "
        "capsule_env/dampers.py",
    )
    parser.add_argument(
        "--d-rule",
        choices=D_RULES,
        default="mean",
        help="Bi-exponential d per branch: 'mean' over the per-current fits (the paper's "
        "procedure, default) or 'joint' (d and the linear laws fitted to all currents at once)",
    )
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


def _fmt(value: float, width: int = 11) -> str:
    return f"{value:{width}.5g}"


def format_table(result: IdentificationResult) -> str:
    """The Bi-exponential linear-law table (the paper's Table 2 analogue) as text."""
    head = (
        f"{'branch':<7}{'a0 (N)':>11}{'a1 (N/A)':>11}{'b0 (Ns/m)':>11}{'b1 (Ns/mA)':>11}"
        f"{'c0 (N)':>11}{'c1 (N/A)':>11}{'d (s/m)':>11}"
    )
    lines = [
        "Bi-exponential linear laws (paper's Table 2 analogue), d rule: " + result.d_rule,
        "  F = a S_d(v) + b v + c,  S_d(v) = sign(v)(1 - exp(-d|v|)),  p = p0 + p1 i;"
        "  upper: x >= 0, lower: x < 0",
        head,
    ]
    for branch, row in result.table.items():
        lines.append(
            f"{branch:<7}"
            + "".join(_fmt(row[k]) for k in ("a0", "a1", "b0", "b1", "c0", "c1", "d"))
        )
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
            f"{result.rmse_current_a:g} A (capsule_env.identify --emit-defaults; RMSE "
            f"{result.models[name].rmse_n:.1f} N at {result.rmse_current_a:g} A)"
        )
        out.extend(dataclass_default_lines(result.models[name].damper))
        out.append("")
    return "\n".join(out).rstrip() + "\n"


def _report(result: IdentificationResult) -> str:
    header = f"Identification from: {result.source}"
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


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.emit_defaults and args.data is not None:
        parser.error("--emit-defaults fits the reference damper; do not combine it with --data")
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
            path: Path = args.data
            if path.is_dir():
                files = measured_files(path)
            elif path.is_file():
                files = [path]
            else:
                raise ValueError(f"--data: no such file or folder: {str(path)!r}")
            results = []
            for file in files:
                try:
                    results.append(identify_measured(file))
                except ValueError as exc:
                    if str(file) in str(exc):
                        raise
                    raise ValueError(f"cannot identify {str(file)!r}: {exc}") from None
                print(_report(results[-1]))
                print()
            if len(results) > 1:
                print(_summary_table(results))
                payload = {
                    "source": str(path),
                    "files": {r.source: r.to_json_dict() for r in results},
                }
            else:
                payload = results[0].to_json_dict()
        if args.emit_defaults:
            print()
            print(format_defaults(results[0]), end="")
        if args.json is not None:
            atomic_write_text(args.json, json.dumps(payload, indent=2) + "\n")
            print(f"\nwrote {args.json}")
        if args.plots is not None:
            written = []
            for r in results:
                prefix = "" if len(results) == 1 else Path(r.source).stem + "_"
                written += plot_fits(r, None, args.plots, prefix=prefix)
            print(f"wrote {len(written)} figures to {args.plots}")
    except (ValueError, OSError, TypeError) as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
