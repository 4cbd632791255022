"""The payload table against the running service (one service, its I/O process, a CAN sensor carrying a
spindle): the PLC selects the spindle's set over Modbus and the correction ramps to the weight-free
value without a step beyond the limiter's rate; selecting a set that does not exist over ADS latches
``payload_invalid``, keeps the spindle's set and logs one line; a reset with a valid index clears it."""

from __future__ import annotations

import logging

import can
import numpy as np
import pyads
import pytest
from pymodbus.client import ModbusTcpClient

from hil.payload import TruePayload
from hil.testing import free_port, write_config
from hil.virtual_sensor import VirtualAtiSensor
from plc_link.contract import Command, Fault
from service.app import Service
from service.ati import AtiProtocol
from service.compensation import FastPredictor
from service.config import load_config
from service.gravity import GravityConfig
from testlib.common import wait_for
from tools.pyads_connection import open_ads

pytestmark = pytest.mark.realtime

SPINDLE = {"index": 1, "name": "spindle + D20 mill", "mass_kg": 28.0, "cog_mm": [5.0, -3.0, 130.0],
           "bias": [2.0, -1.0, 4.0, 0.1, -0.05, 0.02]}
RAMP_S, RATE = 0.3, 5.0



def test_the_plc_switches_payload_sets_bumplessly_and_a_missing_set_is_refused(tmp_path, caplog):
    port = free_port()
    cfg = load_config(write_config(tmp_path, {
        "source": {"type": "can", "can": {"interface": "virtual", "channel": "svc_payload"}},
        "plc": {"port": port, "enable_on_start": True},
        "gravity": {"tool": {"mass_kg": 0.0}, "bias": [0.0] * 6, "payloads": [SPINDLE], "switch_ramp_s": RAMP_S},
        "limits": {"max_rate_deg_s": RATE},
        "faults": {"overrun_trip_count": 1000, "sensor_timeout_ms": 200, "plc_heartbeat_timeout_ms": 0}}))
    s = Service(cfg)
    fp = FastPredictor(s.model)
    fp.kinematics(np.radians(cfg.plc.initial_q_deg))
    truth = TruePayload(GravityConfig(tool={"mass_kg": SPINDLE["mass_kg"], "cog_mm": SPINDLE["cog_mm"]},
                                      bias=SPINDLE["bias"]))
    load = truth.wrench(np.array(fp.R_s)) + truth.bias              # the sensor carries the spindle
    record, work = [], s.work

    def recording_work(t, exceeded):
        go_on = work(t, exceeded)
        r = s.record
        record.append((t, [getattr(r, f"correction_q{i}") for i in range(1, 7)], r.wrench_fx, r.wrench_fy,
                       r.wrench_fz, int(r.payload_active), int(r.fault_word), [getattr(r, f"dq_q{i}") for i in range(1, 7)]))
        return go_on

    s.work = recording_work
    mb = ModbusTcpClient("127.0.0.1", port=port)
    ads = None
    with VirtualAtiSensor(can.Bus(interface="virtual", channel="svc_payload"), AtiProtocol(), lambda t: load), \
            caplog.at_level(logging.INFO):
        s.start()
        try:
            cyc = s.cycle
            # set 0 compensates nothing: the spindle's weight is a load, and the correction settles on it
            assert wait_for(lambda: cyc.status_word & 0x2 and abs(cyc.correction[1]) > 1e-5
                            and np.allclose(cyc.correction, cyc.dq_deg, atol=1e-7))
            before = np.array(cyc.dq_deg)
            assert mb.connect() and not mb.write_register(0x800E, 1).isError()
            n0 = len(record)
            assert wait_for(lambda: record[-1][5] == 1 and np.allclose(cyc.correction, cyc.dq_deg, atol=1e-9))
            n1 = len(record)
            after = np.array(cyc.dq_deg)
            # over ADS, as a TwinCAT PLC selects: an index with no set
            ads, why = open_ads(tcp_port=cfg.ads.port)
            assert ads is not None, why
            ads.write_by_name("GVL_Comp.payload_index", 7, pyads.PLCTYPE_UINT)
            assert wait_for(lambda: record[-1][6] & Fault.PAYLOAD_INVALID and not any(cyc.correction))
            n2 = len(record)
            assert wait_for(lambda: len(record) > n2 + 100)                  # many cycles with the bad index
            assert {r[5] for r in record[n2 - 1:]} == {1}                    # the spindle's set stays
            ads.write_by_name("GVL_Comp.payload_index", 1, pyads.PLCTYPE_UINT)
            assert not mb.write_register(0x8000, int(Command.RESET)).isError()
            assert wait_for(lambda: record[-1][6] == 0 and cyc.status_word & 0x2)
        finally:
            mb.close()
            if ads is not None:
                ads.close()
            s.stop()
    t = np.array([r[0] for r in record[n0 - 1:n1]])
    corr = np.array([r[1] for r in record[n0 - 1:n1]])
    force = np.array([r[2:5] for r in record[n0 - 1:n1]])
    assert np.linalg.norm(force[0]) > 100.0 and np.linalg.norm(force[-1]) < 1.0   # the weight is removed
    change = np.abs(before - after)
    assert change.max() > 2 * RATE * 1e-3               # a jump of it would exceed one cycle's rate limit
    steps = np.abs(np.diff(corr, axis=0)).max(axis=1)
    assert np.all(steps <= RATE * np.minimum(np.diff(t), 2e-3) + 1e-12)
    dq = np.array([r[7] for r in record[n0 - 1:n1]])    # before limits: the ramp's share per cycle
    assert np.all(np.abs(np.diff(dq, axis=0)) <= change * np.diff(t)[:, None] / RAMP_S * 1.05 + 1e-9)
    assert t[-1] - t[0] >= RAMP_S * 0.95                                         # payload_active waits for the ramp
    refusals = [r for r in caplog.records if "payload_index = 7" in r.getMessage()]
    assert len(refusals) == 1 and "set 1 'spindle + D20 mill' (28 kg) stays in use" in refusals[0].getMessage()
    switches = [r.getMessage() for r in caplog.records if "payload switch" in r.getMessage()]
    assert switches == [("payload switch (payload_index): 0 'gravity bodies' (0 kg) -> 1 'spindle + D20 mill' "
                        "(28 kg) over gravity.switch_ramp_s = 0.3 s")]
