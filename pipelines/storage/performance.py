"""Learned performance models: the ``performance_models`` table and the model files.

A model's row holds its name, training span, rows, features, the cleaning rules and fit settings
(what :func:`pipelines.storage.training.training_table` needs to rebuild the same table), the
validation (metrics, coverage, learned voluntary thresholds), the library versions, and the path
of its file. The file lies next to the workspace (``<workspace>.models/<name>.skops``) and is
written with **skops** (``skops.io``), whose loader rebuilds only the object types it is told to
trust: :func:`load_model_file` trusts exactly the scikit-learn types a
``HistGradientBoostingRegressor`` is made of (:data:`TRUSTED_TYPES`) and refuses a file holding
anything else, so a model file cannot run code the way a pickle can.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pandas as pd

from thresholds.errors import StormlaneError

COMPONENT = "performance"

MIGRATIONS = [
    [
        """CREATE TABLE performance_models (
            name          VARCHAR PRIMARY KEY,
            created_at    TIMESTAMPTZ NOT NULL DEFAULT now(),
            span_start    TIMESTAMPTZ,
            span_end      TIMESTAMPTZ,
            rows          BIGINT NOT NULL,
            vessels       INTEGER NOT NULL,
            classes       VARCHAR NOT NULL,
            kind          VARCHAR NOT NULL,
            prior         VARCHAR,
            features      VARCHAR NOT NULL,
            beats_formulas BOOLEAN NOT NULL,
            file          VARCHAR NOT NULL,
            file_sha256   VARCHAR NOT NULL,
            versions_json VARCHAR NOT NULL,
            params_json   VARCHAR NOT NULL,
            metrics_json  VARCHAR NOT NULL
        )""",
    ],
]

#: Object types a model file may hold (everything else is refused by :func:`load_model_file`).
TRUSTED_TYPES = (
    "sklearn.ensemble._hist_gradient_boosting.gradient_boosting.HistGradientBoostingRegressor",
    "sklearn.ensemble._hist_gradient_boosting.predictor.TreePredictor",
    "sklearn.ensemble._hist_gradient_boosting.binning._BinMapper",
    "sklearn._loss.loss.HalfSquaredError",
    "sklearn._loss.loss.PinballLoss",
    "sklearn._loss.link.IdentityLink",
    "sklearn._loss.link.Interval",
    "numpy.dtype",
    # the regressor's input check: a partial of check_array (skops checks the wrapped function
    # on its own, so a partial around anything else is still refused)
    "functools.partial",
    "sklearn.utils.validation.check_array",
)

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")


class ModelError(StormlaneError):
    """A learned model that does not exist, has a bad name, or whose file cannot be trusted."""


def check_name(name: str) -> str:
    """A model name: letters, digits, ``_ . -``, at most 64 characters (it names a file)."""
    if not _NAME.match(str(name or "")):
        raise ModelError(f"--name {name!r}: a model name is 1-64 letters, digits, '_', '.' or '-' and starts "
                         "with a letter or digit")
    return str(name)


def models_dir(workspace: str | Path) -> Path:
    """Where a workspace's model files go: ``<workspace>.models/`` beside it."""
    p = Path(workspace)
    return p.with_name(p.name + ".models")


def _sha256(path: Path) -> str:
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()


def save_model_file(workspace: str | Path, name: str, state: dict) -> tuple[Path, str]:
    """Write a model's state (plain types and estimators) with skops; returns (path, sha256)."""
    import skops.io as sio

    folder = models_dir(workspace)
    folder.mkdir(exist_ok=True)
    path = folder / f"{check_name(name)}.skops"
    tmp = path.with_suffix(".skops.tmp")
    sio.dump(state, tmp)
    tmp.replace(path)
    return path, _sha256(path)


def load_model_file(path: str | Path, sha256: str | None = None) -> dict:
    """A model's state from its skops file, refusing any type outside :data:`TRUSTED_TYPES` and a
    file whose SHA-256 is not the one recorded in the workspace."""
    import skops.io as sio

    path = Path(path)
    if not path.is_file():
        raise ModelError(f"model file {path} is missing (was the workspace moved without its .models folder?)")
    if sha256 is not None and _sha256(path) != sha256:
        raise ModelError(f"model file {path} is not the file the workspace recorded (SHA-256 differs): refit it")
    try:
        untrusted = set(sio.get_untrusted_types(file=path))
    except Exception as err:  # noqa: BLE001 - any failure to parse is a bad file
        raise ModelError(f"model file {path} is not a skops model file ({err})") from None
    unknown = sorted(untrusted - set(TRUSTED_TYPES))
    if unknown:
        raise ModelError(f"model file {path} holds types this version does not trust: {', '.join(unknown)}")
    return sio.load(path, trusted=sorted(untrusted))


def write_model(ws, row: dict) -> None:
    """Insert or replace a model's row (``row`` has the table's columns; dicts are stored as JSON)."""
    cols = ["name", "span_start", "span_end", "rows", "vessels", "classes", "kind", "prior", "features", "beats_formulas",
            "file", "file_sha256", "versions_json", "params_json", "metrics_json"]
    vals = []
    for c in cols:
        v = row[c]
        if isinstance(v, (dict, list)):
            v = json.dumps(v, default=str)
        vals.append(v)
    with ws.transaction() as con:
        con.execute("DELETE FROM performance_models WHERE name = ?", [row["name"]])
        con.execute(f"INSERT INTO performance_models ({', '.join(cols)}) VALUES ({', '.join('?' * len(cols))})", vals)


def list_models(ws) -> pd.DataFrame:
    """Every model's summary row, newest first."""
    df = ws.con.execute(
        "SELECT name, created_at, span_start, span_end, rows, vessels, classes, kind, prior, beats_formulas, file "
        "FROM performance_models ORDER BY created_at DESC, name").df()
    for c in ("created_at", "span_start", "span_end"):
        df[c] = pd.to_datetime(df[c], utc=True)
    return df


def read_model(ws, name: str) -> dict:
    """One model's row, JSON columns parsed; :class:`ModelError` naming the models there when absent."""
    cur = ws.con.execute("SELECT * FROM performance_models WHERE name = ?", [str(name)])
    cols = [d[0] for d in cur.description]
    rows = cur.fetchall()
    if not rows:
        names = [r[0] for r in ws.con.execute("SELECT name FROM performance_models ORDER BY name").fetchall()]
        raise ModelError(f"no learned model {name!r} in the workspace (models: {', '.join(names) or 'none'}; "
                         "run `stormlane learn performance --name NAME`)")
    row = dict(zip(cols, rows[0]))
    for c in ("versions_json", "params_json", "metrics_json"):
        row[c.removesuffix("_json")] = json.loads(row.pop(c))
    for c in ("created_at", "span_start", "span_end"):
        row[c] = pd.Timestamp(row[c]).tz_convert("UTC") if row[c] is not None else None
    return row
