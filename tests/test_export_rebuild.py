"""``rebuild_base_law`` on a contract a rig has edited: one clear ``ValueError`` naming the
entry, never another exception nor a check silently skipped."""

from __future__ import annotations

import json

import pytest

from conftest import NO_SB3

pytest.importorskip("stable_baselines3", reason=NO_SB3)

from capsule_env.export import export_policy  # noqa: E402
from capsule_env.export.base_law import rebuild_base_law  # noqa: E402

NAME = "residual-ppo-mpc"


@pytest.fixture(scope="module")
def block(tmp_path_factory) -> dict:
    files = export_policy(NAME, tmp_path_factory.mktemp("exported"), "c")
    return json.loads(files[f"{NAME}.contract.json"].read_text())["residual"]["base_law"]


@pytest.mark.parametrize("value", [3, "bi_exponential", [1], None])
def test_an_inverse_model_that_is_not_an_object_is_refused(value, block):
    """The installation's inverse model is checked against ``inverse_model.name`` and
    ``.parameters``: an entry that is not a JSON object cannot hold them (3 raised a TypeError,
    a string or a list skipped the check and rebuilt the law)."""
    tampered = json.loads(json.dumps(block)) | {"inverse_model": value}
    with pytest.raises(ValueError, match=r"base_law\.inverse_model must be a JSON object"):
        rebuild_base_law(tampered)


def test_the_untampered_block_rebuilds(block):
    assert type(rebuild_base_law(json.loads(json.dumps(block)))).__name__ == "MPCController"


def test_a_law_in_the_c_file_is_not_rebuilt_but_named(tmp_path):
    """A residual on a law with a C form has ``constructor`` null: the law is the C file's
    ``capsule_law``. Rebuilding it says so (it said the block lacked a constructor object, as
    for a broken contract)."""
    from conftest import residual_copy

    zip_path = residual_copy(tmp_path, NAME, "lqr-clipped-biexp-meas", "res-lqr")
    files = export_policy(str(zip_path), tmp_path / "out", "c")
    card = json.loads(files["res-lqr.contract.json"].read_text())
    with pytest.raises(ValueError, match=r"in_c_file.*capsule_law"):
        rebuild_base_law(card["residual"]["base_law"])


def test_every_block_lists_the_columns_it_reads_as_index_and_name(block, tmp_path):
    """``reads.columns`` has one form in every contract: the quarter-car MPC's ``{index,
    name}`` (the half-car MPC's were bare names), each the observation's column at that index."""
    half = export_policy("residual-ppo-mpc-half-car", tmp_path, "c")
    half_card = json.loads(half["residual-ppo-mpc-half-car.contract.json"].read_text())
    names = [c["name"] for c in half_card["observation"]["columns"]]
    columns = half_card["residual"]["base_law"]["reads"]["columns"]
    assert [c["index"] for c in columns] == list(range(16))
    assert all(names[c["index"]] == c["name"] for c in columns)
    assert all(set(c) == {"index", "name"} for c in block["reads"]["columns"])


@pytest.mark.parametrize("force_n", [0.0, -8000.0])
def test_a_contract_with_a_force_scale_out_of_range_is_refused(force_n, block, tmp_path):
    """``max_force_n`` must be > 0 N: the quarter-car MPC rebuilt with 0 gave a NaN action and
    with -8000 one of +1 (full force); the per-bogie LQR divided by it alike."""
    from conftest import residual_copy

    tampered = json.loads(json.dumps(block))
    tampered["constructor"]["max_force_n"] = force_n
    with pytest.raises(ValueError, match="max_force_n"):
        rebuild_base_law(tampered)
    zip_path = residual_copy(tmp_path, "residual-ppo-mpc-half-car", "lqr-clipped-biexp-meas", "r")
    files = export_policy(str(zip_path), tmp_path / "out", "c")
    lqr = json.loads(files["r.contract.json"].read_text())["residual"]["base_law"]
    lqr["constructor"]["max_force_n"] = force_n
    with pytest.raises(ValueError, match="max_force_n"):
        rebuild_base_law(lqr)
