"""ServiceClient against a real `fulcrum serve` process over iceoryx2."""

import os
import signal
import subprocess
import time

import numpy as np
import pytest

import fulcrum
from test_env import TO_THE_TREE, W
from test_wrapper import E_NEXT


@pytest.fixture(scope="module")
def service(fulcrum_bin):
    ns = f"pytest-{os.getpid()}"
    proc = subprocess.Popen(
        [fulcrum_bin, "serve", "exp1-tree", "--namespace", ns],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        client = fulcrum.ServiceClient(ns, "exp1-tree", timeout=30.0)
    except Exception:
        proc.kill()
        raise
    yield ns, client, proc
    proc.send_signal(signal.SIGTERM)
    proc.wait(timeout=10)


def test_lookup_of_env_states_is_the_exact_table(service):
    _, client, _ = service
    env = fulcrum.make_vec("exp1-tree", num_envs=2)
    env.reset()
    got = []
    for a in TO_THE_TREE:
        env.step(np.array([a, W]))
        values, status = client.lookup(env.states)
        assert status.tolist() == [0, 0]
        got.append(float(values[0]))
        assert float(values[1]) == 0.0
    assert got == E_NEXT


def test_lookup_by_descriptions_and_a_state_outside_the_space(service):
    _, client, _ = service
    values, status = client.lookup(
        [
            "agent=8,2 holding=axe mode=normal",
            # The tree felled without ever holding the axe: well formed, unreachable.
            "agent=1,4 mode=normal tree=destroyed",
        ]
    )
    assert values[0] == 1.0
    assert status.tolist() == [0, 1]


def test_many_states_in_pipelined_batches(service):
    _, client, _ = service
    env = fulcrum.make_vec("exp1-tree", num_envs=3000, seed=0)
    env.step(env.action_space.sample())
    values, status = client.lookup(env.states)
    assert values.shape == (3000,) and (status == 0).all()
    w = fulcrum.World("exp1-tree")
    some = [env.states[i].tobytes() for i in (0, 1500, 2999)]
    assert values[[0, 1500, 2999]].tolist() == fulcrum.empowerment.value(w, some).tolist()


def test_visit_counts_and_query(service):
    _, client, _ = service
    s = "agent=6,6 mode=normal"
    first, _ = client.visit([s])
    second, _ = client.visit([s, s])
    assert second.tolist() == [first[0] + 1, first[0] + 2]
    q = "agent=8,6 holding=pickaxe mode=normal"
    values, _ = client.query([q], tool="pickaxe", objects="wall", horizon=3)
    assert float(values[0]) == fulcrum.empowerment.value(
        "exp1-tree", q, tool="pickaxe", objects="wall", horizon=3
    ) == 1.0


def test_describe_names_the_table(service):
    _, client, _ = service
    d = client.describe()
    assert d["world"] == "exp1-tree" and d["states"] == 8880
    assert (d["tool"], d["objects"]) == ("axe", "tree")
    assert (d["horizon_unequipped"], d["horizon_equipped"]) == (8, 3)


def test_typed_errors(service):
    ns, client, _ = service
    with pytest.raises(fulcrum.WrongWorld, match="serves world 'exp1-tree'"):
        fulcrum.ServiceClient(ns, "exp2", timeout=5.0)
    with pytest.raises(fulcrum.NoService, match="no empowerment service for namespace"):
        fulcrum.ServiceClient(f"nobody-{os.getpid()}", "exp1-tree", timeout=0.3)
    with pytest.raises(ValueError, match="namespace 'a b' is not usable"):
        fulcrum.ServiceClient("a b", "exp1-tree")
    with pytest.raises(ValueError, match="'gate' is neither agent, holding, mode nor an object of world 'exp1-tree'"):
        client.lookup(["agent=1,1 mode=normal gate=open"])
    with pytest.raises(ValueError, match="packed state has 38 bytes, not 3"):
        client.lookup([b"abc"])
    with pytest.raises(ValueError, match="unknown tool 'saw'"):
        client.query(["agent=1,4 mode=normal"], tool="saw", objects="tree", horizon=3)
    assert issubclass(fulcrum.WrongWorld, fulcrum.ServiceError)


def test_a_service_that_goes_away_is_a_typed_error(fulcrum_bin):
    ns = f"pytest-gone-{os.getpid()}"
    proc = subprocess.Popen([fulcrum_bin, "serve", "room", "--namespace", ns])
    client = fulcrum.ServiceClient(ns, "room", timeout=30.0)
    assert client.lookup(["agent=1,1 mode=normal"])[1].tolist() == [0]
    proc.kill()
    proc.wait()
    t0 = time.monotonic()
    with pytest.raises((fulcrum.ServiceGone, fulcrum.ServiceTimeout)):
        client.lookup(["agent=1,1 mode=normal"])
    assert time.monotonic() - t0 < 40
