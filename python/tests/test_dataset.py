"""Datasets of exact empowerment and their scoring, against the command line's
`empowerment query` and `matrix`, the world's own step, the environment's observation
and hand counts."""

import csv
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

import fulcrum
from fulcrum import empowerment

NO_ACTION = 255


def query_cli(fulcrum_bin, tmp_path, world, states, extra):
    """E at each packed state, by `fulcrum empowerment query --states-file`."""
    w = fulcrum.World(world)
    f = tmp_path / "states.txt"
    f.write_text("".join(w.describe(bytes(s)) + "\n" for s in states))
    out = subprocess.run(
        [fulcrum_bin, "empowerment", "query", world, "--states-file", str(f), "--json", *extra],
        check=True,
        capture_output=True,
        text=True,
    )
    values = json.loads(out.stdout)["values"]
    return np.array([v["value"] for v in values]), np.array([v["gap_bits"] for v in values])


@pytest.mark.parametrize(
    "world,kw,extra",
    [
        ("exp1-tree", {}, []),
        ("exp1-tree", {"objects": "agent", "tool": "axe", "horizon": 3}, ["--objects", "agent", "--tool", "axe", "--horizon", "3"]),
        ("exp2", {"states": "sample:400", "seed": 3}, []),
        ("exp1-tree-slip", {"states": "sample:40", "seed": 2, "objects": "agent", "tool": "axe", "horizon": 2}, ["--objects", "agent", "--tool", "axe", "--horizon", "2"]),
        ("exp3", {"states": "sample:300", "objects": "boulder+door", "tool": "axe"}, ["--objects", "boulder+door", "--tool", "axe"]),
    ],
)
def test_E_equals_query_at_every_state(fulcrum_bin, tmp_path, world, kw, extra):
    d = empowerment.dataset(world, sequences=1, **kw)
    want, gap = query_cli(fulcrum_bin, tmp_path, world, d["state"], extra)
    assert len(want) == len(d["E"])
    np.testing.assert_array_equal(d["E"], want)
    np.testing.assert_array_equal(d["gap"], gap)
    assert d["E"].max() > 0


@pytest.mark.parametrize(
    "world,objects,tool,horizon",
    [("exp1-tree", "tree", "axe", 3), ("exp1-tree", "tree", "axe", None), ("exp3", "boulder", "axe", 4)],
)
def test_normal_mean_is_the_matrix_entry(world, objects, tool, horizon):
    d = empowerment.dataset(world, tool=tool, objects=objects, horizon=horizon, sequences=0)
    if horizon is None:
        # The dataset's E takes the world's horizons by what is held (exp1-tree's 8 and
        # 3): the matrix whose rows switch horizon, not the selection's one horizon.
        m = empowerment.matrix(world, objects=objects, horizon_unequipped=8, horizon_equipped=3)
    else:
        m = empowerment.matrix(world, objects=objects, horizon=horizon)
    entry = m["matrix"][m["tools"].index(tool), m["columns"].index(objects)]
    assert d["normal"].sum() == m["normal_states"]
    assert d["E"][d["normal"]].mean() == pytest.approx(entry, abs=1e-12)
    assert entry > 0


def test_sequences_replay_with_the_worlds_step():
    w = fulcrum.World("exp3")
    d = empowerment.dataset(w, objects="boulder+door", tool="axe", states="sample:60", sequences=8, seed=5)
    assert len(d["seq_row"]) == 60 * 8
    assert list(np.bincount(d["seq_row"])) == [8] * 60
    names = d["objects"]
    seen = {}
    for k in range(len(d["seq_row"])):
        r = d["seq_row"][k]
        s = bytes(d["state"][r])
        acts = d["seq_actions"][k]
        h = d["horizon"][r]
        assert (acts[h:] == NO_ACTION).all() and (acts[:h] != NO_ACTION).all()
        assert set(acts[:h].tolist()) <= set(d["tool_actions"].tolist())
        for a in acts[:h]:
            s = w.step(s, int(a))
        assert s == bytes(d["seq_final_state"][k])
        # The projection id names exactly the objects' part of the final state.
        part = tuple(t for t in w.describe(s).split() if t.split("=")[0] in names)
        assert seen.setdefault(int(d["seq_proj"][k]), part) == part
    assert len(set(seen.values())) == len(seen) == len(d["proj_key"])
    # Uniform over the tool's six actions: each appears in about a sixth of the steps.
    steps = d["seq_actions"][d["seq_actions"] != NO_ACTION]
    counts = np.bincount([d["tool_actions"].tolist().index(a) for a in steps], minlength=6)
    assert counts.min() > len(steps) / 6 * 0.8


def test_a_boulder_by_its_condition_is_named_so_and_counted_by_hand():
    # The boulder room (a 5 x 3 interior, the pickaxe, a boulder to destroy), h = 3: by
    # its condition the boulder can be destroyed within 3 steps only with the pickaxe
    # held and the agent beside it (apply, pickaxe, direction; fewer from the prompts):
    # 44 ordered (boulder, agent) pairs of neighbouring cells (12 + 10 neighbours, both
    # ways), in each of the three modes, 1 bit each.
    world = str(Path(__file__).resolve().parents[2] / "tests" / "worlds" / "boulder-room.toml")
    d = empowerment.dataset(
        world, objects="conditions:boulder", tool="pickaxe", horizon=3, sequences=8, seed=1
    )
    assert list(d["objects"]) == ["conditions:boulder"]
    assert sorted(d["proj_key"].tolist()) == [[0], [1]]  # intact, destroyed
    assert sorted(set(d["E"].tolist())) == [0.0, 1.0]
    assert d["E"].sum() == 44 * 3


@pytest.mark.parametrize("view", ["full", "crop:2"])
def test_observation_is_the_environments(view):
    env = fulcrum.make_vec("exp2", 1, view=view)
    obs, _ = env.reset(seed=0)
    d = empowerment.dataset("exp2", view=view, sequences=0)
    init = fulcrum.World("exp2").initial_state
    row = [i for i, s in enumerate(d["state"]) if bytes(s) == init]
    assert len(row) == 1
    np.testing.assert_array_equal(d["glyphs"][row[0]], obs["glyphs"][0])
    np.testing.assert_array_equal(d["flags"][row[0]], obs["flags"][0])
    env.close()


def test_sample_is_distinct_and_seeded():
    a = empowerment.dataset("exp2", states="sample:500", seed=1, sequences=0)
    b = empowerment.dataset("exp2", states="sample:500", seed=1, sequences=0)
    c = empowerment.dataset("exp2", states="sample:500", seed=2, sequences=0)
    ids = a["state_id"]
    assert len(np.unique(ids)) == 500 and (np.diff(ids.astype(np.int64)) > 0).all()
    np.testing.assert_array_equal(ids, b["state_id"])
    assert (ids != c["state_id"]).any()
    n = fulcrum.World("exp1-tree").state_count
    with pytest.raises(ValueError, match=f"more states than the space has \\({n}\\)"):
        empowerment.dataset("exp1-tree", states=f"sample:{n + 1}")
    with pytest.raises(ValueError, match="all or sample:N"):
        empowerment.dataset("exp1-tree", states="some")


def test_cli_file_equals_python(fulcrum_bin, tmp_path):
    out = tmp_path / "d.npz"
    subprocess.run(
        [fulcrum_bin, "empowerment", "dataset", "exp2", "--states", "sample:200", "--seed", "7",
         "--view", "crop:2", "--sequences", "4", "--out", str(out)],
        check=True, capture_output=True,
    )
    d = empowerment.dataset("exp2", states="sample:200", seed=7, view="crop:2", sequences=4)
    with np.load(out) as z:
        for k, v in d.items():
            if isinstance(v, np.ndarray):
                assert z[k].dtype == v.dtype, k
                np.testing.assert_array_equal(z[k], v, err_msg=k)
            else:
                assert z[k].tolist() == v, k
    # Python's file reads back the same through the command line's scorer.
    empowerment.dataset("exp2", states="sample:200", seed=7, view="crop:2", sequences=4, out=tmp_path / "p.npz")
    with np.load(tmp_path / "p.npz") as z:
        np.testing.assert_array_equal(z["E"], d["E"])


# The 5-state example of the Rust scorer's test, counted by hand: truth [0, 1, 1, 2, 3],
# estimates [0.5, 1, 0.5, 2, 2], horizons [1, 1, 3, 3, 3]. Errors [0.5, 0, -0.5, 0, -1]:
# MAE 0.4, bias -0.2, RMSE sqrt(0.3); average ranks x [1.5, 3, 1.5, 4.5, 4.5],
# y [1, 2.5, 2.5, 4, 5]: Spearman 8.25 / sqrt(9 * 9.5).
TOY = {"E": np.array([0.0, 1.0, 1.0, 2.0, 3.0]), "horizon": np.array([1, 1, 3, 3, 3], np.uint32)}
TOY_X = [0.5, 1.0, 0.5, 2.0, 2.0]


def test_score_by_hand():
    s = empowerment.score(TOY_X, TOY)
    assert s["n"] == 5
    assert s["mae"] == pytest.approx(0.4, abs=1e-12)
    assert s["bias"] == pytest.approx(-0.2, abs=1e-12)
    assert s["rmse"] == pytest.approx(0.3**0.5, abs=1e-12)
    assert s["spearman"] == pytest.approx(8.25 / (9 * 9.5) ** 0.5, abs=1e-12)
    assert [(b["lo"], b["hi"], b["n"]) for b in s["by_bin"]] == [(0, 1, 1), (1, 2, 2), (2, 3, 1), (3, 4, 1)]
    assert s["by_bin"][1]["spearman"] is None
    assert [(h["horizon"], h["n"]) for h in s["by_horizon"]] == [(1, 2), (3, 3)]
    assert s["by_horizon"][1]["mae"] == pytest.approx(0.5, abs=1e-12)
    # A subset by row: rows 3 and 4 (errors 0 and -1).
    sub = empowerment.score({3: 2.0, 4: 2.0}, TOY)
    assert (sub["n"], sub["mae"], sub["bias"]) == (2, 0.5, -0.5)
    with pytest.raises(ValueError, match="4 estimates for a dataset of 5 states"):
        empowerment.score(TOY_X[:4], TOY)


def test_score_cli_equals_python(fulcrum_bin, tmp_path):
    path = tmp_path / "toy.npz"
    np.savez(path, **TOY)
    est = tmp_path / "est.csv"
    with open(est, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["row", "estimate"])
        w.writerows(reversed(list(enumerate(TOY_X))))
    out = subprocess.run(
        [fulcrum_bin, "empowerment", "score", str(path), "--estimates", str(est), "--json"],
        check=True, capture_output=True, text=True,
    )
    assert json.loads(out.stdout) == empowerment.score(TOY_X, str(path))
    bad = tmp_path / "bad.csv"
    bad.write_text("estimate\n0.5\n1.0\nlots\n2\n2\n")
    r = subprocess.run(
        [fulcrum_bin, "empowerment", "score", str(path), "--estimates", str(bad)],
        capture_output=True, text=True,
    )
    assert r.returncode == 2
    assert r.stderr.strip().endswith(f"{bad}:4: estimate 'lots' is not a finite number of bits")
    assert r.stderr.count("\n") == 1
