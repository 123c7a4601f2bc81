"""The compiled kernels cache per digest of their sources (routing._kernels._kernel_cache_dir):
machine code compiled from other sources is never loaded, and a process running older sources
writes only into its own digest's folder."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import routing._kernels as kernels

ROOT = Path(__file__).resolve().parents[1]

GATHER = """
import numpy as np
from routing._kernels import gather_bilinear_time
flat = np.array([1.0, 3.0]).reshape(1, 2, 1)  # one time, two grid points, one channel
out = np.zeros((1, 1, 1))
gather_bilinear_time(flat, np.array([[0, 1, 0, 1]]), np.array([[0.5, 0.5, 0.0, 0.0]]), np.array([0]), np.array([0.0]), out)
print(out[0, 0, 0])
"""


def _run(env_cache: Path) -> str:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(env_cache)}
    done = subprocess.run([sys.executable, "-c", GATHER], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


def test_digest_changes_with_a_dependency(tmp_path):
    """Another source of a dependency (here: a copy of the package with one module edited) gives
    another digest, the same sources the same digest."""
    here = Path(kernels.__file__).resolve().parent
    assert kernels._sources_digest(here) == kernels._sources_digest(here)
    copy = tmp_path / "routing" / "_kernels"
    copy.mkdir(parents=True)
    for f in here.glob("*.py"):
        (copy / f.name).write_bytes(f.read_bytes())
    for name in ("speed_loss.py", "speed_loss_kwon.py", "learned.py", "_land.py"):
        (copy.parent / name).write_bytes((here.parent / name).read_bytes())
    (tmp_path / "thresholds").mkdir()
    (tmp_path / "thresholds" / "units.py").write_bytes((here.parent.parent / "thresholds" / "units.py").read_bytes())
    assert kernels._sources_digest(copy) == kernels._sources_digest(here)
    (copy.parent / "speed_loss.py").write_text((here.parent / "speed_loss.py").read_text() + "\nX = 1\n")
    assert kernels._sources_digest(copy) != kernels._sources_digest(here)


def test_kernels_cache_into_their_digest_folder(tmp_path):
    """A fresh process compiles into ``$NUMBA_CACHE_DIR/numba-<digest>`` and nowhere else there; the
    next process loads it and computes the same value (the bilinear weights: 0.5*1 + 0.5*3 = 2)."""
    digest = kernels._sources_digest(Path(kernels.__file__).resolve().parent)
    assert _run(tmp_path) == "2.0"
    folders = [p.name for p in tmp_path.iterdir()]
    assert folders == [f"numba-{digest}"]
    index = list((tmp_path / folders[0]).rglob("*.nbi"))
    assert any("gather_bilinear_time" in p.name for p in index), index
    stamp = {p: p.stat().st_mtime_ns for p in index}
    assert _run(tmp_path) == "2.0"
    assert {p: p.stat().st_mtime_ns for p in index} == stamp  # loaded, not compiled and written again
