"""Download cache keyed by product, variables, bbox and time range: reruns download nothing.

A cached file lives at ``<cache_dir>/<product>/<key>.nc`` next to ``<key>.json`` describing the
request. The key is a SHA-256 of the normalised request (product, dataset, sorted variables, bbox
rounded to 1e-4°, start and end in UTC to the minute). A download is written to a temporary name
and renamed only once it is complete and readable, so a killed run never leaves a half file
that a later run would trust.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

import pandas as pd


def default_cache_dir() -> Path:
    """``$STORMLANE_CACHE`` or ``~/.cache/stormlane/weather``."""
    env = os.environ.get("STORMLANE_CACHE")
    return Path(env) if env else Path.home() / ".cache" / "stormlane" / "weather"


def _utc_minute(t) -> str:
    ts = pd.Timestamp(t)
    ts = ts.tz_localize("UTC") if ts.tz is None else ts.tz_convert("UTC")
    return ts.strftime("%Y-%m-%dT%H:%MZ")


@dataclass(frozen=True)
class Request:
    """A download request, normalised so equal requests get equal keys."""

    product: str  # "cmems-wave", "cmems-current", "era5-wind" ...
    dataset: str  # CMEMS dataset_id or CDS dataset name
    variables: tuple
    bbox: tuple  # lon_min, lat_min, lon_max, lat_max
    start_utc: str
    end_utc: str

    @classmethod
    def make(cls, product, dataset, variables, bbox, start, end) -> "Request":
        lon_min, lat_min, lon_max, lat_max = (round(float(x), 4) for x in bbox)
        if not (lon_min < lon_max and lat_min < lat_max):
            raise ValueError(f"bbox must be lon_min < lon_max and lat_min < lat_max, got {bbox}")
        start_s, end_s = _utc_minute(start), _utc_minute(end)
        if start_s > end_s:
            raise ValueError(f"start {start_s} is after end {end_s}")
        return cls(product, dataset, tuple(sorted(variables)), (lon_min, lat_min, lon_max, lat_max), start_s, end_s)

    def to_dict(self) -> dict:
        return {"product": self.product, "dataset": self.dataset, "variables": list(self.variables),
                "bbox": list(self.bbox), "start_utc": self.start_utc, "end_utc": self.end_utc}

    @property
    def key(self) -> str:
        return hashlib.sha256(json.dumps(self.to_dict(), sort_keys=True).encode()).hexdigest()[:16]


class DownloadCache:
    """Files downloaded for :class:`Request` objects."""

    def __init__(self, root: str | Path | None = None):
        self.root = Path(root) if root else default_cache_dir()

    def path_for(self, req: Request, suffix: str = ".nc") -> Path:
        return self.root / req.product / f"{req.key}{suffix}"

    def lookup(self, req: Request, suffix: str = ".nc") -> Path | None:
        """The cached file for ``req`` if it exists and its description matches."""
        path = self.path_for(req, suffix)
        meta = path.with_suffix(".json")
        if path.exists() and path.stat().st_size > 0 and meta.exists():
            try:
                if json.loads(meta.read_text()).get("request") == req.to_dict():
                    return path
            except (OSError, ValueError):
                return None
        return None

    def temp_path(self, req: Request, suffix: str = ".nc") -> Path:
        path = self.path_for(req, suffix)
        path.parent.mkdir(parents=True, exist_ok=True)
        return path.with_name(f".{path.stem}.partial{suffix}")

    def commit(self, req: Request, tmp: Path, extra: dict | None = None, suffix: str = ".nc") -> Path:
        """Move a complete download into place and write its description."""
        path = self.path_for(req, suffix)
        os.replace(tmp, path)
        path.with_suffix(".json").write_text(json.dumps({"request": req.to_dict(), **(extra or {})}, indent=1))
        return path
