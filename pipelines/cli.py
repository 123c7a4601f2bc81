"""The ``stormlane`` command.

Every module in :mod:`pipelines.commands` exposes ``register(app)`` and adds its commands;
heavy imports (Prefect, xarray, numba, DuckDB) happen inside the command functions so that
``stormlane --help`` stays fast. The conventions every command follows are in ``docs/cli.md``
and enforced here where they can be (one ``error:`` line and exit 2 for user errors; several
values after one option; plain help with flags shown as flags) and by ``tests/test_cli_convention.py``.
"""

from __future__ import annotations

import importlib
import pkgutil
import sys

import typer
from typer.core import TyperCommand

from pipelines import commands
from thresholds.errors import StormlaneError

#: Where the shared conventions are written down; every command's help points there.
CONVENTIONS = "Conventions shared by every command (inputs, outputs, errors): docs/cli.md"


def spread_multiple(command, args: list[str]) -> list[str]:
    """``--opt a b c`` -> ``--opt a --opt b --opt c`` for every option of ``command`` that takes
    several values (``multiple=True``), so one flag followed by several values and the flag
    repeated mean the same in every command. The values after one flag end at the next word
    that starts with ``-``."""
    names = {opt for p in command.params if getattr(p, "multiple", False) and not getattr(p, "is_flag", False)
             for opt in p.opts}
    if not names:
        return args
    out: list[str] = []
    current = None
    for i, word in enumerate(args):
        if word == "--":
            return out + args[i:]
        if word.startswith("-"):
            current = word if word in names else None
            out.append(word)
        elif current is not None and out[-1] != current:
            out.extend([current, word])
        else:
            out.append(word)
    return out


class StormlaneCommand(TyperCommand):
    """A command that reads several values after one multi-valued option (see :func:`spread_multiple`)."""

    def parse_args(self, ctx, args: list[str]) -> list[str]:
        return super().parse_args(ctx, spread_multiple(self, list(args)))


def _version(value: bool) -> None:
    if value:
        from importlib.metadata import version

        typer.echo(f"stormlane {version('stormlane')}")
        raise typer.Exit()


app = typer.Typer(
    name="stormlane",
    epilog=CONVENTIONS,
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,  # plain help: flags shown as flags, paragraphs wrapped, no rich import
)


@app.callback()
def _root(
    version: bool = typer.Option(False, "--version", is_eager=True, callback=_version, help="Print the version and exit."),
) -> None:
    """Historical AIS traffic and marine weather turned into safer, faster routes.

    Start with `stormlane ingest-ais` (AIS files into a workspace), then `lanes`, `weather load`,
    `route`, `audit` and `nightly`; `stormlane COMMAND --help` shows each command's options and an
    example.
    """


def _register_commands() -> None:
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        importlib.import_module(f"{commands.__name__}.{info.name}").register(app)
    _apply_conventions(app)


def _apply_conventions(typer_app: typer.Typer) -> None:
    """Every command of ``typer_app`` (and of its sub-apps) parses with :class:`StormlaneCommand`
    and points to the conventions in its help."""
    for info in typer_app.registered_commands:
        if info.cls in (None, TyperCommand):  # typer fills in its own class by default
            info.cls = StormlaneCommand
        info.epilog = info.epilog or CONVENTIONS
    for group in typer_app.registered_groups:
        group.typer_instance.info.epilog = group.typer_instance.info.epilog or CONVENTIONS
        _apply_conventions(group.typer_instance)


_register_commands()


def _sigterm_exits() -> None:
    """SIGTERM ends a command as an exception (exit status 143, 128 + 15), so that its clean-ups
    run: Python's default action ends the process at once, which left Prefect's temporary API
    server (a subprocess, stopped at exit) running after every command stopped with SIGTERM. A
    flow run swaps in Prefect's own handler and re-sends the signal to this one when it is done."""
    import signal
    import threading

    def _exit(signum, _frame):
        raise SystemExit(128 + signum)

    if threading.current_thread() is threading.main_thread():  # only the main thread may set handlers
        signal.signal(signal.SIGTERM, _exit)


def main(argv: list[str] | None = None) -> None:
    """Console entry point: user errors print one clear line on stderr and exit 2.

    That holds for the option parser's errors too (bad or missing option value, unknown option or
    command): one ``error: ...`` line naming the option, instead of a usage box.
    """
    _sigterm_exits()
    try:
        code = app(args=argv, prog_name="stormlane", standalone_mode=False)
    except StormlaneError as err:
        typer.echo(f"error: {err}", err=True)
        sys.exit(2)
    except typer.Abort:
        typer.echo("Aborted!", err=True)
        sys.exit(1)
    except typer.TyperException as err:  # click's usage errors (typer vendors click)
        ctx = getattr(err, "ctx", None)
        if type(err).__name__ == "NoArgsIsHelpError":  # `stormlane` or `stormlane weather` alone: the help
            typer.echo(ctx.get_help() if ctx is not None else err.format_message())
        else:
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
        from pipelines.prefect_console import CLUSTER_RUNS_OTHER_CODE, cluster_runs_other_code, workspace_locked

        if cluster_runs_other_code(err):
            typer.echo(f"error: {CLUSTER_RUNS_OTHER_CODE}", err=True)
            sys.exit(2)
        # A workspace locked by another process: the flows' I/O tasks retry it (transient), so it
        # stays DuckDB's exception down there; here, once retries are spent, it is one line.
        if not workspace_locked(err):
            raise
        typer.echo(f"error: the workspace is in use by another process ({str(err).splitlines()[0]}); "
                   "retry when it has finished", err=True)
        sys.exit(2)
    if isinstance(code, int) and code:
        sys.exit(code)


if __name__ == "__main__":
    main()
