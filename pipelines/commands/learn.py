"""`stormlane learn ...`: a ship performance model learned from the workspace's AIS x weather.

Commands
--------
``learn performance``  build the training table, fit, validate and store a model (issue 21)
``learn list``         the models stored in the workspace
``learn show NAME``    one model's validation table, training span, settings and versions
"""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from pipelines.commands._common import DbReadOption, JsonOption, emit_json, paths_text, weather_option

learn_app = typer.Typer(help="Learned models: a ship performance model from the fleet's AIS x weather.",
                        no_args_is_help=True, rich_markup_mode=None)


def _time(text: Optional[str], option: str):
    from pipelines.times import utc_or_none
    from thresholds.errors import StormlaneError

    if text is None:
        return None
    t = utc_or_none(text)
    if t is None:
        raise StormlaneError(f"{option} {text!r} is not an ISO 8601 time")
    return t


@learn_app.command("performance")
def performance(
    db: Path = DbReadOption,
    weather: Optional[List[Path]] = weather_option("the weather loaded in the workspace (`stormlane weather load`)"),
    since: Optional[str] = typer.Option(None, "--since", metavar="ISO", help="First AIS time to learn from (UTC if no offset)."),
    until: Optional[str] = typer.Option(None, "--until", metavar="ISO", help="AIS times before this one (UTC if no offset)."),
    classes: Optional[List[str]] = typer.Option(None, "--class", metavar="TYPE",
                                                help="Ship class(es) to learn: passenger, cargo, tanker (AIS ship types "
                                                     "60-69, 70-79, 80-89); default every ship."),
    name: str = typer.Option(..., "--name", metavar="NAME", help="Model name (letters, digits, _ . -); replaces a model of that name."),
    folds: int = typer.Option(5, "--folds", metavar="K", show_default=True, help="Folds of the vessel-grouped cross-validation."),
    json_out: bool = JsonOption,
) -> None:
    """Learn the speed ships make in waves and wind from the workspace's AIS fixes and the weather
    each met; validate it on vessels held out of training and on later weeks against Bowditch,
    Aertssen and Khokhlov on the same fixes; store it in the workspace (table performance_models)
    and its file beside it (WORKSPACE.models/NAME.skops).

    Prints the validation table: MAE, bias and R² in kn per ship class and sea-state band for the
    learned model and each formula, the P10-P90 band's coverage, the time split, and the sea states
    above which each class slows down voluntarily. A model that does not beat the formulas on
    held-out vessels is stored and said to be so.

    --json prints one object with the keys: name, db, span_utc, classes, vessels, fixes, segments,
    table (cleaning counts per rule), kind, prior, band_scale, formulas_outside_range, grouped_cv,
    time_split, voluntary, beats_formulas, params, versions, timings_s, file.

    Example:

    \b
      stormlane learn performance --db work/stormlane.duckdb --name fleet-2025-01
    """
    from pipelines.learn import LearnRequest, learn_performance, table_lines
    from thresholds.errors import StormlaneError

    if folds < 2:
        raise StormlaneError(f"--folds {folds}: the grouped cross-validation needs at least 2 folds")
    req = LearnRequest(db=Path(db), name=name, weather=tuple(paths_text(weather)), since=_time(since, "--since"),
                       until=_time(until, "--until"), classes=tuple(classes or ()), folds=int(folds))
    if req.since is not None and req.until is not None and req.since >= req.until:
        raise StormlaneError(f"--since {since} is not before --until {until}")
    summary = learn_performance(req, echo=(lambda line: None) if json_out else typer.echo)
    if json_out:
        emit_json(summary)
        return
    for line in table_lines(summary):
        typer.echo(line)
    typer.echo(f"stored as {summary['name']!r} in {db} (file {summary['file']}); "
               f"{sum(summary['timings_s'].values()):.1f} s")


@learn_app.command("list")
def list_(db: Path = DbReadOption, json_out: bool = JsonOption) -> None:
    """List the learned models in the workspace, newest first.

    --json prints one object with the key models: a list of (name, created_at, span_start,
    span_end, rows, vessels, classes, kind, prior, beats_formulas, file).

    Example:

    \b
      stormlane learn list --db work/stormlane.duckdb
    """
    from pipelines.storage import open_workspace
    from pipelines.storage.performance import list_models

    with open_workspace(db, read_only=True) as ws:
        df = list_models(ws)
    if json_out:
        emit_json({"models": [{k: (None if v is None else str(v) if k in ("created_at", "span_start", "span_end") else v)
                               for k, v in r.items()} for r in df.to_dict("records")]})
        return
    if df.empty:
        typer.echo(f"no learned models in {db} (run `stormlane learn performance --name NAME`)")
        return
    for r in df.itertuples(index=False):
        typer.echo(f"{r.name:<24} {r.kind:<9} {r.rows:>8,} segments {r.vessels:>4} vessels  {r.classes:<24} "
                   f"{r.span_start:%Y-%m-%d} -> {r.span_end:%Y-%m-%d}  "
                   + ("beats the formulas" if r.beats_formulas else "does NOT beat the formulas"))


@learn_app.command("show")
def show(name: str = typer.Argument(..., metavar="NAME", help="The model's name."), db: Path = DbReadOption,
         json_out: bool = JsonOption) -> None:
    """Show one learned model: its validation table, training span, settings and library versions.

    --json prints the model's row: name, created_at, span_start, span_end, rows, vessels, classes,
    kind, prior, features, beats_formulas, file, file_sha256, versions, params, metrics.

    Example:

    \b
      stormlane learn show fleet-2025-01 --db work/stormlane.duckdb
    """
    from pipelines.learn import row_summary, table_lines
    from pipelines.storage import open_workspace
    from pipelines.storage.performance import read_model

    with open_workspace(db, read_only=True) as ws:
        row = read_model(ws, name)
    if json_out:
        emit_json({k: (str(v) if k in ("created_at", "span_start", "span_end") and v is not None else v)
                   for k, v in row.items()})
        return
    for line in table_lines(row_summary(row)):
        typer.echo(line)
    typer.echo(f"file {row['file']} (sha256 {row['file_sha256'][:12]}...), created {row['created_at']:%Y-%m-%dT%H:%MZ}; "
               + ", ".join(f"{k} {v}" for k, v in row["versions"].items()))


def register(app: typer.Typer) -> None:
    app.add_typer(learn_app, name="learn")
