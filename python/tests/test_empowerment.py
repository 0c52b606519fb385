"""Exact empowerment from Python against the command line's JSON and hand counts."""

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

import fulcrum
from fulcrum import empowerment


def cli(fulcrum_bin, *args):
    out = subprocess.run(
        [fulcrum_bin, "empowerment", *args, "--json"],
        check=True,
        capture_output=True,
        text=True,
    )
    return json.loads(out.stdout)


@pytest.mark.parametrize(
    "world,extra",
    [
        ("exp1-tree", []),
        ("exp1-wall", ["--horizon", "4"]),
        ("exp3", ["--joint", "boulder+door"]),
        ("exp3", ["--horizon-equipped", "5"]),
    ],
)
def test_matrix_equals_the_cli(fulcrum_bin, world, extra):
    want = cli(fulcrum_bin, "matrix", world, *extra)
    kw = {}
    if "--horizon" in extra:
        kw["horizon"] = int(extra[extra.index("--horizon") + 1])
    if "--horizon-equipped" in extra:
        kw["horizon_equipped"] = int(extra[extra.index("--horizon-equipped") + 1])
    if "--joint" in extra:
        kw["joint"] = [extra[extra.index("--joint") + 1]]
    got = empowerment.matrix(world, **kw)
    for key in ("world", "states", "normal_states", "tools", "columns", "selection"):
        assert got[key] == want[key], key
    assert got["horizon_unequipped"] == want["horizon_unequipped"]
    assert got["horizon_equipped"] == want["horizon_equipped"]
    assert got["matrix"].shape == (len(want["tools"]), len(want["columns"]))
    assert np.array_equal(got["matrix"], np.array(want["matrix"]))


def test_matrix_of_exp1_tree_is_the_recorded_one():
    # The entries recorded for exp1-tree (h_u 8, h_e 3): axe -> tree 0.046784 bits,
    # pickaxe -> wall 0.035088, every other 0; the selection axe for the tree.
    m = empowerment.matrix("exp1-tree", horizon_unequipped=8, horizon_equipped=3)
    assert m["matrix"][0, 0] == pytest.approx(0.046784, abs=5e-7)
    assert m["matrix"][1, 1] == pytest.approx(0.035088, abs=5e-7)
    assert m["matrix"][2:].sum() == 0.0
    assert m["selection"] == {"tree": "axe", "wall": "pickaxe"}


@pytest.mark.parametrize(
    "world,args",
    [
        ("exp1-tree", ["--tool", "axe", "--holding", "axe"]),
        ("exp1-tree", ["--tool", "axe"]),
        ("exp2", ["--objects", "boulder", "--tool", "wand", "--holding", "wand"]),
    ],
)
def test_landscape_equals_the_cli(fulcrum_bin, world, args):
    want = cli(fulcrum_bin, "landscape", world, *args)
    kw = dict(zip([a.lstrip("-") for a in args[::2]], args[1::2]))
    got = empowerment.landscape(world, **kw)
    assert got["values"].shape == (want["height"], want["width"])
    expected = np.array(
        [[np.nan if v is None else v for v in row] for row in want["values"]]
    )
    assert np.array_equal(got["values"], expected, equal_nan=True)
    for key in ("tool", "objects", "horizon", "holding"):
        assert got[key] == want[key], key


def test_trace_equals_the_cli_and_the_hand_count(fulcrum_bin):
    actions = "N,N,E,E,E,E,E,E,E,apply,axe,E"
    want = cli(fulcrum_bin, "trace", "exp1-tree", "--actions", actions)
    got = empowerment.trace("exp1-tree", actions.split(","))
    assert [s["state"] for s in got["steps"]] == [s["state"] for s in want["steps"]]
    assert got["values"].tolist() == [s["value"] for s in want["steps"]]
    # By hand (axe -> tree, h_u 8 without the axe, h_e 3 with it): 1 bit where the
    # tree can be felled within the horizon: at (3,2) (1 step to the axe, 4 to the
    # tree, 3 to strike = 8), at (8,2) holding it (3), and at the two prompts.
    assert got["values"].tolist() == [0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 1, 1, 0]


def test_a_boulder_by_its_condition_against_the_hand_count():
    # The boulder room (agent (1,1), pickaxe (3,1), boulder (3,2)), h = 3 along E, E: by
    # its condition the boulder can be destroyed only from (3,1) with the pickaxe held
    # (apply, pickaxe, S); by its cell it has 5 outcomes there (tests/cli/mod.rs).
    world = str(Path(__file__).resolve().parents[2] / "tests" / "worlds" / "boulder-room.toml")
    got = empowerment.trace(world, ["E", "E"], objects="conditions:boulder", horizon=3)
    assert got["objects"] == ["conditions:boulder"]
    assert got["values"].tolist() == [0, 0, 1]
    full = empowerment.trace(world, ["E", "E"], objects="boulder", horizon=3)
    assert full["objects"] == ["boulder"]
    assert full["values"][2] == pytest.approx(np.log2(5))


def test_value_at_states_and_the_cli_query(fulcrum_bin):
    w = fulcrum.World("exp1-tree")
    s = "agent=8,2 holding=axe mode=normal tree=intact wall=intact"
    assert empowerment.value(w, s) == 1.0
    assert empowerment.value(w, w.pack(s)) == 1.0
    want = cli(fulcrum_bin, "query", "exp1-tree", "--state", s, "--horizon", "2")
    assert empowerment.value(w, s, horizon=2) == want["value"] == 0.0
    many = empowerment.value(w, [s, "agent=7,2 holding=axe mode=normal"])
    assert many.tolist() == [1.0, 0.0]
    # The reference method agrees.
    assert empowerment.value(w, s, method="enumerate") == 1.0
