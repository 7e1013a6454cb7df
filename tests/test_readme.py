"""The README's examples run as printed: its Python and every rockscan command of its code blocks."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def readme_commands(text: str) -> list[str]:
    """Every ``rockscan ...`` command in the README's shell code blocks, in order.

    A console block's commands are its ``$ `` lines; a bash block's are all its
    lines. Continued lines (``\\``) are joined; of ``a && b`` only the rockscan
    parts are kept (installing is not this test's business).
    """
    commands = []
    for lang, body in re.findall(r"```(bash|console|sh|shell)\n(.*?)```", text, flags=re.S):
        body = re.sub(r"\s*\\\n\s*", " ", body)
        for line in body.splitlines():
            if lang == "console":
                if not line.startswith("$ "):
                    continue
                line = line[2:]
            for part in line.split("&&"):
                part = part.strip()
                if part.startswith("rockscan ") or part == "rockscan":
                    commands.append(part)
    return commands


def test_commands_are_found_in_shell_blocks():
    text = (
        "```bash\npython3 -m venv v && pip install . && rockscan classify a.png \\\n  b.png\n```\n"
        "```console\n$ rockscan examples ex\nrockscan: copied\n```\n```python\nrockscan = 1\n```\n"
    )
    assert readme_commands(text) == ["rockscan classify a.png b.png", "rockscan examples ex"]


def test_every_rockscan_command_of_the_readme_runs(tmp_path):
    # As in a clone: the project's data folder beside, a copy, so that nothing writes into the tree.
    commands = readme_commands((ROOT / "README.md").read_text(encoding="utf-8"))
    assert len(commands) >= 2, commands
    shutil.copytree(ROOT / "data", tmp_path / "data", ignore=shutil.ignore_patterns("__pycache__"))
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    for command in commands:
        done = subprocess.run(
            ["bash", "-c", command], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600
        )
        assert done.returncode == 0, f"{command}\n{done.stderr}"
        assert "Traceback" not in done.stderr, command


_ROW = re.compile(
    r"^(\S+)\s+(\d+)\s+(\S+)\s+(\S+)\s+([\d.]+)\s+([\d.e+-]+)\s+([\d.]+)\s+\(([\d.]+), ([\d.]+)\)$"
)


def _rows(text: str) -> dict[str, tuple]:
    """The rows of a printed classify table, by photo: rock, match, nearest and the numbers."""
    rows = {}
    for line in text.splitlines():
        found = _ROW.match(line.strip())
        if found:
            photo, rock, match, nearest, *numbers = found.groups()
            rows[photo] = (int(rock), match, nearest, *(float(v) for v in numbers))
    return rows


def test_the_quick_start_prints_what_the_readme_shows(tmp_path):
    # The first command's output block, right after it: the table a new user
    # compares theirs with. Names exactly; numbers to the precision that
    # BLAS threads and platforms leave alike, far below what a change to
    # segmentation or matching moves.
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    found = re.search(r"```bash\n(.*?)```\s*```\n(.*?)```", text, flags=re.S)
    assert found, "the README shows the quick start's output"
    command = readme_commands(f"```bash\n{found.group(1)}```")[0]
    printed = _rows(found.group(2))
    assert len(printed) >= 2, found.group(2)
    shutil.copytree(ROOT / "data", tmp_path / "data", ignore=shutil.ignore_patterns("__pycache__"))
    # As wide as the terminal the README's table was printed on: narrower, photo names are cut short.
    env = {
        **os.environ,
        "COLUMNS": "200",
        "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}",
    }
    done = subprocess.run(
        ["bash", "-c", command], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr
    got = _rows(done.stdout)
    assert got.keys() == printed.keys(), done.stdout
    for photo, (rock, match, nearest, mscore, distance, angle, x, y) in printed.items():
        assert got[photo][:3] == (rock, match, nearest), photo
        g_mscore, g_distance, g_angle, g_x, g_y = got[photo][3:]
        assert g_mscore == pytest.approx(mscore, abs=2e-3), photo
        assert g_distance == pytest.approx(distance, rel=0.02, abs=2e-5), photo
        assert g_angle == pytest.approx(angle, abs=0.5), photo
        assert (g_x, g_y) == pytest.approx((x, y), abs=0.2), photo


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


@pytest.mark.parametrize("name", ["accuracy", "cli", "core-benchmark", "fit", "paper", "speed", "triage"])
def test_linked_sections_and_figures_exist(name):
    section = ROOT / "docs" / f"{name}.md"
    assert section.is_file()
    for link in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", section.read_text(encoding="utf-8")):
        assert (section.parent / link).is_file(), link
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    for link in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", readme):
        assert (ROOT / link).is_file(), link
