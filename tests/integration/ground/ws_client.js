// A Foxglove WebSocket client (@foxglove/ws-protocol's FoxgloveClient over the `ws` package) against
// a running `odonav-ground serve`, decoding CDR with @foxglove/rosmsg2-serialization as Foxglove
// does. Prints one JSON line per event on stdout, for the test to read as it goes:
//   {"event":"subprotocols", ...}  both names accepted (serverInfo each), an unknown one refused
//   {"event":"channels", "topics"}  the advertised topics once the vehicle's are all there
//   {"event":"reconnect", "topics"} the same after disconnecting and connecting again
//   {"event":"samples", ...}        decoded NavSatFix, ScaleFactor, DiagnosticArray, K plot
//   {"event":"slow", ...}           while a second client that never reads is subscribed to all
//   {"event":"diagnostics", ...}    every DiagnosticArray from then on, with its arrival (ms)
// Usage: node ws_client.js PORT VEHICLE SAMPLE_SECONDS. NODE_PATH: the test's npm folder.
"use strict";
const WebSocket = require("ws");
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const { parse } = require("@foxglove/rosmsg");
const { MessageReader } = require("@foxglove/rosmsg2-serialization");

const [port, vehicle, sampleSeconds] = process.argv.slice(2);
const url = `ws://127.0.0.1:${port}`;
const out = (o) => process.stdout.write(JSON.stringify(o, (k, v) => (typeof v === "bigint" ? v.toString() : v)) + "\n");
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
const nowMs = () => performance.timeOrigin + performance.now();
const expected = ["odometer", "ins/attitude", "gnss/fix", "misalignment", "scale_factor", "dead_reckoning",
                  "navigation_position", "health",
                  "navsat/navigation", "navsat/dead_reckoning", "navsat/gnss", "diagnostics", "k"]
  .map((t) => `/odonav/${vehicle}/${t}`);

function connect(subprotocol) {
  return new Promise((resolve, reject) => {
    const ws = new WebSocket(url, [subprotocol]);
    const client = new FoxgloveClient({ ws });
    const state = { ws, client, channels: new Map(), serverInfo: null, protocol: null, errors: [] };
    client.on("serverInfo", (info) => { state.serverInfo = info; state.protocol = ws.protocol; resolve(state); });
    client.on("advertise", (chs) => { for (const c of chs) state.channels.set(c.id, c); });
    client.on("unadvertise", (ids) => { for (const id of ids) state.channels.delete(id); });
    client.on("status", (s) => state.errors.push(s));
    client.on("error", (e) => reject(e));
    setTimeout(() => reject(new Error(`no serverInfo from ${url} (${subprotocol}) within 10 s`)), 10000);
  });
}
function refused(subprotocol) {
  return new Promise((resolve) => {
    const ws = new WebSocket(url, [subprotocol]);
    ws.on("open", () => { ws.close(); resolve({ refused: false }); });
    ws.on("unexpected-response", (req, res) => resolve({ refused: true, status: res.statusCode }));
    ws.on("error", (e) => resolve({ refused: true, error: String(e) }));
  });
}
async function waitForTopics(state, topics, ms) {
  const until = Date.now() + ms;
  const have = () => new Set([...state.channels.values()].map((c) => c.topic));
  while (Date.now() < until && !topics.every((t) => have().has(t))) await sleep(100);
  return [...have()].sort();
}
const readers = new Map();
function decode(channel, data) {
  if (channel.encoding === "json") return JSON.parse(new TextDecoder().decode(data));
  if (!readers.has(channel.id)) readers.set(channel.id, new MessageReader(parse(channel.schema, { ros2: true })));
  return readers.get(channel.id).readMessage(data);
}
const stampS = (h) => h.stamp.sec + 1e-9 * h.stamp.nanosec;

async function main() {
  // 1. Both subprotocol names; an unknown one is refused.
  const a = await connect("foxglove.websocket.v1");
  const b = await connect("foxglove.sdk.v1");
  out({ event: "subprotocols", v1: { protocol: a.protocol, name: a.serverInfo.name },
        sdk: { protocol: b.protocol, name: b.serverInfo.name }, unknown: await refused("chat.v2") });
  b.client.close();

  // 2. The vehicle's channels, and 3. again after a reconnect.
  out({ event: "channels", topics: await waitForTopics(a, expected, 60000),
        channels: [...a.channels.values()].filter((c) => c.topic.startsWith(`/odonav/${vehicle}/`))
          .map((c) => ({ topic: c.topic, encoding: c.encoding, schemaName: c.schemaName, schemaEncoding: c.schemaEncoding })) });
  a.client.close();
  await sleep(300);
  const main = await connect("foxglove.websocket.v1");
  out({ event: "reconnect", topics: await waitForTopics(main, expected, 10000) });

  // 4. Subscribe and decode.
  const byTopic = new Map([...main.channels.values()].map((c) => [c.topic, c]));
  const subs = new Map();
  for (const t of ["navsat/navigation", "navsat/dead_reckoning", "navsat/gnss", "scale_factor", "diagnostics", "k",
                   "dead_reckoning"]) {
    const c = byTopic.get(`/odonav/${vehicle}/${t}`);
    subs.set(main.client.subscribe(c.id), { name: t, channel: c });
  }
  const got = { "navsat/navigation": [], "navsat/dead_reckoning": [], "navsat/gnss": [], scale_factor: [], k: [],
                diagnostics: [], dead_reckoning: [] };
  let phase = "samples";
  let slowWindow = [];
  main.client.on("message", ({ subscriptionId, timestamp, data }) => {
    const s = subs.get(subscriptionId);
    const m = decode(s.channel, data);
    if (s.name.startsWith("navsat/")) {
      got[s.name].push({ stamp: stampS(m.header), lat: m.latitude, lon: m.longitude, alt: m.altitude,
                         status: m.status.status, frame_id: m.header.frame_id });
    } else if (s.name === "scale_factor") {
      got.scale_factor.push({ stamp: stampS(m.header), k: m.k_m_per_pulse, sigma: m.sigma_m_per_pulse });
    } else if (s.name === "k") {
      got.k.push(m);
    } else if (s.name === "dead_reckoning") {
      if (phase === "slow") slowWindow.push(stampS(m.header));
      got.dead_reckoning.push(stampS(m.header));
    } else if (s.name === "diagnostics") {
      const d = { recv_ms: nowMs(), stamp: stampS(m.header),
                  status: m.status.map((x) => ({ name: x.name, level: x.level, message: x.message, hardware_id: x.hardware_id })) };
      if (phase === "watch") out({ event: "diagnostics", ...d });
      else got.diagnostics.push(d);
    }
  });
  await sleep(Number(sampleSeconds) * 1000);
  out({ event: "samples", frame_timestamps_ns: true, ...got, dead_reckoning: got.dead_reckoning.length,
        diagnostics: got.diagnostics.slice(-3), errors: main.errors });

  // 5. A client that subscribes to everything (each channel four times) and never reads a byte: it
  // stops reading at once, so the kernel's buffers stay small and the server's queue for it fills.
  const slowWs = new WebSocket(url, ["foxglove.websocket.v1"]);
  await new Promise((resolve, reject) => { slowWs.on("open", resolve); slowWs.on("error", reject); });
  slowWs._socket.pause();
  const subscriptions = [];
  for (const c of main.channels.values()) for (let k = 0; k < 4; k++) subscriptions.push({ id: subscriptions.length, channelId: c.id });
  slowWs.send(JSON.stringify({ op: "subscribe", subscriptions }));
  phase = "slow";
  await sleep(10000);
  const fleet = await (await fetch(`http://127.0.0.1:${port}/api/fleet`)).json();
  out({ event: "slow", dr_stamps: slowWindow, server: fleet.server });
  slowWs.terminate();

  // 6. Every DiagnosticArray from now on, until the test stops us.
  phase = "watch";
  out({ event: "watching" });
}
main().catch((e) => { out({ event: "error", error: String(e && e.stack || e) }); process.exit(1); });
