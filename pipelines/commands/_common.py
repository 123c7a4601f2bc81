"""Options and output helpers shared by the CLI commands."""

from __future__ import annotations

import json
import math
import sys
from contextlib import contextmanager
from pathlib import Path

import typer

from pipelines.storage import DEFAULT_DB

DbOption = typer.Option(Path(DEFAULT_DB), "--db", help="DuckDB workspace file.", show_default=True)
JsonOption = typer.Option(False, "--json", help="Print one JSON object instead of a table.")


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
