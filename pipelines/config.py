"""Where the project's own files live, and loading of the TOML configuration in ``data/``."""

from __future__ import annotations

import os
from pathlib import Path

#: Repository root (the project is installed in editable mode by ``make``).
PROJECT_ROOT = Path(__file__).resolve().parents[1]


def data_dir() -> Path:
    """The project's ``data/`` folder (``STORMLANE_DATA_DIR`` overrides it)."""
    return Path(os.environ.get("STORMLANE_DATA_DIR", PROJECT_ROOT / "data"))
