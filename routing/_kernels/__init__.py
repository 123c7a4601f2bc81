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
the modules it calls or whose constants it freezes. The kernels therefore cache into a folder of
their own per digest of every source they depend on (:func:`_kernel_cache_dir`): code that
changed never loads machine code compiled from other sources, and a process still running older
sources (an upgrade during a nightly run) writes only into its own digest's folder.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import time
from pathlib import Path

#: Folders of other digests unused for this long are removed (a running process keeps its own).
STALE_CACHE_AGE_S = 7 * 24 * 3600.0


def _sources_digest(here: Path) -> str:
    """Digest of the kernel sources and of the modules whose constants the kernels freeze."""
    deps = sorted(here.glob("*.py")) + [here.parent / name for name in ("speed_loss.py", "speed_loss_kwon.py", "learned.py", "_land.py")]
    deps.append(here.parent.parent / "thresholds" / "units.py")
    h = hashlib.blake2b(digest_size=16)
    for f in deps:
        if f.exists():
            h.update(f.name.encode() + b"\0" + f.read_bytes())
    return h.hexdigest()


def _kernel_cache_dir() -> Path:
    """``<base>/numba-<digest>``: the base is ``$NUMBA_CACHE_DIR`` when set (the benchmarks' empty
    and warm caches), else this package's ``__pycache__``. Other digests' folders unused for
    :data:`STALE_CACHE_AGE_S` and the flat cache files of earlier versions are removed."""
    here = Path(__file__).resolve().parent
    base = Path(os.environ["NUMBA_CACHE_DIR"]) if os.environ.get("NUMBA_CACHE_DIR") else here / "__pycache__"
    folder = base / f"numba-{_sources_digest(here)}"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        os.utime(folder)  # in use: not stale for another week
        now = time.time()
        for old in base.glob("numba-*"):
            if old != folder and now - old.stat().st_mtime > STALE_CACHE_AGE_S:
                shutil.rmtree(old, ignore_errors=True)
        earlier = [*(here / "__pycache__").glob("*.nbi"), *(here / "__pycache__").glob("*.nbc"), here / "__pycache__" / "kernels.sources"]
        for f in earlier:  # the flat cache of earlier versions, keyed on one digest for all processes
            f.unlink(missing_ok=True)
    except OSError:  # read-only install: numba then compiles in memory
        pass
    return folder


def _import_kernels() -> None:
    """Import every kernel module with numba's cache folder set to :func:`_kernel_cache_dir`
    (numba picks a function's cache folder when it is decorated), then restore the setting."""
    import importlib

    from numba.core import config

    previous = config.CACHE_DIR
    config.CACHE_DIR = str(_kernel_cache_dir())
    try:
        here = Path(__file__).resolve().parent
        for f in sorted(here.glob("*.py")):
            if f.stem != "__init__":
                importlib.import_module(f"routing._kernels.{f.stem}")
    finally:
        config.CACHE_DIR = previous


_import_kernels()

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
