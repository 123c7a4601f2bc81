"""Errors a user can act on when exporting routes or rendering reports."""

from thresholds.errors import StormlaneError


class ExportError(StormlaneError):
    """A route cannot be written to, or read back from, an export file (the message names it)."""


class ReportError(StormlaneError):
    """A report model is incomplete or inconsistent (the message names the field)."""
