"""The ATI CAN protocol: the struct decoder agrees with the DBC, and bad frames are refused."""

from __future__ import annotations

import cantools
import numpy as np
import pytest

from service.ati import AtiProtocol
from service.config import DEFAULT_CONFIG
from service.errors import CanFrameError

DBC = DEFAULT_CONFIG.parent / "ati_netft_can.dbc"


def test_struct_decoder_agrees_with_dbc():
    db = cantools.database.load_file(str(DBC))
    p = AtiProtocol(base_id=0x020, counts_per_force=10, counts_per_torque=100)
    rng = np.random.default_rng(3)
    for k in range(50):
        w = rng.uniform(-3000, 3000, 6) * np.array([1, 1, 1, 0.1, 0.1, 0.1])
        (id1, d1), (id2, d2) = p.encode(w, status=0, counter=k)
        m1, m2 = db.decode_message(id1, d1), db.decode_message(id2, d2)
        assert p.decode(id1, d1) is None
        r = p.decode(id2, d2)
        dbc = [m1["Fx"], m1["Fy"], m2["Fz"], m1["Tx"], m1["Ty"], m2["Tz"]]
        np.testing.assert_allclose(r.wrench, dbc, atol=1e-9)
        np.testing.assert_allclose(r.wrench, w, atol=0.05 + 0.005)    # one count of resolution
        assert r.counter == m2["sample_counter"] == k


def test_request_frames_match_dbc():
    db = cantools.database.load_file(str(DBC))
    p = AtiProtocol(base_id=0x020)
    arb, data = p.request_short_data()
    assert db.decode_message(arb, data)["opcode"] == "short_data"
    arb, data = p.request_bias()
    assert db.decode_message(arb, data)["opcode"] == "bias"


def test_other_base_id_moves_every_frame():
    p = AtiProtocol(base_id=0x100)
    (id1, d1), (id2, d2) = p.encode([1, 2, 3, 0.1, 0.2, 0.3])
    assert (id1, id2) == (0x105, 0x106)
    assert p.decode(id1, d1) is None and p.decode(id2, d2) is not None


@pytest.mark.parametrize("arb, data, match", [
    (0x025, b"\x00" * 7, "7 data bytes"),
    (0x026, b"\x00" * 9, "9 data bytes"),
    (0x023, b"\x00" * 8, "not defined by the ATI"),
    (0x300, b"\x00" * 8, "foreign"),
])
def test_bad_frames_raise(arb, data, match):
    with pytest.raises(CanFrameError, match=match):
        AtiProtocol(base_id=0x020).decode(arb, data)


def test_foreign_frames_can_be_ignored():
    assert AtiProtocol(base_id=0x020, foreign_frames="ignore").decode(0x300, b"\x00" * 8) is None


def test_saturation_is_flagged():
    p = AtiProtocol(counts_per_force=10)
    (id1, d1), (id2, d2) = p.encode([1e6, 0, 0, 0, 0, 0])      # clipped to INT16
    p.decode(id1, d1)
    assert p.decode(id2, d2).saturated


def test_second_half_without_first_is_dropped():
    p = AtiProtocol()
    (_, _), (id2, d2) = p.encode([1, 2, 3, 0, 0, 0])
    assert p.decode(id2, d2) is None
