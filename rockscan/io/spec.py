"""Library specs: the TOML files that name a library's shapes.

A spec lists shapes by Superformula parameters or by example photos
(``images = [...]``); ``rockscan library build`` turns one into a library file.
"""

from __future__ import annotations

import math
import os
import re
import tomllib
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from rockscan.core.errors import ParameterError, SpecError
from rockscan.core.superformula import SuperformulaParams

if TYPE_CHECKING:
    from rockscan.core.library import ShapeSpec

from rockscan.io.atomic import write_bytes_atomic

_PARAM_NAMES = SuperformulaParams.names()
_PARAM_KEYS = frozenset(_PARAM_NAMES)
_REQUIRED_KEYS = frozenset({"m1", "m2", "n1", "n2", "n3"})
_SHAPE_KEYS = frozenset({"name", "interest", "images", *_PARAM_NAMES})


def read_spec(path: str | os.PathLike[str]) -> list[ShapeSpec]:
    """Read a library spec (TOML, ``[[shape]]`` tables; see the interface).

    Parameters
    ----------
    path : path-like

    Returns
    -------
    shapes : list of ShapeSpec
        Example image paths are made absolute, relative to the spec's folder.

    Raises
    ------
    SpecError
        On unreadable files, TOML errors, unknown keys or impossible shapes.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SpecError(f"{path}: spec file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SpecError(f"{path}: cannot read spec ({exc})") from None
    data = _simple_spec(text)
    if data is None:
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise SpecError(f"{path}: not valid TOML ({exc})") from None
    return parse_spec(data, base=path.parent, source=str(path))


# One line of a spec as write_spec writes it: a [[shape]] header, or a bare key set to a
# decimal number, a basic string without escapes, or a list of such strings.
_STRING = r'"[^"\\\x00-\x1f\x7f]*"'
_HEADER = re.compile(r"[ \t]*\[\[[ \t]*shape[ \t]*\]\][ \t]*")
_PAIR = re.compile(
    r"[ \t]*(?P<key>[A-Za-z0-9_-]+)[ \t]*=[ \t]*(?:"
    r"(?P<float>[+-]?(?:0|[1-9][0-9]*)(?:\.[0-9]+(?:[eE][+-]?[0-9]+)?|[eE][+-]?[0-9]+))"
    r"|(?P<int>[+-]?(?:0|[1-9][0-9]*))"
    rf"|(?P<string>{_STRING})"
    rf"|\[(?P<list>[ \t]*(?:{_STRING}[ \t]*(?:,[ \t]*{_STRING}[ \t]*)*,?[ \t]*)?)\]"
    r")[ \t]*"
)
_LIST_ITEM = re.compile(_STRING)


def _simple_spec(text: str) -> dict[str, object] | None:
    """The parsed TOML of a spec in the plain form :func:`write_spec` writes, or None.

    ``tomllib`` reads 10,000 tables in about a second; this reads the same
    subset of TOML line by line in a tenth of that. Anything outside it
    (comments, escapes, other tables, repeated keys, ...) returns None, and the
    caller parses the text with ``tomllib``, which gives the same values here
    and the error message elsewhere.
    """
    shapes: list[dict[str, object]] = []
    table: dict[str, object] | None = None
    for line in text.split("\n"):
        if line.endswith("\r"):
            line = line[:-1]
        if not line.strip(" \t"):
            continue
        pair = _PAIR.fullmatch(line)
        if pair is None:
            if _HEADER.fullmatch(line) is None:
                return None
            table = {}
            shapes.append(table)
            continue
        key = pair["key"]
        if table is None or key in table:
            return None
        if pair["float"] is not None:
            table[key] = float(pair["float"])
        elif pair["int"] is not None:
            table[key] = int(pair["int"])
        elif pair["string"] is not None:
            table[key] = pair["string"][1:-1]
        else:
            table[key] = [item[1:-1] for item in _LIST_ITEM.findall(pair["list"])]
    return {"shape": shapes} if shapes else None


def parse_spec(data: dict[str, object], *, base: Path | None = None, source: str = "spec") -> list[ShapeSpec]:
    """Turn parsed TOML (``{"shape": [{...}, ...]}``) into shapes; see :func:`read_spec`."""
    from rockscan.core.library import ShapeSpec

    shapes = data.get("shape")
    if not isinstance(shapes, list) or not shapes:
        raise SpecError(f"{source}: a spec needs [[shape]] tables (see the README)")
    out: list[ShapeSpec] = []
    seen: set[str] = set()
    for i, entry in enumerate(shapes, start=1):
        if not isinstance(entry, dict):
            raise SpecError(f"{source}: shape {i} is not a table")
        name = entry.get("name")
        keys = entry.keys()
        if unknown := keys - _SHAPE_KEYS:
            raise SpecError(f"{_where(source, name, i)}: unknown keys {', '.join(sorted(unknown))}")
        if isinstance(name, str) and name in seen:
            raise SpecError(f"{_where(source, name, i)}: the name is used twice")
        images = entry.get("images", ())
        if not isinstance(images, (list, tuple)) or not all(isinstance(x, str) for x in images):
            raise SpecError(f"{_where(source, name, i)}: images must be a list of file paths")
        try:
            params = None
            if not images or keys & _PARAM_KEYS:
                if missing := _REQUIRED_KEYS - keys:
                    raise SpecError(f"missing {', '.join(sorted(missing))}")
                params = SuperformulaParams(**{k: entry[k] for k in _PARAM_NAMES if k in entry})
            paths = tuple(
                os.path.abspath(base / p) if base is not None and not Path(p).is_absolute() else p
                for p in images
            )
            shape = ShapeSpec(name=name, params=params, interest=entry.get("interest", 1.0), images=paths)
        except (ParameterError, SpecError) as exc:
            # The shape's own checks name it too: say it once.
            reason = str(exc).removeprefix(f"shape {name!r}: ")
            raise SpecError(f"{_where(source, name, i)}: {reason}") from None
        seen.add(shape.name)
        out.append(shape)
    return out


def _where(source: str, name: object, i: int) -> str:
    """How an error names shape ``i``: by its name when it has one."""
    return f"{source}: shape {name!r}" if isinstance(name, str) else f"{source}: shape {i}"


def write_spec(shapes: Sequence[ShapeSpec], path: str | os.PathLike[str] | None = None) -> str:
    """Write shapes as a spec (TOML).

    Parameters
    ----------
    shapes : sequence of ShapeSpec
    path : path-like, optional
        File to write (atomically). None only returns the text.

    Returns
    -------
    text : str
        The spec, readable by :func:`read_spec`. Example image paths are
        written relative to the spec's folder (as :func:`read_spec` reads
        them), or as given when there is no ``path``.

    Raises
    ------
    SpecError
        For no shapes, a name used twice, or an image path that is not valid
        UTF-8 (TOML's encoding): specs :func:`read_spec` would refuse.
    """
    counts = Counter(shape.name for shape in shapes)
    if not counts:
        raise SpecError("a spec needs at least one shape")
    if twice := sorted(name for name, count in counts.items() if count > 1):
        raise SpecError(f"shape names used twice: {', '.join(twice)}")
    folder = os.path.dirname(os.path.abspath(path)) if path is not None else None
    lines: list[str] = []
    for shape in shapes:
        lines.append("[[shape]]")
        lines.append(f'name = "{shape.name}"')
        if shape.params is not None:
            for key, value in shape.params.as_dict().items():
                lines.append(f"{key} = {_toml_float(value)}")
        if shape.images:
            listed = ", ".join(_toml_string(_spec_path(p, folder)) for p in shape.images)
            lines.append(f"images = [{listed}]")
        if shape.interest != 1.0:
            lines.append(f"interest = {_toml_float(shape.interest)}")
        lines.append("")
    text = "\n".join(lines)
    if path is not None:
        write_bytes_atomic(path, text.encode("utf-8"), what="spec")
    return text


def _spec_path(image: str, folder: str | None) -> str:
    """An example image's path as a spec in ``folder`` names it (None: as given)."""
    try:
        image.encode("utf-8")
    except UnicodeEncodeError:
        raise SpecError(
            f"{image!r} is not valid UTF-8, which a spec (TOML) must be; rename the file"
        ) from None
    if folder is None:
        return image
    try:
        return os.path.relpath(os.path.abspath(image), folder)
    except ValueError:  # another drive (Windows): no relative path
        return os.path.abspath(image)


def _toml_string(text: str) -> str:
    """A TOML basic string. JSON's escapes are not TOML's: JSON writes a character
    beyond U+FFFF as a surrogate pair, which TOML refuses, and leaves U+007F bare."""
    out = []
    for ch in text:
        code = ord(ch)
        if ch in '"\\':
            out.append("\\" + ch)
        elif (code < 0x20 and ch != "\t") or code == 0x7F:
            out.append(f"\\u{code:04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _toml_float(value: float) -> str:
    text = repr(float(value))
    return text if math.isfinite(value) else ("inf" if value > 0 else "-inf")
