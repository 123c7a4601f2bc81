"""Where the project's own files live, and loading of the TOML configuration in ``data/``."""

from __future__ import annotations

import os
from pathlib import Path

from thresholds.errors import StormlaneError

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


# --- vessel profiles (data/vessels/<name>.toml) -------------------------------------------------


class VesselProfileError(StormlaneError):
    """A vessel profile is unknown or its TOML file is malformed (the message names file and field)."""


#: Fields every profile must give, all positive numbers.
_VESSEL_REQUIRED_POSITIVE = (
    "speed_kn",
    "lpp_m",
    "beam_m",
    "draught_m",
    "dwt_t",
    "installed_power_kw",
    "design_speed_kn",
    "engine_rpm",
    "sfoc_g_kwh",
)
_VESSEL_OPTIONAL_POSITIVE = ("gm_m", "roll_period_s", "displacement_m3")
_VESSEL_FRACTIONS = ("engine_load_frac", "sulphur_frac", "carbon_frac")
_VESSEL_TEXT = ("name", "vessel_class", "fuel", "description")


def vessels_dir() -> Path:
    """Folder of the vessel profiles: ``data/vessels``."""
    return data_dir() / "vessels"


def list_vessels() -> list[str]:
    """Names of the vessel profiles shipped in ``data/vessels`` (file stems), sorted."""
    folder = vessels_dir()
    return sorted(p.stem for p in folder.glob("*.toml")) if folder.is_dir() else []


def _number(path: Path, key: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise VesselProfileError(f"{path}: field {key!r} must be a number, got {value!r}")
    value = float(value)
    if value != value or value in (float("inf"), float("-inf")):
        raise VesselProfileError(f"{path}: field {key!r} must be finite, got {value!r}")
    return value


def parse_vessel(data: dict, path: Path):
    """Validate one profile mapping (from TOML) and build a :class:`thresholds.vessel.Vessel`.

    Unknown keys are refused (typos would otherwise be silently ignored) except inside an
    ``[extra]`` table. Errors name the file and the field.
    """
    from dataclasses import fields as dc_fields

    from thresholds.vessel import Vessel

    known = {f.name for f in dc_fields(Vessel)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise VesselProfileError(
            f"{path}: unknown field(s) {', '.join(map(repr, unknown))}; known fields: {', '.join(sorted(known))} "
            "(put free metadata under an [extra] table)"
        )
    kwargs: dict = {"name": data.get("name", path.stem)}
    missing = [k for k in ("vessel_class", *_VESSEL_REQUIRED_POSITIVE) if k not in data]
    if missing:
        raise VesselProfileError(f"{path}: missing required field(s) {', '.join(map(repr, missing))}")
    for key in _VESSEL_TEXT:
        if key in data:
            if not isinstance(data[key], str):
                raise VesselProfileError(f"{path}: field {key!r} must be a string, got {data[key]!r}")
            kwargs[key] = data[key]
    for key in _VESSEL_REQUIRED_POSITIVE + _VESSEL_OPTIONAL_POSITIVE:
        if key in data:
            value = _number(path, key, data[key])
            if value <= 0:
                raise VesselProfileError(f"{path}: field {key!r} must be positive, got {value:g}")
            kwargs[key] = value
    for key in _VESSEL_FRACTIONS:
        if key in data:
            value = _number(path, key, data[key])
            if not 0.0 <= value <= 1.0:
                raise VesselProfileError(f"{path}: field {key!r} is a fraction in [0, 1], got {value:g}")
            kwargs[key] = value
    if kwargs.get("engine_load_frac", 1.0) == 0.0:
        raise VesselProfileError(f"{path}: field 'engine_load_frac' must be above 0")
    if "min_speed_kn" in data:
        value = _number(path, "min_speed_kn", data["min_speed_kn"])
        if not 0.0 <= value < kwargs["speed_kn"]:
            raise VesselProfileError(f"{path}: field 'min_speed_kn' must be in [0, speed_kn), got {value:g}")
        kwargs["min_speed_kn"] = value
    if "block_coefficient" in data:
        value = _number(path, "block_coefficient", data["block_coefficient"])
        if not 0.3 <= value <= 1.0:
            raise VesselProfileError(f"{path}: field 'block_coefficient' is Cb, in [0.3, 1.0], got {value:g}")
        kwargs["block_coefficient"] = value
    if "loading" in data:
        if data["loading"] not in ("loaded", "ballast"):
            raise VesselProfileError(f"{path}: field 'loading' must be \"loaded\" or \"ballast\", got {data['loading']!r}")
        kwargs["loading"] = data["loading"]
    if "extra" in data:
        if not isinstance(data["extra"], dict):
            raise VesselProfileError(f"{path}: 'extra' must be a table")
        kwargs["extra"] = dict(data["extra"])
    for key in sorted(known - set(kwargs) - {"extra"}):
        if key in data:  # a field added to Vessel later: pass it through unvalidated
            kwargs[key] = data[key]
    return Vessel(**kwargs)


def load_vessel(name_or_path):
    """Load a vessel profile by name (``data/vessels/<name>.toml``) or from a TOML file path.

    Parameters
    ----------
    name_or_path : str or Path
        A profile name such as ``"simroute-r6"`` or a path to a ``.toml`` file.

    Returns
    -------
    thresholds.vessel.Vessel

    Raises
    ------
    VesselProfileError
        Unknown name (the message lists the known ones), unreadable file, bad TOML (with line),
        missing/unknown/invalid field (with file and field).
    """
    import tomllib

    text = str(name_or_path)
    candidate = Path(text).expanduser()
    if candidate.suffix == ".toml" or candidate.is_file() or "/" in text:
        path = candidate
        if not path.is_file():
            raise VesselProfileError(f"vessel profile file not found: {path}")
    else:
        path = vessels_dir() / f"{text}.toml"
        if not path.is_file():
            known = ", ".join(list_vessels()) or "(none)"
            raise VesselProfileError(f"unknown vessel profile {text!r}; known profiles: {known} (or give a .toml file)")
    try:
        with path.open("rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as err:
        raise VesselProfileError(f"{path}: invalid TOML: {err}") from err
    except OSError as err:
        raise VesselProfileError(f"{path}: cannot read: {err}") from err
    return parse_vessel(data, path)
