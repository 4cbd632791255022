// ads-client (v2, default PLC mode, not rawClient) against the running service: the checks of issue 20.
// The client is given only the target's AMS address and the service's TCP address; it registers an AMS
// port with the service as its router. The second client after the reconnect names its own address.
//
//   node check.js <host> <tcp port> <AMS Net ID>
//
// Prints one line per check (the transcript), then one line "RESULT <json>" with what was seen, which
// tests/plc_link/test_ads_node.py judges. Exits 1 when a step throws (its message on stderr).
"use strict";
const { Client } = require("ads-client");

const [host, port, netId] = process.argv.slice(2);
const TASK = "TwinCAT_SystemInfoVarList._TaskInfo[1]";
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
const say = (...a) => console.log(...a);

// The fewest settings: the client asks the service, as its AMS router, for its own AMS address.
function settings() {
  return {
    targetAmsNetId: netId,
    targetAdsPort: 851,
    routerAddress: host,
    routerTcpPort: Number(port),
    timeoutDelay: 10000,               // generous on a loaded machine; the service answers in about 1 ms
    autoReconnect: false,
  };
}

// The client names its own AMS address instead (no port connect), as with a PLC reached without a router.
const EXPLICIT = { localAmsNetId: "127.0.0.1.1.20", localAdsPort: 32750 };

async function waitFor(what, pred, timeoutMs = 20000) {
  const end = Date.now() + timeoutMs;
  while (!pred()) {
    if (Date.now() > end) throw new Error(`timed out waiting for ${what}`);
    await sleep(10);
  }
}

async function main() {
  const out = {};
  const client = new Client(settings());
  const stateNotified = [];      // set only by ads-client's own subscription of 0xF100 until readPlcRuntimeState
  client.on("plcRuntimeStateChange", (state) => stateNotified.push(state.adsStateStr));
  const conn = await client.connect();
  const md = client.metaData;
  out.connect = {
    connected: conn.connected, localAmsNetId: conn.localAmsNetId, localAdsPort: conn.localAdsPort, tcSystemState: md.tcSystemState, plcRuntimeState: md.plcRuntimeState,
    symbolVersion: md.plcSymbolVersion, uploadInfo: md.plcUploadInfo, deviceName: md.plcDeviceInfo.deviceName,
  };
  say(`connect: ${conn.targetAmsNetId}:${conn.targetAdsPort} as ${conn.localAmsNetId}:${conn.localAdsPort}; ` +
      `system ${md.tcSystemState.adsStateStr}, PLC ${md.plcRuntimeState.adsStateStr}, ` +
      `device "${md.plcDeviceInfo.deviceName}", symbol version ${md.plcSymbolVersion}, ` +
      `${md.plcUploadInfo.symbolCount} symbols, ${md.plcUploadInfo.dataTypeCount} data types`);

  // by name, twice, 1 s apart
  const read = async () => {
    const t = Date.now();
    const c = (await client.readValue(`${TASK}.CycleCount`)).value;
    const e = (await client.readValue(`${TASK}.ExceedCounter`)).value;
    return { t, c, e };
  };
  const a = await read();
  await sleep(1000);
  // deadlines the host held the cycle past are counted by the cycle after the first that runs again
  // (io_base.deadlines): read until two more cycles have run, so a stall under way at the read is counted
  let b = await read();
  const first = b.c, giveUp = Date.now() + 10000;
  while (b.c < first + 2 && Date.now() < giveUp) {
    await sleep(1);
    b = await read();
  }
  out.cycles = [a.c, b.c];
  out.exceed = [a.e, b.e];
  out.elapsed_s = (b.t - a.t) / 1000;
  say(`read by name: CycleCount ${a.c} -> ${b.c} in ${out.elapsed_s.toFixed(3)} s (+${b.c - a.c}), ` +
      `ExceedCounter ${a.e} -> ${b.e}`);

  // a PLC input by name, and back
  const q1 = 12.25 + (process.pid % 100);
  await client.writeValue("GVL_Comp.q1", q1);
  out.q1 = [q1, (await client.readValue("GVL_Comp.q1")).value];
  say(`write by name: GVL_Comp.q1 := ${q1}, read back ${out.q1[1]}`);

  // subscriptions by name: cyclic (10 ms) and on-change
  const cyclic = [];
  const subC = await client.subscribeValue(`${TASK}.CycleCount`, (d) => cyclic.push(d.value), 10, false);
  await waitFor("5 cyclic samples", () => cyclic.length >= 5);
  await subC.unsubscribe();
  out.cyclic = cyclic.slice(0, 5);
  const changes = [];
  const subO = await client.subscribeValue("GVL_Comp.plc_heartbeat", (d) => changes.push(d.value), 10, true);
  await waitFor("the current value", () => changes.length >= 1);
  const beat = (changes[0] + 1234) % 65536;
  await client.writeValue("GVL_Comp.plc_heartbeat", beat);
  await waitFor("the changed value", () => changes.includes(beat));
  await subO.unsubscribe();
  out.on_change = { first: changes[0], written: beat, seen: changes };
  say(`subscribe cyclic: ${out.cyclic.join(", ")}; on change: plc_heartbeat ${changes.join(" -> ")}`);

  // an unknown symbol: 0x710, and the connection still works
  try {
    await client.readValue("GVL_Comp.NoSuchSymbol");
    out.unknown = 0;
  } catch (err) {
    out.unknown = err.adsError ? err.adsError.errorCode : -1;
  }
  out.after_unknown = (await client.readValue(`${TASK}.CycleCount`)).value;
  say(`unknown symbol: ADS error ${out.unknown} (0x${out.unknown.toString(16)}); then CycleCount ${out.after_unknown}`);

  // the data types, a handle with the runtime's full answer, the states
  const types = await client.getDataTypes();
  out.types = Object.values(types).map((t) => ({ name: t.name, size: t.size, ads: t.adsDataType }));
  const h = await client.createVariableHandle("GVL_Comp.q1");
  out.handle = { size: h.size, type: h.dataType, value: (await client.readRawByHandle(h)).readFloatLE(0) };
  await client.deleteVariableHandle(h);
  out.state_notified = [...stateNotified];
  out.states = { system: (await client.readTcSystemState()).adsStateStr,
                 plc: (await client.readPlcRuntimeState()).adsStateStr,
                 symbol_version: await client.readPlcSymbolVersion() };
  say(`data types: ${out.types.map((t) => `${t.name}(${t.size})`).join(", ")}`);
  say(`handle: GVL_Comp.q1 size ${h.size} type ${h.dataType}, by handle ${out.handle.value}; ` +
      `states: system ${out.states.system}, PLC ${out.states.plc}, symbol version ${out.states.symbol_version}`);

  // reconnect: the same client (port close, then port connect), then a second one after it closed,
  // naming its own AMS address
  const re = await client.reconnect();
  out.reconnect = { localAmsNetId: re.localAmsNetId, localAdsPort: re.localAdsPort };
  out.after_reconnect = (await client.readValue(`${TASK}.CycleCount`)).value;
  await client.disconnect();
  const again = new Client({ ...settings(), ...EXPLICIT });
  const second = await again.connect();
  out.second = { localAmsNetId: second.localAmsNetId, localAdsPort: second.localAdsPort };
  out.second_client = (await again.readValue(`${TASK}.CycleCount`)).value;
  await again.disconnect();
  say(`reconnect: as ${re.localAmsNetId}:${re.localAdsPort}, CycleCount ${out.after_reconnect}; ` +
      `new client as ${second.localAmsNetId}:${second.localAdsPort} after disconnect: ${out.second_client}`);
  console.log(`RESULT ${JSON.stringify(out)}`);
}

main().catch((err) => {
  console.error(`FAILED: ${err.message}`, err.adsError || "", err.trace || "");
  process.exit(1);
});
