"""Compiled (numba) cores of the router: flat arrays in, flat arrays out, no Python objects.

* :mod:`.core` — the parameter vector's layout, great-circle geometry, the heap, the goal
  heuristic's tables, :func:`gather_bilinear_time` (weather grid -> mesh nodes).
* :mod:`.speed` — the speed model (:func:`speed_through_water`, pace over ground).
* :mod:`.edge` — the edge model: weather of a node at a slice or quarter-hour sub-slice (linear in
  time between slices), the travel time in the weather of the sub-slice nearest to the departure,
  the FIFO arrival (waiting allowed).
* :mod:`.search` — :func:`astar`, time-dependent A* / Dijkstra on a regular lat/lon mesh.
* :mod:`.search_safe` — :func:`astar_safe`, the same under the vessel's limits (per-cell,
  per-slice, per-heading-sector flags precomputed by :mod:`routing.safety`).
* :mod:`.walk` — :func:`eval_path`, :func:`walk_path_safety`: times (and exposure) along any
  polyline through the same weather (re-timing).
* :mod:`.smooth` — :func:`smooth_path`, :func:`smooth_path_safe`: any-angle smoothing that keeps
  the time-dependent cost.
* :mod:`.cells` — cell and pixel traversals (:func:`allowed_edges`, :func:`gc_leg_is_sea`,
  :func:`segment_cells_sea`, :func:`land_summed_area`, :func:`component_from`).
* :mod:`.flags` — safety-flag helpers and :func:`heading_flags`.

Numba's on-disk cache (``cache=True``) keys a compiled function on its own file only, not on
the modules it calls or whose constants it freezes; :func:`_drop_stale_cache` therefore drops the
package's cached machine code whenever any of the sources it depends on changed.
"""

from __future__ import annotations

import hashlib
from pathlib import Path


def _drop_stale_cache() -> None:
    """Delete this package's numba cache files when a kernel source (or a module whose constants the
    kernels freeze) differs from the one the cache was built from."""
    here = Path(__file__).resolve().parent
    deps = sorted(here.glob("*.py")) + [here.parent / "speed_loss.py", here.parent / "speed_loss_kwon.py", here.parent / "learned.py", here.parent / "_land.py",
                                        here.parent.parent / "thresholds" / "units.py"]
    h = hashlib.blake2b(digest_size=16)
    for f in deps:
        if f.exists():
            h.update(f.read_bytes())
    digest = h.hexdigest()
    cache = here / "__pycache__"
    stamp = cache / "kernels.sources"
    try:
        if stamp.read_text() == digest:
            return
    except OSError:
        pass
    try:
        cache.mkdir(exist_ok=True)
        for f in list(cache.glob("*.nbi")) + list(cache.glob("*.nbc")):
            f.unlink(missing_ok=True)
        stamp.write_text(digest)
    except OSError:  # read-only install: numba then compiles in memory or in its own cache dir
        pass


_drop_stale_cache()

from routing._kernels.cells import (  # noqa: E402
    allowed_edges,
    component_from,
    gc_leg_is_sea,
    land_summed_area,
    segment_cells_sea,
)
from routing._kernels.core import (  # noqa: E402
    N_PARAMS,
    P_AERTSSEN_BANDS,
    P_DWT,
    P_FLOOR,
    P_KWON_CU,
    P_KWON_FORM_A,
    P_KWON_FORM_B,
    P_LPP,
    P_MIN_SOG,
    P_MODEL,
    P_PACE_MIN,
    P_PRINTED,
    P_TIME_STEP,
    P_V0,
    P_WAIT,
    SUBSTEP_MAX_H,
    gather_bilinear_time,
)
from routing._kernels.flags import heading_flags  # noqa: E402
from routing._kernels.search import astar  # noqa: E402
from routing._kernels.search_safe import astar_safe  # noqa: E402
from routing._kernels.smooth import smooth_path, smooth_path_safe  # noqa: E402
from routing._kernels.speed import MODEL_CODES, ship_of, speed_through_water  # noqa: E402
from routing._kernels.walk import eval_path, walk_path_safety  # noqa: E402

__all__ = [
    "MODEL_CODES",
    "N_PARAMS",
    "P_AERTSSEN_BANDS",
    "P_DWT",
    "P_FLOOR",
    "P_KWON_CU",
    "P_KWON_FORM_A",
    "P_KWON_FORM_B",
    "P_LPP",
    "P_MIN_SOG",
    "P_MODEL",
    "P_PACE_MIN",
    "P_PRINTED",
    "P_TIME_STEP",
    "P_V0",
    "P_WAIT",
    "SUBSTEP_MAX_H",
    "allowed_edges",
    "astar",
    "astar_safe",
    "component_from",
    "eval_path",
    "gather_bilinear_time",
    "gc_leg_is_sea",
    "heading_flags",
    "land_summed_area",
    "segment_cells_sea",
    "ship_of",
    "smooth_path",
    "smooth_path_safe",
    "speed_through_water",
    "walk_path_safety",
]
