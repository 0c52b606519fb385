"""`fulcrum train` writes TensorBoard events that TensorBoard's own reader reads back
with every value of metrics.csv (and, with --eval-every, of eval.csv), on a fresh run and
after `--resume`."""

import csv
import subprocess

import numpy as np
import pytest
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
from tensorboard.util import tensor_util


def train(fulcrum_bin, *args):
    out = subprocess.run(
        [fulcrum_bin, "train", *args], capture_output=True, text=True, timeout=600
    )
    assert out.returncode == 0, out.stderr
    return out


def read_events(run):
    acc = EventAccumulator(str(run / "tb"), size_guidance={"scalars": 0, "tensors": 0})
    acc.Reload()
    return acc


def metrics(run):
    with open(run / "metrics.csv") as f:
        return list(csv.DictReader(f))


def assert_events_equal_metrics(run):
    rows = metrics(run)
    acc = read_events(run)
    tags = acc.Tags()["scalars"]
    for col in rows[0].keys():
        want = [(int(r["env_steps"]), float(r[col])) for r in rows if r[col] != ""]
        got = [(e.step, e.value) for e in acc.Scalars(col)] if col in tags else []
        assert [s for s, _ in got] == [s for s, _ in want], col
        # Events hold float32 (`simple_value`): compare after the same rounding.
        assert np.array_equal(
            np.array([v for _, v in got], dtype=np.float32),
            np.array([v for _, v in want], dtype=np.float32),
        ), col
    text = tensor_util.make_ndarray(acc.Tensors("config")[0].tensor_proto)
    assert (run / "config.toml").read_text() in text.item().decode()
    return rows


def test_events_hold_every_metrics_value(fulcrum_bin, tmp_path):
    run = tmp_path / "run"
    train(fulcrum_bin, "room", "--steps", "20480", "--seed", "3", "--out", str(run))
    rows = assert_events_equal_metrics(run)
    assert len(rows) == 20
    assert len(list((run / "tb").iterdir())) == 1


def assert_events_equal_evals(run):
    with open(run / "eval.csv") as f:
        rows = [r for r in csv.DictReader(f) if r["mode"] == "train-greedy"]
    acc = read_events(run)
    for tag, col in [
        ("eval/success_rate", "success"),
        ("eval/return", "return"),
        ("eval/episode_length", "length"),
        ("eval/tool_use", "tool_use"),
        ("eval/tool_choice", "tool_choice"),
    ]:
        got = [(e.step, e.value) for e in acc.Scalars(tag)]
        assert [s for s, _ in got] == [int(r["env_steps"]) for r in rows], tag
        assert np.array_equal(
            np.array([v for _, v in got], dtype=np.float32),
            np.array([float(r[col]) for r in rows], dtype=np.float32),
        ), tag
    return rows


def test_events_after_a_resume_are_the_rows_kept(fulcrum_bin, tmp_path):
    run = tmp_path / "run"
    train(
        fulcrum_bin, "room", "--steps", "40960", "--seed", "3", "--eval-every", "4",
        "--stop-after-updates", "15", "--out", str(run),
    )
    assert len(metrics(run)) == 15
    train(fulcrum_bin, "--resume", str(run))
    rows = assert_events_equal_metrics(run)
    assert [int(r["update"]) for r in rows] == list(range(1, 41))
    # Periodic evaluations at 4, 8, ..., 40: those after the checkpoint (update 10)
    # made again by the resume, none twice.
    evals = assert_events_equal_evals(run)
    assert [int(r["update"]) for r in evals] == list(range(4, 41, 4))
    # One file: the resume rewrote the events from metrics.csv and went on.
    assert len(list((run / "tb").iterdir())) == 1
