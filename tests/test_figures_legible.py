"""The documentation's figures are legible at the width the docs show them.

furo draws an image at most as wide as its content column: 736 px in a 1280 px window (46em
less its padding, measured in chromium; 810 px at 1920 px, less on narrow screens), so a
figure of ``w`` px is scaled by ``min(1, 736 / w)``. Each figure below is drawn by the code
that makes the docs' PNG, from the JSON beside that PNG where there is one, and every text
drawn in it (tick labels, axis labels, titles, legends) must be at least ``MIN_TEXT_PX`` tall
at that scale, and lie inside the figure (a legend that runs off the canvas is cut).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from conftest import load_script

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.text import Text  # noqa: E402
from PIL import Image  # noqa: E402  (a matplotlib dependency)

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "docs" / "figures"
#: The width (px) of furo's content column in a 1280 px window: the docs' figure width.
DISPLAY_PX = 736
#: The smallest text height (font size, px) allowed at that width: about 7.5 pt on a 96 dpi
#: screen, the size of a small legend entry (the body text is 16 px, the tables 12-13 px).
MIN_TEXT_PX = 10.0


@pytest.fixture
def drawn(monkeypatch):
    """Every ``savefig`` call: the saved path, and each text drawn into that file with its
    font size (pt) and whether its box lies on the canvas (taken as it is drawn, at the
    saving dpi)."""
    saved: list[tuple[Path, list[tuple[str, float, bool]]]] = []
    texts: list[tuple[str, float, bool]] = []
    original_draw, original_save = Text.draw, Figure.savefig

    def draw(self, renderer):
        original_draw(self, renderer)
        if self.get_visible() and self.get_text().strip():
            box, canvas = self.get_window_extent(renderer), self.get_figure(root=True).bbox
            inside = (box.x0 >= -1 and box.y0 >= -1 and box.x1 <= canvas.x1 + 1
                      and box.y1 <= canvas.y1 + 1)  # fmt: skip
            texts.append((self.get_text(), self.get_fontsize(), inside))

    def savefig(self, fname, *args, **kwargs):
        texts.clear()
        original_save(self, fname, *args, **kwargs)
        path = Path(fname)  # a staged save's temporary name (safe_io): the target's
        staged = re.fullmatch(r"\.(.+)\.[0-9a-f]{8}\.tmp", path.name)
        saved.append((path.with_name(staged.group(1)) if staged else path, list(texts)))

    monkeypatch.setattr(Text, "draw", draw)
    monkeypatch.setattr(Figure, "savefig", savefig)
    return saved


def problems(path: Path, texts: list[tuple[str, float, bool]]) -> list[str]:
    """What is illegible in the saved ``path``: texts under ``MIN_TEXT_PX`` at the docs'
    width, texts outside the canvas."""
    with Image.open(path) as image:
        width_px, dpi = image.size[0], image.info["dpi"][0]
    px_per_pt = dpi / 72.0 * min(1.0, DISPLAY_PX / width_px)
    out = []
    for text, size_pt, inside in texts:
        if size_pt * px_per_pt < MIN_TEXT_PX:
            out.append(f"{text[:40]!r}: {size_pt * px_per_pt:.1f} px")
        if not inside:
            out.append(f"{text[:40]!r}: outside the figure")
    return out


def assert_legible(saved: list[tuple[Path, list[tuple[str, float, bool]]]], expected: int) -> None:
    assert len(saved) == expected
    for path, texts in saved:
        assert texts, path
        found = problems(path, texts)
        assert not found, f"{path.name}: {len(found)} problems, e.g. {found[:6]}"


def fake_rollout(n_steps: int, action_mode: str, rng: np.random.Generator) -> SimpleNamespace:
    """What :func:`capsule_env.plots.evaluation_figures` reads of a rollout (2 episodes)."""
    keys = ("car_body_displacement_m", "bogie_displacement_m", "stroke_rate_m_s",
            "damper_force_n", "desired_force_n")  # fmt: skip
    signals = {k: 1e-3 * rng.standard_normal((2, n_steps)) for k in keys}
    signals["damper_force_n"] *= 1e6
    signals["desired_force_n"] *= 1e6
    return SimpleNamespace(signals=signals, dt_s=0.005, action_mode=action_mode)


def test_evaluation_figures(drawn, tmp_path):
    """Time histories, spectra and the force-velocity loops of the paper's three controllers
    and the three shipped policies (five loop panels), in both settings."""
    from capsule_env.plots import evaluation_figures

    rng = np.random.default_rng(0)
    names = ("passive", "skyhook-csdc", "skyhook-biexp", "ppo-hils", "ppo-measured",
             "ppo-preview")  # fmt: skip
    rollouts = {(s, n): fake_rollout(2000, "force" if n != "passive" else "current", rng)
                for s in ("sim", "hils") for n in names}  # fmt: skip
    written = evaluation_figures(rollouts, tmp_path)
    assert len(written) == 6
    assert_legible(drawn, 6)


def test_pareto_figure_from_its_json(drawn, tmp_path):
    pareto = load_script("experiments/pareto.py")
    out = tmp_path / "pareto.png"
    assert pareto.main(["--from-json", str(FIGURES / "pareto.json"), "--out", str(out)]) == 0
    assert_legible(drawn, 1)


def test_learning_curve_from_its_json(drawn, tmp_path):
    lc = load_script("experiments/learning_curve.py")
    out = tmp_path / "lc.png"
    assert lc.main(["--from-json", str(FIGURES / "learning_curve.json"), "--out", str(out)]) == 0
    assert_legible(drawn, 1)


@pytest.mark.parametrize("task", ["", "-CapsuleRidePreview-v0", "-CapsuleTrip-v0"])
def test_learned_baselines_from_its_json(drawn, tmp_path, task):
    lb = load_script("experiments/learned_baselines.py")
    data, out = FIGURES / f"learned_baselines{task}.json", tmp_path / "lb.png"
    assert lb.main(["--from-json", str(data), "--plot", str(out)]) == 0
    assert_legible(drawn, 1)


def test_envelope_figures(drawn, tmp_path):
    from capsule_env.envelope.report import figures

    written = figures(json.loads((FIGURES / "envelope.json").read_text()), tmp_path)
    assert [p.name for p in written] == ["envelope_speed.png", "envelope_span_psd.png"]
    assert_legible(drawn, 2)


def test_paper_sensitivity_figure(drawn, tmp_path):
    from capsule_env.sensitivity.runner import plot_tornado

    results = json.loads((FIGURES / "paper_sensitivity.json").read_text())["results"]
    plot_tornado(list(results.values()), tmp_path / "tornado.png")
    assert_legible(drawn, 1)


# ---- redrawing from the JSON: cheap, and a bad file is one line --------------------------------
def test_pareto_from_json_refuses_a_bad_file_in_one_line(tmp_path, capsys):
    pareto = load_script("experiments/pareto.py")
    out = tmp_path / "new" / "pareto.png"
    not_ours = tmp_path / "list.json"
    not_ours.write_text("[1, 2]")
    for source, words in ((tmp_path / "absent.json", "No such file"),
                          (not_ours, "not a JSON this script wrote")):  # fmt: skip
        with pytest.raises(SystemExit, match=f"--from-json .*{words}"):
            pareto.main(["--from-json", str(source), "--out", str(out)])
    assert not out.parent.exists()


def test_learned_baselines_from_json_draws_the_same_curves(tmp_path, monkeypatch):
    """The redraw plots the JSON's IQM curves (every group, against env steps), and needs
    neither run folders nor --json."""
    lb = load_script("experiments/learned_baselines.py")
    data = json.loads((FIGURES / "learned_baselines.json").read_text())
    plotted: dict[str, list[float]] = {}
    import matplotlib.axes

    original = matplotlib.axes.Axes.plot

    def plot(self, x, y, *args, **kwargs):
        if kwargs.get("label") and self.get_subplotspec().colspan.start == 0:
            plotted[kwargs["label"]] = list(y)
        return original(self, x, y, *args, **kwargs)

    monkeypatch.setattr(matplotlib.axes.Axes, "plot", plot)
    assert lb.main(["--from-json", str(FIGURES / "learned_baselines.json"),
                    "--plot", str(tmp_path / "lb.png")]) == 0  # fmt: skip
    assert plotted == {g: c["iqm"] for g, c in data["curves"].items()}


def test_learned_baselines_bad_redraws_are_one_line(tmp_path, capsys):
    lb = load_script("experiments/learned_baselines.py")
    out = tmp_path / "lb.png"
    assert lb.main(["--from-json", str(tmp_path / "absent.json"), "--plot", str(out)]) == 2
    assert "--from-json" in capsys.readouterr().err
    assert lb.main(["--from-json", str(FIGURES / "learned_baselines.json")]) == 2
    assert "needs --plot" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        lb.main(["--plot", str(out)])  # neither runs nor a JSON
    assert exit_.value.code == 2 and "--group and --json are required" in capsys.readouterr().err
    assert not out.exists()


def test_half_car_figure_from_its_json(drawn, tmp_path):
    from capsule_env.evaluation.half_car_figure import half_car_figure

    result = json.loads((FIGURES / "evaluation-CapsuleHalfRide-v0.json").read_text())
    t = 0.005 * np.arange(1, 801)
    trace = {"time_s": t, "passive": np.sin(9 * t), "LQR per bogie": 0.8 * np.sin(9 * t)}
    half_car_figure(result, trace, tmp_path / "half_car.png")
    assert_legible(drawn, 1)
