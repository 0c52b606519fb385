"""World families from Python: ``World.layout(family, seed)`` is the layout the command
line shows for the same family and seed, and a bad family is the command line's sentence."""

import json
import subprocess

import pytest

import fulcrum


def cli_json(fulcrum_bin, *args):
    out = subprocess.run([fulcrum_bin, *args], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def test_a_layout_is_the_command_lines(fulcrum_bin):
    assert fulcrum.builtin_families() == ["toolbox", "two-rooms"]
    for family in fulcrum.builtin_families():
        for seed in [0, 3, 41]:
            w = fulcrum.World.layout(family, seed)
            v = cli_json(fulcrum_bin, "world", "show", family, "--layout", str(seed), "--json")
            assert w.name == v["world"] == f"{family}-{seed}"
            assert "".join(row + "\n" for row in w.map) == v["map"]
            assert w.actions == v["actions"]
    # Every layout of a family has the family's size and actions.
    shapes = {(fulcrum.World.layout("toolbox", s).width, fulcrum.World.layout("toolbox", s).height,
               tuple(fulcrum.World.layout("toolbox", s).actions)) for s in range(50)}
    assert shapes == {(10, 8, ("N", "E", "S", "W", "apply", "axe", "pickaxe", "wand"))}


def test_a_family_is_not_one_world_and_bad_families_are_the_cli_sentence(tmp_path, fulcrum_bin):
    with pytest.raises(ValueError, match="world family"):
        fulcrum.World("toolbox")
    bad = tmp_path / "fam.toml"
    bad.write_text('name = "f"\n\n[family]\nwidth = 10\nheight = 8\ntools = ["key"]\nobjects = ["tree"]\n')
    out = subprocess.run([fulcrum_bin, "world", "show", str(bad), "--layout", "0"],
                         capture_output=True, text=True)
    assert out.returncode == 2
    want = out.stderr.strip().removeprefix("fulcrum: ")
    with pytest.raises(ValueError) as e:
        fulcrum.World.layout(str(bad), 0)
    assert str(e.value) == want and ":7:12:" in want
