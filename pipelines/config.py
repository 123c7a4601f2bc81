"""Where the project's own files live, and loading of the TOML configuration in ``data/``."""

from __future__ import annotations

import os
from pathlib import Path

#: Repository root (the project is installed in editable mode by ``make``).
PROJECT_ROOT = Path(__file__).resolve().parents[1]


def data_dir() -> Path:
    """The project's ``data/`` folder (``STORMLANE_DATA_DIR`` overrides it)."""
    return Path(os.environ.get("STORMLANE_DATA_DIR", PROJECT_ROOT / "data"))


OPERATOR_LIMITS_FILE = "operator_limits.toml"


def _read_toml(path: Path) -> dict:
    import tomllib

    from thresholds.operator import OperatorProfileError

    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise OperatorProfileError(f"operator limits file not found: {path}") from None
    except tomllib.TOMLDecodeError as err:
        raise OperatorProfileError(f"{path}: invalid TOML: {err}") from None


def operator_profile_names(path: str | Path | None = None) -> list[str]:
    """Names of the profiles in an operator-limits file (default ``data/operator_limits.toml``)."""
    data = _read_toml(Path(path) if path else data_dir() / OPERATOR_LIMITS_FILE)
    return sorted(data.get("profiles", {}))


def load_operator_profile(name_or_path: str | Path | None = None):
    """Load an operator profile by name from ``data/operator_limits.toml``, or from a TOML file.

    Parameters
    ----------
    name_or_path : str or Path, optional
        A profile name (``"default"``, ``"seed-literal"`` ...), or a path to a TOML file holding
        either one profile (top-level ``description``, ``imo``, ``[[limits]]``) or several
        (``[profiles.<name>]`` plus an optional top-level ``default = "<name>"``). ``None``
        gives the file's default profile. ``"file.toml:name"`` picks one profile of a file.

    Returns
    -------
    thresholds.operator.OperatorProfile

    Raises
    ------
    thresholds.operator.OperatorProfileError
        Unknown profile (the message lists the available ones), invalid TOML (with line and
        column), unknown keys or bad values (naming the file, profile and variant).
    """
    from thresholds.operator import OperatorProfile, OperatorProfileError

    text = None if name_or_path is None else str(name_or_path)
    wanted = None
    if text is not None and (text.endswith(".toml") or ".toml:" in text or Path(text).is_file()):
        file_part, _, wanted = text.partition(".toml:") if ".toml:" in text else (text, "", "")
        path = Path(file_part + ".toml") if ".toml:" in text else Path(file_part)
        wanted = wanted or None
    else:
        path = data_dir() / OPERATOR_LIMITS_FILE
        wanted = text
    data = _read_toml(path)
    if "profiles" not in data:
        if wanted is not None:
            raise OperatorProfileError(f"{path} holds a single profile; drop ':{wanted}'")
        return OperatorProfile.from_dict(path.stem, data, where=str(path))
    profiles = data["profiles"]
    if wanted is None:
        wanted = data.get("default") or (next(iter(profiles)) if len(profiles) == 1 else None)
        if wanted is None:
            raise OperatorProfileError(f"{path}: several profiles and no top-level default = \"<name>\"")
    if wanted not in profiles:
        raise OperatorProfileError(
            f"unknown operator profile {wanted!r} in {path}; available: {', '.join(sorted(profiles))}"
        )
    return OperatorProfile.from_dict(wanted, profiles[wanted], where=f"{path} [profiles.{wanted}]")
