"""Claims of the docs against the evidence behind them (issue 40): the oracle is a local
search (never a bound or a limit), the figures a page states are its files', and a shipped
policy is marked where its metadata says."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
FIGURES = DOCS / "figures"
# ways the pages and docstrings once called the oracle's local search a limit
OVERCLAIMS = ("a bound no", "bounds everything", "clairvoyant bound:", "clairvoyant bound.",
              "oracle's bound", "physical headroom", "the oracle, a bound", "no causal law lowers")  # fmt: skip


def test_the_oracle_is_never_called_a_bound():
    import capsule_env.oracle
    import capsule_env.oracle.search

    texts = {p.name: p.read_text() for p in sorted(DOCS.glob("*.md"))}
    texts["capsule_env.oracle"] = capsule_env.oracle.__doc__
    texts["capsule_env.oracle.search"] = capsule_env.oracle.search.__doc__
    texts["clairvoyant_bound"] = capsule_env.oracle.search.clairvoyant_bound.__doc__
    found = [(name, claim) for name, text in texts.items() for claim in OVERCLAIMS
             if claim in " ".join(text.split()).lower()]  # fmt: skip
    assert not found


def test_the_trip_acceleration_in_g_is_the_default_s():
    from capsule_env.envelope import trips

    g = trips.TripParams().acceleration_m_s2 / 9.80665
    doc = " ".join(trips.__doc__.split())
    assert f"({g:.3f} g)" in doc
    low, high = (float(x) for x in re.search(r"the (\d\.\d+)-(\d\.\d+) g", doc).groups())
    assert ("inside the" in doc) == (low <= g <= high)


def test_the_paper_studys_stated_time_and_held_out_rows_are_its_jsons():
    page = " ".join((DOCS / "paper-reproduction.md").read_text().split())
    study = json.loads((FIGURES / "paper_sensitivity.json").read_text())
    assert f"took {round(study['runtime_s'])} s of wall time in all" in page
    held = json.loads((FIGURES / "paper_sensitivity-heldout.json").read_text())
    assert held["config"]["seed"] == 1010 and held["config"]["episodes"] == 10
    rows = re.findall(r"^\| (today's reproduction|current terms × 0\.3[^|]*|c_max[^|]*|longest"
                      r"[^|]*) \|((?: [−+\d.]+ ± [\d.]+ \|){6})$",
                      (DOCS / "paper-reproduction.md").read_text(), flags=re.M)  # fmt: skip
    assert len(rows) == 6
    for label, cells in rows:
        figures = [[float(x.replace("−", "-")) for x in c.split("±")]
                   for c in cells.split("|") if c.strip()]  # fmt: skip
        for data, at in ((study, 0), (held, 3)):
            name = label.replace("×", "x").replace("1.4e5", "1.4e+05")
            (point,) = [v for v in data["results"].values()
                        if v["setting"] == "sim" and v["label"] == name]  # fmt: skip
            for k, (side, key) in enumerate((("csdc", "vre"), ("biexp", "vre"), ("gap", "gap"))):
                key = f"{key}_body_mode1_pct"
                value = point[key] if side == "gap" else point[side][key]
                low, high = point["ci95"][side][key]  # the 95 % interval over the episodes
                assert figures[at + k] == pytest.approx([value, (high - low) / 2], abs=0.051)


def test_the_trip_groups_interval_is_its_json_and_called_level_with():
    data = json.loads((FIGURES / "learned_baselines-CapsuleTrip-v0.json").read_text())
    mpc = data["references_eval_wk_m_s2"]["mpc-biexp-meas"]
    row = data["statistics"]["residual-ppo-mpc"]
    low, high = (w / mpc for w in row["iqm_wk_ci95_m_s2"])
    assert low < 1.0 < high  # the interval over seeds includes parity
    page = " ".join((DOCS / "learned-baselines.md").read_text().split())
    assert f"0.995 x [{low:.3f}, {high:.3f}] the MPC" in page
    assert "level with the MPC" in page and "first learned group below" not in page


def test_a_policy_marked_shipped_is_the_shipped_seed():
    page = (DOCS / "fair-comparison.md").read_text()
    marked = re.findall(r"^\| (ppo-[a-z]+) \| (\d+) \(shipped\) \|", page, flags=re.M)
    assert marked  # ppo-measured, ppo-trip
    for name, seed in marked:
        meta = json.loads((ROOT / "capsule_env" / "pretrained" / f"{name}.json").read_text())
        assert meta["seed"] == int(seed), name


def test_the_mpcs_plan_time_is_the_benchmarks():
    bench = (DOCS / "benchmarks.md").read_text()
    median_ms = float(re.search(r"^\| `mpc-biexp-meas` \| ([\d.]+) \|", bench, flags=re.M)[1])
    controllers = " ".join((DOCS / "controllers.md").read_text().split())
    assert f"costs a median {median_ms:.2f} ms" in controllers


def test_the_shipped_seeds_episode_intervals_are_the_envelopes():
    # learned-baselines.md quotes the episode-only paired interval of two shipped policies
    # against the MPC, from the per-episode Wk that experiments/envelope.py stored
    import numpy as np

    from capsule_env.evaluation.rl_statistics import paired_ratio_interval

    points = json.loads((FIGURES / "envelope.json").read_text())["points"]
    page = " ".join((DOCS / "learned-baselines.md").read_text().split())
    for point, policy in (("trip", "residual-ppo-mpc-trip"), ("speed/fixed/810", "ppo-measured")):
        wk = points[point]["controllers"]
        est = paired_ratio_interval(np.array([wk[policy]["wk_per_episode_m_s2"]]),
                                    np.array(wk["mpc-biexp-meas"]["wk_per_episode_m_s2"]),
                                    resample="episodes")  # fmt: skip
        assert f"{est.value:.3f} x [{est.low:.3f}, {est.high:.3f}]" in page, policy


def test_the_groups_within_half_a_per_cent_are_the_jsons():
    # the page lists every group whose interval over the seeds, as a ratio to its task's best
    # law, includes 1 or lies within 0.5 % above it
    page = " ".join((DOCS / "learned-baselines.md").read_text().split())
    near = []
    for name in ("learned_baselines.json", "learned_baselines-CapsuleRidePreview-v0.json",
                 "learned_baselines-CapsuleTrip-v0.json"):  # fmt: skip
        data = json.loads((FIGURES / name).read_text())
        refs = data["references_eval_wk_m_s2"]
        law = min(data["laws"], key=lambda k: refs[k])
        for group, row in data["statistics"].items():
            low, high = (w / refs[law] for w in row["iqm_wk_ci95_m_s2"])
            assert high >= 1.0, (name, group)  # no group's interval lies below its law
            if low < 1.005:
                near.append((name, group, f"[{low:.3f}, {high:.3f}]"))
                assert f"[{low:.3f}, {high:.3f}]" in page, (name, group)
    assert len(near) == 8
