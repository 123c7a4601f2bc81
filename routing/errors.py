"""Errors of the routing engine a user can act on (printed by the CLI as one line, exit 2)."""

from __future__ import annotations

from thresholds.errors import StormlaneError


class RoutingError(StormlaneError):
    """Base class of the routing errors."""


class NoRouteError(RoutingError):
    """No sea path joins start and goal on this mesh (land, mesh bounds or resolution)."""


class DisconnectedSeaError(NoRouteError):
    """Start and goal lie in sea areas the mesh does not connect (a passage narrower than its step,
    or the bbox cutting the way round)."""


class LandPointError(RoutingError):
    """A start or goal lies on land farther than the snapping limit from any sea node."""

    def __init__(self, message: str, what: str = "point", limit_nmi: float = 0.0):
        super().__init__(message)
        self.what, self.limit_nmi = what, limit_nmi  # "start" or "goal"; the snapping limit


class OutsideMeshError(RoutingError):
    """A start or goal lies outside the mesh bounding box."""


class WeatherCoverageError(RoutingError):
    """The weather does not cover the departure time or the route's area."""


class MeshSizeError(RoutingError):
    """The requested mesh is empty or too large for memory; choose a coarser spacing or a smaller bbox."""


class WeatherVariableError(WeatherCoverageError):
    """The speed-loss model needs a weather variable the files lack (the message names the model,
    the variable and the files)."""
