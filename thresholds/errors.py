"""The project's error base class.

Errors a user can act on (bad input file, missing weather coverage, unreachable goal) derive
from :class:`StormlaneError`; the CLI prints their message without a traceback and exits 2.
"""


import copyreg


class StormlaneError(Exception):
    """An error caused by the input or the configuration, with a message that says what to fix.

    Pickled as its message and attributes, whatever its subclass's ``__init__`` takes: a task on
    a Dask worker raises it in another process (Python's default rebuilds an exception by calling
    its class with ``args``, which fails for ``AisInputError(path, message)``)."""

    def __reduce__(self):
        return copyreg.__newobj__, (type(self), *self.args), self.__dict__
