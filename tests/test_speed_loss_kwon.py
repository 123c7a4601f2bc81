"""Kwon's wind speed loss (hand-computed from the published tables) and Aertssen's two Hs -> Beaufort
conventions at every band; the validity refusals name the vessel and the numbers."""

from __future__ import annotations

import doctest
import math

import numpy as np
import pytest

import routing.speed_loss_kwon as kw
from pipelines.config import load_vessel
from routing.astar import ShipModel
from routing.speed_loss import SpeedLossRangeError, aertssen_beaufort, speed_loss_aertssen
from routing.speed_loss_kwon import (
    KwonHull,
    beaufort_number,
    kwon_check,
    kwon_direction_coefficient,
    kwon_form_coefficient,
    kwon_speed_coefficient,
    speed_loss_kwon,
)


def test_beaufort_number_from_the_wmo_scale():
    # WMO-No. 558: force 4 is 5.5-7.9 m/s, force 5 8.0-10.7, force 7 13.9-17.1, force 12 >= 32.7
    w = np.array([0.0, 0.29, 0.3, 5.49, 5.5, 7.95, 8.0, 13.9, 17.1, 17.2, 32.6, 32.7, 60.0, np.nan])
    assert beaufort_number(w).tolist() == [0, 0, 1, 3, 4, 4, 5, 7, 7, 8, 11, 12, 12, 0]


@pytest.mark.parametrize("angle,expected", [
    (0.0, 1.0), (30.0, 1.0),                        # head 0-30 deg: 2 C_beta = 2
    (30.5, (1.7 - 0.03 * 2 ** 2) / 2),              # bow, BN 6: (1.7 - 0.03 (6 - 4)^2) / 2 = 0.79
    (60.0, 0.79), (60.5, 0.9 / 2), (150.0, 0.45),   # beam, BN 6: 0.9 - 0.06 (6 - 6)^2
    (150.5, (0.4 - 0.03 * 2 ** 2) / 2), (180.0, 0.14), (270.0, 0.45), (345.0, 1.0),  # following; port side mirrored
])  # fmt: skip
def test_direction_coefficient_table_1(angle, expected):
    assert float(kwon_direction_coefficient(6, angle)) == pytest.approx(expected, abs=1e-12)


def test_direction_coefficient_never_negative():
    # following seas at BN 3: 0.4 - 0.03 (3 - 8)^2 = -0.35 -> 0 (the fit describes losses, never gains)
    assert float(kwon_direction_coefficient(3, 180.0)) == 0.0
    assert float(kwon_direction_coefficient(12, 45.0)) == 0.0  # bow at BN 12: 1.7 - 0.03 * 64 < 0


@pytest.mark.parametrize("cb,loading,fn,expected", [
    (0.55, "loaded", 0.20, 1.7 - 1.4 * 0.2 - 7.4 * 0.04),
    (0.70, "loaded", 0.18, 3.1 - 5.3 * 0.18 - 12.4 * 0.18 ** 2),
    (0.85, "loaded", 0.12, 3.1 - 18.7 * 0.12 + 28.0 * 0.12 ** 2),
    (0.80, "ballast", 0.13, 3.0 - 16.3 * 0.13 - 21.6 * 0.13 ** 2),
    (0.575, "loaded", 0.20, 0.5 * ((1.7 - 0.28 - 0.296) + (2.2 - 0.5 - 0.388))),  # halfway between two rows
    (0.65, "ballast", 0.20, 2.6 - 3.7 * 0.2 - 11.6 * 0.04),  # no ballast row below 0.75: the normal one
])  # fmt: skip
def test_speed_reduction_coefficient_table_2(cb, loading, fn, expected):
    assert kwon_speed_coefficient(cb, fn, loading) == pytest.approx(expected, rel=1e-12)


def test_form_coefficient_table_3():
    vol = 30000.0
    v23 = vol ** (2.0 / 3.0)
    assert float(kwon_form_coefficient(7, vol, "container")) == pytest.approx(0.7 * 7 + 7**6.5 / (22.0 * v23))
    assert float(kwon_form_coefficient(7, vol, "loaded")) == pytest.approx(0.5 * 7 + 7**6.5 / (2.7 * v23))
    assert float(kwon_form_coefficient(7, vol, "ballast")) == pytest.approx(0.7 * 7 + 7**6.5 / (2.7 * v23))


def test_speed_loss_by_hand_container_feeder_head_wind_beaufort_8():
    hull = KwonHull(0.65, 160.0, 0.65 * 160.0 * 27.2 * 9.5, "container")
    fn = 17.0 * 1852.0 / 3600.0 / math.sqrt(9.80665 * 160.0)
    c_u = 2.6 - 3.7 * fn - 11.6 * fn**2
    c_form = 0.7 * 8 + 8**6.5 / (22.0 * hull.displacement_m3 ** (2.0 / 3.0))
    expected = 17.0 * 1.0 * c_u * c_form / 100.0  # [1]: dV/V1 = C_beta C_U C_Form %
    assert float(speed_loss_kwon(17.0, 18.0, 0.0, hull)) == pytest.approx(expected, rel=1e-12)
    # beam wind at BN 8: C_beta = (0.9 - 0.06 * 4) / 2
    assert float(speed_loss_kwon(17.0, 18.0, 90.0, hull)) == pytest.approx(expected * 0.33, rel=1e-12)
    assert float(speed_loss_kwon(17.0, 0.2, 0.0, hull)) == 0.0  # calm air: BN 0


def test_kwon_refuses_outside_its_table_naming_the_vessel():
    with pytest.raises(SpeedLossRangeError, match="ro-pax.*0.55-0.85.*Cb = 0.524"):
        ShipModel.from_vessel(load_vessel("ro-pax"), "kwon")
    with pytest.raises(SpeedLossRangeError, match=r"C_U is -?\d\.\d+ <= 0 for vessel fast.*Cb 0.8"):
        kwon_check(KwonHull(0.80, 100.0, 9000.0, "loaded"), 14.0, "fast")  # Fn 0.23: beyond the 0.80 row's fit
    v = load_vessel("simroute-r6")
    ship = ShipModel.from_vessel(v, "kwon")
    assert ship.kwon.form == "loaded" and ship.kwon.cb == pytest.approx(0.575)
    assert ship.kwon.displacement_m3 == pytest.approx(0.575 * 225.0 * 30.4 * 7.0)
    assert ShipModel.from_vessel(load_vessel("container-large"), "kwon").kwon.form == "container"
    import dataclasses

    with pytest.raises(SpeedLossRangeError, match="block coefficient of vessel simroute-r6"):
        ShipModel.from_vessel(dataclasses.replace(v, block_coefficient=None), "kwon")


def test_docstring_examples():
    result = doctest.testmod(kw)
    assert result.attempted > 0 and result.failed == 0


# ------------------------------------------------------------------ Aertssen's two conventions

HS = np.array([0.0, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 5.5, 6.0, 7.5, 8.0])


def test_aertssen_beaufort_at_every_band():
    # ours: the WMO probable maximum heights 1.5/2.5/4/5.5/7.5 m are the classes' upper edges
    assert aertssen_beaufort(HS, "wmo").tolist() == [4, 4, 4, 5, 5, 6, 6, 7, 7, 8, 8, 9]
    # SIMROUTE's code (ANCHORS.md): Hs < 2.5 / 2.5-4 / 4-5.5 / 5.5-7.5 / >= 7.5 m -> none, 5, 6, 7, 8
    assert aertssen_beaufort(HS, "simroute").tolist() == [4, 4, 4, 4, 5, 5, 6, 6, 7, 7, 8, 8]
    with pytest.raises(ValueError, match="unknown Aertssen"):
        aertssen_beaufort(HS, "other")


def test_aertssen_loss_of_each_convention_in_head_seas_r6_ship():
    # (m / 225 + n) * 16.1 / 100 with [1] Table A1.2's head-sea m, n of Beaufort 5..8
    head = {5: (900, 2), 6: (1300, 6), 7: (2100, 11), 8: (3600, 18)}
    loss = {b: (m / 225.0 + n) * 16.1 / 100.0 for b, (m, n) in head.items()}
    wmo = [0, 0, 0, loss[5], loss[5], loss[6], loss[6], loss[7], loss[7], loss[8], loss[8], loss[8]]
    sim = [0, 0, 0, 0, loss[5], loss[5], loss[6], loss[6], loss[7], loss[7], loss[8], loss[8]]
    with pytest.warns(UserWarning, match="beyond Beaufort 8"):
        np.testing.assert_allclose(speed_loss_aertssen(16.1, HS, 0.0, 225.0, "wmo"), wmo, rtol=1e-12)
    np.testing.assert_allclose(speed_loss_aertssen(16.1, HS, 0.0, 225.0, "simroute"), sim, rtol=1e-12)
    assert loss[5] == pytest.approx(0.9660) and loss[8] == pytest.approx(5.474)
