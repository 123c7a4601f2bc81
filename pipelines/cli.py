"""The ``stormlane`` command.

Every module in :mod:`pipelines.commands` exposes ``register(app)`` and adds its commands;
heavy imports (Prefect, xarray, numba) happen inside the command functions so that
``stormlane --help`` stays fast.
"""

from __future__ import annotations

import importlib
import pkgutil
import sys

import typer

from pipelines import commands
from thresholds.errors import StormlaneError

app = typer.Typer(
    name="stormlane",
    help="Historical AIS traffic and marine weather turned into safer, faster routes.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


@app.callback()
def _root() -> None:
    """Historical AIS traffic and marine weather turned into safer, faster routes."""


def _register_commands() -> None:
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        importlib.import_module(f"{commands.__name__}.{info.name}").register(app)


_register_commands()


def main(argv: list[str] | None = None) -> None:
    """Console entry point: user errors print one clear line on stderr and exit 2.

    That holds for the option parser's errors too (bad or missing option value, unknown option or
    command): one ``error: ...`` line naming the option, instead of a usage box whose message
    rich wraps over several lines.
    """
    try:
        code = app(args=argv, prog_name="stormlane", standalone_mode=False)
    except StormlaneError as err:
        typer.echo(f"error: {err}", err=True)
        sys.exit(2)
    except typer.Abort:
        typer.echo("Aborted!", err=True)
        sys.exit(1)
    except typer.TyperException as err:  # click's usage errors (typer vendors click)
        if type(err).__name__ != "NoArgsIsHelpError":  # that one has printed the help already
            ctx = getattr(err, "ctx", None)
            hint = f" (see `{ctx.command_path} --help`)" if ctx is not None else ""
            typer.echo(f"error: {' '.join(err.format_message().split())}{hint}", err=True)
        sys.exit(getattr(err, "exit_code", 2))
    except OSError as err:
        # a path the user gave cannot be read or written (a file where a folder is needed, no
        # permission, a full disk ...): one line naming it
        if err.filename is None:
            raise
        other = f" -> {err.filename2}" if err.filename2 else ""
        typer.echo(f"error: {err.filename}{other}: {err.strerror or err}", err=True)
        sys.exit(2)
    except Exception as err:
        # A workspace locked by another process: the flows' I/O tasks retry it (transient), so it
        # stays DuckDB's exception down there; here, once retries are spent, it is one line.
        if not _workspace_locked(err):
            raise
        typer.echo(f"error: the workspace is in use by another process ({str(err).splitlines()[0]}); "
                   "retry when it has finished", err=True)
        sys.exit(2)
    if isinstance(code, int) and code:
        sys.exit(code)


def _workspace_locked(err: BaseException) -> bool:
    import duckdb

    return isinstance(err, duckdb.IOException) and "Could not set lock" in str(err)


if __name__ == "__main__":
    main()
