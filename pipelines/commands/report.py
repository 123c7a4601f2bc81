"""`stormlane report`: re-render a stored report model (nightly run or voyage audit) to HTML."""

from __future__ import annotations

from pathlib import Path

import typer

from pipelines.commands._common import JsonOption, check_output_file, emit_json


def register(app: typer.Typer) -> None:
    @app.command("report")
    def report(
        model: Path = typer.Option(..., "--model", metavar="FILE.json", help="Report model JSON written next to a report (report.json of `stormlane nightly`)."),
        out: Path = typer.Option(..., "--out", metavar="FILE.html", callback=lambda v: check_output_file(v, "--out"), help="HTML file to write."),
        screenshot: Path = typer.Option(None, "--screenshot", metavar="FILE.png", callback=lambda v: check_output_file(v, "--screenshot"),
                                        help="Also save a PNG of the report's first screen (headless Chromium)."),
        json_out: bool = JsonOption,
    ) -> None:
        """Render a nightly or audit report model to one self-contained HTML file.

        Example:

        \b
          stormlane report --model work/nightly/report.json --out night.html --screenshot night.png
        """
        from dashboards.errors import ReportError
        from dashboards.model import NightlyReport, report_from_json
        from dashboards.report import render_report

        try:
            text = model.read_text(encoding="utf-8")
        except OSError as err:
            raise ReportError(f"{model}: cannot read the report model ({err.strerror})") from None
        except UnicodeDecodeError as err:
            raise ReportError(f"{model}: not a report model (binary content: byte {err.start} is not UTF-8 text)") from None
        try:
            obj = report_from_json(text)
        except ReportError as err:
            raise ReportError(f"{model}: {err}") from None
        try:
            path = render_report(obj, out)
        except (TypeError, ValueError, KeyError, AttributeError, IndexError) as err:
            # the JSON decoded but holds values of the wrong kind (an edited file): one line
            raise ReportError(f"{model}: report model JSON is malformed ({type(err).__name__}: "
                              f"{' '.join(str(err).split())[:300]})") from None
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
