"""Comfort trade-offs of the classical laws' gains, with the learned policies beside them.

    python experiments/pareto.py --out docs/figures/pareto.png --json docs/figures/pareto.json
    python experiments/pareto.py --policy runs/ppo/best_model.zip     # add any SB3 policy

For each tuned classical law (default: those of ``evaluate.py``'s default run) one gain is
swept over its whole search range (:mod:`capsule_env.agents.learning.search_space`: Skyhook's and the hybrid's
``c_sky``, the two-state laws' ``i_on``, the LQR's ``r_force``), the other gains held at their
tuned values, and every sweep point runs on the EVALUATION bank (``guideway_seed`` 2026,
episode seeds 1000..1009, ``hils``): for this figure only. The shipped gains were tuned on the
TRAINING bank (``guideway_seed`` 0, :mod:`capsule_env.agents.controllers.tuning`) and are starred on each curve. The
passive damper (the VRE's reference), the constant currents and the learned policies (the
shipped ones unless ``--no-shipped-policy``, and each ``--policy``) are points.

Figure: Wk-weighted RMS body acceleration against the body's first-mode vibration reduction
effect, and against the worst max |stroke| over the episodes; JSON: every point's metrics.
"""

from __future__ import annotations

import argparse
import datetime
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from capsule_env.agents.controllers.classical import make_controller  # noqa: E402
from capsule_env.agents.controllers.tuning import TuningSettings  # noqa: E402
from capsule_env.agents.learning.search_space import SEARCH_SPACES  # noqa: E402

from capsule_env.common.safe_io import atomic_write_text, check_writable_file  # noqa: E402
from capsule_env.engine.config import EnvConfig  # noqa: E402
from capsule_env.evaluation.episodes import (  # noqa: E402
    EVALUATION_GUIDEWAY_SEED,
    Rollout,
    check_episode_length,
    episode_metrics,
    run_episodes,
)
from capsule_env.evaluation.evaluate import DEFAULT_CONTROLLERS  # noqa: E402

SETTING = "hils"
#: The laws drawn by default: the tuned ones of evaluate.py's default run.
DEFAULT_LAWS = [n for n in DEFAULT_CONTROLLERS if n in SEARCH_SPACES]
OPEN_LOOP = ("mr-0A", "mr-imax")


def summary(m: dict[str, Any], worst_stroke_m: float) -> dict[str, Any]:
    """The figure's metrics of one point (``episode_metrics`` output)."""
    return {
        "wk_rms_body_acc_m_s2": m["wk_rms_body_acc_m_s2"],
        "vre_body_mode1_pct": m["vre_pct"]["body_mode1"] if "vre_pct" in m else None,
        "max_stroke_m": worst_stroke_m,
        "mean_max_stroke_m": m["max_stroke_m"],
        "terminated_episodes": m["terminated_episodes"],
    }


def _worst_stroke(roll: Rollout) -> float:
    return float(np.max(np.abs(roll.signals["stroke_m"])))


def sweep(
    name: str, points: int, seeds: list[int], length_s: float, passive: Rollout
) -> dict[str, Any]:
    """Law ``name`` at ``points`` values of its swept gain over the search range, and at its
    tuned value, all in one vector env; returns the curve."""
    space = SEARCH_SPACES[name]
    tuned = make_controller(name)
    param = space.sweep_param
    tuned_value = float(getattr(tuned, param.name))
    values = np.unique(np.append(param.to_value(np.linspace(0.0, 1.0, points)), tuned_value))
    n_ep = len(seeds)
    gains = {g: float(getattr(tuned, g)) for g in (*space.names, *space.tied)}
    gains[param.name] = values
    for tied, source in space.tied.items():
        if source == param.name:
            gains[tied] = values
    per_vehicle = {g: np.repeat(np.broadcast_to(v, values.shape), n_ep) for g, v in gains.items()}
    ctrl = make_controller(name, **per_vehicle)
    roll = run_episodes(ctrl, {**ctrl.env_kwargs, "setting": SETTING}, episode_length_s=length_s,
                        seeds=np.tile(seeds, len(values)))  # fmt: skip
    rows = []
    for k in range(len(values)):
        part = roll.select(slice(k * n_ep, (k + 1) * n_ep))
        rows.append(summary(episode_metrics(part, passive), _worst_stroke(part)))
    curve: dict[str, Any] = {
        "observation": tuned.observation,
        "swept_gain": tuned.gain_key(param.name),
        "values": values.tolist(),
        "tuned_index": int(np.argmin(np.abs(values - tuned_value))),
        "tuned_gains": tuned.gains(),
    }
    for key in rows[0]:
        curve[key] = [row[key] for row in rows]
    return curve


def point(
    ctrl: Any, seeds: list[int], length_s: float, passive: Rollout | None
) -> tuple[dict[str, Any], Rollout]:
    """One controller (open loop or a policy) on the evaluation episodes: its figure metrics
    and its rollout."""
    roll = run_episodes(ctrl, {**ctrl.env_kwargs, "setting": SETTING}, episode_length_s=length_s,
                        seeds=seeds)  # fmt: skip
    return summary(episode_metrics(roll, passive), _worst_stroke(roll)), roll


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    p.add_argument("--out", type=Path, default=Path("docs/figures/pareto.png"), help="the PNG")
    p.add_argument("--json", type=Path, default=None, help="also write the sweep as JSON")
    p.add_argument("--laws", default=",".join(DEFAULT_LAWS),
                   help="comma-separated tuned laws, or 'all': " + ", ".join(SEARCH_SPACES))  # fmt: skip
    p.add_argument("--points", type=int, default=13, help="sweep points per law (>= 2)")
    p.add_argument("--episodes", type=int, default=10, help="evaluation episodes (>= 1)")
    p.add_argument("--seed", type=int, default=1000, help="first evaluation episode seed")
    p.add_argument("--episode-length", type=float, default=10.0, help="seconds per episode")
    p.add_argument("--policy", action="append", default=[], metavar="PATH",
                   help="an SB3 policy (.zip with its .vecnormalize.pkl); repeatable")  # fmt: skip
    p.add_argument("--no-shipped-policy", action="store_true",
                   help="leave out the policies shipped with the package")  # fmt: skip
    p.add_argument("--from-json", type=Path, default=None, metavar="PATH",
                   help="redraw the figure from a JSON this script wrote (runs nothing)")  # fmt: skip
    return p.parse_args(argv)


def checked_inputs(args: argparse.Namespace) -> tuple[list[str], list[Any]]:
    """The laws to sweep and the policies loaded, after every check of the arguments (the
    output paths writable); ``ValueError`` or ``OSError`` naming the option otherwise."""
    laws = list(SEARCH_SPACES) if args.laws == "all" else args.laws.split(",")
    unknown = [n for n in laws if n not in SEARCH_SPACES]
    if unknown:
        raise ValueError(f"--laws: no search space for {unknown}")
    if args.points < 2 or args.episodes < 1 or args.seed < 0:
        raise ValueError("--points must be >= 2, --episodes >= 1, --seed >= 0")
    check_episode_length(args.episode_length, EnvConfig().dt_s, "--episode-length")
    for path, option in ((args.out, "--out"), (args.json, "--json")):
        if path is not None:
            check_writable_file(path, option)
    paths = list(args.policy)
    if not args.no_shipped_policy:
        from capsule_env.agents.learning.sb3_policy import shipped_policy_paths

        paths = shipped_policy_paths({}) + paths  # those trained in the paper's env
    if not paths:
        return laws, []
    from capsule_env.agents.learning.sb3_policy import SB3Policy, use_one_torch_thread

    use_one_torch_thread()
    return laws, [SB3Policy.load(p) for p in paths]


def other_points(
    policies: list[Any], seeds: list[int], length_s: float, passive: Rollout
) -> dict[str, dict[str, Any]]:
    """The figure's single points: the open-loop currents and the policies."""
    points = {}
    for name in OPEN_LOOP:
        metrics_ = point(make_controller(name), seeds, length_s, passive)[0]
        points[name] = {"kind": "open loop", "observation": "none", **metrics_}
    for policy in policies:
        metrics_ = point(policy, seeds, length_s, passive)[0]
        reads = policy.observation + ("+preview" if policy.preview else "")
        points[policy.name] = {"kind": "policy", "observation": reads,
                               "path": str(policy.path), **metrics_}  # fmt: skip
    return points


def redraw(source: Path, out: Path) -> int:
    """``--from-json``: the figure of a JSON this script wrote, to ``out``; nothing is run (a
    JSON that cannot be read or drawn: one line, nothing written)."""
    from capsule_env.plots import pareto_figure

    try:
        data = json.loads(source.read_text())
        missing = [k for k in ("laws", "points", "seeds", "setting", "guideway_seed")
                   if not isinstance(data, dict) or k not in data]  # fmt: skip
        if missing:
            raise ValueError(f"not a JSON this script wrote (no {', '.join(missing)})")
    except (OSError, ValueError) as exc:
        sys.exit(f"pareto.py: error: --from-json {source}: {exc}")
    try:
        check_writable_file(out, "--out")
    except ValueError as exc:
        sys.exit(f"pareto.py: error: {exc}")
    pareto_figure(data, out)
    print(f"wrote {out}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (bad arguments: one line and status 1)."""
    args = parse_args(argv)
    if args.from_json is not None:
        return redraw(args.from_json, args.out)
    try:
        laws, policies = checked_inputs(args)
    except (ValueError, OSError) as exc:
        sys.exit(f"pareto.py: error: {exc}")
    seeds = list(range(args.seed, args.seed + args.episodes))
    t0 = time.perf_counter()
    passive_metrics, passive = point(make_controller("passive"), seeds, args.episode_length, None)
    data: dict[str, Any] = {
        "description": "Gain sweeps of the tuned classical laws on the EVALUATION bank, for this "
        "figure only (the gains were tuned on the training bank, agents/controllers/tuned_gains.json).",
        "date": datetime.date.today().isoformat(),
        "command": " ".join(
            ["python experiments/pareto.py", *(sys.argv[1:] if argv is None else argv)]
        ),  # fmt: skip
        "setting": SETTING,
        "guideway_seed": EVALUATION_GUIDEWAY_SEED,
        "seeds": seeds,
        "episode_length_s": args.episode_length,
        "stroke_limit_m": TuningSettings().stroke_limit_m,
        "laws": {},
        "points": {"passive": {"kind": "open loop", "observation": "none", **passive_metrics}},
    }
    data["points"].update(other_points(policies, seeds, args.episode_length, passive))
    for name in laws:
        data["laws"][name] = curve = sweep(name, args.points, seeds, args.episode_length, passive)
        k = curve["tuned_index"]
        print(f"{name:<24} {len(curve['values']):3d} points; tuned: Wk "
              f"{curve['wk_rms_body_acc_m_s2'][k]:.4f} m/s^2, VRE body m1 "
              f"{curve['vre_body_mode1_pct'][k]:6.2f} %, worst stroke "
              f"{1e3 * curve['max_stroke_m'][k]:5.2f} mm", flush=True)  # fmt: skip
    data["elapsed_s"] = round(time.perf_counter() - t0, 1)
    from capsule_env.plots import pareto_figure

    pareto_figure(data, args.out)
    print(f"wrote {args.out} ({data['elapsed_s']:.1f} s)")
    if args.json is not None:
        atomic_write_text(args.json, json.dumps(data, indent=2) + "\n")
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
