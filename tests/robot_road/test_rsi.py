"""KUKA RSI packets (robot_road.rsi): the robot's ``<Rob>`` packet read and the sensor's ``<Sen>``
answer written (round trips), the IPOC and joint refusals, and any bytes or text, a DTD or an entity bomb
among them, refused with PacketError and nothing else."""

from __future__ import annotations

import math
import time

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robot_road import rsi
from robot_road.kuka_rsi import KukaRsiSettings
from robot_road.packets import PacketError

S = KukaRsiSettings()
NAMED = KukaRsiSettings(command_element="Cmd", heartbeat_element="Beat", payload_element="Load")
deg = st.floats(-720, 720, allow_nan=False)
six = st.tuples(*[deg] * 6)
ipocs = st.integers(0, 2**63)


@given(ipoc=ipocs, setpoint=six, actual=six, delay=st.integers(0, 10**6),
       extra=st.fixed_dictionaries({"Cmd": st.integers(0, 2**16), "Beat": st.integers(0, 2**31),
                                    "Load": st.integers(-5, 5)}))
def test_robot_packet_parses_back(ipoc, setpoint, actual, delay, extra):
    data = rsi.robot_packet(ipoc, setpoint, actual, delay, extra)
    p = rsi.parse(data, NAMED)
    assert (p.stamp, p.late, p.command, p.heartbeat, p.payload) == (ipoc, delay, extra["Cmd"], extra["Beat"],
                                                                  extra["Load"])
    assert p.joints_deg == pytest.approx(setpoint, abs=6e-5)             # written with at least 4 decimals
    q = rsi.parse(data, KukaRsiSettings(joints="AIPos"))
    assert q.joints_deg == pytest.approx(actual, abs=6e-5)
    assert (q.command, q.heartbeat, q.payload) == (None, None, None)     # not named: not read


@given(ipoc=ipocs, values=six, cartesian=st.booleans(), sen_type=st.sampled_from(["ImFree", "Sensor_1"]))
def test_answer_reads_back(ipoc, values, cartesian, sen_type):
    data = rsi.answer(sen_type, ipoc, values, cartesian)
    got_ipoc, tag, got = rsi.read_answer(data)
    assert (got_ipoc, tag) == (ipoc, "RKorr" if cartesian else "AK")
    assert got == pytest.approx(values, abs=6e-7)
    assert f'Type="{sen_type}"'.encode() in data


def _packet(ipoc: str = "<IPOC>4208275</IPOC>", aspos: str = 'A1="1" A2="2" A3="3" A4="4" A5="5" A6="6"',
            more: str = "") -> bytes:
    return f'<Rob TYPE="KUKA"><ASPos {aspos} /><Delay D="0" />{more}{ipoc}</Rob>'.encode()


def _refused(data: bytes, reason: str, s: KukaRsiSettings = S) -> PacketError:
    with pytest.raises(PacketError) as e:
        rsi.parse(data, s)
    assert e.value.reason == reason
    return e.value


def test_the_helper_packet_is_good():
    assert rsi.parse(_packet(), S).joints_deg == (1.0, 2.0, 3.0, 4.0, 5.0, 6.0)


@pytest.mark.parametrize("ipoc", ["", "<IPOC></IPOC>", "<IPOC>-4</IPOC>", "<IPOC>abc</IPOC>",
                                  "<IPOC>4.5</IPOC>", "<IPOC><x/></IPOC>"])
def test_an_ipoc_that_is_not_a_whole_number_is_refused(ipoc):
    assert "IPOC" in str(_refused(_packet(ipoc=ipoc), "ipoc"))


@pytest.mark.parametrize("aspos", ['A1="1" A2="2" A3="nan" A4="4" A5="5" A6="6"',
                                   'A1="1" A2="2" A3="3" A4="inf" A5="5" A6="6"',
                                   'A1="1" A2="2" A3="3" A4="4" A5="5" A6="1e999"',
                                   'A1="1" A2="2" A3="three" A4="4" A5="5" A6="6"',
                                   'A1="1" A2="2" A3="3" A4="4" A5="5"', ""])
def test_joints_that_are_not_six_finite_numbers_are_refused(aspos):
    assert "ASPos" in str(_refused(_packet(aspos=aspos), "joints"))


def test_other_bad_packets_are_refused():
    assert "AIPos" in str(_refused(_packet(), "joints", KukaRsiSettings(joints="AIPos")))   # not sent
    _refused(_packet().replace(b"Rob", b"Sen"), "malformed")
    _refused(_packet().replace(b'D="0"', b'D="x"'), "malformed")
    assert "Cmd" in str(_refused(_packet(more="<Cmd>on</Cmd>"), "malformed", NAMED))
    _refused(_packet(more="<Pad>" + "0" * rsi.MAX_BYTES + "</Pad>"), "malformed")
    _refused(b"", "malformed")
    _refused(_packet()[:-3], "malformed")


BOMB = ('<?xml version="1.0"?><!DOCTYPE Rob [<!ENTITY a "aaaaaaaaaa">'
        + "".join(f'<!ENTITY {c} "{("&" + p + ";") * 10}">' for p, c in zip("abcdefgh", "bcdefghi"))
        + ']><Rob TYPE="KUKA"><ASPos A1="&i;" A2="0" A3="0" A4="0" A5="0" A6="0" /><IPOC>1</IPOC></Rob>').encode()


@pytest.mark.parametrize("doc", [
    BOMB,                                                                                    # 10**9 a's
    b'<!DOCTYPE Rob [<!ENTITY x SYSTEM "file:///etc/passwd">]><Rob><IPOC>&x;</IPOC></Rob>',   # external
    b'<!DOCTYPE Rob SYSTEM "http://192.0.2.1/rsi.dtd"><Rob><IPOC>1</IPOC></Rob>',            # a DTD to fetch
    b"<!DOCTYPE Rob><Rob><IPOC>1</IPOC></Rob>",                                              # any DTD at all
])
def test_a_document_type_declaration_is_refused_before_anything_is_expanded(doc):
    assert len(doc) < rsi.MAX_BYTES             # refused for its DTD, not for its length
    t0 = time.perf_counter()
    for f in (lambda: rsi.parse(doc, S), lambda: rsi.read_answer(doc)):
        with pytest.raises(PacketError) as e:
            f()
        assert e.value.reason == "malformed" and "DTDForbidden" in str(e.value)
    assert time.perf_counter() - t0 < 1.0       # expanding the bomb would take minutes and gigabytes


xml_bits = st.sampled_from(['<Rob TYPE="KUKA">', "</Rob>", "<Sen>", "</Sen>", "<ASPos ", "<AIPos ", "/>", ">",
                            'A1="1"', 'A2="nan"', "A3=", '"', "<IPOC>", "</IPOC>", "12", "-3", "<Delay D=", "&amp;",
                            "&x;", "<!DOCTYPE Rob>", "<![CDATA[", "]]>", "<?xml version='1.0'?>", "<AK ", "<RKorr ",
                            "\x00", "é", "\ud7ff", " ", "<!--", "-->"])
texts = st.text(max_size=300) | st.lists(xml_bits | st.text(max_size=4), max_size=40).map("".join)


@settings(max_examples=400, deadline=None)
@given(st.binary(max_size=5000) | texts.map(lambda t: t.encode("utf-8", "surrogatepass")))
def test_any_bytes_or_text_are_read_or_refused(data):
    """A packet, or a PacketError: nothing else escapes the reader, whatever the robot's port receives."""
    for f in (lambda: rsi.parse(data, NAMED), lambda: rsi.read_answer(data)):
        try:
            out = f()
        except PacketError as e:
            assert e.reason in ("malformed", "ipoc", "joints")
            continue
        if isinstance(out, tuple) and hasattr(out, "joints_deg"):
            assert len(out.joints_deg) == 6 and all(math.isfinite(v) for v in out.joints_deg)
