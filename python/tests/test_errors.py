"""Bad input raises ValueError with the command line's sentence; nothing panics."""

import subprocess

import numpy as np
import pytest

import fulcrum


def cli_error(fulcrum_bin, *args) -> str:
    out = subprocess.run([fulcrum_bin, *args], capture_output=True, text=True)
    assert out.returncode == 2, out.stderr
    return out.stderr.strip().removeprefix("fulcrum: ")


def test_unknown_world_is_the_cli_sentence(fulcrum_bin):
    want = cli_error(fulcrum_bin, "world", "show", "no-such-world")
    with pytest.raises(ValueError) as e:
        fulcrum.World("no-such-world")
    assert str(e.value) == want
    with pytest.raises(ValueError):
        fulcrum.make_vec("no-such-world")


def test_bad_world_text_names_the_line_and_column(tmp_path, fulcrum_bin):
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "x"\nmax_steps = 10\nmap = """\n#####\n#@.Q#\n#####\n"""\n')
    want = cli_error(fulcrum_bin, "world", "show", str(bad))
    with pytest.raises(ValueError) as e:
        fulcrum.World(str(bad))
    assert str(e.value) == want and ":5:" in want
    with pytest.raises(ValueError, match="<text>:5:"):
        fulcrum.World.from_text(bad.read_text())


def test_bad_state_descriptions_are_the_cli_sentence(fulcrum_bin):
    w = fulcrum.World("exp1-tree")
    for text in ["agent=0,0", "agent=1,1 mode=flying", "agent=1,1 holding=saw", "nonsense"]:
        want = cli_error(fulcrum_bin, "empowerment", "query", "exp1-tree", "--state", text)
        with pytest.raises(ValueError) as e:
            fulcrum.empowerment.value(w, text)
        assert want.endswith(str(e.value)), (want, str(e.value))
    with pytest.raises(ValueError, match="not a state of world 'exp1-tree'"):
        w.describe(bytes([200] * 38))
    with pytest.raises(ValueError, match="is not reachable from the initial state"):
        fulcrum.empowerment.value(w, "agent=1,4 mode=normal tree=destroyed")


def test_bad_requests_to_the_engine():
    with pytest.raises(ValueError, match="unknown object 'rock' in world 'exp1-tree'"):
        fulcrum.empowerment.matrix("exp1-tree", objects="rock")
    with pytest.raises(ValueError, match="unknown tool 'saw'"):
        fulcrum.empowerment.landscape("exp1-tree", tool="saw")
    with pytest.raises(ValueError, match="unknown tool 'saw' in the inventory"):
        fulcrum.empowerment.landscape("exp1-tree", tool="axe", holding=["saw"])
    with pytest.raises(ValueError, match="horizon 65 is too large: at most 64"):
        fulcrum.empowerment.matrix("exp1-tree", horizon=65)
    with pytest.raises(ValueError, match="unknown method 'magic'"):
        fulcrum.empowerment.matrix("exp1-tree", method="magic")
    with pytest.raises(ValueError, match="unknown action 'jump'"):
        fulcrum.empowerment.trace("exp1-tree", ["N", "jump"])
    with pytest.raises(ValueError, match="the enumerate method at horizon 12"):
        fulcrum.empowerment.value("exp2", "agent=2,2 mode=normal", horizon=12, method="enumerate")


def test_actions_of_any_integer_kind_and_bad_ones():
    env = fulcrum.make_vec("exp1-tree", num_envs=3)
    env.step([1, 1, 1])  # a list
    env.step(np.array([1, 1, 1], dtype=np.int32))
    env.step(np.array([[1, 0], [1, 0], [1, 0]])[:, 0])  # a strided view
    assert env.describe(0).startswith("agent=4,4")
    with pytest.raises(ValueError, match="2 actions for 3 environments"):
        env.step([1, 1])
    with pytest.raises(ValueError, match="action 9 of environment 2 is out of range"):
        env.step([1, 1, 9])
    with pytest.raises(ValueError, match="action -1 of environment 0"):
        env.step([-1, 1, 1])
    with pytest.raises(ValueError, match="actions must be integers, not float64"):
        env.step(np.array([1.0, 1.0, 1.0]))
    with pytest.raises(ValueError, match="one-dimensional array of 3 integers"):
        env.step(np.ones((3, 1), dtype=np.int64))
    # A refused step changes nothing.
    assert env.describe(0).startswith("agent=4,4")


def test_bad_environment_arguments():
    with pytest.raises(ValueError, match="num_envs is 0"):
        fulcrum.make_vec("room", num_envs=0)
    with pytest.raises(ValueError, match="render_mode 'human' is not offered"):
        fulcrum.make_vec("room", render_mode="human")
    with pytest.raises(ValueError, match="tile is 0 pixels"):
        fulcrum.World("room").render(tile=0)
    env = fulcrum.make_vec("room", num_envs=2)
    with pytest.raises(ValueError, match="reset_mask has 3 entries for 2"):
        env.reset(options={"reset_mask": np.array([True, True, True])})
    with pytest.raises(ValueError, match="environment 5 does not exist"):
        env.describe(5)
