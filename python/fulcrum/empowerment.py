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
    object), ``joint`` joint columns such as ``"boulder+door"``."""
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
