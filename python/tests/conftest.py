"""Shared fixtures: the repository, the built ``fulcrum`` binary, the world files.

The tests import the installed package (``pip install ./python``) and compare it with
the command line built from the same commit (``cargo build --release``). A missing
binary fails the tests that need it, loudly: nothing is skipped.
"""

import os
import pathlib

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def repo() -> pathlib.Path:
    return REPO


@pytest.fixture(scope="session")
def fulcrum_bin() -> str:
    path = os.environ.get("FULCRUM_BIN", str(REPO / "target" / "release" / "fulcrum"))
    if not os.access(path, os.X_OK):
        pytest.fail(
            f"the fulcrum binary is not at {path}: build it with `cargo build --release` "
            "(or set FULCRUM_BIN)"
        )
    return path


def world_map(repo: pathlib.Path, name: str) -> list[str]:
    """The map rows of a built-in world, read from its file in worlds/."""
    text = (repo / "worlds" / f"{name}.toml").read_text()
    body = text.split('map = """', 1)[1].split('"""', 1)[0]
    return [row for row in body.split("\n") if row]
