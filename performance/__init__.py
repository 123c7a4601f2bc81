"""A ship performance model learned from the fleet's own AIS joined with the weather each fix met.

Pure domain code (data in, results out; no files, DuckDB or Prefect): the training table comes
from :mod:`pipelines.storage.training`, the model file is written by
:mod:`pipelines.storage.performance`, the command is ``stormlane learn``.

* :mod:`.features` — the sea state relative to the ship (encounter angle, head and cross wind,
  current along track, speed through the water), ship classes and particulars, the voyage's
  calm-water speed, the target (speed through the water / calm-water speed).
* :mod:`.formulas` — the published speed-loss formulas (:mod:`routing.speed_loss`) on the same
  fixes: the physical prior and the yardstick.
* :mod:`.fit` — gradient-boosted trees (scikit-learn ``HistGradientBoostingRegressor``) with
  monotonic constraints, directly or as the residual to the best formula, plus P10/P90 quantile
  models.
* :mod:`.validate` — grouped cross-validation leaving whole vessels out, a time split, R², MAE
  and bias in kn per ship class and sea-state band against every formula on the same held-out
  fixes, coverage of the P10-P90 band.
* :mod:`.voluntary` — the sea states in which masters of each class actually slow down.
* :mod:`.tabulate` — the model on a grid (Hs x encounter x period x head wind) for one vessel,
  the arrays the router interpolates (routing never imports this package).

The demo fleet sails by a law of the scenario generator's own (:mod:`scenario.performance_law`);
an import-linter contract keeps it out of this package.
"""
