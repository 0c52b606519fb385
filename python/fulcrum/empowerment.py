"""Exact object empowerment, as ``fulcrum empowerment`` computes it.

``E^h_{j,D}(s) = log2 |R_h(s)|`` bits: the number of distinct configurations of the
objects D that tool j's actions {N, E, S, W, apply, select_j} can bring about within h
steps of s. Defaults are the world's ``[empowerment]`` tool, objects and horizons (h_e
where the tool is held, h_u elsewhere). Results are numpy arrays and plain dicts with
the command line's ``--json`` keys. ``world`` is a :class:`fulcrum.World` (whose state
space is enumerated once and kept), a built-in name or a file path.
"""

from __future__ import annotations

from typing import Sequence

from fulcrum import _native


def _objects(objects: str | Sequence[str] | None, joint: str = "+") -> str | None:
    if objects is None or isinstance(objects, str):
        return objects
    return joint.join(objects)


def matrix(
    world,
    objects: str | Sequence[str] | None = None,
    joint: Sequence[str] = (),
    horizon: int | None = None,
    horizon_unequipped: int | None = None,
    horizon_equipped: int | None = None,
    method: str = "dp",
) -> dict:
    """The tool-object matrix (``"matrix"``: float64, tools x columns) and the tool
    selection of each column (equation (6): argmax, ties to the lower tool, ``None``
    for a column of zeros). ``objects`` are single-object columns (default: every
    object), ``joint`` joint columns such as ``"boulder+door"``. By default one horizon
    for every state and row, the world's ``horizon_unequipped``: the matrix that
    ``tool = "auto"`` selects from. ``horizon_equipped`` asks for rows that switch to it
    where their own tool is held (rows that cannot be compared: a tool held in fewer
    states is favoured)."""
    return _native.matrix(
        world,
        objects=_objects(objects, ","),
        joint=list(joint),
        horizon=horizon,
        horizon_unequipped=horizon_unequipped,
        horizon_equipped=horizon_equipped,
        method=method,
    )


def landscape(
    world,
    tool: str | None = None,
    objects: str | Sequence[str] | None = None,
    horizon: int | None = None,
    holding: str | Sequence[str] | None = None,
    method: str = "dp",
) -> dict:
    """E over the map (``"values"``: float64 (H, W), NaN where the agent cannot stand)
    for one inventory ``holding``, every object as at the start."""
    return _native.landscape(
        world,
        tool=tool,
        objects=_objects(objects),
        horizon=horizon,
        holding=holding,
        method=method,
    )


def trace(
    world,
    actions: str | Sequence[str | int],
    tool: str | None = None,
    objects: str | Sequence[str] | None = None,
    horizon: int | None = None,
) -> dict:
    """E along ``actions`` from the initial state: ``"values"`` (float64, one per step,
    t = 0 before any action) and ``"steps"`` (t, action, value, horizon, state)."""
    return _native.trace(
        world, actions, tool=tool, objects=_objects(objects), horizon=horizon
    )


def value(
    world,
    state,
    tool: str | None = None,
    objects: str | Sequence[str] | None = None,
    horizon: int | None = None,
    method: str = "dp",
):
    """E at ``state`` (a description such as ``"agent=2,4 mode=normal tree=intact"``, or
    38 packed bytes): a float; for a list of states (or uint8 rows), a float64 array."""
    return _native.value(
        world,
        state,
        tool=tool,
        objects=_objects(objects),
        horizon=horizon,
        method=method,
    )


def dataset(
    world,
    tool: str | None = None,
    objects: str | Sequence[str] | None = None,
    horizon: int | None = None,
    states: str = "all",
    seed: int = 0,
    view: str = "full",
    sequences: int = 16,
    method: str = "dp",
    out=None,
) -> dict:
    """Exact E as ground truth for a learned estimator, one row per state (``states``:
    ``"all"`` or ``"sample:N"``), as ``fulcrum empowerment dataset`` writes it:

    - ``glyphs`` uint8 (n, H, W) and ``flags`` uint8 (n, F): the observation in ``view``
      (``"full"`` or ``"crop:R"``), exactly as a policy sees it;
    - ``state`` uint8 (n, 38) packed, ``state_id`` uint32, ``normal`` bool (mode normal);
    - ``E`` float64 (n,) bits, ``gap`` (a stochastic world's capacity bound, else 0),
      ``horizon`` uint32 (the one given, else the world's by whether the tool is held);
    - ``sequences`` action sequences per row, uniform over the tool's actions:
      ``seq_row`` uint32 (m,), ``seq_actions`` uint8 (m, h_max) (world action indices,
      255 past the row's horizon), ``seq_final_state`` uint8 (m, 38), ``seq_proj`` uint32
      (m,) (proj_D of the final state as a dense id) and ``proj_key`` uint16 (P, k) (what
      each id is); ``tool_actions`` (the tool's action indices), ``actions`` (names);
    - ``world``, ``tool``, ``objects``, ``view``, ``seed``.

    The mean of ``E`` over ``normal`` rows of ``states="all"`` is the matrix entry at the
    same horizon. With ``out`` (a path) the arrays are also written there as ``.npz``.
    """
    d = _native.dataset(
        world,
        tool=tool,
        objects=_objects(objects),
        horizon=horizon,
        states=states,
        seed=seed,
        view=view,
        sequences=sequences,
        method=method,
    )
    if out is not None:
        _save_npz(out, d)
    return d


def _save_npz(path, d: dict) -> None:
    """``numpy.savez`` to a temporary file beside ``path``, then renamed over it."""
    import os
    import tempfile

    import numpy as np

    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".fulcrum-", suffix=".npz")
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **{k: np.asarray(v) for k, v in d.items()})
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def score(estimates, dataset) -> dict:
    """Score ``estimates`` (bits) against a dataset's exact ``E``: ``dataset`` is the dict
    of :func:`dataset`, a loaded ``.npz`` or its path; ``estimates`` one value per row, or
    a dict ``{row: value}`` to score a subset. Returns ``n``, ``mae``, ``bias``
    (estimate minus truth, averaged), ``rmse``, ``spearman`` (ties share their mean
    rank; ``None`` where a side is constant), and the same ``by_bin`` (true E in
    ``[lo, hi)``, one bit wide) and ``by_horizon``, as ``fulcrum empowerment score``."""
    import os

    import numpy as np

    if isinstance(dataset, (str, os.PathLike)):
        with np.load(dataset) as z:
            truth, horizon = np.array(z["E"]), np.array(z["horizon"])
    else:
        truth, horizon = np.asarray(dataset["E"]), np.asarray(dataset["horizon"])
    truth = truth.astype(np.float64).ravel()
    horizon = horizon.astype(np.uint32).ravel()
    if isinstance(estimates, dict):
        rows = np.array(sorted(estimates), dtype=np.int64)
        if len(rows) and (rows[0] < 0 or rows[-1] >= len(truth)):
            raise ValueError(
                f"estimates name rows outside the dataset's {len(truth)} states"
            )
        x = np.array([estimates[r] for r in rows.tolist()], dtype=np.float64)
        truth, horizon = truth[rows], horizon[rows]
    else:
        x = np.asarray(estimates, dtype=np.float64).ravel()
    return _native.score(x.tolist(), truth.tolist(), horizon.tolist())
