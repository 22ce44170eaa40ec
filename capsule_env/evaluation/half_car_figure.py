"""The half-car page's figure (docs/half-car.md): the car body's pitch over a few seconds of one
evaluation episode, passive against the tuned per-bogie clipped LQR, and the Wk at the floor's
front, centre and rear of each law of the evaluation relative to that LQR, in per cent (the
rear's gain from the wheelbase preview: the ``wheelbase-*`` bars beside their no-preview twins,
``discrete LQ`` and ``coupled MPC``).

    python -m capsule_env.evaluation.half_car_figure docs/figures/evaluation-CapsuleHalfRide-v0.json docs/figures/half_car.png
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["pitch_trace", "half_car_figure", "main"]

#: The laws drawn in the right panel, in order, with their labels.
_BARS = {
    "passive": "passive",
    "lqr-clipped-biexp-meas": "LQR per bogie",
    "lqr-coupled-biexp-meas": "coupled LQR",
    "lq-discrete-biexp-meas": "discrete LQ",
    "wheelbase-lq-biexp-meas": "wheelbase LQ",
    "wheelbase-lq-biexp-exact": "wheelbase LQ, exact",
    "mpc-coupled-biexp-meas": "coupled MPC",
    "wheelbase-mpc-biexp-meas": "wheelbase MPC",
}


def pitch_trace(seed: int = 1000, seconds: float = 4.0) -> dict[str, np.ndarray]:
    """The body's pitch angle (mrad) over ``seconds`` of evaluation episode ``seed``, passive
    and with the per-bogie clipped LQR: ``{"time_s": ..., label: ...}``."""
    from capsule_env.agents.controllers.declared_lqr import IndependentClippedLQR
    from capsule_env.envs.declared_vector import DeclaredVectorEnv
    from capsule_env.evaluation.half_car import EVALUATION_GUIDEWAY_SEED, TASK_KWARGS

    out: dict[str, np.ndarray] = {}
    for label, law in (("passive", None), ("LQR per bogie", IndependentClippedLQR())):
        kwargs = dict(TASK_KWARGS, **(law.env_kwargs if law is not None else {"damper": "passive"}))
        kwargs.pop("vehicle_params", None)
        env = DeclaredVectorEnv(1, guideway_seed=EVALUATION_GUIDEWAY_SEED,
                                episode_length_s=seconds, **kwargs)  # fmt: skip
        obs, _ = env.reset(seed=[seed])
        pitch_column = env.batch.model.state_names.index("car_body_pitch_rad") // 2
        angles = []
        for _ in range(env.batch.max_steps):
            action = np.zeros((1, 2)) if law is None else law.predict(obs)[0]
            obs, *_ = env.step(action)
            angles.append(1e3 * env.batch.state[0, pitch_column])
        out[label] = np.array(angles)
        out["time_s"] = env.batch.dt * np.arange(1, len(angles) + 1)
    return out


def half_car_figure(result: dict[str, Any], trace: dict[str, np.ndarray], path: Path) -> Path:
    """Draw the two panels into ``path`` (PNG, 736 px wide: the docs' column)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(7.36, 3.2), dpi=100)
    for label, style in (("passive", "--"), ("LQR per bogie", "-")):
        left.plot(trace["time_s"], trace[label], style, label=label, linewidth=1.2)
    left.set_xlabel("time (s)", fontsize=10)
    left.set_ylabel("body pitch (mrad)", fontsize=10)
    left.legend(fontsize=9, loc="lower left")
    rows = result["settings"]["hils"]["controllers"]  # evaluate.py's layout
    base = rows["lqr-clipped-biexp-meas"]
    names = [n for n in _BARS if n in rows and n not in ("passive", "lqr-clipped-biexp-meas")]
    x = np.arange(len(names))
    top = 0.0
    for k, (key, where) in enumerate((("wk_front_m_s2", "front"), ("wk_centre_m_s2", "centre"),
                                      ("wk_rear_m_s2", "rear"))):  # fmt: skip
        change = [100.0 * (rows[n][key] / base[key] - 1.0) for n in names]
        right.bar(x + (k - 1) * 0.27, change, 0.27, label=where)
        top = max(top, *change)
    right.set_ylim(top=1.6 * top + 0.1)  # room for the legend above the bars
    right.axhline(0.0, color="black", linewidth=0.8)
    right.set_xticks(x, [_BARS[n] for n in names], rotation=35, ha="right", fontsize=9)
    right.set_ylabel("Wk vs LQR per bogie (%)", fontsize=10)
    right.legend(fontsize=9, ncol=3, loc="upper right")
    for ax in (left, right):
        ax.tick_params(labelsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 2 or not Path(args[0]).is_file():
        print("usage: python -m capsule_env.evaluation.half_car_figure RESULT.json OUT.png",
              file=sys.stderr)  # fmt: skip
        return 2
    problem = _input_problem(Path(args[0]), Path(args[1]))
    if problem:  # before the seconds of the pitch trace, not a traceback after them
        print(f"python -m capsule_env.evaluation.half_car_figure: error: {problem}",
              file=sys.stderr)  # fmt: skip
        return 2
    half_car_figure(json.loads(Path(args[0]).read_text()), pitch_trace(), Path(args[1]))
    return 0


def _input_problem(result_json: Path, out_png: Path) -> str | None:
    """Why the figure cannot be drawn from ``result_json`` into ``out_png`` (one line), or
    None: the JSON must be evaluate.py's layout with the per-bogie LQR's hils row; ``out_png``
    is checked last (its folder is made when missing)."""
    from capsule_env.common.safe_io import check_writable_file

    try:
        result = json.loads(result_json.read_text())
    except (OSError, ValueError) as exc:
        return f"cannot read {result_json} as JSON ({exc})"
    try:
        base = result["settings"]["hils"]["controllers"]["lqr-clipped-biexp-meas"]
        missing = [k for k in ("wk_front_m_s2", "wk_centre_m_s2", "wk_rear_m_s2") if k not in base]
    except (KeyError, TypeError):
        return (f"{result_json} is not evaluate.py's JSON of the half-car task (it needs "
                "settings.hils.controllers.lqr-clipped-biexp-meas)")  # fmt: skip
    if missing:
        return f"{result_json}: the per-bogie LQR's row has no {', '.join(missing)}"
    try:
        check_writable_file(out_png, "OUT.png")
    except ValueError as exc:
        return str(exc)
    return None


if __name__ == "__main__":
    sys.exit(main())
