"""Errors of the AIS readers and the lanes chain that a user can act on."""

from __future__ import annotations

from thresholds.errors import StormlaneError


class AisInputError(StormlaneError):
    """An AIS input file that cannot be read as a whole (missing, unknown format, bad header).

    Bad *rows* never raise: they go to the quarantine with a reason code. This error is for
    problems that make the whole file unusable, and its message names the file (and the line or
    column when there is one).
    """

    def __init__(self, path, message: str, line: int | None = None):
        self.path = str(path)
        self.line = line
        self.detail = message  # without the path: the same error can be said of another spelling of it
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {message}")


class AisFormatError(AisInputError):
    """The format of an AIS file cannot be detected, or the file does not match the forced format."""
