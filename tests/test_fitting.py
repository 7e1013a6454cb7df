"""What the fitting scripts share (scripts/fitting.py): measuring tasks, kept between runs, with progress."""

from __future__ import annotations

import io
import pickle
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import fitting


def _square(task: int) -> int:
    return task * task


def test_measured_keeps_the_order_reports_progress_and_reads_back(tmp_path, capsys):
    keep = tmp_path / "measured.pkl"
    tasks = list(range(fitting.PROGRESS_EVERY * 2 + 7))
    results = fitting.measured(_square, tasks, jobs=1, cache=None, keep=keep)
    assert results == [t * t for t in tasks]
    lines = capsys.readouterr().err.splitlines()
    done = [line.split()[1] for line in lines]
    total = len(tasks)
    assert done == [
        f"{fitting.PROGRESS_EVERY}/{total}",
        f"{2 * fitting.PROGRESS_EVERY}/{total}",
        f"{total}/{total}",
    ]
    assert pickle.loads(keep.read_bytes()) == results

    def never(task):
        raise AssertionError("a kept measurement is read back, not measured again")

    assert fitting.measured(never, tasks, jobs=1, cache=None, keep=keep) == results


def test_measured_on_two_processes_gives_the_same_results_in_order(capsys):
    tasks = list(range(12))
    assert fitting.measured(_square, tasks, jobs=2, cache=None, keep=None) == [t * t for t in tasks]
    assert capsys.readouterr().err.splitlines()[-1].split()[1] == "12/12"


def test_progress_lines_say_how_much_is_left():
    stream = io.StringIO()
    passed = list(fitting._reported(iter(range(3)), 3, stream))
    assert passed == [0, 1, 2]
    (line,) = stream.getvalue().splitlines()
    assert line.startswith("  measured 3/3 (") and line.endswith("0 min left)")


@pytest.mark.parametrize("total", [1, fitting.PROGRESS_EVERY])
def test_the_last_task_always_reports(total):
    stream = io.StringIO()
    list(fitting._reported(iter(range(total)), total, stream))
    assert stream.getvalue().splitlines()[-1].split()[1] == f"{total}/{total}"


def test_written_trees_read_back_as_the_same_sums(tmp_path):
    import importlib.util

    import numpy as np

    from rockscan.core.segment.trees import tree_sum, trees_of

    # Two stumps: x0 <= 0.5 -> -1 else 2; x1 <= -3 -> 0.25 else -0.5; bias 0.1.
    stumps = {
        "ROOTS": np.array([0, 3]),
        "FEATURE": np.array([0, -1, -1, 1, -1, -1]),
        "LEFT": np.array([1, 0, 0, 4, 0, 0]),
        "RIGHT": np.array([2, 0, 0, 5, 0, 0]),
        "THRESHOLD": np.array([0.5, 0.0, 0.0, -3.0, 0.0, 0.0]),
        "VALUE": np.array([0.0, -1.0, 2.0, 0.0, 0.25, -0.5]),
        "BIAS": 0.1,
        "DEPTH": 1,
    }
    path = tmp_path / "stump_model.py"
    fitting.write_trees(
        path, "Two stumps", "scripts/none.py", "Fitted on nothing.", {"": stumps, "B_": stumps}
    )
    spec = importlib.util.spec_from_file_location("stump_model", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert "Fitted on nothing." in module.__doc__
    x = np.array([[0.0, -4.0], [1.0, 0.0], [0.5, -3.0]])
    expected = [0.1 - 1.0 + 0.25, 0.1 + 2.0 - 0.5, 0.1 - 1.0 + 0.25]
    for prefix in ("", "B_"):
        assert tree_sum(x, trees_of(module, prefix)).tolist() == pytest.approx(expected, abs=1e-15)
