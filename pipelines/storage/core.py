"""Workspace-wide bookkeeping tables."""

COMPONENT = "core"

MIGRATIONS = [
    [
        """CREATE TABLE workspace_meta (
            key   VARCHAR PRIMARY KEY,
            value VARCHAR NOT NULL
        )""",
        "INSERT INTO workspace_meta VALUES ('created_at', CAST(now() AS VARCHAR))",
    ],
]


def describe(ws) -> dict:
    """Schema version per component and row count per table."""
    schema = dict(
        ws.con.execute("SELECT component, max(version) FROM schema_version GROUP BY component ORDER BY component").fetchall()
    )
    names = [r[0] for r in ws.con.execute(
        "SELECT table_name FROM information_schema.tables WHERE table_schema = 'main' ORDER BY table_name"
    ).fetchall()]
    tables = {}
    for name in names:
        # Identifiers cannot be bound as parameters; quote the catalogue's own name.
        quoted = '"' + name.replace('"', '""') + '"'
        tables[name] = int(ws.con.execute(f"SELECT count(*) FROM {quoted}").fetchone()[0])
    return {"path": str(ws.path), "schema": schema, "tables": tables}
