"""``stormlane learn``: the performance model learned from the workspace's AIS x weather.

:func:`learn_performance` wires the steps (no formulas or SQL here):

1. the weather grid (``--weather`` files loaded into the workspace first, as ``weather load``
   does; else the workspace's latest grid);
2. the training table (:func:`pipelines.storage.training.training_table`: cleaning rules and the
   weather at each fix, in DuckDB);
3. each ship's particulars where AIS lacks them and its vessel profile by the house rule
   (:func:`pipelines.vessels.vessel_for_ship`: the formulas' Lpp, deadweight and floor);
4. features, calm-water speeds, segments (:func:`performance.features.prepare`), the formulas on
   the same segments (:func:`performance.formulas.formula_speeds`);
5. grouped cross-validation, time split, the final model of the winning kind with its
   conformalised band, the voluntary thresholds (:mod:`performance.validate`,
   :mod:`performance.fit`, :mod:`performance.voluntary`);
6. the model file (skops) and its row (:mod:`pipelines.storage.performance`).

Scikit-learn's trees run on OpenMP threads; ``threads`` limits them, default **1**: on the shared
2-core machine under load (load average 11) one fit of the demo's 41,537 segments took 39 s on
two OpenMP threads and 2.3 s on one (OpenMP threads spin-wait for each other when the cores are
busy). The OpenMP runtime is loaded before the limit is set, so the limit takes.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from thresholds.errors import StormlaneError


class LearnError(StormlaneError):
    """``learn performance`` cannot learn from what the workspace holds (one line, exit 2)."""


#: The model ``make demo`` learns.
DEMO_MODEL = "demo-fleet"
#: Fewest segments and vessels a model is fitted on.
MIN_SEGMENTS = 200
MIN_VESSELS = 2


@dataclass(frozen=True)
class LearnRequest:
    """What ``stormlane learn performance`` was asked."""

    db: Path
    name: str
    weather: tuple[str, ...] = ()
    since: pd.Timestamp | None = None
    until: pd.Timestamp | None = None
    classes: tuple[str, ...] = ()
    folds: int = 5
    threads: int | None = None


def class_ranges(classes) -> list[tuple[int, int]] | None:
    """AIS ship-type ranges of the named classes (:data:`performance.features.SHIP_CLASSES`)."""
    from performance.features import SHIP_CLASSES

    if not classes:
        return None
    out = []
    for c in classes:
        if c not in SHIP_CLASSES:
            raise LearnError(f"--class {c!r}: not a ship class; use one of {', '.join(SHIP_CLASSES)} "
                             "(AIS ship types 60-69, 70-79, 80-89)")
        out.append(SHIP_CLASSES[c])
    return out


def ship_particulars(table: pd.DataFrame) -> pd.DataFrame:
    """Per MMSI: its vessel profile by the house rule, the profile's Lpp, deadweight and floor
    (for the formulas), and length/beam/draught where AIS gives none (the profile's)."""
    from pipelines.config import load_vessel
    from pipelines.vessels import vessel_for_ship

    rows = []
    ships = table.drop_duplicates("mmsi")[["mmsi", "ship_type", "length_m"]]
    cache: dict[str, object] = {}
    for r in ships.itertuples(index=False):
        static = {"ship_type": None if pd.isna(r.ship_type) else r.ship_type,
                  "length_m": None if pd.isna(r.length_m) else r.length_m}
        prof = vessel_for_ship(static)
        v = cache.setdefault(prof, load_vessel(prof))
        rows.append({"mmsi": int(r.mmsi), "profile": prof, "lpp_m": v.lpp_m, "dwt_t": v.dwt_t,
                     "min_speed_kn": v.min_speed_kn, "length_m": v.lpp_m, "beam_m": v.beam_m, "draught_m": v.draught_m})
    return pd.DataFrame(rows, columns=["mmsi", "profile", "lpp_m", "dwt_t", "min_speed_kn", "length_m", "beam_m",
                                       "draught_m"])


def _threads(threads: int | None) -> int:
    return max(1, int(threads)) if threads else 1


def _grid(ws, req: LearnRequest) -> dict:
    from pipelines.storage.weather import get_grid

    try:
        return get_grid(ws)
    except StormlaneError:
        raise LearnError(f"workspace {req.db} holds no weather; pass --weather FILE|DIR (or run "
                         "`stormlane weather load`)") from None


def _versions() -> dict:
    from importlib.metadata import version

    return {p: version(p) for p in ("scikit-learn", "numpy", "pandas", "duckdb", "skops", "stormlane")}


def learn_performance(req: LearnRequest, echo=lambda line: None) -> dict:
    """Learn, validate and store a performance model (module notes); returns the summary."""
    from pipelines.storage import open_workspace
    from pipelines.storage.performance import check_name
    from pipelines.storage.training import CleaningRules, training_table

    check_name(req.name)
    ranges = class_ranges(req.classes)
    timings = {}
    t0 = time.perf_counter()
    if req.weather:
        from pipelines.weather import load_weather_paths

        grid_row = load_weather_paths(list(req.weather), req.db)
        echo(f"weather grid {grid_row['grid_id']} {grid_row['name']!r} loaded from --weather")
    rules = CleaningRules()
    with open_workspace(req.db) as ws:
        grid = _grid(ws, req)
        table, funnel = training_table(ws, grid, since=req.since, until=req.until, ship_types=ranges, rules=rules)
    timings["table_s"] = time.perf_counter() - t0
    return _fit_and_store(req, table, funnel, grid, rules, timings, echo)


def _fit_and_store(req: LearnRequest, table: pd.DataFrame, funnel: dict, grid: dict, rules, timings: dict, echo) -> dict:
    # Long by design: the fitting steps in order, each timed, then one row and one file written.
    from sklearn.ensemble import HistGradientBoostingRegressor  # noqa: F401 - loads OpenMP before the limit
    from threadpoolctl import threadpool_limits

    from performance.features import prepare
    from performance.fit import FitSettings, fit_model
    from performance.formulas import formula_speeds
    from performance.validate import grouped_cv, time_split
    from performance.voluntary import voluntary_thresholds

    t = time.perf_counter()
    ships = ship_particulars(table)
    fixes, seg, prep = prepare(table, ships[["mmsi", "length_m", "beam_m", "draught_m"]])
    vessels = int(seg["mmsi"].nunique()) if len(seg) else 0
    if len(seg) < MIN_SEGMENTS or vessels < MIN_VESSELS:
        raise LearnError(f"too little to learn from in {req.db}: {len(seg)} ten-minute segments of {vessels} vessel(s) "
                         f"after cleaning ({funnel['kept']:,} of {funnel['fixes_in_span']:,} fixes kept: "
                         + ", ".join(f"{k} {v:,}" for k, v in funnel["counts"].items() if v)
                         + f"); at least {MIN_SEGMENTS} segments of {MIN_VESSELS} vessels are needed")
    formula_kn, outside = formula_speeds(seg, ships)
    timings["features_s"] = time.perf_counter() - t
    settings = FitSettings()
    with threadpool_limits(limits=_threads(req.threads)):
        t = time.perf_counter()
        cv = grouped_cv(seg, formula_kn, settings, k=req.folds)
        timings["grouped_cv_s"] = time.perf_counter() - t
        t = time.perf_counter()
        ts = time_split(seg, formula_kn, settings, cv.pop("oof_score"))
        timings["time_split_s"] = time.perf_counter() - t
        t = time.perf_counter()
        kind = cv["winner"]
        prior = cv["best_formula"]
        prior_ratio = formula_kn[f"speed_{prior}_kn"].to_numpy(float) / seg["v0_kn"].to_numpy(float)
        model = fit_model(seg, kind, settings, prior=prior, prior_ratio=prior_ratio)
        model.band_scale = cv["band_scale"]
        model.band_scales = cv["band_scales"]
        timings["final_fit_s"] = time.perf_counter() - t
    from performance.tabulate import sea_context

    t = time.perf_counter()
    limits = voluntary_thresholds(fixes)
    timings["voluntary_s"] = time.perf_counter() - t
    summary = _summary(req, table, funnel, prep, grid, cv, ts, limits, outside, model, fixes, seg, rules, settings)
    summary["timings_s"] = {k: round(v, 2) for k, v in timings.items()}
    summary["context"] = sea_context(seg)
    summary["limits"] = beside_operator_limits(limits)
    _store(req, model, summary)
    summary["file"] = str(_file_of(req))
    return summary


#: The vessel profile of each learned class (the house rule of :func:`pipelines.vessels.vessel_for_ship`).
CLASS_PROFILE = {"passenger": "ro-pax", "cargo": "container-feeder", "tanker": "tanker-aframax", "other": "container-feeder"}


def beside_operator_limits(voluntary: list[dict], profile: str | None = None, vessels=None) -> list[dict]:
    """Per vessel (default: each learned class's vessel profile, :data:`CLASS_PROFILE`): the Hs and
    heading sector above which AIS shows voluntary slow-down for its class (head-to-bow seas first,
    then the other sectors that show a step), beside the operator's configured Hs limit for that
    vessel (evidence for the operator, not a replacement of the limits)."""
    from performance.tabulate import PROFILE_CLASS
    from pipelines.config import load_operator_profile, load_vessel

    prof = load_operator_profile(profile)
    by_class: dict = {}
    for r in voluntary:
        by_class.setdefault(r["ship_class"], []).append(r)
    if vessels is None:
        pairs = [(c, load_vessel(CLASS_PROFILE.get(c, "container-feeder"))) for c in by_class
                 if any(r["sector"] == "head-bow" for r in by_class[c])]
    else:
        pairs = [(PROFILE_CLASS.get(str(v.vessel_class), "other"), v) for v in vessels]
    rows = []
    for cls, v in pairs:
        sectors = by_class.get(cls, [])
        head = next((r for r in sectors if r["sector"] == "head-bow"), None)
        lim = prof.limits_for(v.vessel_class, v.lpp_m)
        hs_lim = lim.hs_max_m if isinstance(lim.hs_max_m, (int, float)) else None
        found = [{"sector": r["sector"], "encounter_deg": r.get("encounter_deg"), "hs_m": r["threshold_hs_m"]}
                 for r in sectors if r["threshold_hs_m"] is not None]
        rows.append({"ship_class": cls, "vessel_profile": v.name, "operator_profile": prof.name,
                     "limits": lim.name, "operator_hs_max_m": hs_lim,
                     "learned_hs_m": None if head is None else head["threshold_hs_m"],
                     "learned_interval_hs_m": [head["from_hs_m"], head["to_hs_m"]] if head and head["threshold_hs_m"] is not None else None,
                     "learned_sectors": found,
                     # a class the model never saw: nothing was looked for (not "none found", which reads as evidence)
                     "why_none": f"{_NOT_LEARNED}{cls} ships" if cls not in by_class else None if head is None else head.get("why")})
    return rows


#: How :func:`beside_operator_limits` starts ``why_none`` for a class the model never saw.
_NOT_LEARNED = "the model holds no "


def class_not_learned(r: dict) -> bool:
    """Whether a row of :func:`beside_operator_limits` is of a class the model never saw (nothing
    was looked for), as opposed to one where no voluntary slow-down was found."""
    return r["learned_hs_m"] is None and str(r.get("why_none") or "").startswith(_NOT_LEARNED)


def learned_limits(db, name: str | None = None, *, profile: str | None = None, vessels=None) -> dict | None:
    """The voluntary slow-down a stored model learned (``name``; default the newest model in the
    workspace), beside the operator limits of ``profile`` for ``vessels``: ``{"model", "rows"}``
    (:func:`beside_operator_limits`), None when the workspace holds no model. Reads the model's row
    only (its stored metrics), not its file."""
    from pipelines.storage import open_workspace
    from pipelines.storage.performance import read_model

    if name is None:
        newest = newest_learned(db)
        if newest is None:
            return None
        name = newest.learned_name
    with open_workspace(db, read_only=True) as ws:
        row = read_model(ws, name)
    return {"model": f"learned:{name}", "rows": beside_operator_limits(row["metrics"]["voluntary"], profile, vessels)}


def limit_line(r: dict) -> str:
    """One row of :func:`beside_operator_limits` in words."""
    op = "none" if r["operator_hs_max_m"] is None else f"Hs {r['operator_hs_max_m']:.2f} m"
    if class_not_learned(r):
        got = f"not learned: {r['why_none']}"
    elif r["learned_hs_m"] is None:
        got = "no voluntary slow-down found in head-to-bow seas" + (f" ({r['why_none']})" if r.get("why_none") else "")
    else:
        got = f"masters slow down above Hs {r['learned_hs_m']:.2f} m in head-to-bow seas (0-60 deg)"
    other = [f"{s['sector']} above Hs {s['hs_m']:.2f} m" for s in r.get("learned_sectors", []) if s["sector"] != "head-bow"]
    return (f"{r['ship_class']} ({r['vessel_profile']}): {got}" + (f", {', '.join(other)}" if other else "")
            + f"; operator limit {op} ({r['operator_profile']}: {r['limits']})")


def _file_of(req: LearnRequest) -> Path:
    from pipelines.storage.performance import models_dir

    return models_dir(req.db) / f"{req.name}.skops"


def _summary(req, table, funnel, prep, grid, cv, ts, limits, outside, model, fixes, seg, rules, settings) -> dict:
    t = pd.to_datetime(fixes["time_utc"], utc=True)
    span = [t.min(), t.max()] if len(t) else [None, None]
    return {
        "name": req.name, "db": str(req.db),
        "span_utc": [None if x is None else x.strftime("%Y-%m-%dT%H:%M:%SZ") for x in span],
        "classes": sorted(str(c) for c in fixes["ship_class"].unique()), "vessels": int(seg["mmsi"].nunique()),
        "fixes": int(len(fixes)), "segments": int(len(seg)), "table": {**funnel, **prep},
        "kind": model.kind, "prior": model.prior, "band_scale": model.band_scale,
        "formulas_outside_range": outside,
        "grouped_cv": cv, "time_split": ts, "voluntary": limits,
        "beats_formulas": cv["beats_formulas"],
        "params": {"since": None if req.since is None else req.since.isoformat(),
                   "until": None if req.until is None else req.until.isoformat(), "classes": list(req.classes),
                   "rules": rules.to_dict(), "fit": settings.to_dict(), "folds": req.folds,
                   "grid": {"grid_id": int(grid["grid_id"]), "name": str(grid["name"])}},
        "versions": _versions(),
    }


def _store(req: LearnRequest, model, summary: dict) -> None:
    from pipelines.storage import open_workspace
    from pipelines.storage.performance import save_model_file, write_model

    path, sha = save_model_file(req.db, req.name, model.to_state())
    span = summary["span_utc"]
    metrics = {k: summary[k] for k in ("grouped_cv", "time_split", "voluntary", "table", "formulas_outside_range",
                                       "band_scale", "fixes", "segments", "context", "limits")}
    with open_workspace(req.db) as ws:
        write_model(ws, {
            "name": req.name, "span_start": span[0], "span_end": span[1], "rows": summary["segments"],
            "vessels": summary["vessels"], "classes": ",".join(summary["classes"]), "kind": model.kind,
            "prior": model.prior, "features": list(model.features), "beats_formulas": bool(summary["beats_formulas"]),
            "file": str(path), "file_sha256": sha, "versions_json": summary["versions"],
            "params_json": summary["params"], "metrics_json": metrics})


def load_performance_model(db, name: str):
    """A stored model, rebuilt from its skops file (trusted types only), and its row."""
    from performance.fit import PerformanceModel
    from pipelines.storage import open_workspace
    from pipelines.storage.performance import load_model_file, read_model

    with open_workspace(db, read_only=True) as ws:
        row = read_model(ws, name)
    state = load_model_file(row["file"], row["file_sha256"])
    model = PerformanceModel.from_state(state)
    return model, row


def parse_learned(speed_loss: str) -> str | None:
    """The model name of ``--speed-loss learned:NAME`` (None for a formula's name)."""
    from pipelines.storage.performance import check_name

    if not str(speed_loss).startswith("learned:"):
        return None
    return check_name(str(speed_loss).split(":", 1)[1])


@dataclass
class SpeedLossChoice:
    """``--speed-loss`` resolved once per command (:func:`resolve_speed_loss`): a formula's name, or
    a stored learned model, loaded once and tabulated per vessel and calm-water speed.

    ``label`` is what every output names (``bowditch``, ``learned:NAME``); ``model`` is the router's
    model code (the formula's name, or ``learned``)."""

    label: str
    db: Path | None = None
    _loaded: tuple | None = None

    @property
    def learned_name(self) -> str | None:
        return self.label.split(":", 1)[1] if self.label.startswith("learned:") else None

    @property
    def model(self) -> str:
        return "learned" if self.learned_name else self.label

    def table(self, vessel, speed_kn: float | None = None):
        """The learned model's table for ``vessel`` at ``speed_kn`` (default its service speed); None
        for a formula. One ``error:`` line when the vessel lies outside what the model was trained on."""
        if self.learned_name is None:
            return None
        from performance.tabulate import OutsideTraining
        from performance.tabulate import speed_table as tabulate

        if self._loaded is None:
            self._loaded = load_performance_model(self.db, self.learned_name)
        model, row = self._loaded
        try:
            return tabulate(model, row["metrics"]["context"], self.learned_name,
                            speed_kn=float(speed_kn if speed_kn is not None else vessel.speed_kn), vessel=vessel)
        except OutsideTraining as err:
            raise LearnError(f"--speed-loss {self.label}: {err}") from None

    def check_settings(self, vessel, speeds_kn) -> None:
        """The least-fuel search sails every speed setting with the table of the service speed (its speed ratios):
        a setting outside the calm-water speeds the model saw for the vessel's class is refused as a vessel's speed
        is (one ``error:`` line), never sailed by a model extrapolating beyond its data. Nothing for a formula."""
        if self.learned_name is None or not len(speeds_kn):
            return
        for s in sorted({min(speeds_kn), max(speeds_kn)}):
            try:
                self.table(vessel, float(s))
            except LearnError as err:
                raise LearnError(f"{err} (the least-fuel speed setting {float(s):g} kn: give --speeds or --speed-range "
                                 "within the speeds the model saw)") from None

    def ship(self, vessel, speed_kn: float | None = None, table=None, **kwargs):
        """The router's :class:`routing.astar.ShipModel` of ``vessel`` with this model (``table``: one
        already tabulated for this vessel and speed)."""
        from routing.astar import ShipModel

        if self.learned_name is None:
            return ShipModel.from_vessel(vessel, self.label, speed_kn=speed_kn, **kwargs)
        table = table if table is not None else self.table(vessel, speed_kn)
        return ShipModel.from_vessel(vessel, "learned", speed_kn=speed_kn, learned=table)

    def __getstate__(self):  # shipped to workers without the fitted model (they get tables)
        return {"label": self.label, "db": self.db, "_loaded": None}


def resolve_speed_loss(text, db=None, option: str = "--speed-loss") -> SpeedLossChoice:
    """The one resolution of ``--speed-loss`` for route, audit, deviate and nightly: a formula's
    name (:data:`routing.speed_loss.MODELS`) or ``learned:NAME``, a model stored in the workspace
    ``db`` (checked now: an unknown name is one line listing the stored models); a choice already
    resolved is returned as it is."""
    from routing.speed_loss import MODELS

    if isinstance(text, SpeedLossChoice):
        return text

    name = parse_learned(text)
    if name is None:
        if text not in MODELS:
            raise LearnError(f"{option} {text!r} is not one of {', '.join(MODELS)}, learned:NAME")
        return SpeedLossChoice(str(text))
    from pipelines.storage import open_workspace
    from pipelines.storage.performance import read_model

    if db is None or not Path(db).exists():
        raise LearnError(f"{option} learned:{name} reads its model from a workspace: {db} does not exist (--db)")
    with open_workspace(db, read_only=True) as ws:
        read_model(ws, name)  # one line naming the stored models when there is no such model
    return SpeedLossChoice(f"learned:{name}", db=Path(db))


def newest_learned(db) -> SpeedLossChoice | None:
    """The newest model stored in the workspace as a choice (None when it holds none)."""
    from pipelines.storage import open_workspace
    from pipelines.storage.performance import list_models

    if db is None or not Path(db).exists():
        return None
    try:
        with open_workspace(db, read_only=True) as ws:
            names = list_models(ws)["name"].tolist()
    except Exception:  # noqa: BLE001 - a workspace without the models table holds no model
        return None
    return SpeedLossChoice(f"learned:{names[0]}", db=Path(db)) if names else None


def eta_band(plan, name: str = "optimal_smoothed") -> dict | None:
    """P10, P50 and P90 sailing time of a planned route sailed with a learned model's quantile
    tables (None for a formula): :func:`routing.bands.quantile_bands` (the errors of one voyage
    taken as fully correlated along it, the wide reading of the band)."""
    from routing.bands import quantile_bands

    if name not in plan.routes or plan.ship is None or plan.ship.model != "learned":
        return None
    band = quantile_bands(plan.routes[name], plan, label=f"learned:{plan.ship.learned.name}")
    return None if band is None else {k: band[k] for k in ("route", "assumption", "time_h_p10", "time_h_p50", "time_h_p90")}


def row_summary(row: dict) -> dict:
    """What :func:`table_lines` needs, from a stored model's row (``learn show``)."""
    m = row["metrics"]
    span = [None if t is None else t.strftime("%Y-%m-%dT%H:%M:%SZ") for t in (row["span_start"], row["span_end"])]
    return {"name": row["name"], "kind": row["kind"], "prior": row["prior"], "segments": int(row["rows"]),
            "fixes": int(m["fixes"]), "vessels": int(row["vessels"]), "span_utc": span, "grouped_cv": m["grouped_cv"],
            "time_split": m["time_split"], "voluntary": m["voluntary"], "limits": m.get("limits", [])}


def headline(cv: dict) -> dict:
    """The overall scores of the learned model and each formula, by model name."""
    return {r["model"]: r for r in cv["scores"] if r["scope"] == "all"}


def coverage_all(cv: dict) -> float:
    return float(next(c["coverage"] for c in cv["coverage"] if c["scope"] == "all"))


def _fmt(x, nd=3) -> str:
    return "-" if x is None or (isinstance(x, float) and not np.isfinite(x)) else f"{x:.{nd}f}"


def table_lines(summary: dict) -> list[str]:
    """The validation table for people (``learn performance`` and ``learn show``)."""
    cv = summary["grouped_cv"]
    lines = [f"model {summary['name']!r}: {summary['kind']} "
             + (f"(residual to {summary['prior']}) " if summary["kind"] == "residual" else "")
             + f"on {summary['segments']:,} ten-minute segments ({summary['fixes']:,} fixes) of "
             f"{summary['vessels']} vessels, {summary['span_utc'][0]} -> {summary['span_utc'][1]}",
             f"held-out vessels ({cv['k']}-fold grouped CV): the learned model vs the formulas on the same segments",
             f"  {'scope':<22}{'model':<18}{'n':>8}{'MAE kn':>9}{'bias kn':>9}{'R2 loss':>9}{'R2 speed':>9}"]
    for r in cv["scores"]:
        if r["model"] in ("learned_direct", "learned_residual") and r["model"] != f"learned_{summary['kind']}":
            if r["scope"] != "all":
                continue
        lines.append(f"  {r['group']:<22}{r['model']:<18}{r['n']:>8,}{_fmt(r['mae_kn']):>9}{_fmt(r['bias_kn']):>9}"
                     f"{_fmt(r['r2_loss']):>9}{_fmt(r['r2_speed']):>9}")
    gain = cv["mae_gain_frac"]
    lines.append(f"  MAE {_fmt(cv['learned_mae_kn'])} kn against {cv['best_formula']}'s {_fmt(cv['best_formula_mae_kn'])} kn "
                 f"({'-' if gain is None else f'{100 * gain:.0f} %'} lower): "
                 + ("beats every formula" if cv["beats_formulas"] else "does NOT beat the formulas (not used by default)"))
    cov = ", ".join(f"{c['group']} {100 * c['coverage']:.0f} %" for c in cv["coverage"])
    lines.append(f"  P10-P90 band coverage on held-out vessels (nominal 80 %): {cov}")
    ts = summary.get("time_split")
    if ts:
        h = headline(ts)
        lines.append(f"time split at {ts['cut_utc']} ({ts['train_rows']:,} segments before, {ts['rows']:,} after): "
                     f"MAE {_fmt(ts['learned_mae_kn'])} kn vs {ts['best_formula']} {_fmt(ts['best_formula_mae_kn'])} kn, "
                     f"R2 loss {_fmt(h['learned_' + ts['winner']]['r2_loss'])}, coverage {100 * coverage_all(ts):.0f} %")
    lines.append("learned voluntary slow-down (evidence beside the operator limits):")
    for r in summary["voluntary"]:
        if r["threshold_hs_m"] is not None:
            lines.append(f"  {r['ship_class']:<10} {r['sector']:<10} above Hs {r['threshold_hs_m']:.2f} m "
                         f"(step {r['from_hs_m']:.2f}-{r['to_hs_m']:.2f} m, {100 * r['drop_frac']:.0f} % of the speed, "
                         f"{r['vessels']} vessels)")
        else:
            lines.append(f"  {r['ship_class']:<10} {r['sector']:<10} none: {r['why']}")
    if summary.get("limits"):
        lines.append("beside the configured operator limits (head-to-bow seas):")
    for r in summary.get("limits", []):
        lines.append(f"  {limit_line(r)}")
    return lines
