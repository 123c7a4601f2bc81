"""The DuckDB workspace: the one place with SQL.

A workspace is one DuckDB file (default ``stormlane.duckdb`` in the working directory). Each
module of this package owns the tables of one component (``ais``, ``lanes``, ``weather`` ...):
it declares ``COMPONENT`` and ``MIGRATIONS`` (a list of migrations, each a list of SQL
statements) next to the functions that read and write those tables. Parameters are always bound
(``?``), never formatted into SQL. :func:`open_workspace` applies pending migrations in order and
records them in ``schema_version`` (one row per component and version).
"""

from __future__ import annotations

import importlib
import pkgutil
from contextlib import contextmanager
from pathlib import Path

import duckdb

from thresholds.errors import StormlaneError

DEFAULT_DB = "stormlane.duckdb"

_SCHEMA_TABLE_SQL = """
CREATE TABLE IF NOT EXISTS schema_version (
    component  VARCHAR NOT NULL,
    version    INTEGER NOT NULL,
    applied_at TIMESTAMPTZ NOT NULL DEFAULT now(),
    PRIMARY KEY (component, version)
)
"""


def _components() -> dict[str, list[list[str]]]:
    """Discover every storage module declaring ``COMPONENT`` and ``MIGRATIONS``."""
    found: dict[str, list[list[str]]] = {}
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        module = importlib.import_module(f"{__name__}.{info.name}")
        component = getattr(module, "COMPONENT", None)
        if component is None:
            continue
        if component in found:
            raise RuntimeError(f"storage component {component!r} declared twice")
        found[component] = module.MIGRATIONS
    return found


def migrate(con: duckdb.DuckDBPyConnection) -> dict[str, int]:
    """Apply pending migrations, each in its own transaction; return the version per component."""
    con.execute(_SCHEMA_TABLE_SQL)
    versions: dict[str, int] = {}
    for component, migrations in _components().items():
        row = con.execute(
            "SELECT coalesce(max(version), 0) FROM schema_version WHERE component = ?", [component]
        ).fetchone()
        current = int(row[0])
        if current > len(migrations):
            raise RuntimeError(
                f"workspace schema for {component!r} is version {current}, newer than this code ({len(migrations)})"
            )
        for version, statements in enumerate(migrations[current:], start=current + 1):
            con.execute("BEGIN TRANSACTION")
            try:
                for sql in statements:
                    con.execute(sql)
                con.execute("INSERT INTO schema_version (component, version) VALUES (?, ?)", [component, version])
                con.execute("COMMIT")
            except Exception:
                con.execute("ROLLBACK")
                raise
        versions[component] = len(migrations)
    return versions


class WorkspaceError(StormlaneError):
    """The ``--db`` path is not a DuckDB workspace (another kind of file)."""


#: Bytes 8..11 of every DuckDB database file (its main header's magic).
_DUCKDB_MAGIC = b"DUCK"


def _check_is_duckdb(path: Path) -> None:
    """A file that exists must be a DuckDB database: say so in one line instead of DuckDB's
    IOException (a lock held by another process stays an IOException: that one is transient)."""
    if not path.is_file():
        if path.exists():
            raise WorkspaceError(f"workspace {path} is not a file (give --db a DuckDB file)")
        return
    with path.open("rb") as fh:
        head = fh.read(12)
    if head[8:12] != _DUCKDB_MAGIC:
        raise WorkspaceError(f"workspace {path} is not a DuckDB database file ({'empty' if not head else 'other content'}); "
                             "give --db a stormlane workspace or a new file name")


def _check_is_workspace(con, path: Path) -> None:
    """A DuckDB database with tables must be a stormlane workspace (it has ``schema_version``):
    another application's database is never migrated into one (nor half-migrated, when one of
    its tables has a workspace table's name)."""
    names = [r[0] for r in con.execute(
        "SELECT table_name FROM information_schema.tables WHERE table_catalog = current_database() "
        "AND table_schema = 'main' ORDER BY table_name").fetchall()]
    if names and "schema_version" not in names:
        shown = ", ".join(names[:5]) + (f" and {len(names) - 5} more" if len(names) > 5 else "")
        raise WorkspaceError(f"workspace {path} is a DuckDB database but not a stormlane workspace (it holds "
                             f"{shown} and no schema_version table); give --db a stormlane workspace or a new file name")


class Workspace:
    """An open DuckDB workspace. Use as a context manager; ``con`` is the DuckDB connection."""

    def __init__(self, path: str | Path = DEFAULT_DB, read_only: bool = False):
        self.path = Path(path)
        if read_only and not self.path.exists():
            raise FileNotFoundError(f"workspace {self.path} does not exist (run `stormlane ingest-ais` or `stormlane demo` first)")
        _check_is_duckdb(self.path)
        if not read_only and not self.path.parent.is_dir():
            # a typo in a folder name must not silently create a new tree of folders
            what = "is not a folder" if self.path.parent.exists() else "does not exist"
            raise WorkspaceError(f"workspace {self.path}: folder {self.path.parent} {what}")
        self.con = duckdb.connect(str(self.path), read_only=read_only)
        self.read_only = read_only
        try:
            _check_is_workspace(self.con, self.path)
            if not read_only:
                migrate(self.con)
        except BaseException:
            self.con.close()
            raise

    @contextmanager
    def transaction(self):
        """All statements inside commit together or not at all."""
        self.con.execute("BEGIN TRANSACTION")
        try:
            yield self.con
        except BaseException:
            self.con.execute("ROLLBACK")
            raise
        self.con.execute("COMMIT")

    def close(self) -> None:
        self.con.close()

    def __enter__(self) -> "Workspace":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def open_workspace(path: str | Path | None = None, read_only: bool = False) -> Workspace:
    """Open (and create or migrate) the workspace at ``path`` (default ``stormlane.duckdb``)."""
    return Workspace(path or DEFAULT_DB, read_only=read_only)
