"""RESULTS.md's tables recomputed from the data committed beside them: the script that
made each table runs again on the committed per-seed outcomes and must print the
committed table exactly. (noisy_tables.py also recomputes every log-rank p-value of the
experiment's summary with its own standard-library test and asserts they agree.)"""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def run_script(name: str) -> str:
    return subprocess.run(
        [sys.executable, str(ROOT / "scripts" / name)],
        capture_output=True,
        text=True,
        check=True,
    ).stdout


@pytest.mark.parametrize(
    "script, table",
    [
        ("noisy_tables.py", "noisy-tables.md"),
        ("misses_table.py", "misses-table.md"),
        ("robust_tables.py", "robust-tables.md"),
        ("trap_check_table.py", "trap-check-table.md"),
        ("layouts_tables.py", "layouts-tables.md"),
        ("estimators_tables.py", "estimators-tables.md"),
        ("estimators_ppo_table.py", "estimators-ppo-table.md"),
    ],
)
def test_a_results_table_recomputes_from_committed_data(script, table):
    assert run_script(script) == (ROOT / "docs" / "results" / table).read_text()


def test_the_worlds_nobody_wrote_tables_are_results_mds():
    """scripts/robust_tables.py recomputes every figure but the bootstrap interval from
    the committed pairs and asserts it equals the experiment's; its tables are RESULTS.md's."""
    results = (ROOT / "RESULTS.md").read_text().splitlines()
    for line in run_script("robust_tables.py").splitlines():
        if line.startswith("|"):
            assert line in results, line


def test_the_masked_tables_recompute_from_committed_summaries():
    """scripts/masked_tables.py recomputes the log-rank tests and Holm's adjustment from
    the per-seed steps of every committed summary (the four worlds; rerun with the code of
    their day, they gave the published tables to the digit) and prints rows that are
    RESULTS.md's."""
    out = run_script("masked_tables.py")
    committed = sorted(p.name for p in (ROOT / "docs" / "results").glob("masked-*-summary.json"))
    assert committed == [
        "masked-exp1-tree-summary.json",
        "masked-exp1-wall-summary.json",
        "masked-exp2-summary.json",
        "masked-exp3-summary.json",
    ]
    for world in [
        "exp1-tree (budget 500k)",
        "exp1-wall (budget 500k)",
        "exp2 (budget 3M)",
        "exp3 (budget 3M)",
    ]:
        assert world in out
    table = (ROOT / "docs" / "results" / "masked-tables.md").read_text().splitlines()
    results = (ROOT / "RESULTS.md").read_text().splitlines()
    rows = [line for line in out.splitlines() if line.startswith("| ") and "---" not in line]
    assert len(rows) == 4 * 9
    for line in rows:
        assert line in table and line in results, line
