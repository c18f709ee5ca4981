// The Foxglove client of the fleet-scale benchmark (bench/fleet_bench.sh): subscribes to EVERY channel
// of `odonav-ground serve` (as it is advertised), and measures, for the dead-reckoning channels, the
// delay from the DDS sample (its stamp: the synthetic publisher's UNIX time of writing) to the
// arrival of its WebSocket frame here, on the same host and clock. It also notes when fleet-000's
// identification first shows STALE in its DiagnosticArray. Prints one JSON summary at the end.
// Usage: node fleet_client.js PORT SECONDS WARMUP_SECONDS. NODE_PATH: the npm folder.
"use strict";
const WebSocket = require("ws");
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const { parse } = require("@foxglove/rosmsg");
const { MessageReader } = require("@foxglove/rosmsg2-serialization");

const [port, seconds, warmup] = process.argv.slice(2).map(Number);
const ws = new WebSocket(`ws://127.0.0.1:${port}`, ["foxglove.websocket.v1"]);
const client = new FoxgloveClient({ ws });
const nowMs = () => performance.timeOrigin + performance.now();
const start = nowMs();
const channels = new Map(), subs = new Map(), readers = new Map();
const delays = [];
let frames = 0, bytes = 0, staleAtMs = null;
client.on("advertise", (list) => {
  for (const c of list) {
    if (channels.has(c.id)) continue;
    channels.set(c.id, c);
    subs.set(client.subscribe(c.id), c);
  }
});
client.on("message", ({ subscriptionId, timestamp, data }) => {
  const c = subs.get(subscriptionId);
  if (!c) return;
  frames++;
  bytes += data.byteLength;
  const t = nowMs();
  if (t - start < warmup * 1000) return;
  if (c.topic.endsWith("/dead_reckoning") && !c.topic.includes("navsat")) {
    delays.push(t - Number(timestamp / 1000n) / 1000);
  } else if (c.topic === "/odonav/fleet-000/diagnostics" && staleAtMs === null) {
    if (!readers.has(c.id)) readers.set(c.id, new MessageReader(parse(c.schema, { ros2: true })));
    const m = readers.get(c.id).readMessage(data);
    for (const s of m.status) if (s.name === "fleet-000/odonav-identification" && s.level === 3) staleAtMs = t;
  }
});
setTimeout(() => {
  delays.sort((a, b) => a - b);
  const q = (p) => (delays.length ? delays[Math.min(delays.length - 1, Math.floor(p * delays.length))] : null);
  process.stdout.write(JSON.stringify({ channels: channels.size, frames, bytes, dr_frames: delays.length,
    delay_ms: { p50: q(0.5), p90: q(0.9), p99: q(0.99), max: delays.length ? delays[delays.length - 1] : null },
    stale_at_unix_s: staleAtMs === null ? null : staleAtMs / 1000 }) + "\n");
  ws.terminate();
  process.exit(0);
}, seconds * 1000);
