"""User-actionable weather errors (the CLI prints them as one line and exits 2)."""

from __future__ import annotations

from thresholds.errors import StormlaneError


class WeatherError(StormlaneError):
    """Base class of the weather package's errors."""


class WeatherFileError(WeatherError):
    """A weather file cannot be read or is not in a recognised product schema."""


class CoverageError(WeatherError):
    """The weather data does not cover a requested time span, area or variable.

    The message names the product, the variable and the missing span or bbox.
    """


class FetchError(WeatherError):
    """A download from CMEMS or the CDS failed (credentials, network, or the service)."""
