"""The ``rockscan`` command line: parse, call the library, format.

No math lives here. Heavy modules are imported inside the commands so that
``rockscan --help`` starts at once. A :class:`rockscan.core.errors.RockscanError`
becomes a one-line error and exit status 1; usage errors exit 2 (click).

One module per command family; :mod:`rockscan.cli._main` holds the group,
shared options and the logging setup: library modules log to ``rockscan.*``
loggers and never print; here the ``rockscan`` logger gets one handler that
writes one line per record to standard error. Every command takes ``-q``
(warnings and errors only) and ``-v`` (debug lines too); the default shows what
a command wrote and the progress of long runs.
"""

from __future__ import annotations

# Importing a command module registers its commands on the group.
from rockscan.cli import _classify, _examples, _fit, _library, _render, _triage  # noqa: F401
from rockscan.cli._main import BROKEN_PIPE_STATUS, _verbosity_options, main

__all__ = ["BROKEN_PIPE_STATUS", "main"]

for _command in main.commands.values():
    _verbosity_options(_command)
