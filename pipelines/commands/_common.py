"""Options and output helpers shared by the CLI commands (the conventions of docs/cli.md).

One definition per concept: the workspace (``--db``), weather inputs (``--weather``), the vessel
(``--vessel``), the operator limits (``--profile``), the speed-loss model (``--speed-loss``),
output files and folders, ``--json``. Only typer is imported here, so that ``stormlane --help``
stays fast.
"""

from __future__ import annotations

import json
import math
import os
import sys
from contextlib import contextmanager
from pathlib import Path

import typer

from thresholds.errors import StormlaneError

#: The workspace used when --db is not given (same as ``pipelines.storage.DEFAULT_DB``).
DEFAULT_DB = "stormlane.duckdb"
#: Speed-loss models (same as ``routing.speed_loss.MODELS``; checked by the convention test).
SPEED_LOSS_MODELS = ("bowditch", "aertssen", "khokhlov", "kwon", "none")


class PathOptionError(StormlaneError):
    """A path given on the command line cannot be used (one ``error:`` line, exit 2)."""


def _parent_ok(path: Path, what: str) -> None:
    parent = Path(path).expanduser().parent
    if parent.exists() and not parent.is_dir():
        raise PathOptionError(f"{what}: {parent} exists and is not a folder")
    if not parent.exists():
        raise PathOptionError(f"{what}: folder {parent} does not exist")


def check_output_file(value: Path | None, option: str = "--out") -> Path | None:
    """An output file goes into an existing folder (never created behind the user's back)."""
    if value is not None:
        _parent_ok(value, f"{option} {value}")
        if Path(value).is_dir():
            raise PathOptionError(f"{option} {value}: is a folder; give a file name")
    return value


def check_output_dir(value: Path | None, option: str = "--out") -> Path | None:
    """An output folder is created, but the folder it goes into must exist."""
    if value is not None:
        if Path(value).exists() and not Path(value).is_dir():
            raise PathOptionError(f"{option} {value}: exists and is not a folder")
        _parent_ok(value, f"{option} {value}")
    return value


def _db_new_ok(value: Path) -> Path:
    """A workspace is created when missing, in a folder that exists."""
    _parent_ok(value, f"workspace {value}")
    return value


def _db_existing(value: Path) -> Path:
    """A command that reads a workspace never creates one."""
    if not Path(value).exists():
        _parent_ok(value, f"workspace {value}")
        raise PathOptionError(f"workspace {value} does not exist; create it with `stormlane ingest-ais PATH... --db {value}`")
    return value


#: ``--db`` of a command that writes into the workspace (created when missing, in an existing folder).
DbOption = typer.Option(Path(DEFAULT_DB), "--db", metavar="FILE", callback=_db_new_ok, show_default=True,
                        help="DuckDB workspace file; created when missing (its folder must exist).")
#: ``--db`` of a command that reads the workspace (it must exist).
DbReadOption = typer.Option(Path(DEFAULT_DB), "--db", metavar="FILE", callback=_db_existing, show_default=True,
                            help="DuckDB workspace file (must exist: `stormlane ingest-ais` creates it).")
#: ``--db`` of a command that reads a workspace only for ``--speed-loss learned:NAME`` (checked then).
LearnedDbOption = typer.Option(None, "--db", metavar="FILE", callback=lambda v: None if v is None else _db_existing(v),
                               help=f"DuckDB workspace holding the learned model of --speed-loss learned:NAME (default {DEFAULT_DB}).")


def check_workspace(value: Path | None) -> Path:
    """The workspace of ``--db`` (default :data:`DEFAULT_DB`), which must exist."""
    return _db_existing(Path(value if value is not None else DEFAULT_DB))


JsonOption = typer.Option(False, "--json", help="Print one JSON object on stdout instead of a table.")


def weather_option(without: str) -> typer.models.OptionInfo:
    """``--weather FILE|DIR...``: files or folders, several after one flag or the flag repeated."""
    return typer.Option(
        None, "--weather", metavar="FILE|DIR",
        help="Weather files or folders (CMEMS/ERA5 NetCDF, GFS GRIB, zarr); several after one --weather, or "
             f"--weather repeated. Without it: {without}.")


def vessel_option(without: str) -> typer.models.OptionInfo:
    """``--vessel NAME|FILE`` with the command's part of the one default-vessel rule."""
    return typer.Option(None, "--vessel", metavar="NAME|FILE",
                        help=f"Vessel profile: a name in data/vessels or a TOML file. Default: {without}.")


#: The default vessel where no AIS says which ship it is (``pipelines.vessels.DEFAULT_VESSEL``).
VESSEL_WITHOUT_AIS = "container-feeder (no AIS ship to take it from)"
VESSEL_FROM_AIS = "from the AIS ship type and length of the ship(s) that sailed it, else container-feeder"

ProfileOption = typer.Option(
    None, "--profile", metavar="NAME|FILE",
    help="Operator-limits profile: a name in data/operator_limits.toml or a TOML file (default: that file's default).")
SpeedLossOption = typer.Option("bowditch", "--speed-loss", metavar="|".join(SPEED_LOSS_MODELS),
                               help="Speed-loss model: in waves (bowditch, aertssen, khokhlov), in the wind (kwon), or learned:NAME, "
                                    "a model learned from the fleet's AIS (`stormlane learn performance`; read from --db).",
                               show_default=True)


def speed_loss_choice(text: str, db):
    """``--speed-loss`` resolved by the one shared function (:func:`pipelines.learn.resolve_speed_loss`):
    a name that is neither a formula nor ``learned:NAME`` is one line naming the option; a learned
    model is read from the workspace ``db`` (default :data:`DEFAULT_DB`, which must exist)."""
    from pipelines.learn import parse_learned, resolve_speed_loss
    from routing.speed_loss import MODELS

    learned = parse_learned(text)
    if learned is None and text not in MODELS:
        raise typer.BadParameter(f"{text!r} is not one of {', '.join(MODELS)}, learned:NAME", param_hint="--speed-loss")
    return resolve_speed_loss(text, check_workspace(db) if learned is not None else None)
TaskRunnerOption = typer.Option(
    "sequential", "--task-runner", metavar="sequential|dask[:ADDRESS]", show_default=True,
    help="Where the parallel part runs: in this process, on a local Dask cluster, or on the Dask scheduler at ADDRESS.")


def check_choice(value: str, choices, option: str) -> str:
    """One line naming the option when ``value`` is not one of ``choices``."""
    if value not in choices:
        raise typer.BadParameter(f"{value!r} is not one of {', '.join(choices)}", param_hint=option)
    return value


def paths_text(paths) -> list[str]:
    """Paths given to a multi-valued option, as text (empty when the option was not given)."""
    return [str(p) for p in paths or []]


def _clean(obj):
    """Make numpy scalars, NaN and paths JSON-friendly (NaN becomes null)."""
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if hasattr(obj, "item") and not isinstance(obj, (str, bytes)):
        try:
            obj = obj.item()
        except (ValueError, AttributeError):
            pass
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, Path):
        return str(obj)
    return obj


def emit_json(obj) -> None:
    """Print exactly one JSON object on stdout."""
    typer.echo(json.dumps(_clean(obj), sort_keys=False))


def count(n: int, noun: str) -> str:
    """``n`` and the noun, plural unless ``n`` is 1 ("1 lane", "3 lanes")."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def note(text: str) -> None:
    """One ``note:`` line on stderr (something the user should know; not an error)."""
    typer.echo(f"note: {text}", err=True)


def warning(text: str) -> None:
    """One ``warning:`` line on stderr (the command did its work, but part of it gave nothing)."""
    typer.echo(f"warning: {text}", err=True)


@contextmanager
def warnings_as_lines(logger: str):
    """While the block runs, the WARNING records of ``logger`` (and its children) print as the
    convention's ``warning:`` lines on stderr: without a handler, Python's last-resort handler
    printed the bare message (``x/empty.csv: empty file in x, skipped``)."""
    import logging

    class _Lines(logging.Handler):
        def emit(self, record):
            warning(record.getMessage())

    target, handler = logging.getLogger(logger), _Lines(logging.WARNING)
    target.addHandler(handler)
    try:
        yield
    finally:
        target.removeHandler(handler)


def interactive() -> bool:
    """Progress bars only when a person is watching."""
    return sys.stderr.isatty()


@contextmanager
def progress(description: str, total: float | None = None, enabled: bool | None = None):
    """A rich progress bar on stderr when attached to a terminal; yields ``advance(n, total=None)``
    (``total`` sets the bar's length once it is known)."""
    if enabled is None:
        enabled = interactive()
    if not enabled:
        yield lambda n=1, total=None: None
        return
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),  # "n/?" while the total is unknown
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=Console(stderr=True),
        transient=True,
    ) as bar:
        task = bar.add_task(description, total=total)
        yield lambda n=1, total=None: bar.update(task, advance=n, total=total)


def xarray_without_dask_arrays() -> None:
    """Tell xarray that this process holds no dask arrays, so that it does not import dask.

    With dask installed (stormlane runs Prefect tasks on Dask, never dask *arrays*), xarray
    imports ``dask.array`` (and with it scipy.sparse and scipy.fft) at its first Variable, only
    to check whether the data is a dask array, and ``dask.base`` at every duck-array check: about
    0.4 s of CPU and 40 MB at the start of every command that reads weather, a fifth of a cold
    ``stormlane route``. Every dataset stormlane builds is numpy-backed (the readers never pass
    ``chunks``), so the CLI pre-answers both questions with "no dask". Only the CLI does this, in
    its own process: the library and Dask workers keep xarray's normal behaviour. A no-op when
    dask.array is already imported.
    """
    import sys

    if "dask.array" in sys.modules:
        return
    from packaging.version import Version
    from xarray.namedarray import pycompat, utils

    if "dask" not in pycompat._cached_duck_array_modules:
        none = object.__new__(pycompat.DuckArrayModule)
        none.module, none.version, none.type, none.available = None, Version("0.0.0"), (), False
        pycompat._cached_duck_array_modules["dask"] = none
    utils.is_dask_collection = lambda x: False


def checked_task_runner(spec: str | None) -> str:
    """The kind of a ``--task-runner`` spec (``sequential`` or ``dask``), checked before any work:
    a bad spec, or a ``dask:ADDRESS`` where no scheduler answers, is the one ``error:`` line; a
    scheduler with no worker yet is a ``note:`` line (the tasks wait until a worker joins, as a
    cluster that scales up on demand does)."""
    from pipelines.runners import check_scheduler, parse_task_runner

    kind, address = parse_task_runner(spec)
    if address and check_scheduler(spec) == 0:
        note(f"the Dask scheduler at {address} has no worker yet: the tasks wait until one joins "
             f"(`dask worker {address}`)")
    return kind


def start_prefect_api(spec: str | None) -> None:
    """A command about to run a Prefect flow on the runner ``spec``, its inputs checked: with no
    Prefect API configured, the temporary one starts now, before Prefect is imported, so that it
    boots on another core meanwhile (:mod:`pipelines.prefect_api`). After the checks: a user
    error starts nothing."""
    from pipelines.runners import uses_local_api

    if uses_local_api(spec):
        from pipelines import prefect_api

        prefect_api.start_early()


def quiet_prefect(console_info: bool = True) -> None:
    """Prefect quiet and offline for a command that runs a flow."""
    # quiet and offline (STACK.md): no telemetry look-ups from Prefect
    os.environ.setdefault("PREFECT_SERVER_ANALYTICS_ENABLED", "false")
    os.environ.setdefault("DO_NOT_TRACK", "1")
    if not console_info:
        # an interactive run shows its progress bar and summary, not a log line per task (as
        # `stormlane demo`); PREFECT_LOGGING_LEVEL set by the user wins
        os.environ.setdefault("PREFECT_LOGGING_LEVEL", "WARNING")


def flow_errors_one_line():
    """While a command runs a Prefect flow: a user error ends it with the CLI's one ``error:``
    line, Prefect's run errors held back unless PREFECT_LOGGING_LEVEL asks for Prefect's INFO or
    DEBUG lines (:func:`pipelines.prefect_console.user_errors_one_line`)."""
    from pipelines.prefect_console import prefect_console_verbose, user_errors_one_line

    return user_errors_one_line(hold_console=not prefect_console_verbose())


