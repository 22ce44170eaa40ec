"""The one table of observable signals reproduces the hand-written layout it replaced.

Every expectation below is written out by hand (the column order, bounds and noise channels
the env had before the table existed, issue 26 item 2): the table must generate exactly them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from capsule_env.engine import layout, observations
from capsule_env.engine.config import (
    FULL_STATE_NAMES,
    MEASURED_NAMES,
    SENSOR_NAMES,
    SENSOR_NOISE_STD,
    EnvConfig,
    observation_bounds,
)
from capsule_env.engine.observations_docs import docs_tables, main, sync_docs

ROOT = Path(__file__).resolve().parents[1]

SENSORS = (
    "car_body_acceleration_m_s2",
    "bogie_acceleration_m_s2",
    "stroke_m",
    "stroke_rate_m_s",
    "last_current_command_a",
)
FULL_STATE = (
    "car_body_displacement_m",
    "car_body_velocity_m_s",
    "bogie_displacement_m",
    "bogie_velocity_m_s",
    "guideway_elevation_m",
    "car_body_acceleration_m_s2",
    "bogie_acceleration_m_s2",
    "stroke_m",
    "stroke_rate_m_s",
    "coil_current_a",
)
MEASURED = (
    "car_body_acceleration_m_s2",
    "bogie_acceleration_m_s2",
    "stroke_m",
    "stroke_rate_m_s",
    "levitation_gap_m",
    "coil_current_a",
    "last_current_command_a",
    "car_body_velocity_estimate_m_s",
    "bogie_velocity_estimate_m_s",
)
NOISE = (
    ("car_body_acceleration_m_s2", 0.02),
    ("bogie_acceleration_m_s2", 0.1),
    ("stroke_m", 1e-4),
    ("stroke_rate_m_s", 2e-3),
    ("car_body_displacement_m", 1e-4),
    ("car_body_velocity_m_s", 2e-3),
    ("bogie_displacement_m", 1e-4),
    ("bogie_velocity_m_s", 2e-3),
    ("guideway_elevation_m", 1e-4),
    ("levitation_gap_m", 1e-4),
    ("coil_current_a", 0.01),
)


def test_names_of_every_set():
    assert SENSOR_NAMES == SENSORS
    assert FULL_STATE_NAMES == FULL_STATE
    assert MEASURED_NAMES == MEASURED
    assert observations.OBSERVATION_NAMES == {
        "sensors": SENSORS,
        "full_state": FULL_STATE,
        "measured": MEASURED,
    }
    assert layout.MEASUREMENT_NAMES == SENSORS  # the inverse's and estimators' readings


def test_noise_channels_by_name():
    assert layout.NOISE_CHANNEL_NAMES == tuple(name for name, _ in NOISE)
    np.testing.assert_array_equal(SENSOR_NOISE_STD, [std for _, std in NOISE])
    # each set's columns read the channel of their own name, or none
    expected = {
        "sensors": [0, 1, 2, 3, -1],
        "full_state": [4, 5, 6, 7, 8, 0, 1, 2, 3, -1],
        "measured": [0, 1, 2, 3, 9, 10, -1, -1, -1],
    }
    for name, channels in expected.items():
        assert observations.COLUMN_NOISE[name].tolist() == channels
    # what the kernel draws (the measurements' channels included)
    assert observations.noise_channels_read("sensors") == (0, 1, 2, 3)
    assert observations.noise_channels_read("full_state") == tuple(range(9))
    assert observations.noise_channels_read("measured") == (0, 1, 2, 3, 9, 10)


@pytest.mark.parametrize("stroke_limit_m, i_max", [(0.06, 1.5), (0.03, 2.0)])
def test_bounds_as_written_before(stroke_limit_m, i_max):
    x = 2.0 * stroke_limit_m
    expected = {
        "sensors": ([-100, -100, -x, -10, 0], [100, 100, x, 10, i_max]),
        "full_state": (
            [-1, -10, -1, -10, -1, -100, -100, -x, -10, 0],
            [1, 10, 1, 10, 1, 100, 100, x, 10, i_max],
        ),
        "measured": (
            [-100, -100, -x, -10, -1, -0.5, 0, -10, -10],
            [100, 100, x, 10, 1, i_max + 0.5, i_max, 10, 10],
        ),
    }
    for name, (low, high) in expected.items():
        cfg = EnvConfig(observation=name, stroke_limit_m=stroke_limit_m, preview_points=2)
        got_low, got_high = observation_bounds(cfg, i_max)
        np.testing.assert_array_equal(got_low, np.float32([*low, -1, -1]))
        np.testing.assert_array_equal(got_high, np.float32([*high, 1, 1]))


def test_column_map_reads_the_right_quantity():
    q = observations.QUANTITY_NAMES
    for name, columns in observations.OBSERVATION_NAMES.items():
        # every column so far reads the quantity of its own name
        assert [q[k] for k in observations.COLUMN_SOURCES[name]] == list(columns)
    assert [q[k] for k in observations.MEASUREMENT_SOURCES] == list(SENSORS)
    assert observations.MEASUREMENT_NOISE.tolist() == [0, 1, 2, 3, -1]


def test_rest_observation():
    np.testing.assert_array_equal(
        observations.rest_observation("full_state", 0.004),
        [0.004, 0, 0.004, 0, 0.004, 0, 0, 0, 0, 0],
    )
    np.testing.assert_array_equal(observations.rest_observation("measured", 0.004), np.zeros(9))


def test_unknown_set_names_the_choices():
    with pytest.raises(ValueError, match="observation must be one of"):
        observations.observables("camera")


def test_docs_in_sync():
    text = (ROOT / "docs" / "env.md").read_text(encoding="utf-8")
    assert sync_docs(text) == text, (
        "run: python -m capsule_env.engine.observations_docs docs/env.md"
    )
    for key in docs_tables():  # every generated table is in the docs
        assert f"<!-- generated: {key} -->" in text


def test_docs_rewrite(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("a\n<!-- generated: observations sensors -->\nold\n<!-- /generated -->\nb\n")
    assert main([str(page)]) == 0
    text = page.read_text()
    assert "old" not in text and "| 4 | `last_current_command_a` |" in text
    assert text.startswith("a\n") and text.endswith("<!-- /generated -->\nb\n")
    page.write_text("<!-- generated: nothing -->\nx\n<!-- /generated -->\n")
    assert main([str(page)]) == 1  # an unknown key: one line on stderr, no traceback


def test_trip_and_preview_columns_are_declared_in_the_table_module():
    """Issue 41: the trip's and the preview's columns come from observations.py, and the kernels'
    offsets point at their names."""
    from capsule_env.engine.config import EnvConfig, observation_bounds
    from capsule_env.engine.env_params import EnvParams
    from capsule_env.engine.observations import TRIP_COLUMN_NAMES, columns, first_column

    config = EnvConfig(setting="hils", observation="measured", speed_profile="trip",
                       preview_points=3)  # fmt: skip
    names = config.observation_names
    assert names == columns("measured", trip=True, preview_points=3)
    trip = first_column("measured", "trip", True, 3)
    preview = first_column("measured", "preview", True, 3)
    assert names[trip : trip + 2] == TRIP_COLUMN_NAMES
    assert names[preview:] == ("preview_ahead_1", "preview_ahead_2", "preview_ahead_3")
    assert preview == len(names) - 3  # the env kernel writes the preview as the last columns
    assert EnvParams.from_config(config).trip_column == trip
    low, high = observation_bounds(config, 1.0)
    assert low.shape == high.shape == (len(names),)
    assert high[trip] == np.float32(2000.0 / 3.6) and high[preview] == 1.0
    assert first_column("measured", "trip", False, 0) == -1
    with pytest.raises(ValueError, match="group must be"):
        first_column("measured", "speed", True, 0)


def test_speed_conversions_go_through_units():
    """Issue 41: km/h <-> m/s only in capsule_env/common/units.py (no literal 3.6 in arithmetic)."""
    import ast
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    found = []
    for path in [*(root / "capsule_env").rglob("*.py"), *(root / "agents").rglob("*.py")]:
        if path.name == "units.py":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.BinOp) and any(
                isinstance(side, ast.Constant) and side.value == 3.6
                for side in (node.left, node.right)
            ):
                found.append(f"{path.relative_to(root)}:{node.lineno}")
    assert not found, found
