"""The ``ginn`` command line: train, resume, status, problems, eval, export, plot, sweep.

Every user error (bad flag, unknown ``--set`` key, bad value, malformed spec) prints one line
``ginn: error: ...`` to stderr and exits with status 2.
"""

from __future__ import annotations

import sys

from ..errors import GinnError
from ..train.rundir import io_error
from . import commands
from .parser import build_parser

__all__ = ["main", "build_parser"]


def _fail(msg: str) -> int:
    sys.stderr.write(f"ginn: error: {msg}\n")
    return 2


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        return commands.COMMANDS[args.command](args)
    except GinnError as e:
        return _fail(str(e))
    except FileNotFoundError as e:
        return _fail(f"{e.filename or e}: no such file")
    except OSError as e:  # a read-only directory, a full disk, ...: one line naming the file
        return _fail(str(io_error(e, e.filename or "a file", "write")))
    except KeyboardInterrupt:
        return _fail("interrupted")


if __name__ == "__main__":
    sys.exit(main())
