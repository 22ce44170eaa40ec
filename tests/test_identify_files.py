"""Identification from CSV and NumPy files (issue 17, section 4).

Synthetic loops of known damper models (:mod:`capsule_env.dampers`, run on the test rig
:func:`capsule_env.dampers.rig.simulate_damper`) are written the way users' files come (CSV
with a header, ``.npz`` with one file per current, a headerless ``.npy`` in other units), read
back and identified: the fitted parameters must be the model's own within a stated tolerance.
The derived velocity is checked against the analytic derivative of a sine, and every bad file
must give one error naming the file and the column.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest

from capsule_env.dampers import BiExponentialDamper, TanhDamper
from capsule_env.dampers.rig import simulate_damper, sinusoidal_stroke
from capsule_env.identification import (
    PlausibilityWarning,
    derive_velocity,
    identify_files,
    identify_measured,
    load_loops,
)
from capsule_env.identification import cli as identify
from capsule_env.identification.tabular import current_from_file_name, default_velocity_window

REPO = Path(__file__).resolve().parents[1]
CURRENTS = (0.0, 0.5, 1.0, 1.5)
FREQ_HZ, AMPLITUDE_M, CYCLES, PER_CYCLE = 1.0, 0.02, 3, 500


def _loop(damper, current):
    """Three cycles of a 1 Hz, +-20 mm sine stroke: (t, x, v, F) of the model at ``current``."""
    t, x, v = sinusoidal_stroke(FREQ_HZ, AMPLITUDE_M, CYCLES, PER_CYCLE)
    return t, x, v, simulate_damper(damper, t, x, v, current)["force_n"]


def _write_csv(path: Path, header: str, rows: np.ndarray) -> Path:
    lines = [header] + [",".join(repr(float(a)) for a in row) for row in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def _assert_params(fitted, true, rel: float) -> None:
    """Every identified field of ``fitted`` within ``rel`` of ``true`` (relative to the value,
    or to 1 for values below 1)."""
    for f in fields(true):
        a, b = getattr(true, f.name), getattr(fitted, f.name)
        assert abs(b - a) <= rel * max(abs(a), 1.0), (f.name, a, b)


# ------------------------------------------------------------------------------ recovery
@pytest.mark.parametrize(
    ("damper", "model"), [(BiExponentialDamper(), "bi_exponential"), (TanhDamper(), "tanh")]
)
def test_csv_with_velocity_and_current_columns_recovers_the_model(tmp_path, damper, model):
    # One CSV, four currents one after the other (time restarts at each), SI units.
    blocks = []
    for i in CURRENTS:
        t, x, v, force = _loop(damper, i)
        blocks.append(np.column_stack([t, x, v, force, np.full_like(t, i)]))
    path = _write_csv(tmp_path / "sweep.csv", "time,displacement,velocity,force,current",
                      np.vstack(blocks))  # fmt: skip
    with pytest.warns(PlausibilityWarning, match="synthetic"):  # noise-free: too good a fit
        result = identify_measured(path)
    assert sorted(lp.current_a for lp in result.loops) == list(CURRENTS)
    # Exact samples (printed at full precision): the model's own parameters to 1e-6.
    _assert_params(result.models[model].damper, damper, rel=1e-6)
    assert result.models[model].rmse_n < 1e-3 * result.peak_force_n


def test_npz_per_current_without_velocity_recovers_the_bi_exponential(tmp_path):
    # One .npz per current, the current in the file name (A and mA), displacement in mm and
    # no velocity: the Savitzky-Golay derivative stands in for it.
    true = BiExponentialDamper()
    paths = []
    for i, name in zip(CURRENTS, ("loop_0A", "loop_0.5A", "loop_1A", "loop_1500mA"), strict=True):
        t, x, _, force = _loop(true, i)
        paths.append(tmp_path / f"{name}.npz")
        np.savez(paths[-1], time_s=t, displacement_mm=x * 1e3, force=force)
    with pytest.warns(PlausibilityWarning, match="synthetic"):  # noise-free: too good a fit
        result = identify_files(paths)
    assert sorted(lp.current_a for lp in result.loops) == list(CURRENTS)
    # Stated tolerance with the derived velocity: 0.1 % (measured: about 1e-5).
    _assert_params(result.models["bi_exponential"].damper, true, rel=1e-3)
    # The CLI gives the same fit (JSON), the files given one by one.
    out = tmp_path / "fit.json"
    code = identify.main(["--data", *map(str, paths), "--together", "--json", str(out)])
    assert code == 0
    params = json.loads(out.read_text())["models"]["bi_exponential"]["params"]
    for f in fields(true):
        a = getattr(true, f.name)
        assert abs(params[f.name] - a) <= 1e-3 * max(abs(a), 1.0), f.name


def test_headerless_npy_with_columns_in_other_units(tmp_path):
    t, x, v, force = _loop(TanhDamper(), 0.75)
    temperature = 20.0 + 0.0 * t
    np.save(tmp_path / "rig.npy", np.column_stack([force / 1e3, t * 1e3, temperature, x * 1e3]))
    (loop,) = load_loops(tmp_path / "rig.npy", columns="force[kN],time (ms),skip,x_mm",
                         current_a=0.75)  # fmt: skip
    assert loop.current_a == 0.75 and loop.source == "rig.npy"
    np.testing.assert_allclose(loop.force_n, force, rtol=1e-12)
    np.testing.assert_allclose(loop.time_s, t, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(loop.stroke_m, x - x.mean(), rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(loop.stroke_rate_m_s, v, atol=1e-3 * np.abs(v).max())
    # the same from a CSV with a header of aliases and units, semicolons, comments
    lines = ["# rig export", "t [ms];stroke (mm);temperature;F [kN]"]
    lines += [f"{float(a) * 1e3!r};{float(b) * 1e3!r};20;{float(c) / 1e3!r}"
              for a, b, c in zip(t, x, force, strict=True)]  # fmt: skip
    (tmp_path / "rig.txt").write_text("\n".join(lines) + "\n")
    (same,) = load_loops(tmp_path / "rig.txt", current_a=0.75)
    np.testing.assert_allclose(same.force_n, loop.force_n, rtol=1e-12)
    np.testing.assert_allclose(same.stroke_rate_m_s, loop.stroke_rate_m_s, rtol=1e-9, atol=1e-12)


def test_force_offset_is_kept_unless_removed(tmp_path):
    t, x, v, force = _loop(BiExponentialDamper(), 0.5)
    path = _write_csv(tmp_path / "f.csv", "time,displacement,velocity,force",
                      np.column_stack([t, x, v, force + 150.0]))  # fmt: skip
    (kept,) = load_loops(path)
    np.testing.assert_allclose(kept.force_n, force + 150.0)
    (removed,) = load_loops(path, remove_force_offset=True)
    assert removed.force_offset_n == pytest.approx(np.mean(force) + 150.0)
    assert abs(np.mean(removed.force_n)) < 1e-9 * np.abs(force).max()


# ------------------------------------------------------------------------------ velocity
@pytest.mark.parametrize(("freq_hz", "rate_hz"), [(1.0, 1000.0), (2.0, 100.0), (0.8, 100.0)])
def test_derived_velocity_matches_the_analytic_derivative_of_a_sine(freq_hz, rate_hz):
    t = np.arange(int(3.5 * rate_hz / freq_hz)) / rate_hz
    w, amp, phase = 2 * np.pi * freq_hz, 0.012, 0.3
    x = amp * np.sin(w * t + phase)
    v = amp * w * np.cos(w * t + phase)
    window = default_velocity_window(x)
    assert window % 2 == 1 and window >= 5
    assert abs(window - rate_hz / freq_hz / 10) <= 1.0  # a tenth of the period
    err = np.abs(derive_velocity(t, x) - v) / (amp * w)
    half = window // 2
    assert err[half:-half].max() < 1e-4  # away from the ends
    assert err.max() < 5e-3  # the ends: polynomial fitted to the first or last window
    # the parameters are honoured: a short window with a quadratic is worse in the interior
    coarse = np.abs(derive_velocity(t, x, window=7, polyorder=2) - v) / (amp * w)
    assert coarse[3:-3].max() > err[half:-half].max()


def test_derived_velocity_averages_measurement_noise():
    # 1 kHz, 1 Hz sine with noise of 1e-3 of the amplitude: the default window (a tenth of the
    # period) keeps the RMS error within 5e-3 of the peak velocity; a two-point difference
    # amplifies the same noise to about 0.1.
    rate, amp = 1000.0, 0.012
    t = np.arange(3000) / rate
    x = amp * np.sin(2 * np.pi * t) + 1e-3 * amp * np.random.default_rng(0).standard_normal(3000)
    v = amp * 2 * np.pi * np.cos(2 * np.pi * t)
    rms = float(np.sqrt(np.mean((derive_velocity(t, x) - v) ** 2))) / (amp * 2 * np.pi)
    raw = float(np.sqrt(np.mean((np.gradient(x, t) - v) ** 2))) / (amp * 2 * np.pi)
    assert rms < 5e-3 and raw > 10 * rms


def test_derived_velocity_refuses_bad_windows_and_uneven_sampling():
    t = np.arange(200) * 0.01
    x = np.sin(t)
    for window, match in ((4, "odd"), (3, "> velocity_polyorder"), (201, "at most")):
        with pytest.raises(ValueError, match=f"velocity_window.*{match}"):
            derive_velocity(t, x, window=window)
    with pytest.raises(ValueError, match="velocity_polyorder"):
        derive_velocity(t, x, polyorder=0)
    t2 = t.copy()
    t2[100:] += 0.005
    with pytest.raises(ValueError, match="uniform sampling"):
        derive_velocity(t2, x)


def test_current_in_the_file_name():
    assert current_from_file_name("loop_0.75A.csv") == 0.75
    assert current_from_file_name("damper-750mA.npz") == pytest.approx(0.75)
    assert current_from_file_name("1A.csv") == 1.0
    assert current_from_file_name("ensaio.A.1.mat") is None
    assert current_from_file_name("run_2Amp.csv") is None  # "A" must end the number's word
    with pytest.raises(ValueError, match="2 currents"):
        current_from_file_name("loop_0.5A_to_1A.csv")


# ------------------------------------------------------------------------------ bad files
def _good_rows(n: int = 64) -> np.ndarray:
    t = np.arange(n) * 0.01
    return np.column_stack([t, 0.01 * np.sin(6 * t), 100 * np.cos(6 * t)])


BadFile = tuple[Path, dict, str, str]


def _bad_file(case: str, tmp: Path) -> BadFile:
    """``(path, load options, the column named, text of the error)`` of a bad file."""
    made = _bad_table(case, tmp, _good_rows()) or _bad_layout(case, tmp, _good_rows())
    if made is None:
        raise KeyError(case)
    return made


def _bad_table(case: str, tmp: Path, rows: np.ndarray) -> BadFile | None:
    """A CSV whose names or values are wrong (None: ``case`` is not one of these)."""
    header = "time,displacement,force"
    if case == "not a number":
        text = _write_csv(tmp / "a.csv", header, rows).read_text().splitlines()
        text[5] = "0.04,0.002,abc"
        (tmp / "a.csv").write_text("\n".join(text))
        return tmp / "a.csv", {}, "'force'", "line 6"
    if case == "no force column":
        return _write_csv(tmp / "b.csv", "time,displacement,load", rows), {}, "'force'", "no"
    if case == "NaN":
        rows[10, 1] = np.nan
        return _write_csv(tmp / "c.csv", "time,x [mm],force", rows), {}, "'x [mm]'", "NaN"
    if case == "unknown unit":
        return _write_csv(tmp / "d.csv", "time,displacement [in],force", rows), {}, "'displacement [in]'", "unit"  # fmt: skip
    if case == "time goes back":
        rows[20:, 0] -= 0.5
        return _write_csv(tmp / "e.csv", header, rows), {}, "'time'", "does not increase"
    if case == "constant force":
        rows[:, 2] = 5.0
        return _write_csv(tmp / "m.csv", header, rows), {}, "'force'", "constant"
    return None


def _bad_layout(case: str, tmp: Path, rows: np.ndarray) -> BadFile | None:
    """A file whose columns, sampling, current or lines are wrong (None: ``case`` is not one
    of these)."""
    header = "time,displacement,force"
    if case == "no names":
        np.save(tmp / "f.npy", rows)
        return tmp / "f.npy", {}, "--columns", "no column names"
    if case == "columns count":
        np.save(tmp / "g.npy", rows)
        return tmp / "g.npy", {"columns": "time,displacement"}, "columns", "the file has 3"
    if case == "two displacements":
        return _write_csv(tmp / "h.csv", "time,x,stroke", rows), {}, "'stroke'", "both"
    if case == "uneven time, no velocity":
        rows[30:, 0] += 0.003
        return _write_csv(tmp / "i.csv", header, rows), {}, "'time'", "uniform sampling"
    if case == "current run too short":
        cur = np.where(np.arange(64) < 60, 0.5, 1.0)[:, None]
        path = _write_csv(tmp / "j.csv", header + ",current", np.hstack([rows, cur]))
        return path, {}, "'current'", "run of 4 samples"
    if case == "current twice":
        path = _write_csv(tmp / "k.csv", header + ",current", np.hstack([rows, rows[:, :1] * 0]))
        return path, {"current_a": 1.0}, "'current'", "do not also give"
    if case == "mixed npz":
        np.savez(tmp / "l.npz", time=rows[:, 0], data=rows)
        return tmp / "l.npz", {}, "'time'", "shapes"
    if case == "ragged line":
        (tmp / "n.csv").write_text(header + "\n0,1,2\n0.1,1\n")
        return tmp / "n.csv", {}, "line 3", "2 fields"
    return None


BAD_CASES = [
    "not a number", "no force column", "NaN", "unknown unit", "time goes back", "no names",
    "columns count", "two displacements", "uneven time, no velocity", "current run too short",
    "current twice", "mixed npz", "constant force", "ragged line",
]  # fmt: skip


@pytest.mark.parametrize("case", BAD_CASES)
def test_bad_files_raise_one_error_naming_file_and_column(case, tmp_path):
    path, options, column, text = _bad_file(case, tmp_path)
    with pytest.raises(ValueError) as err:
        load_loops(path, **options)
    message = str(err.value)
    assert str(path) in message and column in message and text in message, message
    assert "\n" not in message


@pytest.mark.parametrize("case", ["not a number", "NaN", "columns count", "current twice"])
def test_cli_bad_files_exit_2_with_one_line(case, tmp_path, capsys):
    path, options, column, text = _bad_file(case, tmp_path)
    argv = ["--data", str(path)]
    if "columns" in options:
        argv += ["--columns", options["columns"]]
    if "current_a" in options:
        argv += ["--current", str(options["current_a"])]
    assert identify.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(
        "python -m capsule_env.identification.cli: error:"
    )
    assert str(path) in err and column in err and text in err


def test_cli_process_reads_a_folder_and_fails_cleanly(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               MPLBACKEND="Agg")  # fmt: skip

    def run(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "capsule_env.identification.cli", *args], cwd=tmp_path,
                              env=env, capture_output=True, text=True, timeout=300)  # fmt: skip

    folder = tmp_path / "loops"
    folder.mkdir()
    for i in (0.0, 1.0):
        t, x, v, force = _loop(BiExponentialDamper(), i)
        _write_csv(folder / f"loop_{i:g}A.csv", "time,displacement,force",
                   np.column_stack([t, x, force]))  # fmt: skip
    (folder / "notes.md").write_text("not data")
    out = run("--data", "loops", "--json", "fit.json")
    assert out.returncode == 0, out.stderr
    files = json.loads((tmp_path / "fit.json").read_text())["files"]
    assert sorted(files) == ["loop_0A.csv", "loop_1A.csv"]
    assert files["loop_1A.csv"]["rmse_current_a"] == 1.0
    bad = _write_csv(tmp_path / "bad.csv", "time,displacement,force", _good_rows()[:10])
    out = run("--data", str(bad))
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert out.stderr.count("\n") == 1 and "bad.csv" in out.stderr and "16" in out.stderr
    out = run("--columns", "time,force")  # file options need --data
    assert out.returncode == 2 and "--columns" in out.stderr and "--data" in out.stderr
    out = run("--data", "loops", "--velocity-window", "4")
    assert out.returncode == 2 and "--velocity-window" in out.stderr and "odd" in out.stderr
