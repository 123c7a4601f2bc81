"""Fitting the performance model: gradient-boosted trees on the speed ratio, and P10/P90 bands.

The learner is scikit-learn's ``HistGradientBoostingRegressor`` (histogram gradient boosting,
after LightGBM: G. Ke et al., "LightGBM: a highly efficient gradient boosting decision tree,"
NeurIPS 2017), the family the published AIS x weather studies use (Pant et al. 2026; LightGBM in
JMSE 2025). Two forms of the point model are fitted and compared by
:mod:`performance.validate`:

* ``direct``: the ratio ``stw / v0`` itself, with monotonic constraints where physics requires
  them (:data:`performance.features.MONOTONIC`: the speed never rises with Hs or with the head
  wind);
* ``residual``: the difference between the ratio and a physical prior, the best published formula
  on the training fixes. The residual cannot carry the same constraints (where the formula
  overstates the loss the correction *grows* with Hs), so the sum is only as monotonic as the
  data make it.

The band comes from two quantile models of the ratio (pinball loss at 0.1 and 0.9, the same
constraints; at most ``max_band_rows`` rows and ``band_max_iter`` iterations: scikit-learn
recomputes every leaf's quantile at every iteration, which made them 2/3 of the fitting time),
widened by the conformal margins :mod:`performance.validate` finds on held-out vessels, one per
sea-state band; at prediction P10 <= P50 <= P90 is enforced by ordering.

Training rows: AIS fixes a minute apart share their weather cell and time and are strongly
correlated, so each model is fitted on at most ``max_train_rows`` fixes drawn at random (seeded);
``performance.validate`` reports what the cap costs on the demo.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np
import pandas as pd

from performance.features import CATEGORICAL, FEATURES, MONOTONIC, feature_matrix

KINDS = ("direct", "residual")


@dataclass(frozen=True)
class FitSettings:
    """Hyper-parameters (the same for every fit of a run; stored with the model)."""

    max_iter: int = 150
    learning_rate: float = 0.1
    max_leaf_nodes: int = 31
    min_samples_leaf: int = 40
    l2_regularization: float = 0.0
    max_train_rows: int = 120_000
    max_band_rows: int = 15_000  # the quantile models' cap (their band is conformalised on held-out scores anyway)
    band_max_iter: int = 80  # the quantile models' boosting iterations
    band_learning_rate: float = 0.2
    quantiles: tuple[float, float] = (0.1, 0.9)
    seed: int = 0

    def to_dict(self) -> dict:
        d = asdict(self)
        d["quantiles"] = list(self.quantiles)
        return d


def _estimator(settings: FitSettings, *, quantile: float | None = None, constrained: bool = True):
    from sklearn.ensemble import HistGradientBoostingRegressor

    mono = [MONOTONIC.get(f, 0) if constrained else 0 for f in FEATURES]
    cat = [f in CATEGORICAL for f in FEATURES]
    kw = dict(loss="quantile", quantile=quantile) if quantile is not None else dict(loss="squared_error")
    band = quantile is not None
    return HistGradientBoostingRegressor(
        **kw, max_iter=settings.band_max_iter if band else settings.max_iter,
        learning_rate=settings.band_learning_rate if band else settings.learning_rate, max_leaf_nodes=settings.max_leaf_nodes,
        min_samples_leaf=settings.min_samples_leaf, l2_regularization=settings.l2_regularization,
        monotonic_cst=mono, categorical_features=cat, early_stopping=False, random_state=settings.seed)


def _subsample(n: int, settings: FitSettings, cap: int | None = None) -> np.ndarray:
    cap = settings.max_train_rows if cap is None else cap
    if n <= cap:
        return np.arange(n)
    rng = np.random.default_rng(settings.seed)
    return np.sort(rng.choice(n, cap, replace=False))


def scale_at(hs_m, scales: list) -> np.ndarray:
    """The conformal scale of each row's sea-state band (:func:`performance.validate.band_scales`)."""
    lows = np.asarray([lo for lo, _ in scales], dtype=float)
    vals = np.asarray([v for _, v in scales], dtype=float)
    i = np.clip(np.searchsorted(lows, np.nan_to_num(np.asarray(hs_m, dtype=float), nan=0.0), side="right") - 1, 0, len(vals) - 1)
    return vals[i]


@dataclass
class PerformanceModel:
    """A fitted model: the point model of one ``kind``, the quantile models, their settings."""

    kind: str
    prior: str | None
    point: object
    bands: dict = field(default_factory=dict)  # quantile -> estimator
    settings: FitSettings = field(default_factory=FitSettings)
    features: tuple = FEATURES
    band_scale: float = 0.0  # the conformal widening, in speed ratio (performance.validate.band_scale)
    band_scales: list = field(default_factory=list)  # [hs_lo_m, scale] per sea-state band (validate.band_scales)
    scale_in_widths: bool = False  # a model stored before the per-band margins: its one scale is in band widths

    def predict(self, df: pd.DataFrame, prior_ratio=None) -> pd.DataFrame:
        """``p50`` (the point model), and ``p10``/``p90`` (the bands) of the speed ratio per row.

        ``prior_ratio`` (the prior formula's ratio at the same rows) is needed for a residual model.
        """
        X = feature_matrix(df)
        p50 = self.point.predict(X)
        if self.kind == "residual":
            if prior_ratio is None:
                raise ValueError(f"a residual model needs the {self.prior} prior's ratio at the rows")
            p50 = p50 + np.asarray(prior_ratio, dtype=float)
        out = pd.DataFrame({"p50": p50}, index=df.index)
        (q_lo, lo), (q_hi, hi) = sorted(self.bands.items())
        low, high = lo.predict(X), hi.predict(X)
        scale = self.band_scale
        if self.band_scales:  # per sea-state band (performance.validate.band_scales)
            scale = scale_at(df["hs_m"].to_numpy(float), self.band_scales)
        if self.scale_in_widths:
            scale = scale * np.maximum(high - low, 1e-6)
        out["p10"] = np.minimum(low - scale, p50)  # additive, in speed ratio (performance.validate.conformity)
        out["p90"] = np.maximum(high + scale, p50)
        return out

    def to_state(self) -> dict:
        """Plain types and estimators only (what :mod:`pipelines.storage.performance` saves with skops)."""
        return {"kind": self.kind, "prior": self.prior or "", "point": self.point,
                "band_quantiles": [float(q) for q in sorted(self.bands)],
                "band_models": [self.bands[q] for q in sorted(self.bands)],
                "settings": self.settings.to_dict(), "features": list(self.features),
                "band_scale": float(self.band_scale),
                "band_scale_hs_lo_m": [float(lo) for lo, _ in self.band_scales],
                "band_scale_by_hs": [float(v) for _, v in self.band_scales]}

    @classmethod
    def from_state(cls, state: dict) -> "PerformanceModel":
        s = dict(state["settings"])
        s["quantiles"] = tuple(s["quantiles"])
        if tuple(state["features"]) != FEATURES:
            raise ValueError(f"the model was fitted on features {state['features']}, this code uses {list(FEATURES)}")
        return cls(kind=state["kind"], prior=state["prior"] or None, point=state["point"],
                   bands=dict(zip(state["band_quantiles"], state["band_models"])), settings=FitSettings(**s),
                   band_scale=float(state.get("band_scale", 0.0)), scale_in_widths="band_scale_by_hs" not in state,
                   band_scales=[[float(lo), float(v)] for lo, v in zip(state.get("band_scale_hs_lo_m", []),
                                                                        state.get("band_scale_by_hs", []))])


def fit_point(df: pd.DataFrame, kind: str, settings: FitSettings, prior_ratio=None):
    """The point model of ``kind`` on the rows of ``df`` (target ``speed_ratio``)."""
    if kind not in KINDS:
        raise ValueError(f"unknown model kind {kind!r}; use one of {KINDS}")
    idx = _subsample(len(df), settings)
    X = feature_matrix(df)[idx]
    y = df["speed_ratio"].to_numpy(dtype=float)[idx]
    if kind == "residual":
        y = y - np.asarray(prior_ratio, dtype=float)[idx]
    return _estimator(settings, constrained=(kind == "direct")).fit(X, y)


def fit_bands(df: pd.DataFrame, settings: FitSettings) -> dict:
    """The quantile models of the ratio (``settings.quantiles``), on at most ``settings.max_band_rows`` rows."""
    idx = _subsample(len(df), settings, min(settings.max_band_rows, settings.max_train_rows))
    X = feature_matrix(df)[idx]
    y = df["speed_ratio"].to_numpy(dtype=float)[idx]
    return {float(q): _estimator(settings, quantile=q).fit(X, y) for q in settings.quantiles}


def fit_model(df: pd.DataFrame, kind: str, settings: FitSettings, prior: str | None = None,
              prior_ratio=None) -> PerformanceModel:
    """A complete model: point model of ``kind`` and the P10/P90 bands."""
    return PerformanceModel(kind=kind, prior=prior if kind == "residual" else None,
                            point=fit_point(df, kind, settings, prior_ratio), bands=fit_bands(df, settings),
                            settings=settings)
