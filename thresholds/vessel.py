"""Vessel particulars shared by the thresholds, the speed-loss models and the emission model.

Profiles are configuration (TOML files under ``data/vessels/``), loaded by
``pipelines.config.load_vessel``; this module only defines the typed record.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields


@dataclass(frozen=True)
class Vessel:
    """One ship's particulars.

    Attributes carry their units. ``gm_m`` or ``roll_period_s`` gives the natural roll period
    (IS Code 2008, Part A, 2.3.4); ``vessel_class`` selects the operator limits.
    ``block_coefficient`` (Cb), ``loading`` ("loaded" or "ballast") and ``displacement_m3``
    (default Cb·Lpp·B·T) are what Kwon's wind speed-loss method needs.
    """

    name: str
    vessel_class: str  # "container", "ro-pax", "tanker", "bulk", "general"
    speed_kn: float  # service speed in calm water
    lpp_m: float
    beam_m: float
    draught_m: float
    dwt_t: float
    installed_power_kw: float
    design_speed_kn: float
    engine_rpm: float
    sfoc_g_kwh: float
    gm_m: float | None = None
    roll_period_s: float | None = None
    engine_load_frac: float = 0.8
    fuel: str = "HFO"
    sulphur_frac: float = 0.027
    carbon_frac: float = 0.85
    min_speed_kn: float = 2.0  # speed floor for the speed-loss models
    block_coefficient: float | None = None  # Cb, Kwon's method
    loading: str = "loaded"  # "loaded" or "ballast", Kwon's method
    displacement_m3: float | None = None  # displacement volume; default Cb * Lpp * B * T
    description: str = ""
    extra: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "Vessel":
        """Build from a mapping; unknown keys go to ``extra`` rather than being lost."""
        known = {f.name for f in fields(cls)}
        kwargs = {k: v for k, v in data.items() if k in known}
        extra = {k: v for k, v in data.items() if k not in known}
        if extra:
            kwargs["extra"] = {**kwargs.get("extra", {}), **extra}
        return cls(**kwargs)
