"""The project's own error type.

Everything a user can get wrong (a tree file, a config, a world, a map, a corrupt store)
is reported as a :class:`BomcError` that names the file and the field, so the command
line can print one line and exit 2 instead of showing a traceback.
"""

from __future__ import annotations

from pathlib import Path


class BomcError(Exception):
    """A user-facing error about an input: ``file: field: message``."""

    def __init__(self, message: str, file: str | Path | None = None, field: str | None = None):
        self.message = message
        self.file = str(file) if file is not None else None
        self.field = field
        super().__init__(self.__str__())

    def __str__(self) -> str:
        parts = [p for p in (self.file, self.field) if p]
        return ": ".join([*parts, self.message])


def read_input_text(path: Path, what: str) -> str:
    """The text of a user's input file; a missing or unreadable one is a one-line BomcError.

    ``what`` names the kind of file in the message ("world file not found").
    """
    try:
        return path.read_text()
    except FileNotFoundError:
        raise BomcError(f"{what} file not found", path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise BomcError(f"cannot read {what} file ({type(exc).__name__})", path) from None


class MissionFailed(Exception):
    """The mission ran but could not complete (exit code 1, not a user's mistake)."""
