"""An automatic mesh too coarse for a narrow passage or a port is refined, and says so.

A lake behind a channel narrower than the mesh step (as a fjord or a harbour behind skerries):
with the automatic step the planner halves the step until start and goal connect, plans on the
coarsest step that connects, and notes it; every leg stays at sea on the mask; a step the user
chose is kept and the error stands; a basin that no refinement opens is the same error, saying
how far the mesh was refined. A port with no sea node within the snapping limit (a coarse
weather grid's step) is refined the same way, an inland point refused at once.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from routing import planner
from routing.astar import ShipModel
from routing.errors import DisconnectedSeaError, LandPointError
from routing.mesh import LandMask
from routing.planner import RouteRequest, plan_routes
from routing.planner_window import plan_window
from thresholds.geodesy import intermediate_point

T0 = pd.Timestamp("2025-01-01T00:00Z")
STEP = 1.5 / 60  # the automatic step without weather [deg]


def channel_lake(center_lat: float | None, width_deg: float, calls: list | None = None):
    """A ring of land round a lake at (40.5 N, 3.0 E), cut by a channel due west of ``width_deg``
    centred on ``center_lat`` (None: no channel)."""

    def land(la, lo):
        r = np.hypot(la - 40.5, lo - 3.0)
        ring = (r > 0.3) & (r < 0.45)
        if center_lat is None:
            return ring
        return ring & ~((np.abs(la - center_lat) < width_deg / 2) & (lo < 3.0))

    return _mask(land, calls)


def _mask(land, calls: list | None):
    """A land-mask function (as ``plan_routes`` takes): 30" pixels round the mesh, land where
    ``land(lat, lon)`` of their centres; each mesh step asked is appended to ``calls``."""

    def mask(grid):
        if calls is not None:
            calls.append(grid.dlat_deg)
        ppd = 120
        r0 = int((90.0 - (grid.lat_deg[-1] + 1.5 * grid.dlat_deg)) * ppd)
        c0 = int((grid.lon_deg[0] - 1.5 * grid.dlon_deg + 180.0) * ppd)
        rows = int((grid.ny + 3) * grid.dlat_deg * ppd) + 2
        cols = int((grid.nx + 3) * grid.dlon_deg * ppd) + 2
        la, lo = np.meshgrid(90.0 - (r0 + np.arange(rows) + 0.5) / ppd, -180.0 + (c0 + np.arange(cols) + 0.5) / ppd,
                             indexing="ij")
        return LandMask(~land(la, lo), r0, c0, ppd)

    return mask


def _req(spacing=None):
    return RouteRequest((40.5, 2.0), (40.5, 3.0), T0, ShipModel(12.0, "none"), spacing_deg=spacing)


def _legs_on_mask_at_sea(route, mask_fn, grid) -> bool:
    """Every leg, a great circle sampled every 1/200 of its length, on the mask's sea."""
    mask = mask_fn(grid)
    lat, lon = np.asarray(route.lat_deg, float), np.asarray(route.lon_deg, float)
    f = np.linspace(0.0, 1.0, 200)[:, None]
    return bool(mask.is_ocean(*intermediate_point(lat[:-1], lon[:-1], lat[1:], lon[1:], f)).all())


@pytest.mark.parametrize("center, width, halvings", [(40.5 + STEP / 2, 0.02, 1), (40.5 + STEP / 4, 0.008, 2)],
                         ids=["one-halving", "two-halvings"])
def test_a_channel_narrower_than_the_step_is_planned_on_the_coarsest_step_that_connects(center, width, halvings):
    mask = channel_lake(center, width)
    plan = plan_routes(_req(), None, land_mask_fn=mask)
    step = STEP / 2**halvings
    assert plan.mesh.grid.dlat_deg == pytest.approx(step)
    assert f"start and goal do not connect through the sea on the automatic 1.5 nmi mesh: planned on a {step * 60:.3g} nmi mesh" \
        in plan.notes
    for name in ("optimal", "optimal_smoothed", "min_distance"):
        assert _legs_on_mask_at_sea(plan.routes[name], mask, plan.mesh.grid), name
    # the coarsest that connects: the step before it does not, and the step given by hand plans the same route
    with pytest.raises(DisconnectedSeaError):
        plan_routes(_req(2 * step), None, land_mask_fn=mask)
    same = plan_routes(_req(step), None, land_mask_fn=mask)
    assert same.routes["optimal"].time_h == plan.routes["optimal"].time_h
    assert not any("automatic" in n for n in same.notes)


def test_a_wide_channel_keeps_the_automatic_step_and_says_nothing():
    plan = plan_routes(_req(), None, land_mask_fn=channel_lake(40.5, 0.1))
    assert plan.mesh.grid.dlat_deg == pytest.approx(STEP) and not any("automatic" in n for n in plan.notes)


def test_a_step_the_user_chose_is_kept():
    with pytest.raises(DisconnectedSeaError, match=r"do not connect within the mesh .*1\.5 nmi.*refine the mesh; the great circle's box "
                                                   r"widened up to 16 times its margin on a 1\.5 nmi mesh"):
        plan_routes(_req(STEP), None, land_mask_fn=channel_lake(40.5 + STEP / 2, 0.02))


def test_a_closed_basin_is_refused_after_the_refinements_and_the_wider_boxes():
    """The refinements on the great circle's box (1 deg margin), then the box widened at the first
    step while it holds at most 2 M nodes: margins 2, 4, 8 and 16 deg (33 x 32 deg, 1.69 M nodes;
    32 deg would be 6.6 M)."""
    calls = []
    with pytest.raises(DisconnectedSeaError, match=r"\(the automatic mesh refined from 1\.5 nmi\); the great circle's box widened "
                                                   r"up to 16 times its margin on a 1\.5 nmi mesh did not connect them either$"):
        plan_routes(_req(), None, land_mask_fn=channel_lake(None, 0.0, calls))
    assert calls == pytest.approx([STEP / 2**k for k in range(planner.MAX_MESH_REFINEMENTS + 1)] + [STEP] * 4)


def wall(lat_min: float, lat_max: float):
    """A wall of land 0.2 deg thick at 2.4-2.6 E from ``lat_min`` to ``lat_max``: between start and goal."""
    return _mask(lambda la, lo: (lo > 2.4) & (lo < 2.6) & (la > lat_min) & (la < lat_max), None)


def test_a_sea_way_round_the_box_is_found_in_a_wider_box():
    """The wall ends 3.5 deg south of the route (and 5.5 deg north): the great circle's box (1 deg
    margin) and the box with a 2 deg margin hold no way round it, the 4 deg margin's does (36.5 N). The route is the
    one planned by hand in that box on the same step, every leg at sea; a box given by hand keeps
    its error."""
    mask = wall(37.0, 46.0)
    plan = plan_routes(_req(), None, land_mask_fn=mask)
    assert ("start and goal do not connect through the sea within the great circle's box: planned in a box widened to "
            "lon -2.00..7.00, lat 36.50..44.50") in plan.notes
    assert plan.mesh.grid.dlat_deg == pytest.approx(STEP)
    for name in ("optimal", "optimal_smoothed", "min_distance"):
        route = plan.routes[name]
        assert _legs_on_mask_at_sea(route, mask, plan.mesh.grid), name
        assert min(route.lat_deg) < 37.0  # round the wall's end
    by_hand = plan_routes(dataclasses.replace(_req(STEP), bbox=(-2.0, 36.5, 7.0, 44.5)), None, land_mask_fn=mask)
    assert by_hand.routes["optimal"].time_h == plan.routes["optimal"].time_h
    with pytest.raises(DisconnectedSeaError, match=r"\(bbox \(1\.0, 39\.0, 4\.0, 42\.0\).*\(the automatic mesh refined from 1\.5 nmi\)$"):
        plan_routes(dataclasses.replace(_req(), bbox=(1.0, 39.0, 4.0, 42.0)), None, land_mask_fn=mask)


def test_venice_to_naples_rounds_italy_on_the_land_mask():
    """On the real coastline (routing.land): the great circle's box of Venice -> Naples (1 deg
    margin) holds no sea way; the box widened to an 8 deg margin rounds Italy's heel (the Strait
    of Otranto, 18.5-19.5 E), and every leg of every route is at sea on the land check."""
    from routing import land

    req = RouteRequest((45.4, 12.4), (40.8, 14.2), T0, ShipModel(12.0, "none"))
    plan = plan_routes(req, None)
    assert any(n.startswith("start and goal do not connect through the sea within the great circle's box: planned in a box "
                            "widened to lon 4.40..22.20") for n in plan.notes), plan.notes
    for name in ("optimal", "optimal_smoothed", "min_distance"):
        route = plan.routes[name]
        lat, lon = np.asarray(route.lat_deg), np.asarray(route.lon_deg)
        assert land.legs_at_sea(lat, lon, berths=[(45.4, 12.4), (40.8, 14.2)]).all(), name
        assert lon.max() > 18.0 and lat.min() < 38.5, name  # out of the Adriatic and round Calabria
        assert 700.0 < route.dist_nmi < 900.0, name


def test_a_departure_window_refines_the_same_way():
    res = plan_window(_req(), None, [T0, T0 + pd.Timedelta(hours=6)], land_mask_fn=channel_lake(40.5 + STEP / 2, 0.02))
    assert [r.get("error") for r in res["rows"]] == [None, None]
    assert all(r["route"] is not None for r in res["rows"])
    # the table says it as a single departure's does (it was dropped: a window's rows had no notes)
    assert res["notes"] == ["speed loss: none",
                            "no weather given: every route is sailed in a calm sea (no waves, wind or current)",
                            "start and goal do not connect through the sea on the automatic 1.5 nmi mesh: planned on a 0.75 nmi mesh"]


def coast_west_of(lon_deg: float, calls: list | None = None):
    """Land west of ``lon_deg`` (pixel centres), sea east of it."""
    return _mask(lambda la, lo: lo < lon_deg, calls)


def test_a_port_without_a_sea_node_within_the_limit_is_planned_on_a_finer_step():
    """The start lies on the coast's last land pixel, 0.38 nmi from the sea: on the 1.5 nmi mesh
    its nearest sea node is 1.14 nmi away (over a 1 nmi limit), on 0.75 nmi 0.57 nmi."""
    req = dataclasses.replace(_req(), snap_limit_nmi=1.0)
    plan = plan_routes(req, None, land_mask_fn=coast_west_of(2.005))
    assert plan.mesh.grid.dlat_deg == pytest.approx(STEP / 2)
    assert ("the start has no sea node within 1 nmi on the automatic 1.5 nmi mesh: planned on a 0.75 nmi mesh"
            in plan.notes)
    assert plan.routes["optimal"].properties["start_snap_nmi"] == pytest.approx(0.57, abs=0.01)
    with pytest.raises(LandPointError, match=r"^start \(40\.5000, 2\.0000\) is on land .*\(1\.5 nmi\)"):
        plan_routes(dataclasses.replace(req, spacing_deg=STEP), None, land_mask_fn=coast_west_of(2.005))


def test_an_inland_point_is_refused_at_once():
    """20 nmi from the sea: no mesh finer than the limit brings a sea node within it."""
    calls = []
    with pytest.raises(LandPointError, match=r"no sea node within 10 nmi$"):
        plan_routes(_req(), None, land_mask_fn=coast_west_of(2.44, calls))
    assert calls == [pytest.approx(STEP)]
