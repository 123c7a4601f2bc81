"""HTML reports: self-contained, escaped, and showing what the model holds.

The model is the fixture in ``tests/_report_fixtures.py`` (real ``Route`` objects, numbers typed
in by hand, title marked TEST FIXTURE). Expected values below are hand-computed from those
typed numbers.
"""

from __future__ import annotations

import base64
import io
import math
import re
from html.parser import HTMLParser

import numpy as np
import pandas as pd
import pytest

import _report_fixtures as fx
from dashboards.errors import ReportError
from dashboards.html import Markup, el, escape, fmt, table
from dashboards.model import LaneDeparture, RouteSet, WeatherSnapshot, report_from_json, report_to_json
from dashboards.plots import land_mask
from dashboards.report import audit_html, nightly_html, render_audit_report, render_nightly_report
from routing.route import Route

XSS = "<script>alert(1)</script>"
XSS_ESCAPED = "&lt;script&gt;alert(1)&lt;/script&gt;"


class Collector(HTMLParser):
    """Collects tags, attributes and table cell texts of a page."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.tags: list[tuple[str, dict]] = []
        self.tables: list[list[list[str]]] = []
        self._cell: list[str] | None = None
        self._row: list[str] | None = None
        self.text: list[str] = []

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))
        if tag == "table":
            self.tables.append([])
        elif tag == "tr":
            self._row = []
        elif tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self._row.append(" ".join("".join(self._cell).split()))
            self._cell = None
        elif tag == "tr" and self._row is not None:
            self.tables[-1].append(self._row)
            self._row = None

    def handle_data(self, data):
        self.text.append(data)
        if self._cell is not None:
            self._cell.append(data)


def parse(html_text: str) -> Collector:
    c = Collector()
    c.feed(html_text)
    return c


@pytest.fixture(scope="module")
def nightly_page():
    return nightly_html(fx.nightly())


@pytest.fixture(scope="module")
def audit_page():
    return audit_html(fx.audit())


# ------------------------------------------------------------------ escaping path


def test_escape_and_markup():
    assert escape(XSS) == XSS_ESCAPED
    assert escape('a"b\'c&') == "a&quot;b&#x27;c&amp;"
    assert escape(Markup("<b>x</b>")) == "<b>x</b>"
    assert escape(None) == ""
    assert el("td", XSS) == f"<td>{XSS_ESCAPED}</td>"
    assert el("a", "x", href='" onmouseover="alert(1)') == '<a href="&quot; onmouseover=&quot;alert(1)">x</a>'
    assert el("img", src="data:x", alt="<") == '<img src="data:x" alt="&lt;">'
    # Markup + plain string escapes the plain part.
    assert Markup("<i>") + "<" == "<i>&lt;"
    assert table(["<h>"], [[XSS]]).count("&lt;") == 3


def test_fmt_numbers():
    assert fmt(1.23456, 2) == "1.23"
    assert fmt(-0.001, 2) == "0.00"
    assert fmt(-1.5, 1, signed=True) == "-1.5"
    assert fmt(2.0, 1, signed=True) == "+2.0"
    assert fmt(float("nan")) == "\u2013" and fmt(None) == "\u2013"
    assert fmt(np.int64(3)) == "3"
    assert fmt(pd.Timestamp("2025-01-31T06:00Z")) == "2025-01-31 06:00 UTC"


def test_ais_strings_are_escaped_in_audit_report(tmp_path):
    audit = fx.audit(ship_name=XSS)
    audit.callsign = '"><img src=x onerror=alert(2)>'
    audit.ais_destination = "<b>PALMA</b>"
    path = render_audit_report(audit, tmp_path / "audit.html")
    text = path.read_text(encoding="utf-8")
    assert XSS not in text
    assert XSS_ESCAPED in text
    assert "<img src=x" not in text and "&lt;img src=x onerror=alert(2)&gt;" in text
    assert "<b>PALMA</b>" not in text and "&lt;b&gt;PALMA&lt;/b&gt;" in text
    page = parse(text)
    assert not [t for t, _ in page.tags if t == "script"]
    # The browser-visible text is the literal name, shown as text.
    assert XSS in "".join(page.text)


def test_port_names_and_rules_are_escaped_in_nightly_report():
    model = fx.nightly(origin=XSS)
    model.departures[0].rules.append("<i>rule</i>")
    model.departures[-1].error = "<iframe>"
    text = nightly_html(model)
    assert XSS not in text and "<i>rule</i>" not in text and "<iframe>" not in text
    assert text.count(XSS_ESCAPED) >= 3  # lanes table x2, case headings x2
    assert not [t for t, _ in parse(text).tags if t in ("script", "iframe")]


# ------------------------------------------------------------------ self-contained


@pytest.mark.parametrize("which", ["nightly", "audit"])
def test_report_is_self_contained(which, nightly_page, audit_page):
    text = nightly_page if which == "nightly" else audit_page
    page = parse(text)
    tags = [t for t, _ in page.tags]
    assert "script" not in tags and "link" not in tags and "iframe" not in tags
    srcs = [a["src"] for t, a in page.tags if "src" in a]
    assert srcs and all(s.startswith("data:image/png;base64,") for s in srcs)
    assert not re.search(r"""(src|href)\s*=\s*["']?\s*(https?:)?//""", text)
    assert "url(" not in text  # no CSS fetch
    csp = [a for t, a in page.tags if t == "meta" and a.get("http-equiv") == "Content-Security-Policy"]
    assert csp and "default-src 'none'" in csp[0]["content"] and "script-src" not in csp[0]["content"]
    # Each inline image is a real PNG with content (not a blank canvas).
    from PIL import Image

    for src in srcs:
        img = Image.open(io.BytesIO(base64.b64decode(src.split(",", 1)[1]))).convert("L")
        assert img.size[0] > 300 and img.size[1] > 200
        assert np.asarray(img).std() > 10


def _table(page, first):
    return next(t for t in page.tables if t[0][: len(first)] == first)


def test_nightly_overview_ranked_list_matrix_and_chips(nightly_page):
    page = parse(nightly_page)
    text = " ".join(" ".join(page.text).split())
    # Overview cards: counts from the model (no run summary in the fixture, so the page counts and
    # sums the cases); sums hand-computed from the typed metrics: fuel 2 x (29.1 - 30.0) = -1.8 t,
    # CO2 2 x (90.8 - 93.6) = -5.6 t, events 2 x (3 - 0) = 6, at risk avoided 2 x 3.0 h.
    for card in ("7 lanes checked", "112 lane-departures checked", "2 adverse, on 2 lanes", "2 proposed reroutes", "1 failed",
                 "6.0 h at risk avoided (sum)", "6 IMO events avoided", "-1.8 t \u0394 fuel (sum)", "-5.6 t \u0394 CO2 (sum)"):
        assert card in text
    # every delta names its reference (the fixture's cases compare against the historical route)
    assert "\u0394 = proposed \u2212 the historical (lane / AIS track) route, sailed by the same vessel model" in text
    # ranked list: the ranking key is a column, rank order, linked to the case
    top = _table(page, ["#", "lane", "departure [UTC]", "proposed", "at risk avoided [h]"])
    assert [r[:5] for r in top[1:]] == [["1", "L1", "2025-01-31 06:00", "time-optimal A*", "3.0"],
                                       ["2", "L2", "2025-01-31 09:00", "time-optimal A*", "3.0"],
                                       ["3", "L9", "2025-01-31 06:00", "failed", "\u2013"]]
    assert dict(zip(top[0], top[1]))["\u0394 fuel [t]"] == "-0.9"
    # matrix: rows lanes (by their best case), columns the departures, the proposed role in the cell
    m = _table(page, ["#", "lane", "route", "worst at risk [h]"])
    assert [r[:4] for r in m[1:]] == [["1", "L1", "Barcelona \u2192 Palma", "5.5"], ["2", "L2", "Barcelona \u2192 Palma", "5.5"],
                                     ["3", "L9", "Genoa \u2192 Tunis", "\u2013"], ["4", "L4", "Valencia \u2192 Ibiza", "\u2013"]]
    assert m[1][4:] == ["TO", "", ""] and m[2][4:] == ["", "TO", ""] and m[3][4:] == ["\u2715", "", ""]
    links = [a["href"] for t, a in page.tags if t == "a" and a.get("href", "").startswith("#")]
    assert {"#case-1", "#case-2", "#case-3"} <= set(links)
    # 3 h avoided falls in the 3-6 h class; passed cells have their own class
    classes = [a.get("class") for t, a in page.tags if t == "td" and a.get("class", "").startswith("m")]
    assert classes.count("m3") == 2 and classes.count("m-fail") == 1 and classes.count("m-ok") == 4 * 3 - 3
    # all cases, compact: rules as chips (rule, worst value/limit with the unit, day and time)
    allc = _table(page, ["#", "lane", "route", "vessel"])
    row1 = dict(zip(allc[0], allc[1]))
    assert row1["rules (worst value/limit, when)"] == "Hs 6.3/4.5 m 31 10:00 surf-riding 14.2/13.1 kn 31 10:30"
    assert row1["worst Hs on lane [m]"] == "6.3" and row1["\u0394 fuel [t]"] == "-0.90" and row1["\u0394 CO2 [t]"] == "-2.80"
    failed = dict(zip(allc[0], allc[3]))
    assert failed["lane"] == "L9" and failed["proposed"] == "failed"
    assert "NoRouteError: goal (36.8N 10.3E) unreachable" in text
    # every case folded, the anchor inside it; the full rule wording in the case
    cases = [a for t, a in page.tags if t == "details" and a.get("class") == "case"]
    assert len(cases) == 3 and not any("open" in a for a in cases)
    assert [a["id"] for t, a in page.tags if t == "h3" and "id" in a] == ["case-1", "case-2", "case-3"]
    assert "Rules fired (worst point of each): operator: hs_m 6.31 > 4.5 IMO MSC.1/Circ.1228: surf-riding/broaching" in text
    # fleet map + two drawn cases (map and time plot each) + the speed-loss curve
    imgs = [a for t, a in page.tags if t == "img"]
    assert len(imgs) == 1 + 2 * 2 + 1
    assert "Methods and provenance" in text and "container<200m" in text and "bowditch" in text


def test_a_role_the_page_does_not_know_gets_its_initials_and_a_legend_entry():
    """New roles (a run may propose e.g. ``least_fuel``) reach the matrix and its legend."""
    model = fx.nightly()
    model.grid.loc[model.grid["proposed"] == "optimal", "proposed"] = "least_fuel"
    page = parse(nightly_html(model))
    m = _table(page, ["#", "lane", "route", "worst at risk [h]"])
    assert m[1][4] == "LF"
    assert "LF = least fuel" in " ".join(" ".join(page.text).split())


def test_print_style_unfolds_the_cases(nightly_page):
    style = nightly_page.split("<style>", 1)[1].split("</style>", 1)[0]
    printed = style.split("@media print", 1)[1]
    assert "details::details-content" in printed and "content-visibility:visible" in printed


def _comparison(page):
    comp = next(t for t in page.tables if t[0][0] == "metric" and len(t[0]) == 5)
    return {r[0]: dict(zip(comp[0], r)) for r in comp[1:]}


def test_comparison_table_shows_values_and_deltas(nightly_page):
    rows = _comparison(parse(nightly_page))
    fuel = rows["fuel burnt (STEAM2) [t]"]
    assert fuel["historical (lane / AIS track) (reference)"] == "30.00"
    assert fuel["time-optimal A* \u2605 proposed"] == "29.10 (-0.90)"
    assert rows["IMO MSC.1/Circ.1228 events (count)"]["minimum-distance A*"] == "4 (+1)"
    assert rows["highest significant wave height met [m]"]["cargo-safe deviation"] == "3.20 (-3.11)"
    # Rows in the documented order, only the columns that were given.
    assert list(rows) == ["sailing time [h]", "distance sailed [nmi]", "highest significant wave height met [m]", "fuel burnt (STEAM2) [t]", "CO2 emitted [t]", "IMO MSC.1/Circ.1228 events (count)"]


def test_comparison_uses_given_deltas_and_shows_seed_metrics():
    """A metrics frame shaped like routing.evaluate.comparison_table (typed in by hand here):
    given ``d_*`` deltas are shown as they are (not recomputed), ``d_*_pct`` next to them, the
    seed's metrics in their own table."""
    metrics = pd.DataFrame(
        {
            "time_h": [10.0, 9.0], "d_time_h": [0.0, -1.0], "d_time_h_pct": [0.0, -10.0],
            "fuel_t": [20.0, 19.0], "d_fuel_t": [0.0, -1.25],  # deliberately not 19 - 20: must be taken as given
            "n_safety_events": [2.0, 0.0], "d_n_safety_events": [0.0, -2.0],
            "hs_decrease_pct": [0.0, 41.5], "length_diff_pct": [0.0, 3.25],
        },
        index=["historical", "optimal"],
    )
    audit = fx.audit()
    audit.routes = RouteSet(routes={k: v for k, v in fx.routes().items() if k in ("historical", "optimal")}, metrics=metrics, proposed="optimal")
    page = parse(audit_html(audit))
    comp = next(t for t in page.tables if t[0][0] == "metric" and len(t[0]) == 3)
    rows = {r[0]: r[1:] for r in comp[1:]}
    assert list(rows) == ["sailing time [h]", "fuel burnt (STEAM2) [t]", "IMO MSC.1/Circ.1228 events (count)"]
    assert rows["sailing time [h]"] == ["10.00", "9.00 (-1.00, -10.0 %)"]
    assert rows["fuel burnt (STEAM2) [t]"] == ["20.00", "19.00 (-1.25)"]
    assert rows["IMO MSC.1/Circ.1228 events (count)"] == ["2", "0 (-2)"]
    seed = next(t for t in page.tables if t[0] == ["metric", "time-optimal A*"])
    assert seed[1:] == [["decrease of mean Hs over the adverse portion [%]", "41.5"], ["length difference [%]", "3.2"]]


def test_max_detail_limits_maps(tmp_path):
    model = fx.nightly(n_adverse=3)
    model.max_detail = 1
    page = parse(nightly_html(model))
    assert len([a for t, a in page.tags if t == "img"]) == 1 + 2 + 1  # fleet map, one case's map and plot, speed loss
    assert "1 with maps and plots (the first 1 of 3 in ranking order: --max-detail)" in " ".join(" ".join(page.text).split())


def test_empty_night_says_so():
    model = fx.nightly(n_adverse=0)
    model.departures = []
    text = " ".join(" ".join(parse(nightly_html(model)).text).split())
    assert "No adverse lane-departure in the window" in text
    assert "0 adverse, on 0 lanes" in text


def test_audit_report_content(audit_page):
    page = parse(audit_page)
    text = " ".join(" ".join(page.text).split())
    ident = next(t for t in page.tables if t[0][0] == "ship name (AIS)")
    fields = {r[0]: r[1] for r in ident}
    assert fields["ship name (AIS)"] == "MV FIXTURE" and fields["MMSI"] == "224000001" and fields["call sign (AIS)"] == "EA1234"
    assert fields["departure \u2192 arrival"] == "2025-01-31 06:00 UTC \u2192 2025-01-31 15:06 UTC"
    assert "Fixture finding" in text
    assert "3 IMO events on the sailed track" in text
    assert len([a for t, a in page.tags if t == "img"]) == 3
    # issue 22: the sailed track's events as chips (criterion, count, hours, first start), the
    # reference of the deltas named, events / waypoints / provenance folded with anchors inside
    assert ("On the sailed track: operator hs_m > 4.5 1\u00d7, 2.5 h from 31 09:40 parametric roll 1\u00d7, 0.8 h from 31 10:30 "
            "surf-riding/broaching 1\u00d7, 1.0 h from 31 10:00") in text
    assert "\u0394 = time-optimal A* \u2212 historical (lane / AIS track) (the reference of every delta on this page)" in text
    ids = [a["id"] for t, a in page.tags if "id" in a]
    assert {"overview", "routes", "events", "waypoints", "provenance"} <= set(ids)
    assert len([a for t, a in page.tags if t == "details" and a.get("class") == "section"]) == 3


def test_render_writes_html_file_and_refuses_other_suffix(tmp_path):
    path = render_nightly_report(fx.nightly(n_adverse=1), tmp_path / "sub" / "night.html")
    assert path.exists() and path.read_text(encoding="utf-8").startswith("<!DOCTYPE html>")
    with pytest.raises(ReportError, match=r"\.html"):
        render_nightly_report(fx.nightly(), tmp_path / "night.pdf")
    with pytest.raises(ReportError, match="NightlyReport"):
        render_nightly_report(fx.audit(), tmp_path / "x.html")


# ------------------------------------------------------------------ model


def test_model_json_round_trip_renders_identically():
    for model, render in ((fx.nightly(n_adverse=1), nightly_html), (fx.audit(), audit_html)):
        back = report_from_json(report_to_json(model))
        assert type(back) is type(model)
        assert render(back) == render(model)


def test_model_validation_names_the_field():
    with pytest.raises(ReportError, match="depart_utc"):
        LaneDeparture(lane_id=1, origin="a", destination="b", depart_utc=pd.Timestamp("2025-01-01T00:00"))
    with pytest.raises(ReportError, match="hs_m has shape"):
        WeatherSnapshot(time_utc=pd.Timestamp("2025-01-01T00:00Z"), lat_deg=[1, 2], lon_deg=[1, 2, 3], hs_m=np.zeros((3, 2)))
    with pytest.raises(ReportError, match="proposed"):
        RouteSet(routes=fx.routes(), proposed="nonexistent")
    with pytest.raises(ReportError, match="no error message"):
        LaneDeparture(lane_id=1, origin="a", destination="b", depart_utc=pd.Timestamp("2025-01-01T00:00Z"), status="failed")
    with pytest.raises(ReportError, match="NightlyReport or a VoyageAudit"):
        report_from_json('{"a": 1}')


def test_one_delta_is_the_cell_of_the_deltas_table():
    """``RouteSet.delta`` (the night page's and totals' path) equals :meth:`RouteSet.deltas` cell
    by cell: given ``d_*`` columns taken as given, the rest differences from the reference, the
    seed's and the ``d_*`` columns themselves and unknown roles NaN."""
    given = pd.DataFrame({"time_h": [10.0, 9.0], "d_time_h": [0.0, -1.0], "fuel_t": [20.0, 19.0],
                          "d_fuel_t": [0.0, -1.25], "dist_nmi": [100.0, "n/a"], "hs_decrease_pct": [0.0, 41.5]},
                         index=["historical", "optimal"])
    for rs in (RouteSet(routes=fx.routes()), RouteSet(routes={}, metrics=given, proposed="optimal")):
        table_ = rs.deltas()
        for role in table_.index:
            for col in table_.columns:
                assert rs.delta(col, role) == pytest.approx(table_.loc[role, col], nan_ok=True), (role, col)
        for col in ("d_time_h", "hs_decrease_pct", "no_such_metric"):
            assert math.isnan(rs.delta(col, table_.index[0]))
        assert math.isnan(rs.delta("time_h", "no_such_role"))
    assert RouteSet(routes={}, metrics=given, proposed="optimal").delta("fuel_t", "optimal") == -1.25
    assert math.isnan(RouteSet(routes={}, metrics=given, proposed="optimal").delta("dist_nmi", "optimal"))


def test_metrics_fall_back_to_route_values():
    rs = RouteSet(routes=fx.routes())
    table_ = rs.metrics_table()
    assert list(table_.index) == ["historical", "deviation", "optimal", "min_distance"]
    hs = fx.routes()["historical"].weather["hs_m"]
    assert table_.loc["historical", "max_hs_m"] == pytest.approx(hs.max())
    assert table_.loc["historical", "mean_hs_m"] == pytest.approx(hs.mean())
    assert rs.deltas().loc["historical"].abs().max() == 0


# ------------------------------------------------------------------ maps


def test_land_mask_at_the_masks_own_resolution():
    """The map's land is the 30" raster itself (the pixels the land check tests), not a resampling."""
    from thresholds import land_raster

    lon_e, lat_e, land = land_mask(2.0, 3.6, 39.0, 40.2)
    assert land.shape == (lat_e.size - 1, lon_e.size - 1)
    assert np.allclose(np.diff(lon_e), 1 / 120) and np.allclose(np.diff(lat_e), 1 / 120)
    assert lon_e[0] <= 2.0 + 1e-9 and lon_e[-1] >= 3.6 - 1e-9 and lat_e[0] <= 39.0 + 1e-9 and lat_e[-1] >= 40.2 - 1e-9
    centre_lat, centre_lon = np.meshgrid((lat_e[:-1] + lat_e[1:]) / 2, (lon_e[:-1] + lon_e[1:]) / 2, indexing="ij")
    assert np.array_equal(land, land_raster.is_land(centre_lat, centre_lon))
    # a big box is drawn in blocks that are land when any pixel is: land never disappears
    lon_b, lat_b, big = land_mask(2.0, 3.6, 39.0, 40.2, max_px=50)
    assert big.shape[1] <= 50 and big.sum() * (lon_b[1] - lon_b[0]) ** 2 >= land.sum() / 120 ** 2

    def at(la, lo):
        return land[np.searchsorted(lat_e, la) - 1, np.searchsorted(lon_e, lo) - 1]

    assert at(39.62, 2.95)  # inland Mallorca
    assert not at(39.3, 2.2)  # open sea south-west of Mallorca
    assert not at(40.1, 2.5)  # between Mallorca and the mainland


# ------------------------------------------------------------------ with the evaluation's own output


def test_audit_report_renders_routing_audit_output(tmp_path):
    """The audit's real output (routing.audit.audit_routes on a two-layer sea: Hs 6 m south of
    40.5N, 3 m north) goes into the model unchanged and every number shown is the table's."""
    from pipelines.reporting import route_set_from_evaluations
    from routing.audit import audit_routes
    from routing.route import Route
    from thresholds.operator import OperatorLimits
    from thresholds.vessel import Vessel

    t0 = pd.Timestamp("2025-01-15T00:00Z")
    vessel = Vessel(name="t", vessel_class="container", speed_kn=12.0, lpp_m=100.0, beam_m=16.0, draught_m=6.0, dwt_t=8000.0,
                    installed_power_kw=6000.0, design_speed_kn=15.0, engine_rpm=500.0, sfoc_g_kwh=200.0)

    def weather(times, lat, lon):
        lat = np.asarray(lat, dtype=float)
        return {"hs_m": np.where(lat < 40.5, 6.0, 3.0), "wave_from_deg": np.full(lat.size, 270.0), "tm_s": np.full(lat.size, 5.0)}

    def straight(lat, name, hours=(0.0, 4.6, 9.2)):  # open sea between Menorca and Sardinia
        return Route(name, [lat] * 3, [4.5, 5.5, 6.5], t0 + pd.to_timedelta(list(hours), unit="h"), [10.0, 10.0])

    out = audit_routes(straight(40.0, "as_sailed"), weather, vessel, limits=OperatorLimits(name="t", hs_max_m=4.5),
                       alternatives={"optimal": straight(41.0, "optimal")})
    rs = route_set_from_evaluations(out["evaluations"], out["table"], out["proposed"])
    audit = fx.audit()
    audit.routes, audit.findings = rs, out["findings"]
    path = render_audit_report(audit, tmp_path / "a.html")
    page = parse(path.read_text(encoding="utf-8"))
    comp = next(t for t in page.tables if t[0][0] == "metric" and len(t[0]) == 3)
    assert comp[0][2] == "time-optimal A* \u2605 proposed"
    rows = {r[0]: r[1:] for r in comp[1:]}
    table_ = out["table"]
    assert rows["fuel burnt (STEAM2) [t]"][0] == f"{table_.loc['as_sailed', 'fuel_t']:.2f}"
    assert rows["fuel burnt (STEAM2) [t]"][1].startswith(f"{table_.loc['optimal', 'fuel_t']:.2f} ({table_.loc['optimal', 'd_fuel_t']:+.2f}")
    assert rows["highest significant wave height met [m]"] == ["6.00", "3.00 (-3.00)"]
    text = " ".join(" ".join(page.text).split())
    assert "Proposed alternative: optimal (safer)" in text
    assert len([a for t, a in page.tags if t == "img"]) == 3


def test_long_tracks_show_every_kth_waypoint():
    from dashboards.report import waypoints_section

    n = 1001
    track = Route("historical", np.linspace(39.0, 41.0, n), np.full(n, 2.0), pd.date_range("2025-01-15", periods=n, freq="min", tz="UTC"), np.full(n - 1, 10.0))
    page = parse(waypoints_section(RouteSet(routes={"historical": track}), max_rows=200))
    (tab,) = page.tables
    # ceil(1001 / 200) = 6: rows 0, 6, ..., 996 (167 rows) plus the last one (1000).
    assert len(tab) - 1 == 168
    assert tab[1][0] == "39.00000" and tab[-1][0] == "41.00000"
    assert "(1001; every 6th shown, all of them in the exports)" in " ".join(page.text)


def test_case_notes_say_when_the_safe_route_breaks_the_limits_or_outlasts_the_weather():
    model = fx.nightly(n_adverse=2)
    routes = model.departures[0].routes.routes
    routes["optimal"].properties.update({"safety_requested": "hard", "safety_mode": "soft", "weather_held_after_h": 2.4})
    text = nightly_html(model)
    assert text.count("no route keeps within the vessel") == 1  # only the first case carries the flags
    assert "arrives 2.4 h after the last weather time" in text
    # a route that kept within its limits, inside the weather, gets no note
    routes["optimal"].properties.update({"safety_mode": "hard", "weather_held_after_h": None})
    assert "no route keeps within" not in nightly_html(model) and "last weather time" not in nightly_html(model)
