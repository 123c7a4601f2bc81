"""The 30" land mask read through its bit-packed cache (thresholds.land_raster, routing.land.land_window).

Checked against the package itself (global-land-mask's own ``globe.is_ocean``, run in a child
process so its 0.93 GB array never lives in the test process), across the antimeridian, when two
processes build the cache at once, with bounded memory, and when the cache cannot be written.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from routing.land import land_window
from thresholds import land_raster


def _child(code: str, env: dict | None = None, stderr: bool = False):
    full_env = dict(os.environ, **(env or {}))
    out = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, env=full_env, timeout=300)
    assert out.returncode == 0, out.stderr
    return (out.stdout, out.stderr) if stderr else out.stdout


def test_cache_matches_the_package_lookup_at_random_points():
    rng = np.random.default_rng(16)
    lat = rng.uniform(-90.0, 90.0, 200_000)
    lon = rng.uniform(-180.0, 180.0, 200_000)
    # plus points along real coasts, where land and sea alternate pixel by pixel (Mallorca, Gibraltar)
    lat = np.concatenate([lat, rng.uniform(39.2, 40.0, 50_000), rng.uniform(35.8, 36.2, 50_000)])
    lon = np.concatenate([lon, rng.uniform(2.3, 3.5, 50_000), rng.uniform(-5.8, -5.2, 50_000)])
    # and the demo's 1/12-deg weather grid, whose points lie exactly on pixel edges: the package's
    # float arithmetic decides which side, and the cache's look-up must decide the same
    g_lat, g_lon = np.meshgrid(35.5 + np.arange(115) / 12.0, -1.5 + np.arange(157) / 12.0, indexing="ij")
    lat, lon = np.concatenate([lat, g_lat.ravel()]), np.concatenate([lon, g_lon.ravel()])
    np.save(path := os.path.join(os.environ.get("TMPDIR", "/tmp"), f"lr_pts_{os.getpid()}.npy"), np.stack([lat, lon]))
    try:
        out = _child(f"""
            import numpy as np
            from global_land_mask import globe
            lat, lon = np.load({path!r})
            print(np.packbits(globe.is_ocean(lat, lon)).tobytes().hex())
        """)
    finally:
        os.unlink(path)
    want = np.unpackbits(np.frombuffer(bytes.fromhex(out.strip()), dtype=np.uint8))[: lat.size].astype(bool)
    got = land_raster.is_ocean(lat, lon)
    assert 0.2 < got.mean() < 0.9 and 0.2 < (~got[-118_055:-18_055]).mean()  # both classes present
    assert np.array_equal(got, want)


def test_windows_agree_with_points_and_wrap_across_the_antimeridian():
    # a window over Fiji / the antimeridian in a continuous frame (lon up to 181.5) and in [-180, 180)
    w = land_window(-18.5, -15.5, 176.5, 181.5)
    assert w.ocean.shape == (360, 600) and w.c0 == (176.5 + 180) * 120
    lat = np.linspace(-18.4, -15.6, 300) + 1.3e-6  # off the pixel edges, where windows (floor) and the
    lon = np.linspace(176.6, 181.4, 400) + 1.7e-6  # package's point arithmetic may take either side
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    from_window = w.is_ocean(la, lo)
    assert (~from_window).sum() > 1000  # Fiji's islands are in it
    assert np.array_equal(from_window, land_raster.is_ocean(la, lo))
    assert np.array_equal(from_window, w.is_ocean(la, lo - 360.0))  # the same pixels from the other frame
    assert np.array_equal(land_raster.is_ocean(la, lo), land_raster.is_ocean(la, lo - 360.0))
    # the window's pixels are exactly the raster rows/columns it names
    r = np.arange(w.ocean.shape[0])[:, None] + w.r0
    c = (np.arange(w.ocean.shape[1])[None, :] + w.c0) % land_raster.N_COLS
    centre_lat = 90.0 - (r + 0.5) / 120.0
    centre_lon = -180.0 + (c + 0.5) / 120.0
    assert np.array_equal(w.ocean, land_raster.is_ocean(np.broadcast_to(centre_lat, w.ocean.shape), np.broadcast_to(centre_lon, w.ocean.shape)))


def test_two_processes_build_one_cache_with_bounded_memory(tmp_path):
    code = """
        import json
        from thresholds import land_raster
        p = land_raster.build_cache()
        # VmHWM (peak resident set of this program; ru_maxrss would count the forked test process)
        hwm_kb = next(int(line.split()[1]) for line in open("/proc/self/status") if line.startswith("VmHWM"))
        print(json.dumps({"path": str(p), "rss_mb": hwm_kb / 1024}))
    """
    env = dict(os.environ, STORMLANE_CACHE=str(tmp_path))
    procs = [subprocess.Popen([sys.executable, "-c", textwrap.dedent(code)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env) for _ in range(2)]
    results = []
    for p in procs:
        out, err = p.communicate(timeout=300)
        assert p.returncode == 0, err
        results.append(json.loads(out))
    assert results[0]["path"] == results[1]["path"]
    files = sorted(x.name for x in (tmp_path / "land").iterdir())
    assert files == sorted([os.path.basename(results[0]["path"]), os.path.basename(results[0]["path"]) + ".lock"])  # no temporary left
    assert all(r["rss_mb"] < 250 for r in results), results  # the raster inflated in blocks (0.93 GB whole)
    built = np.memmap(results[0]["path"], dtype=np.uint8, mode="r")
    assert np.array_equal(built, np.memmap(land_raster.build_cache(), dtype=np.uint8, mode="r"))


def test_unwritable_cache_reads_windows_from_the_package_with_a_warning(tmp_path):
    blocker = tmp_path / "not-a-dir"
    blocker.write_text("a file where the cache folder should be")
    out, err = _child(
        """
        import logging, json
        import numpy as np
        logging.basicConfig(level=logging.WARNING)
        from routing.land import land_window
        from thresholds import land_raster
        w = land_window(35.8, 36.2, -5.8, -5.2)
        pts = land_raster.is_ocean(np.array([36.0, 35.9]), np.array([-5.5, -5.35]))
        print(json.dumps({"sum": int(w.ocean.sum()), "shape": list(w.ocean.shape), "pts": pts.tolist()}))
        """,
        env={"STORMLANE_CACHE": str(blocker)},
        stderr=True,
    )
    assert "land mask cache unavailable" in err and str(blocker) in err
    got = json.loads(out.strip().splitlines()[-1])
    w = land_window(35.8, 36.2, -5.8, -5.2)
    assert got["shape"] == list(w.ocean.shape) and got["sum"] == int(w.ocean.sum())
    assert got["pts"] == land_raster.is_ocean(np.array([36.0, 35.9]), np.array([-5.5, -5.35])).tolist()


def test_window_errors_name_the_box():
    with pytest.raises(ValueError, match="outside the 21600 x 43200 raster"):
        land_raster.read_ocean(5, 5, 0, 10)
