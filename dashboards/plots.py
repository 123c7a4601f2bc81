"""Static figures for the reports, drawn with matplotlib's object API (no pyplot state, Agg).

Every function returns PNG bytes that the renderer inlines as a ``data:`` URI, so a report
needs no file but itself and no network (no tile server, no Natural Earth download: land comes
from the 30-arc-second mask bundled with ``global-land-mask``, at its own resolution).
Only numbers and the project's own labels are drawn; AIS-supplied text never enters a figure
(it is written, escaped, into the HTML around it).
"""

from __future__ import annotations

import io

import numpy as np
import pandas as pd

from dashboards.model import ROLE_LABELS, SpeedLossCurve, WeatherSnapshot
from routing.route import Route

#: Line styles per route role (Okabe-Ito colours, readable by colour-blind readers).
ROLE_STYLE = {
    "historical": {"color": "#000000", "linestyle": (0, (5, 3)), "linewidth": 2.0},
    "lane": {"color": "#000000", "linestyle": (0, (5, 3)), "linewidth": 2.0},
    "as_sailed": {"color": "#000000", "linestyle": "-", "linewidth": 1.6},
    "as_sailed_modelled": {"color": "#E69F00", "linestyle": (0, (5, 3)), "linewidth": 2.0},
    "deviation": {"color": "#009E73", "linestyle": "-", "linewidth": 2.4},
    "optimal": {"color": "#0072B2", "linestyle": "-", "linewidth": 2.4},
    "safe_optimal": {"color": "#56B4E9", "linestyle": (0, (8, 2)), "linewidth": 2.6},
    "min_distance": {"color": "#CC79A7", "linestyle": (0, (6, 2, 1, 2)), "linewidth": 2.0},
    "least_fuel": {"color": "#D55E00", "linestyle": (0, (3, 1.5)), "linewidth": 2.2},
}
OTHER_STYLE = {"color": "#7f7f7f", "linestyle": ":", "linewidth": 1.8}
HS_CMAP = "YlOrRd"
LAND_RGB = (0.85, 0.83, 0.78)
LIMIT_COLOR = "#7a0177"


def style_for(role: str) -> dict:
    return dict(ROLE_STYLE.get(role, OTHER_STYLE))


def label_for(role: str) -> str:
    return ROLE_LABELS.get(role, role.replace("_", " "))


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", bbox_inches="tight", metadata={"Software": None})
    return palette_png(buf.getvalue())


def palette_png(png: bytes, colors: int = 256) -> bytes:
    """The figure as an 8-bit palette PNG (median cut, no dithering), when that is smaller: a
    figure holds few distinct colours, and a report of 20 maps is a third of the size (issue 22)."""
    from PIL import Image

    img = Image.open(io.BytesIO(png)).convert("RGB")
    small = img.quantize(colors=colors, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    out = io.BytesIO()
    small.save(out, format="PNG", optimize=True)
    return out.getvalue() if out.tell() < len(png) else png


def _naive_utc(times: pd.DatetimeIndex) -> np.ndarray:
    return pd.DatetimeIndex(times).tz_convert("UTC").tz_localize(None).to_numpy()


def map_extent(routes: dict, weather: WeatherSnapshot | None = None, pad_frac: float = 0.15, min_pad_deg: float = 0.4):
    """Lon/lat box around all routes (padded); the whole weather grid when there is no route."""
    lats = [r.lat_deg for r in routes.values() if r.n_waypoints]
    lons = [r.lon_deg for r in routes.values() if r.n_waypoints]
    if lats:
        lat = np.concatenate(lats)
        # one continuous longitude frame (the routes' lines are drawn unwrapped): a route across the
        # antimeridian spans 170..190, not -180..180
        ref = float(lons[0][0])
        lon = np.concatenate([ref + (np.degrees(np.unwrap(np.radians(np.asarray(x, dtype=float)))) - float(x[0]))
                              + ((float(x[0]) - ref + 180.0) % 360.0 - 180.0) for x in lons])
    elif weather is not None:
        lat, lon = weather.lat_deg, weather.lon_deg
    else:
        raise ValueError("nothing to draw: no route and no weather")
    lat0, lat1, lon0, lon1 = float(np.min(lat)), float(np.max(lat)), float(np.min(lon)), float(np.max(lon))
    pad_lat = max((lat1 - lat0) * pad_frac, min_pad_deg)
    pad_lon = max((lon1 - lon0) * pad_frac, min_pad_deg)
    return lon0 - pad_lon, lon1 + pad_lon, max(lat0 - pad_lat, -89.9), min(lat1 + pad_lat, 89.9)


def land_mask(lon0: float, lon1: float, lat0: float, lat1: float, max_px: int = 2400):
    """Land over a box at the 30" mask's own resolution (global-land-mask, through the cache of
    :mod:`thresholds.land_raster`), so a map shows exactly the land the land check sees.

    Boxes wider or taller than ``max_px`` raster pixels (20 deg; a map is ~620 screen pixels wide)
    are drawn in blocks of k x k pixels, a block being land when any of its pixels is (land is
    never hidden, only thickened).

    Returns
    -------
    lon_edges, lat_edges, is_land
        Cell edges (ascending, ``nx + 1`` and ``ny + 1``) [deg] and ``is_land[lat, lon]`` (rows
        south to north).
    """
    from routing.land import land_window

    w = land_window(lat0, lat1, lon0, lon1)
    land = ~w.ocean[::-1]  # rows south to north
    ppd = w.px_per_deg
    lat_edges = 90.0 - (w.r0 + land.shape[0] - np.arange(land.shape[0] + 1)) / ppd
    lon_edges = -180.0 + (w.c0 + np.arange(land.shape[1] + 1)) / ppd
    lon_edges = lon_edges + 360.0 * np.round((lon0 - lon_edges[0]) / 360.0)  # the box's own longitude frame
    k = int(np.ceil(max(land.shape) / max_px))
    if k > 1:
        ny, nx = -(-land.shape[0] // k) * k, -(-land.shape[1] // k) * k
        pad = np.zeros((ny, nx), dtype=bool)
        pad[: land.shape[0], : land.shape[1]] = land
        land = pad.reshape(ny // k, k, nx // k, k).any(axis=(1, 3))
        lat_edges = lat_edges[0] + np.arange(land.shape[0] + 1) * k / ppd
        lon_edges = lon_edges[0] + np.arange(land.shape[1] + 1) * k / ppd
    return lon_edges, lat_edges, land


def gc_polyline(lat_deg, lon_deg, step_nmi: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """A route's legs as drawn: points along each great circle at most ``step_nmi`` apart, the
    longitudes made continuous, so a map shows the legs the route sails (a straight line in
    lat/lon between two waypoints is not the leg and can miss or invent a land crossing)."""
    from thresholds.geodesy import haversine_nmi, intermediate_point

    lat = np.asarray(lat_deg, dtype=float)
    lon = np.asarray(lon_deg, dtype=float)
    if lat.size < 2:
        return lat, lon
    out_lat, out_lon = [lat[:1]], [lon[:1]]
    for k in range(lat.size - 1):
        n = max(1, int(np.ceil(float(haversine_nmi(lat[k], lon[k], lat[k + 1], lon[k + 1])) / step_nmi)))
        la, lo = intermediate_point(lat[k], lon[k], lat[k + 1], lon[k + 1], np.arange(1, n + 1) / n)
        out_lat.append(np.atleast_1d(la))
        out_lon.append(np.atleast_1d(lo))
    la, lo = np.concatenate(out_lat), np.concatenate(out_lon)
    step = (np.diff(lo) + 180.0) % 360.0 - 180.0
    return la, np.concatenate([[lon[0]], lon[0] + np.cumsum(step)])


def route_map_png(
    routes: dict,
    weather: WeatherSnapshot | None = None,
    *,
    hs_limit_m: float | None = None,
    worst: tuple | None = None,
    worst_role: str = "reference",
    width_in: float = 6.2,
    dpi: int = 100,
) -> bytes:
    """Map: land, Hs field and wave-direction arrows at the snapshot time, routes with a legend.

    Parameters
    ----------
    routes : dict of str -> Route
        Keyed by role; drawn in :data:`ROLE_STYLE` colours.
    weather : WeatherSnapshot, optional
        Hs field (colour) and mean wave direction (arrows pointing where the waves travel TO,
        i.e. ``wave_from_deg + 180``).
    hs_limit_m : float, optional
        Vessel's Hs limit, drawn as a contour. [m]
    worst : (lat_deg, lon_deg), optional
        Where the worst weather is met, marked with a star.
    worst_role : str
        The route it is met on (the legend names it).
    """
    from matplotlib.figure import Figure

    lon0, lon1, lat0, lat1, aspect = _map_box(routes, weather)
    height_in = width_in * (lat1 - lat0) * aspect / (lon1 - lon0) * 0.9 + 1.6
    fig = Figure(figsize=(width_in, height_in), dpi=dpi)
    ax = fig.add_subplot()
    ax.set_facecolor("white")
    handles = []

    if weather is not None:
        _draw_weather(fig, ax, weather, (lon0, lon1, lat0, lat1), hs_limit_m, handles)

    lon_e, lat_e, land = land_mask(lon0, lon1, lat0, lat1)
    rgba = np.zeros(land.shape + (4,), dtype=np.uint8)  # 4 bytes a pixel: the mask's own resolution stays small
    rgba[land] = [round(255 * x) for x in (*LAND_RGB, 1.0)]
    ax.imshow(rgba, extent=(lon_e[0], lon_e[-1], lat_e[0], lat_e[-1]), origin="lower", interpolation="nearest", zorder=4, aspect="auto")

    _draw_routes(ax, routes, worst, worst_role, handles)

    ax.set_xlim(lon0, lon1)
    ax.set_ylim(lat0, lat1)
    ax.set_aspect(aspect)
    ax.set_xlabel("longitude [deg E]")
    ax.set_ylabel("latitude [deg N]")
    ax.grid(True, color="#999999", linewidth=0.4, alpha=0.5, zorder=5)
    if weather is not None:
        ax.set_title(f"Hs and mean wave direction at {weather.time_utc:%Y-%m-%d %H:%M} UTC", fontsize=11)
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2, fontsize=8, frameon=False)
    return _png(fig)


def _map_box(routes: dict, weather) -> tuple:
    """(lon0, lon1, lat0, lat1, aspect): the map's extent, widened on its short side to keep it
    between 1:1 and 2:1 on screen, and the axes' aspect 1/cos(mid latitude)."""
    lon0, lon1, lat0, lat1 = map_extent(routes, weather)
    mid_lat = np.deg2rad(0.5 * (lat0 + lat1))
    coslat = max(np.cos(mid_lat), 0.05)
    aspect = 1.0 / coslat
    # Keep the map between 1:1 and 2:1 (width:height on screen) by widening the short side.
    screen_w, screen_h = (lon1 - lon0) * coslat, lat1 - lat0
    if screen_w < screen_h:
        grow = (screen_h / coslat - (lon1 - lon0)) / 2
        lon0, lon1 = lon0 - grow, lon1 + grow
    elif screen_w > 2 * screen_h:
        grow = (screen_w / 2 - screen_h) / 2
        lat0, lat1 = max(lat0 - grow, -89.9), min(lat1 + grow, 89.9)
    return lon0, lon1, lat0, lat1, aspect


def _draw_weather(fig, ax, weather, box: tuple, hs_limit_m, handles: list) -> None:
    """Hs in colour with its colour bar, the vessel's Hs limit as a contour, wave-direction arrows."""
    from matplotlib.lines import Line2D

    hs = np.ma.masked_invalid(weather.hs_m)
    vmax = max(1.0, float(np.ceil(np.nanmax(weather.hs_m)))) if np.isfinite(weather.hs_m).any() else 1.0
    mesh = ax.pcolormesh(weather.lon_deg, weather.lat_deg, hs, cmap=HS_CMAP, vmin=0.0, vmax=vmax, shading="nearest", zorder=1)
    cbar = fig.colorbar(mesh, ax=ax, shrink=0.8, pad=0.02, fraction=0.04)
    cbar.set_label("significant wave height Hs [m]")
    if hs_limit_m is not None and np.nanmax(weather.hs_m) > hs_limit_m > np.nanmin(weather.hs_m):
        ax.contour(weather.lon_deg, weather.lat_deg, weather.hs_m, levels=[hs_limit_m], colors=LIMIT_COLOR, linewidths=1.3, zorder=2)
        handles.append(Line2D([], [], color=LIMIT_COLOR, linewidth=1.3, label=f"Hs limit {hs_limit_m:g} m"))
    if weather.wave_from_deg is not None:
        _wave_arrows(ax, weather, box, handles)


def _wave_arrows(ax, weather, box: tuple, handles: list) -> None:
    """Arrows of the mean wave direction (where the waves travel to) on about 14 columns inside the box."""
    from matplotlib.lines import Line2D

    lon0, lon1, lat0, lat1 = box
    inside_lon = (weather.lon_deg >= lon0) & (weather.lon_deg <= lon1)
    inside_lat = (weather.lat_deg >= lat0) & (weather.lat_deg <= lat1)
    n_lon = max(int(inside_lon.sum()), 1)
    step = max(1, int(np.ceil(n_lon / 14)))
    ii = np.flatnonzero(inside_lat)[::step]
    jj = np.flatnonzero(inside_lon)[::step]
    if ii.size and jj.size:
        d_from = weather.wave_from_deg[np.ix_(ii, jj)]
        ok = np.isfinite(d_from) & np.isfinite(weather.hs_m[np.ix_(ii, jj)])
        to_rad = np.deg2rad(d_from + 180.0)
        lon_g, lat_g = np.meshgrid(weather.lon_deg[jj], weather.lat_deg[ii])
        # angles="uv": arrow direction on screen; with the aspect set to 1/cos(lat) the
        # screen is locally conformal, so (sin, cos) of the bearing points the right way.
        ax.quiver(lon_g[ok], lat_g[ok], np.sin(to_rad[ok]), np.cos(to_rad[ok]), angles="uv", pivot="middle", color="#333333", scale=28, width=0.0028, headwidth=4, zorder=3)
        handles.append(Line2D([], [], color="#333333", marker=r"$\rightarrow$", markersize=12, linestyle="none", label="mean wave direction (travelling to)"))


def _draw_routes(ax, routes: dict, worst, worst_role: str, handles: list) -> None:
    """Every route (great-circle legs, white halo), the departure and arrival marks, and the worst weather's star."""
    from matplotlib.lines import Line2D
    from matplotlib.patheffects import withStroke

    halo = [withStroke(linewidth=4.5, foreground="white")]
    for role, route in routes.items():
        st = style_for(role)
        g_lat, g_lon = gc_polyline(route.lat_deg, route.lon_deg)
        ax.plot(g_lon, g_lat, zorder=6, solid_capstyle="round", path_effects=halo, label=label_for(role), **st)
        handles.append(Line2D([], [], label=f"{label_for(role)}: {route.dist_nmi:.0f} nmi, {route.time_h:.1f} h", **st))
    if routes:
        first = next(iter(routes.values()))
        ax.plot(first.lon_deg[0], first.lat_deg[0], "o", color="white", markeredgecolor="black", markersize=8, zorder=7)
        ax.plot(first.lon_deg[-1], first.lat_deg[-1], "s", color="white", markeredgecolor="black", markersize=8, zorder=7)
        handles.append(Line2D([], [], marker="o", color="white", markeredgecolor="black", linestyle="none", label="departure"))
        handles.append(Line2D([], [], marker="s", color="white", markeredgecolor="black", linestyle="none", label="arrival"))
    if worst is not None and all(v is not None and np.isfinite(v) for v in worst):
        ax.plot(worst[1], worst[0], marker="*", color="white", markeredgecolor="black", markersize=17, linestyle="none", zorder=8)
        handles.append(Line2D([], [], marker="*", color="white", markeredgecolor="black", markersize=12, linestyle="none", label=f"worst weather on {label_for(worst_role)}"))


def series_png(routes: dict, *, hs_limit_m: float | None = None, profiles: dict | None = None, width_in: float = 5.8,
               dpi: int = 100) -> bytes:
    """Hs met (top) and speed over ground (bottom) along each route against time (UTC).

    Hs comes from ``profiles[role]`` (the evaluation's samples along the legs) when given, else
    from the route's waypoints.
    """
    from matplotlib.dates import AutoDateLocator, ConciseDateFormatter
    from matplotlib.figure import Figure

    profiles = profiles or {}
    fig = Figure(figsize=(width_in, 5.6), dpi=dpi)
    ax_hs, ax_v = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [1.2, 1.0]})
    for role, route in routes.items():
        st = style_for(role)
        t = _naive_utc(route.time_utc)
        prof = profiles.get(role)
        if prof is not None and len(prof):
            ax_hs.plot(_naive_utc(pd.DatetimeIndex(prof["time_utc"])), prof["hs_m"].to_numpy(dtype=float), label=label_for(role), **st)
        elif (hs := route.weather.get("hs_m")) is not None:
            ax_hs.plot(t, hs, marker="." if route.n_waypoints < 80 else None, label=label_for(role), **st)
        if route.n_waypoints >= 2:
            ax_v.step(t, np.append(route.leg_speed_kn, route.leg_speed_kn[-1]), where="post", label=label_for(role), **st)
    if hs_limit_m is not None:
        ax_hs.axhline(hs_limit_m, color=LIMIT_COLOR, linewidth=1.2, label=f"Hs limit {hs_limit_m:g} m")
    ax_hs.set_ylabel("Hs met [m]")
    ax_hs.set_ylim(bottom=0)
    ax_v.set_ylabel("speed over ground [kn]")
    ax_v.set_xlabel("time [UTC]")
    ax_v.set_ylim(bottom=0)
    for ax in (ax_hs, ax_v):
        ax.grid(True, linewidth=0.4, alpha=0.6)
    locator = AutoDateLocator(minticks=3, maxticks=7)
    ax_v.xaxis.set_major_locator(locator)
    ax_v.xaxis.set_major_formatter(ConciseDateFormatter(locator))
    handles, labels = ax_hs.get_legend_handles_labels()
    ax_v.legend(handles, labels, fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.32), ncol=2, frameon=False)
    fig.align_ylabels()
    return _png(fig)


def _sector_name(encounter_deg: float) -> str:
    a = abs(((encounter_deg + 180.0) % 360.0) - 180.0)
    if a <= 45:
        return "head"
    if a < 135:
        return "beam"
    return "following"


def speed_loss_png(curve: SpeedLossCurve, *, width_in: float = 6.4, dpi: int = 100) -> bytes:
    """Attainable speed against Hs, one line per encounter angle (0 = head seas)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, 4.0), dpi=dpi)
    ax = fig.add_subplot()
    angles = sorted(curve.table["encounter_deg"].unique())
    colors = ["#b3261e", "#E69F00", "#009E73", "#56B4E9", "#0072B2", "#CC79A7", "#000000"]
    for k, angle in enumerate(angles):
        part = curve.table[curve.table["encounter_deg"] == angle].sort_values("hs_m")
        ax.plot(part["hs_m"], part["speed_kn"], color=colors[k % len(colors)], linewidth=2, label=f"{angle:g}\u00b0 ({_sector_name(angle)} seas)")
    ax.axhline(curve.speed_kn, color="#555555", linestyle="--", linewidth=1, label=f"calm water {curve.speed_kn:g} kn")
    if curve.min_speed_kn is not None:
        ax.axhline(curve.min_speed_kn, color="#555555", linestyle=":", linewidth=1, label=f"floor {curve.min_speed_kn:g} kn")
    ax.set_xlabel("significant wave height Hs [m]")
    ax.set_ylabel("attainable speed [kn]")
    ax.set_ylim(bottom=0)
    ax.set_xlim(left=0)
    ax.grid(True, linewidth=0.4, alpha=0.6)
    ax.set_title(f"speed loss, model {curve.model}", fontsize=11)
    ax.legend(fontsize=8, loc="lower left", framealpha=0.92)
    return _png(fig)


#: Classes of the fleet map and the matrix: worst hours at risk on the lane as planned over the
#: window (hours over an operator limit or in an IMO situation), and the colours (ColorBrewer
#: RdYlBu, readable by colour-blind readers). Upper bounds in hours.
RISK_CLASSES = ((0.0, "no adverse departure", "#4575b4"), (1.0, "< 1 h at risk", "#fee090"), (3.0, "1\u20133 h", "#fdae61"),
                (6.0, "3\u20136 h", "#f46d43"), (float("inf"), "\u2265 6 h", "#a50026"))
FAILED_STYLE = {"color": "#000000", "linestyle": (0, (2, 2)), "linewidth": 1.6}


def risk_class(worst_h: float | None, adverse: bool) -> int:
    """Index into :data:`RISK_CLASSES` (0: no adverse departure; unknown hours count as the first adverse class)."""
    if not adverse:
        return 0
    h = 0.0 if worst_h is None or not np.isfinite(worst_h) else float(worst_h)
    return next(k for k, (upper, _, _) in enumerate(RISK_CLASSES) if k > 0 and h < upper)


def fleet_map_png(lanes: list, *, width_in: float = 6.4, dpi: int = 90) -> bytes:
    """Every lane checked on one map, coloured by its worst risk over the window, numbered as in
    the matrix, with a ringed number where a reroute is proposed.

    Parameters
    ----------
    lanes : list of dict
        ``number`` (int), ``lat_deg``, ``lon_deg`` (its path), ``risk`` (index into
        :data:`RISK_CLASSES`), ``failed`` (bool: a departure failed), ``reroute`` (bool).
        Only numbers are drawn: lane names and ports stay in the HTML.
    """
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patheffects import withStroke

    routes = {str(k): Route(str(k), ln["lat_deg"], ln["lon_deg"], pd.DatetimeIndex([pd.Timestamp(0, tz="UTC")] * len(ln["lat_deg"])),
                            np.ones(max(len(ln["lat_deg"]) - 1, 0)), {}, {}) for k, ln in enumerate(lanes) if len(ln["lat_deg"]) > 1}
    if not routes:
        fig = Figure(figsize=(width_in, 2.0), dpi=dpi)
        fig.text(0.5, 0.5, "no lane with a path to draw", ha="center", va="center")
        return _png(fig)
    lon0, lon1, lat0, lat1 = map_extent(routes, pad_frac=0.06, min_pad_deg=0.3)
    coslat = max(np.cos(np.deg2rad(0.5 * (lat0 + lat1))), 0.05)
    height_in = min(max(width_in * (lat1 - lat0) / ((lon1 - lon0) * coslat) * 0.95 + 0.9, 2.5), 7.0)
    fig = Figure(figsize=(width_in, height_in), dpi=dpi)
    ax = fig.add_subplot()
    ax.set_facecolor("#eef4f8")
    lon_e, lat_e, land = land_mask(lon0, lon1, lat0, lat1, max_px=1200)
    rgba = np.zeros(land.shape + (4,), dtype=np.uint8)
    rgba[land] = [round(255 * x) for x in (*LAND_RGB, 1.0)]
    ax.imshow(rgba, extent=(lon_e[0], lon_e[-1], lat_e[0], lat_e[-1]), origin="lower", interpolation="nearest", zorder=1, aspect="auto")
    halo = [withStroke(linewidth=3.2, foreground="white")]
    order = sorted(range(len(lanes)), key=lambda k: lanes[k]["risk"])  # the riskiest drawn last, on top
    for k in order:
        ln = lanes[k]
        if len(ln["lat_deg"]) < 2:
            continue
        g_lat, g_lon = gc_polyline(ln["lat_deg"], ln["lon_deg"], step_nmi=2.0)
        style = dict(FAILED_STYLE) if ln.get("failed") and ln["risk"] == 0 else {"color": RISK_CLASSES[ln["risk"]][2], "linewidth": 2.6}
        ax.plot(g_lon, g_lat, zorder=3 + ln["risk"], path_effects=halo, solid_capstyle="round", **style)
    for ln in lanes:
        if len(ln["lat_deg"]) < 1:
            continue
        # a third of the way along: the lanes A -> B and B -> A share a path, not their labels
        i = int(len(ln["lat_deg"]) * 0.33)
        x, y = ln["lon_deg"][i], ln["lat_deg"][i]
        if ln.get("reroute"):
            ax.plot(x, y, "o", markersize=15, markerfacecolor="white", markeredgecolor="black", markeredgewidth=1.8, zorder=10)
            ax.text(x, y, str(ln["number"]), ha="center", va="center", fontsize=7.5, fontweight="bold", zorder=11)
        else:
            ax.text(x, y, str(ln["number"]), ha="center", va="center", fontsize=7, color="#333333", zorder=9,
                    path_effects=[withStroke(linewidth=2.5, foreground="white")])
    handles = [Line2D([], [], color=c, linewidth=2.6, label=label) for _, label, c in RISK_CLASSES]
    handles.append(Line2D([], [], label="failed", **FAILED_STYLE))
    handles.append(Line2D([], [], marker="o", markersize=10, markerfacecolor="white", markeredgecolor="black", linestyle="none",
                          label="reroute proposed (lane number)"))
    ax.set_xlim(lon0, lon1)
    ax.set_ylim(lat0, lat1)
    ax.set_aspect(1.0 / coslat)
    ax.tick_params(labelsize=7)
    ax.grid(True, color="#999999", linewidth=0.3, alpha=0.5, zorder=2)
    ax.set_title("Worst hours at risk on each lane as planned over the window", fontsize=9)
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.06), ncol=4, fontsize=7, frameon=False)
    return _png(fig)
