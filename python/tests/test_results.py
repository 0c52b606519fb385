"""RESULTS.md's tables recomputed from the data committed beside them: the script that
made each table runs again on the committed per-seed outcomes and must print the
committed table exactly. (noisy_tables.py also recomputes every log-rank p-value of the
experiment's summary with its own standard-library test and asserts they agree.)"""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_the_noisy_worlds_tables_recompute_from_committed_data():
    out = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "noisy_tables.py")],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert out == (ROOT / "docs" / "results" / "noisy-tables.md").read_text()


def test_the_two_misses_table_recomputes_from_committed_data():
    out = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "misses_table.py")],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert out == (ROOT / "docs" / "results" / "misses-table.md").read_text()
