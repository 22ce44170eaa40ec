"""Which lost detail can produce the paper's Bi-exponential vs Bouc-Wen gap (issue 27).

    python experiments/paper_sensitivity.py            # both tables, 10 episodes, resumes
    python experiments/paper_sensitivity.py --settings sim --episodes 3 --json out/s.json
    python experiments/paper_sensitivity.py --measured-data ../shared/data/labcontrol-mr-damper

Runs the paper's comparison (on-off Skyhook, c_max 7e4 N s/m, through the Bi-exponential
inverse and through CSDC on the Bouc-Wen model; passive on the same seeds; evaluate.py's
evaluation bank, seeds 1000..) once per point of :mod:`capsule_env.sensitivity.points`: one
lost detail at a time varied over its plausible range. Each finished point is saved at once
to the JSON (atomically): a killed run started again with the same arguments skips what is
done (other arguments: the JSON is refused, one line, unless ``--restart``). At the end the
Markdown tables and the figure (``--figure``) are written from the JSON. Every VRE and gap
is stored per episode, with its 95 % interval over the episodes (t; paired t for the gaps).
``--measured-data DIR`` adds the ``hils`` points on a plant identified from the measured
Labcontrol loops in DIR (read at run time, never copied;
:mod:`capsule_env.sensitivity.measured_plant`). Bad arguments: one line on stderr, exit
status 1 (2 for argument syntax).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import NoReturn

from capsule_env.common.safe_io import atomic_write_text, check_writable_file
from capsule_env.identification.measured import measured_files
from capsule_env.sensitivity.points import fitted_models, study_points
from capsule_env.sensitivity.runner import format_table, plot_tornado, run_point

REPO = Path(__file__).resolve().parents[1]


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message}\n")


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = _Parser(prog="paper_sensitivity.py", description=__doc__,
                formatter_class=argparse.RawTextHelpFormatter)  # fmt: skip
    p.add_argument("--settings", default="sim,hils", help="sim, hils or sim,hils")
    p.add_argument("--episodes", type=int, default=10, help="episodes per point (>= 1)")
    p.add_argument("--seed", type=int, default=1000, help="first episode seed (>= 0)")
    p.add_argument("--episode-length", type=float, default=10.0, help="seconds (>= 2)")
    p.add_argument("--json", type=Path, default=REPO / "docs/figures/paper_sensitivity.json")
    p.add_argument("--figure", type=Path, default=REPO / "docs/figures/paper_sensitivity.png")
    p.add_argument("--quick-fits", action="store_true",
                   help="fit on 4 currents, 200 samples a cycle (tests)")  # fmt: skip
    p.add_argument("--only", default="", help="comma-separated factors to run (default all)")
    p.add_argument("--restart", action="store_true", help="discard a JSON of other arguments")
    p.add_argument("--measured-data", type=Path, default=None,
                   help="folder of Labcontrol .mat loops: adds the measured-plant hils points")  # fmt: skip
    return p.parse_args(argv)


def check(args: argparse.Namespace) -> list[str]:
    """The settings; ``ValueError`` naming the option for a bad value."""
    settings = [s.strip() for s in args.settings.split(",") if s.strip()]
    if not settings or any(s not in ("sim", "hils") for s in settings):
        raise ValueError(f"--settings must be sim, hils or sim,hils, got {args.settings!r}")
    if args.episodes < 1:
        raise ValueError(f"--episodes must be >= 1, got {args.episodes}")
    if args.seed < 0:
        raise ValueError(f"--seed must be >= 0, got {args.seed}")
    if not args.episode_length >= 2.0:
        raise ValueError(f"--episode-length must be >= 2 s, got {args.episode_length}")
    check_writable_file(args.json, "--json")
    check_writable_file(args.figure, "--figure")
    if args.measured_data is not None:
        if "hils" not in settings:
            raise ValueError("--measured-data needs the hils setting (its points are hils ones)")
        try:
            measured_files(args.measured_data)
        except ValueError as exc:
            raise ValueError(f"--measured-data: {exc}") from None
    return settings


def load(args: argparse.Namespace, config: dict) -> dict:
    """The JSON's finished results, or a fresh record (``ValueError`` for a JSON of other
    arguments without ``--restart``)."""
    if args.json.exists() and not args.restart:
        try:
            data = json.loads(args.json.read_text())
        except (OSError, ValueError) as exc:
            raise ValueError(f"--json {args.json} cannot be read ({exc}); use --restart") from None
        if data.get("config") != config:
            raise ValueError(f"--json {args.json} holds a run of other arguments "
                             f"({data.get('config')}); use --restart or another --json")  # fmt: skip
        return data
    return {"config": config, "results": {}, "runtime_s": 0.0}


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        settings = check(args)
        config = {"settings": settings, "episodes": args.episodes, "seed": args.seed,
                  "episode_length_s": args.episode_length, "quick_fits": args.quick_fits,
                  "per_episode": True,
                  "measured_data": None if args.measured_data is None
                  else args.measured_data.resolve().name}  # fmt: skip
        data = load(args, config)
    except ValueError as exc:
        print(f"paper_sensitivity.py: error: {exc}", file=sys.stderr)
        return 1
    t0 = time.perf_counter()
    try:
        models = fitted_models(quick=args.quick_fits, measured=args.measured_data)
    except ValueError as exc:  # a measured folder whose loops cannot make a plant
        print(f"paper_sensitivity.py: error: --measured-data: {exc}", file=sys.stderr)
        return 1
    data["fits"] = {k: models[k] for k in ("free_rmse_n", "biexp_rmse_n", "ratio_target_n")}
    if "measured" in models:
        data["fits"]["measured"] = models["measured"]
    only = {f.strip() for f in args.only.split(",") if f.strip()}
    points = [p for p in study_points(models, tuple(settings))
              if not only or p.factor in only or p.factor == "baseline"]  # fmt: skip
    seeds = list(range(args.seed, args.seed + args.episodes))
    cache: dict = {}
    for k, point in enumerate(points):
        if point.key in data["results"]:
            continue
        start = time.perf_counter()
        data["results"][point.key] = run_point(point, seeds, args.episode_length, cache)
        data["results"][point.key]["runtime_s"] = time.perf_counter() - start
        data["runtime_s"] = data.get("runtime_s", 0.0) + time.perf_counter() - start
        atomic_write_text(args.json, json.dumps(data, indent=1) + "\n")
        r = data["results"][point.key]
        print(f"[{k + 1}/{len(points)}] {point.key}: CSDC {r['csdc']['vre_body_mode1_pct']:.1f} %, "
              f"Bi-exp {r['biexp']['vre_body_mode1_pct']:.1f} % "
              f"({time.perf_counter() - start:.0f} s)", file=sys.stderr, flush=True)  # fmt: skip
    results = [data["results"][p.key] for p in points if p.key in data["results"]]
    for setting in settings:
        print(f"\n{setting}\n" + format_table(results, setting))
    plot_tornado(results, args.figure)
    print(f"study time (all sessions): {data['runtime_s']:.0f} s; this call "
          f"{time.perf_counter() - t0:.0f} s", file=sys.stderr)  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
