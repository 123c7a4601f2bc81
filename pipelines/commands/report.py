"""`stormlane report`: re-render a stored report model (nightly run or voyage audit) to HTML."""

from __future__ import annotations

from pathlib import Path

import typer

from pipelines.commands._common import JsonOption, emit_json


def register(app: typer.Typer) -> None:
    @app.command("report")
    def report(
        model: Path = typer.Option(..., "--model", help="Report model JSON written next to a report (report_to_json)."),
        out: Path = typer.Option(..., "--out", help="HTML file to write."),
        screenshot: Path = typer.Option(None, "--screenshot", help="Also save a PNG of the report's first screen (headless Chromium)."),
        json_out: bool = JsonOption,
    ) -> None:
        """Render a nightly or audit report model to one self-contained HTML file."""
        from dashboards.errors import ReportError
        from dashboards.model import NightlyReport, report_from_json
        from dashboards.report import render_report

        try:
            text = model.read_text(encoding="utf-8")
        except OSError as err:
            raise ReportError(f"{model}: cannot read the report model ({err.strerror})") from None
        try:
            obj = report_from_json(text)
        except ReportError as err:
            raise ReportError(f"{model}: {err}") from None
        path = render_report(obj, out)
        shot = None
        if screenshot is not None:
            from dashboards.browser import screenshot as take

            shot = take(path, screenshot)
        kind = "nightly" if isinstance(obj, NightlyReport) else "audit"
        if json_out:
            emit_json({"report": str(path), "kind": kind, "bytes": path.stat().st_size, "screenshot": None if shot is None else str(shot)})
            return
        typer.echo(str(path))
        if shot is not None:
            typer.echo(str(shot))
