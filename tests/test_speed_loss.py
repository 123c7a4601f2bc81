"""Speed-loss models against hand-computed values at table boundaries and in every sector.

Expected values are worked out by hand from the formulas of Grifoll et al. (2022), Appendix I
(Eq. A1.1-A1.3, Tables A1.1-A1.2), written out as arithmetic below; none comes from the
functions under test. Tolerances: 1e-9 relative (pure floating-point arithmetic).
"""

from __future__ import annotations

import doctest
import warnings

import numpy as np
import pandas as pd
import pytest
import xarray as xr

import routing.speed_loss as sl
from routing.speed_loss_kwon import KwonHull
from routing.speed_loss import (
    SpeedLossValidityWarning,
    attained_speed_kn,
    encounter_angle_deg,
    max_attainable_speed_kn,
    speed_loss,
    speed_loss_aertssen,
    speed_loss_bowditch,
    speed_loss_khokhlov,
    speed_loss_none,
)
from thresholds.vessel import Vessel

FT = 0.3048  # one foot [m]
TEN_FT_M = 10 * FT  # H = 10 ft -> H^2 = 100 ft^2


def approx(x):
    return pytest.approx(x, rel=1e-9, abs=1e-12)


# ---------------------------------------------------------------- encounter angle convention


def test_encounter_angle_convention():
    # Heading north, waves from the north: head seas (0). From the south: following (180).
    assert encounter_angle_deg(0.0, 0.0) == 0.0
    assert encounter_angle_deg(0.0, 180.0) == 180.0
    # Heading east, waves from the south hit the starboard side: 90.
    assert encounter_angle_deg(90.0, 180.0) == 90.0
    assert encounter_angle_deg(350.0, 20.0) == approx(30.0)
    assert isinstance(encounter_angle_deg(10.0, 20.0), float)


# ------------------------------------------------------------------------------- Bowditch

# (encounter_deg, f [kn/ft^2]) with theta = (encounter + 180) mod 360 in Table A1.1's convention.
BOWDITCH_SYMMETRIC = [
    (0.0, 0.0248),  # theta 180: head
    (45.0, 0.0248),  # theta 225: head, closed edge
    (46.0, 0.0165),  # theta 226: beam
    (90.0, 0.0165),  # theta 270: beam
    (134.0, 0.0165),  # theta 314: beam (mirrors theta 46)
    (135.0, 0.0083),  # theta 315: following (mirrors theta 45)
    (180.0, 0.0083),  # theta 0: following
    (225.0, 0.0083),  # theta 45: following, closed edge
    (226.0, 0.0165),  # theta 46: beam
    (314.0, 0.0165),  # theta 134: beam
    (315.0, 0.0248),  # theta 135: head, closed edge
    (359.0, 0.0248),
]


@pytest.mark.parametrize("enc, f", BOWDITCH_SYMMETRIC)
def test_bowditch_sectors_symmetric(enc, f):
    assert speed_loss_bowditch(16.1, TEN_FT_M, enc) == approx(f * 100.0)


@pytest.mark.parametrize(
    "enc, f",
    [(91.0, 0.0083), (134.0, 0.0083), (90.0, 0.0083), (89.0, 0.0165), (226.0, 0.0165), (46.0, 0.0165)],
)
def test_bowditch_sectors_as_printed(enc, f):
    # Table A1.1 as printed: theta in [270, 360] is following, i.e. encounter in [90, 180].
    assert speed_loss_bowditch(16.1, TEN_FT_M, enc, sectors="printed") == approx(f * 100.0)


def test_bowditch_metres_to_feet():
    # Hs 5 m = 16.404199 ft; head seas: 0.0248 * 269.097778 ft^2 = 6.673625 kn.
    h_ft = 5.0 / 0.3048
    assert speed_loss_bowditch(16.1, 5.0, 0.0) == approx(0.0248 * h_ft * h_ft)
    assert speed_loss_bowditch(16.1, 5.0, 0.0) == pytest.approx(6.673625, abs=1e-6)


def test_bowditch_unknown_sector_table():
    with pytest.raises(ValueError, match="sector table"):
        speed_loss_bowditch(16.1, 1.0, 0.0, sectors="other")


# ------------------------------------------------------------------------------- Aertssen

LPP = 225.0
V0 = 16.1


def aertssen(m, n):
    return (m / LPP + n) * V0 / 100.0  # Eq. A1.2


@pytest.mark.parametrize(
    "hs, enc, expected",
    [
        (1.5, 0.0, 0.0),  # Beaufort 4: below the table
        (0.0, 0.0, 0.0),
        (1.5001, 0.0, aertssen(900, 2)),  # Beaufort 5, head
        (2.5, 0.0, aertssen(900, 2)),  # upper edge of Beaufort 5
        (2.5001, 0.0, aertssen(1300, 6)),  # Beaufort 6
        (4.0, 0.0, aertssen(1300, 6)),
        (4.0001, 0.0, aertssen(2100, 11)),  # Beaufort 7
        (5.5, 0.0, aertssen(2100, 11)),
        (5.5001, 0.0, aertssen(3600, 18)),  # Beaufort 8
        (7.5, 0.0, aertssen(3600, 18)),
        # sectors at Beaufort 5 (Hs 2 m): head [0, 30), bow [30, 60), beam [60, 150), following [150, 180]
        (2.0, 29.9, aertssen(900, 2)),
        (2.0, 30.0, aertssen(700, 2)),
        (2.0, 59.9, aertssen(700, 2)),
        (2.0, 60.0, aertssen(350, 1)),
        (2.0, 149.9, aertssen(350, 1)),
        (2.0, 150.0, aertssen(100, 0)),
        (2.0, 180.0, aertssen(100, 0)),
        (2.0, 330.1, aertssen(900, 2)),  # folds to 29.9: head from port
        (2.0, 330.0, aertssen(700, 2)),  # folds to 30
        (2.0, 210.0, aertssen(100, 0)),  # folds to 150
        # the other rows, one sector each
        (3.0, 45.0, aertssen(1000, 5)),  # Beaufort 6 bow
        (5.0, 90.0, aertssen(700, 5)),  # Beaufort 7 beam
        (7.0, 170.0, aertssen(700, 3)),  # Beaufort 8 following
        (7.0, 100.0, aertssen(1000, 7)),  # Beaufort 8 beam
        (6.0, 50.0, aertssen(2300, 12)),  # Beaufort 8 bow
    ],
)
def test_aertssen_table(hs, enc, expected):
    assert speed_loss_aertssen(V0, hs, enc, LPP) == approx(expected)


def test_aertssen_worked_value():
    # Beaufort 6 head seas for the R6 ship: (1300/225 + 6) * 16.1 / 100 = 1.896222 kn.
    assert speed_loss_aertssen(16.1, 3.0, 0.0, 225.0) == pytest.approx(1.896222, abs=1e-6)


def test_aertssen_beyond_table_warns_and_uses_beaufort_8():
    with pytest.warns(SpeedLossValidityWarning, match="7.5 m"):
        loss = speed_loss_aertssen(V0, 9.0, 0.0, LPP)
    assert loss == approx(aertssen(3600, 18))


def test_aertssen_needs_length():
    with pytest.raises(ValueError, match="length"):
        speed_loss_aertssen(V0, 2.0, 0.0, 0.0)


# ------------------------------------------------------------------------------- Khokhlov

K8000 = 1.0 - 1.35e-6 * 8000.0 * 16.1  # = 0.82612


@pytest.mark.parametrize(
    "enc, theta",
    [(0.0, 0.0), (90.0, np.pi / 2), (180.0, np.pi), (270.0, np.pi / 2), (45.0, np.pi / 4), (315.0, np.pi / 4)],
)
def test_khokhlov_sectors(enc, theta):
    expected = (0.745 * 3.0 - 0.245 * theta * 3.0) * K8000  # Eq. A1.3, theta in rad, 0 = head
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # 8 000 dwt and 16.1 kn are inside the validity range
        assert speed_loss_khokhlov(16.1, 3.0, enc, 8000.0) == approx(expected)


def test_khokhlov_worked_values():
    assert K8000 == pytest.approx(0.82612, abs=1e-12)
    assert speed_loss_khokhlov(16.1, 3.0, 0.0, 8000.0) == pytest.approx(1.8463782, abs=1e-7)
    # Following seas: a small gain, (0.745 - 0.245 pi) * 3 * 0.82612 = -0.0611912 kn.
    assert speed_loss_khokhlov(16.1, 3.0, 180.0, 8000.0) == pytest.approx(-0.0611912, abs=1e-7)


@pytest.mark.parametrize("dwt, v0, match", [(3000.0, 16.1, "deadweight"), (25000.0, 16.1, "deadweight"), (8000.0, 25.0, "speed")])
def test_khokhlov_validity_warnings(dwt, v0, match):
    with pytest.warns(SpeedLossValidityWarning, match=match):
        speed_loss_khokhlov(v0, 2.0, 0.0, dwt)


# --------------------------------------------------------------------- dispatcher, floor, types


def test_none_model():
    assert speed_loss_none(16.1, 5.0, 0.0) == 0.0
    assert np.isnan(speed_loss_none(16.1, np.nan, 0.0))


def test_dispatch_matches_named_models_and_unknown_name():
    assert speed_loss(16.1, 3.0, 0.0, "bowditch") == approx(0.0248 * (3.0 / FT) ** 2)
    assert speed_loss(16.1, 3.0, 0.0, "aertssen", lpp_m=225.0) == approx(aertssen(1300, 6))
    assert speed_loss(16.1, 3.0, 0.0, "khokhlov", dwt_t=8000.0) == approx(2.235 * K8000)
    assert speed_loss(16.1, 3.0, 0.0, "none") == 0.0
    with pytest.raises(ValueError, match="unknown speed-loss model 'visir'"):
        speed_loss(16.1, 3.0, 0.0, "visir")
    with pytest.raises(ValueError, match="lpp_m"):
        speed_loss(16.1, 3.0, 0.0, "aertssen")


def test_floor_keeps_the_ship_moving():
    # SIMROUTE R6 at 12 kn: Bowditch head seas at Hs 7 m lose 0.0248*(7/0.3048)^2 = 13.08 kn > 12 kn.
    raw = 0.0248 * (7.0 / FT) ** 2
    assert raw > 12.0
    assert attained_speed_kn(12.0, 7.0, 0.0, "bowditch", floor_kn=2.0) == approx(2.0)
    assert speed_loss(12.0, 7.0, 0.0, "bowditch", floor_kn=2.0) == approx(10.0)
    # The vessel's floor is used when no floor is given.
    vessel = Vessel("t", "general", 12.0, 100.0, 20.0, 6.0, 5000.0, 5000.0, 14.0, 500.0, 200.0, min_speed_kn=3.5)
    assert attained_speed_kn(12.0, 7.0, 0.0, "bowditch", vessel=vessel) == approx(3.5)
    # A floor above v0 never raises the speed.
    assert attained_speed_kn(1.0, 0.0, 0.0, "bowditch", floor_kn=2.0) == approx(1.0)


def test_input_types_and_nan():
    hs = np.array([0.0, TEN_FT_M, np.nan, -1.0])
    out = speed_loss(16.1, hs, 0.0, "bowditch")
    assert isinstance(out, np.ndarray)
    np.testing.assert_allclose(out[:2], [0.0, 2.48], rtol=1e-9)
    assert np.isnan(out[2]) and np.isnan(out[3])  # land and invalid height
    series = pd.Series([TEN_FT_M, 0.0], index=["a", "b"], name="hs_m")
    out_s = attained_speed_kn(16.1, series, pd.Series([180.0, 0.0], index=["a", "b"]), "bowditch")
    assert isinstance(out_s, pd.Series) and list(out_s.index) == ["a", "b"]
    assert out_s["a"] == approx(16.1 - 0.83)
    da = xr.DataArray([[TEN_FT_M]], dims=("lat", "lon"))
    out_da = speed_loss(16.1, da, 0.0, "bowditch")
    assert isinstance(out_da, xr.DataArray) and out_da.dims == ("lat", "lon")
    assert float(out_da[0, 0]) == approx(2.48)
    assert isinstance(speed_loss(16.1, 1.0, 0.0), float)


def test_max_attainable_speed_bounds_every_model():
    hs = np.linspace(0.0, 8.0, 33)[:, None]
    enc = np.linspace(0.0, 359.0, 360)[None, :]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SpeedLossValidityWarning)
        for model in sl.MODELS:
            vmax = max_attainable_speed_kn(16.1, model, hs_max_m=8.0, dwt_t=8000.0)
            wind = {"wind_ms": hs * 5.0, "kwon": KwonHull(0.6, 225.0, 30000.0, "loaded")} if model == "kwon" else {}
            v = attained_speed_kn(16.1, hs, enc, model, lpp_m=225.0, dwt_t=8000.0, **wind)
            assert np.nanmax(v) <= vmax + 1e-12
        # outside Khokhlov's range (factor < 0) the bound is the head-sea gain, not the following-sea one
        assert max_attainable_speed_kn(19.0, "khokhlov", hs_max_m=5.0, dwt_t=100000.0) == approx(
            19.0 + 0.745 * 5.0 * (1.35e-6 * 100000.0 * 19.0 - 1.0)
        )
    # Khokhlov's following-sea gain: 16.1 + (0.245 pi - 0.745) * 8 * 0.82612.
    assert max_attainable_speed_kn(16.1, "khokhlov", hs_max_m=8.0, dwt_t=8000.0) == approx(
        16.1 + (0.245 * np.pi - 0.745) * 8.0 * K8000
    )


def test_docstring_examples():
    result = doctest.testmod(sl)
    assert result.attempted > 0 and result.failed == 0
