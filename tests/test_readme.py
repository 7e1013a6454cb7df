"""The README's Python example runs as printed."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_the_python_example_runs(monkeypatch, capsys):
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert blocks, "the README has a Python example"
    monkeypatch.chdir(ROOT)  # its photos are named from the project's root
    for block in blocks:
        exec(compile(block, "README.md", "exec"), {})
    printed = capsys.readouterr().out
    assert printed.splitlines()[0].startswith("circle ")
    assert printed.splitlines()[-1] == "six-pointed-star"


@pytest.mark.parametrize("name", ["accuracy", "core-benchmark", "fit", "paper", "speed", "triage"])
def test_linked_sections_and_figures_exist(name):
    section = ROOT / "docs" / f"{name}.md"
    assert section.is_file()
    for link in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", section.read_text(encoding="utf-8")):
        assert (section.parent / link).is_file(), link
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    for link in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", readme):
        assert (ROOT / link).is_file(), link
