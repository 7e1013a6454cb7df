"""Print pip constraints that pin every dependency to its declared minimum series.

Each ``pkg>=X.Y`` of pyproject.toml (the dependencies and the optional extras
named, by default all) becomes ``pkg==X.Y.*``: the oldest release series the
project claims to support, at its newest patch. CI installs with these
constraints and runs the suite, so the declared bounds are tested, and, being
read from pyproject.toml each time, they cannot drift from it::

    python scripts/min_constraints.py > min.txt
    pip install -c min.txt ".[test]"
"""

from __future__ import annotations

import argparse
import re
import sys
import tomllib
from pathlib import Path

#: ``name[extras]>=X.Y[.Z]``, the only form of bound the project declares.
_REQUIREMENT = re.compile(r"^\s*([A-Za-z0-9][A-Za-z0-9._-]*)\s*(?:\[[^\]]*\])?\s*(.*?)\s*(?:;.*)?$")
_LOWER = re.compile(r"^>=\s*([0-9]+(?:\.[0-9]+)*)$")


def constraints(pyproject: dict, extras: list[str] | None = None) -> list[str]:
    """``name==X.Y.*`` lines for the dependencies and ``extras`` of a parsed pyproject.

    Raises
    ------
    ValueError
        If a requirement has no lower bound, or a bound of another form, or
        one package gets two different minimums.
    """
    project = pyproject["project"]
    optional = project.get("optional-dependencies", {})
    names = sorted(optional) if extras is None else extras
    requirements = list(project.get("dependencies", []))
    for extra in names:
        if extra not in optional:
            raise ValueError(f"no optional dependency group {extra!r}")
        requirements += optional[extra]
    pins: dict[str, str] = {}
    for requirement in requirements:
        match = _REQUIREMENT.match(requirement)
        bound = _LOWER.match(match.group(2)) if match else None
        if bound is None:
            raise ValueError(f"{requirement!r}: declare a lower bound as 'name>=X.Y'")
        name = re.sub(r"[-_.]+", "-", match.group(1)).lower()
        pin = f"{name}=={bound.group(1)}.*"
        if pins.setdefault(name, pin) != pin:
            raise ValueError(f"{name}: two different lower bounds ({pins[name]}, {pin})")
    return [pins[name] for name in sorted(pins)]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("pyproject", nargs="?", default="pyproject.toml", help="default: ./pyproject.toml")
    parser.add_argument(
        "--extra", action="append", default=None, help="optional group to include (repeatable; default all)"
    )
    args = parser.parse_args(argv)
    try:
        lines = constraints(tomllib.loads(Path(args.pyproject).read_text()), args.extra)
    except (OSError, ValueError, KeyError) as exc:
        print(f"min_constraints: error: {exc}", file=sys.stderr)
        return 1
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
