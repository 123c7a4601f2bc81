"""Run the ``stormlane`` CLI in-process for tests."""

from __future__ import annotations


def run_cli(capsys, *args) -> tuple[int, str, str]:
    """Run ``stormlane ARGS`` in-process; returns (exit code, stdout, stderr)."""
    from pipelines.cli import main

    try:
        main(list(args))
        code = 0
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    out = capsys.readouterr()
    return code, out.out, out.err
