"""Every controller across the capsule's operating envelope (issue 28, section 3).

    python experiments/envelope.py                                   # the page's run, resumes
    python experiments/envelope.py --sweeps speed --oracle ''        # the speed sweep only
    python experiments/envelope.py --json out/e.json --figures '' --page ''

The ISO 2631-1 Wk-weighted RMS car-body acceleration (the project's metric, m/s^2) of the
passive damper, the tuned classical laws that read measured signals, the shipped PPO policy
that reads them (``ppo-measured``) and, at the points ``--oracle`` names, the clairvoyant bound
(:mod:`capsule_env.oracle`), on the evaluation bank (guideway bank
:data:`~capsule_env.evaluation.episodes.EVALUATION_GUIDEWAY_SEED`, episode seeds 1000..1009 of 10 s,
``evaluate.py``'s default), in the ``hils`` setting, at each point of four sweeps
(:func:`envelope_points`):

- ``speed``: 150 (lift-off) to 1200 km/h, ``levitation="eds"`` and ``"fixed"``;
- ``payload``: the car body's mass -30 % to +40 % (``payload_range=(p, p)``), EDS, 810 km/h;
- ``spans``: the tube's sag between pylons (``spans="continuous"``: 20, 30, 50 m spans at
  a sag of L/3000, 30 m spans at L/1500 and L/6000; ``"simply_supported"`` 30 m), EDS,
  810 km/h;
- ``trip``: the registered task ``CapsuleTrip-v0``.

Every controller runs on the point's env options with its own over them (what it reads and how
it acts: :func:`capsule_env.evaluation.condition.controller_env`, as ``evaluate.py --env`` does); the
fixed-gain laws keep the gains tuned at 810 km/h. A policy whose observation is not the
point's (``ppo-measured`` on the trip task: two more columns), or a law that refuses the
point's env with a ``ValueError``, is recorded as not run, with the reason. Each finished
(point, controller) pair is saved at once to ``--json`` (atomically): a rerun with the same
``--episodes``, ``--seed`` and ``--episode-length`` skips what is done (another JSON is
refused unless ``--restart``), so controllers added later (e.g. a new law) run alone. At the end the figures (``--figures``) and the page's tables (``--page``) are
written from the JSON (:mod:`capsule_env.envelope.report`). Bad arguments: one line on stderr,
exit status 2.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from capsule_env.common.cli import ArgumentParser, add_dataclass_options, dataclass_values
from capsule_env.common.safe_io import atomic_write_text, check_writable_dir, check_writable_file
from capsule_env.engine.config import EnvConfig
from capsule_env.evaluation.condition import controller_env, physics_changes, task_env_kwargs
from capsule_env.evaluation.episodes import (
    EVALUATION_GUIDEWAY_SEED,
    check_episode_length,
    episode_metrics,
    run_episodes,
)

REPO = Path(__file__).resolve().parents[1]
#: The setting and observation of every point (the ride task's): the signals a capsule has.
BASE_ENV = {"observation": "measured"}
SETTING = "hils"
#: The classical laws run by default: the passive damper and the tuned laws on measured signals.
CLASSICAL = ("passive", "skyhook-meas", "skyhook-cont-biexp-meas", "hybrid-biexp-meas",
             "add-meas", "sh-add-meas", "lqr-clipped-biexp-meas", "mpc-biexp-meas")  # fmt: skip
#: The gain-scheduled clipped LQR (issue 28), run by default once it is registered.
SCHEDULED = "lqr-sched-biexp-meas"
SPEEDS_KMH = (150.0, 200.0, 300.0, 400.0, 600.0, 810.0, 1000.0, 1200.0)
PAYLOADS = (-0.30, -0.15, 0.0, 0.20, 0.40)
#: ``(shape, span length m, sag as a fraction of the span)`` of the spans sweep.
SPANS = (("continuous", 20.0, 1 / 3000), ("continuous", 30.0, 1 / 3000),
         ("continuous", 50.0, 1 / 3000), ("continuous", 30.0, 1 / 1500),
         ("continuous", 30.0, 1 / 6000), ("simply_supported", 30.0, 1 / 3000))  # fmt: skip
SWEEPS = ("speed", "payload", "spans", "trip")
TRIP_TASK = "CapsuleTrip-v0"
#: Welch PSD of the car-body acceleration at the points flagged ``psd``: segment (s), top (Hz).
PSD_SEGMENT_S, PSD_TOP_HZ = 2.0, 40.0


def _default_controllers() -> str:
    from capsule_env.agents import classical_controllers

    extra = (SCHEDULED,) if SCHEDULED in classical_controllers() else ()
    return ",".join(CLASSICAL + extra)


@dataclass
class Args:
    """The command line (``--field-name`` per field, its help the string under it)."""

    json: str = str(REPO / "docs/figures/envelope.json")
    """the results file: read to resume, rewritten after every (point, controller)"""
    sweeps: str = ",".join(SWEEPS)
    """comma-separated sweeps to run: speed, payload, spans, trip"""
    controllers: str = field(default_factory=_default_controllers)
    """comma-separated classical controllers (names of capsule_env.agents)"""
    policies: str = "ppo-measured,ppo-trip,residual-ppo-mpc-trip"
    """comma-separated shipped policies (capsule_env/pretrained; '' for none)"""
    oracle: str = "speed/eds/150,speed/eds/400,speed/eds/810,speed/eds/1200,trip"
    """comma-separated point keys at which to search the clairvoyant bound (2-5 min each on a
    2-core machine; '' for none)"""
    episodes: int = 10
    """guideway seeds per point (>= 1)"""
    seed: int = 1000
    """first episode seed (>= 0)"""
    episode_length: float = 10.0
    """seconds per episode (long enough for the spectra: >= 0.335 s)"""
    only: str = ""
    """comma-separated point keys to run (default: every point of --sweeps)"""
    figures: str = str(REPO / "docs/figures")
    """folder of the two figures ('' for none)"""
    page: str = str(REPO / "docs/envelope.md")
    """the Markdown page whose generated block is rewritten from the JSON ('' for none)"""
    restart: bool = False
    """discard a --json of other --episodes, --seed or --episode-length"""


@dataclass(frozen=True)
class Point:
    """One operating point: its key, sweep, label, swept value and env options."""

    key: str
    sweep: str
    label: str
    value: float
    env_kwargs: dict[str, Any]
    psd: bool = False

    def describe(self) -> dict[str, Any]:
        """What the JSON records of the point (besides its results)."""
        return {"sweep": self.sweep, "label": self.label, "value": self.value,
                "env_kwargs": self.env_kwargs, "setting": SETTING}  # fmt: skip


def envelope_points(sweeps: tuple[str, ...] = SWEEPS) -> list[Point]:
    """The points of the sweeps ``sweeps``, in the page's order."""
    points: list[Point] = []
    eds810 = {**BASE_ENV, "levitation": "eds", "speed_kmh": 810.0}
    if "speed" in sweeps:
        for lev in ("eds", "fixed"):
            points += [Point(f"speed/{lev}/{v:g}", "speed", f"{lev} {v:g} km/h", v,
                             {**BASE_ENV, "levitation": lev, "speed_kmh": v},
                             psd=(lev == "eds" and v == 810.0)) for v in SPEEDS_KMH]  # fmt: skip
    if "payload" in sweeps:
        points += [Point(f"payload/{p:+.2f}", "payload", f"payload {100 * p:+.0f} %", p,
                         {**eds810, "payload_range": (p, p)}) for p in PAYLOADS]  # fmt: skip
    if "spans" in sweeps:
        for shape, span_m, sag in SPANS:
            params = {"span_m": span_m, "sag_m": round(span_m * sag, 9)}
            points.append(Point(
                f"spans/{shape}/{span_m:g}m/L{round(1 / sag)}", "spans",
                f"{shape.replace('_', ' ')} {span_m:g} m, sag L/{round(1 / sag)}", span_m,
                {**eds810, "spans": shape, "span_params": params}, psd=True))  # fmt: skip
    if "spans" in sweeps:  # the same pair at the random profile's physical level (unscaled)
        raw = {**eds810, "guideway_params": {"peak_m": None}}
        points += [
            Point("spans/unscaled/none", "spans", "no spans, unscaled profile", 0.0, raw, True),
            Point("spans/unscaled/continuous/30m/L3000", "spans",
                  "continuous 30 m, sag L/3000, unscaled profile", 30.0,
                  {**raw, "spans": "continuous", "span_params": {"span_m": 30.0, "sag_m": 0.01}},
                  psd=True),
        ]  # fmt: skip
    if "trip" in sweeps:
        kwargs = {k: v for k, v in task_env_kwargs(TRIP_TASK).items() if k != "setting"}
        points.append(Point("trip", "trip", TRIP_TASK, 0.0, kwargs))
    return points


def _jsonable(value: Any) -> Any:
    """``value`` with tuples as lists (the JSON's form, so that a reread compares equal)."""
    return json.loads(json.dumps(value))


def psd_of(acc_m_s2: np.ndarray, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Welch PSD ((m/s^2)^2/Hz) of each episode's car-body acceleration, averaged over the
    episodes, up to :data:`PSD_TOP_HZ`: ``(frequencies Hz, psd)``."""
    from scipy.signal import welch

    fs = 1.0 / dt_s
    nperseg = min(acc_m_s2.shape[-1], int(round(PSD_SEGMENT_S * fs)))
    f, p = welch(acc_m_s2, fs=fs, nperseg=nperseg, axis=-1)
    keep = f <= PSD_TOP_HZ + 1e-9
    return f[keep], np.mean(np.atleast_2d(p), axis=0)[keep]


def guideway_gain(point: Point, seeds: list[int], episode_length_s: float) -> list[float]:
    """Each episode's guideway scale at ``point``: the factor the env applies to its window of
    the random profile so that its largest elevation is the guideway's ``peak_m`` (1 with
    ``peak_m=None``; the spans are added after it)."""
    from capsule_env.envs.capsule_suspension import CapsuleSuspensionVectorEnv

    env = CapsuleSuspensionVectorEnv(
        num_envs=len(seeds), episode_length_s=episode_length_s, setting=SETTING,
        **{"guideway_seed": EVALUATION_GUIDEWAY_SEED, **point.env_kwargs},
    )  # fmt: skip
    env.reset(seed=[int(s) for s in seeds])
    gain = [float(g) for g in env.batch.gain]
    env.close()
    return gain


def observation_mismatch(ctrl: Any, env_kwargs: dict[str, Any]) -> str | None:
    """Why a policy cannot run on ``env_kwargs`` (its observation size is not the env's), or
    None (also for a classical law)."""
    model = getattr(ctrl, "model", None)
    if model is None:
        return None
    config = EnvConfig.from_kwargs(**env_kwargs)
    trained, given = tuple(model.observation_space.shape), (len(config.observation_names),)
    if trained == given:
        return None
    n = trained[0] if trained else 0
    extra = ", ".join(config.observation_names[n:]) if given > trained else ""
    return (f"not run: trained on {trained[0]} observation columns, the env gives {given[0]}"
            + (f" (the extra ones: {extra})" if extra else ""))  # fmt: skip


def physics_mismatch(
    point_env: dict[str, Any], own: dict[str, Any], episode_length_s: float | None = None
) -> str | None:
    """Why a controller cannot run at a point: its own options (``own``) change the point's
    operating condition, i.e. the plant's physics resolved with every default
    (:func:`capsule_env.evaluation.condition.physics_changes`: speeds, envelope, vehicle, payload,
    damper, guideway, bump stop; what it reads and how it acts are its own), or None."""
    changed = physics_changes({**point_env, "setting": SETTING}, own, episode_length_s,
                              "the point")  # fmt: skip
    return f"not run: its own options set {', '.join(changed)}" if changed else None


def run_point(point: Point, ctrl: Any, seeds: list[int], episode_length_s: float) -> dict:
    """Run the controller ``ctrl`` on ``point`` (its own env options over the point's) for the
    episodes ``seeds``: Wk (mean, spread, per episode), RMS, largest stroke, terminations,
    the env options run and, at a ``psd`` point, the car-body acceleration's PSD."""
    env, kept = controller_env(point.env_kwargs, ctrl.env_kwargs, SETTING)
    start = time.perf_counter()
    try:
        reason = physics_mismatch(point.env_kwargs, ctrl.env_kwargs, episode_length_s)
        reason = reason or observation_mismatch(ctrl, env)
        if reason is not None:
            return {"skipped": reason, "env_kwargs": _jsonable(env)}
        roll = run_episodes(ctrl, env, seeds=seeds, episode_length_s=episode_length_s)
    except ValueError as exc:  # a controller that refuses the point (e.g. one that needs a trip)
        return {"skipped": f"not run: {exc}", "env_kwargs": _jsonable(env)}
    return _entry(roll, point.psd, env, kept, time.perf_counter() - start)


def _entry(roll: Any, psd: bool, env: dict, kept: dict, runtime_s: float) -> dict:
    """A controller's record at a point from its rollout."""
    m = episode_metrics(roll, None)
    per_episode = [episode_metrics(roll.select([k]), None)["wk_rms_body_acc_m_s2"]
                   for k in range(len(roll.terminated))]  # fmt: skip
    entry = {
        "wk_rms_body_acc_m_s2": m["wk_rms_body_acc_m_s2"],
        "wk_std_m_s2": m["std"]["wk_rms_body_acc_m_s2"],
        "wk_per_episode_m_s2": per_episode,
        "rms_body_acc_m_s2": m["rms_body_acc_m_s2"],
        "max_stroke_m": m["max_stroke_m"],
        "terminated_episodes": m["terminated_episodes"],
        "env_kwargs": _jsonable(env),
        "own_options_kept": _jsonable(kept),
        "runtime_s": runtime_s,
    }
    if psd:
        f, p = psd_of(roll.signals["car_body_acceleration_m_s2"], roll.dt_s)
        entry["psd_frequency_hz"] = f.tolist()
        entry["psd_m2_s4_per_hz"] = [float(f"{x:.5g}") for x in p]
    return entry


def run_oracle(point: Point, seeds: list[int], episode_length_s: float) -> dict:
    """The clairvoyant bound at ``point`` (:func:`capsule_env.oracle.clairvoyant_bound`,
    default search, as ``evaluate.py --oracle``; on a trip it follows the trip)."""
    from capsule_env.oracle import clairvoyant_bound

    env = {**point.env_kwargs, "setting": SETTING}
    start = time.perf_counter()
    result = clairvoyant_bound(env, seeds, episode_length_s)
    return _entry(result.rollout, point.psd, env, {}, time.perf_counter() - start)


# ----------------------------------------------------------------------------- the command line
def parse_args(argv: list[str] | None) -> Args:
    """The arguments, checked (one line on stderr and exit status 2 for a bad one)."""
    parser = ArgumentParser(prog="envelope.py", description=__doc__,
                            formatter_class=argparse.RawTextHelpFormatter)  # fmt: skip
    add_dataclass_options(parser, Args)
    args = Args(**dataclass_values(parser.parse_args(argv), Args))
    try:
        check(args)
    except (ValueError, OSError) as exc:
        parser.error(str(exc))
    return args


def _names(text: str) -> list[str]:
    return [n.strip() for n in text.split(",") if n.strip()]


def check(args: Args) -> None:
    """``ValueError`` naming the option for a bad value."""
    sweeps = _names(args.sweeps)
    if not sweeps or any(s not in SWEEPS for s in sweeps):
        raise ValueError(f"--sweeps must be names among {', '.join(SWEEPS)}, got {args.sweeps!r}")
    if args.episodes < 1:
        raise ValueError(f"--episodes must be >= 1, got {args.episodes}")
    if args.seed < 0:
        raise ValueError(f"--seed must be >= 0, got {args.seed}")
    check_episode_length(args.episode_length, EnvConfig().dt_s, "--episode-length")
    keys = {p.key for p in envelope_points()}  # those of other sweeps are valid, not run
    for option in ("oracle", "only"):
        unknown = [k for k in _names(getattr(args, option)) if k not in keys]
        if unknown:
            raise ValueError(f"--{option}: unknown point(s) {unknown}; the sweeps' points: "
                             + ", ".join(sorted(keys)))  # fmt: skip
    check_writable_file(args.json, "--json")
    if args.figures:
        check_writable_dir(args.figures, "--figures")
    if args.page and not Path(args.page).is_file():
        raise ValueError(f"--page must be an existing Markdown file, got {args.page!r}")


def controllers(args: Args) -> dict[str, Any]:
    """The classical controllers and shipped policies named (``ValueError`` for an unknown)."""
    from capsule_env.agents import classical_controllers

    available = classical_controllers()
    names = _names(args.controllers)
    unknown = [n for n in names if n not in available]
    if unknown:
        raise ValueError(f"--controllers: unknown {unknown}; accepted: {', '.join(available)}")
    ctrls = {n: available[n] for n in names}
    policies = _names(args.policies)
    if policies:
        from capsule_env.agents.learning.sb3_policy import shipped_policies

        shipped = shipped_policies()
        unknown = [n for n in policies if n not in shipped]
        if unknown:
            raise ValueError(f"--policies: unknown {unknown}; shipped: {', '.join(shipped)}")
        ctrls.update({n: shipped[n] for n in policies})
    return ctrls


def run_config(args: Args) -> dict[str, Any]:
    """What a resumed run must share with the JSON's: the episodes and the guideway bank."""
    return {"episodes": args.episodes, "seed": args.seed, "episode_length_s": args.episode_length,
            "guideway_seed": EVALUATION_GUIDEWAY_SEED, "setting": SETTING}  # fmt: skip


def load(args: Args) -> dict[str, Any]:
    """The JSON's results, or a fresh record (``ValueError`` for a JSON of another run
    configuration without ``--restart``)."""
    path, config = Path(args.json), run_config(args)
    if path.exists() and not args.restart:
        try:
            data = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise ValueError(f"--json {path} cannot be read ({exc}); use --restart") from None
        if data.get("config") != config:
            raise ValueError(f"--json {path} holds a run of {data.get('config')}, not {config}; "
                             "use --restart or another --json")  # fmt: skip
        return data
    return {"config": config, "points": {}, "runtime_s": 0.0}


def _todo(data: dict, points: list[Point], ctrls: dict, oracle: set[str]) -> list[tuple]:
    """The (point, name) pairs not in ``data`` yet (name ``"oracle"`` at the oracle points)."""
    todo = []
    for point in points:
        done = data["points"].get(point.key, {}).get("controllers", {})
        names = [*ctrls, *(["oracle"] if point.key in oracle else [])]
        todo += [(point, name) for name in names if name not in done]
    return todo


def sweep(args: Args, data: dict, ctrls: dict) -> None:
    """Run every pair not done, saving the JSON after each."""
    only = set(_names(args.only))
    points = [p for p in envelope_points(tuple(_names(args.sweeps))) if not only or p.key in only]
    seeds = list(range(args.seed, args.seed + args.episodes))
    todo = _todo(data, points, ctrls, set(_names(args.oracle)))
    for point in points:  # records of an earlier version of this script
        record = data["points"].get(point.key)
        if record is not None and "guideway_gain" not in record:
            record["guideway_gain"] = guideway_gain(point, seeds, args.episode_length)
    for k, (point, name) in enumerate(todo):
        start = time.perf_counter()
        if name == "oracle":
            entry = run_oracle(point, seeds, args.episode_length)
        else:
            entry = run_point(point, ctrls[name], seeds, args.episode_length)
        record = data["points"].setdefault(point.key, {**_jsonable(point.describe()),
                                                       "controllers": {}})  # fmt: skip
        if "guideway_gain" not in record:
            record["guideway_gain"] = guideway_gain(point, seeds, args.episode_length)
        record["controllers"][name] = entry
        data["runtime_s"] = data.get("runtime_s", 0.0) + time.perf_counter() - start
        atomic_write_text(args.json, json.dumps(data, indent=1) + "\n")
        wk = entry.get("wk_rms_body_acc_m_s2")
        print(f"[{k + 1}/{len(todo)}] {point.key} {name}: "
              + (f"Wk {wk:.4f} m/s^2" if wk is not None else entry["skipped"])
              + f" ({time.perf_counter() - start:.1f} s)", file=sys.stderr, flush=True)  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    args = parse_args(argv)
    try:
        ctrls = controllers(args)
        data = load(args)
    except ValueError as exc:
        print(f"envelope.py: error: {exc}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    sweep(args, data, ctrls)
    from capsule_env.envelope import report as envelope_report

    print(envelope_report.tables(data))
    if args.figures:
        for path in envelope_report.figures(data, Path(args.figures)):
            print(f"wrote {path}", file=sys.stderr)
    if args.page:
        changed = envelope_report.sync_page(Path(args.page), Path(args.json))
        print(("updated " if changed else "unchanged ") + args.page, file=sys.stderr)
    print(f"run time (all sessions): {data['runtime_s']:.0f} s; this call "
          f"{time.perf_counter() - t0:.0f} s", file=sys.stderr)  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
