"""ais.io.float32.widen_float32 against the brute-force reference: numpy's shortest text of
each binary32, read back as a double (Steele & White; what Python and numpy print)."""

import numpy as np

from ais.io.float32 import widen_float32


def _reference(v: np.ndarray) -> np.ndarray:
    return v.astype(str).astype(np.float64)


def _same(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return (a == b) & (np.signbit(a) == np.signbit(b)) | (np.isnan(a) & np.isnan(b))


def test_every_kind_of_binary32_gives_its_shortest_decimal():
    rng = np.random.default_rng(23)
    ais_like = [rng.uniform(-180, 180, 200_000).round(d) for d in (1, 4, 5, 6)] + [
        rng.uniform(0, 102.2, 200_000).round(1), rng.uniform(0, 359.9, 200_000).round(1),
        rng.integers(0, 360, 50_000).astype(float), rng.uniform(-90, 90, 200_000)]
    wide = [10.0 ** rng.uniform(-45, 38.5, 200_000), -(10.0 ** rng.uniform(-12, 12, 200_000))]
    bits = np.frombuffer(rng.integers(0, 2 ** 32, 1_000_000, dtype=np.uint32).tobytes(), np.float32)
    special = np.array([0.0, -0.0, np.inf, -np.inf, np.nan, 1.0, 0.1, 511, 102.3, 360, 3.4028235e38, 1e-45,
                        1.17549435e-38, 1e13, 9.999999e12, 1e-13, 9.99999e-14], np.float32)
    with np.errstate(over="ignore", invalid="ignore"):
        v = np.concatenate([np.concatenate(ais_like + wide).astype(np.float32), bits, special])
    got = widen_float32(v)
    want = _reference(v)
    bad = np.flatnonzero(~_same(got, want))
    assert not len(bad), [(repr(v[i]), got[i], want[i]) for i in bad[:5]]


def test_hand_computed_values():
    v = np.array([5.9, 0.1, 359.9, -162.921875, 1e-7, 55.123456], np.float32)
    # 5.9f is 5.900000095367431640625 bit for bit; -162.921875 is exact in binary32, but the
    # shortest text that reads back as it is -162.92188
    assert widen_float32(v).tolist() == [5.9, 0.1, 359.9, -162.92188, 1e-7, 55.123455]
    assert float(v[0]) != 5.9
