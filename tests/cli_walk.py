"""Walking the ``stormlane`` command tree (typer's vendored click) for the CLI tests."""

from __future__ import annotations

import shlex
from contextlib import contextmanager

from typer.core import TyperGroup


def walk_commands(group, prefix: str = ""):
    """``(path, command)`` of every leaf command under ``group``, e.g. ``("weather join", cmd)``."""
    for name, cmd in sorted(group.commands.items()):
        path = f"{prefix} {name}".strip()
        if isinstance(cmd, TyperGroup):
            yield from walk_commands(cmd, path)
        else:
            yield path, cmd


def example_lines(help_text: str, path: str) -> list[str]:
    """The example command lines of a help text: lines starting with ``stormlane <path>``, with
    their backslash continuations joined."""
    joined = help_text.replace("\\\n", " ")
    return [" ".join(line.split()) for line in joined.splitlines() if line.strip().startswith(f"stormlane {path} ")]


@contextmanager
def paths_unchecked(root):
    """Parse without the path callbacks (output folders, workspaces): documented command lines
    name paths of the reader's machine; their options and values are what is checked."""
    saved = []
    for _, cmd in walk_commands(root):
        for p in cmd.params:
            cb = p.callback
            if cb is not None and (cb.__name__ == "<lambda>" or cb.__name__.startswith("_db_")):
                saved.append((p, cb))
                p.callback = None
    try:
        yield
    finally:
        for p, cb in saved:
            p.callback = cb


def parse_command_line(root, line: str):
    """Parse one ``stormlane ...`` line with the command's own parser (nothing runs) and return the
    leaf command's context; an unknown option, a bad value or a missing required option raises
    the parser's error. Paths are not checked (:func:`paths_unchecked`)."""
    words = shlex.split(line)[1:]
    with paths_unchecked(root):
        cmd, ctx = root, root.make_context("stormlane", list(words))
        words = [*ctx._protected_args, *ctx.args]
        while isinstance(cmd, TyperGroup):
            name, cmd, words = cmd.resolve_command(ctx, words)
            ctx = cmd.make_context(name, list(words), parent=ctx)
            if isinstance(cmd, TyperGroup):
                words = [*ctx._protected_args, *ctx.args]
    return ctx
