"""The project's error base class.

Errors a user can act on (bad input file, missing weather coverage, unreachable goal) derive
from :class:`StormlaneError`; the CLI prints their message without a traceback and exits 2.
"""


class StormlaneError(Exception):
    """An error caused by the input or the configuration, with a message that says what to fix."""
