// Reads an MCAP file with the npm packages Foxglove uses (@mcap/core, @foxglove/rosmsg,
// @foxglove/rosmsg2-serialization) and prints what it holds as one JSON document:
//   {"mode", "complete", "bytes_left", "statistics", "schemas": [...], "channels": [...],
//    "messages": [{"topic", "sequence", "log_time_ns", "data": <decoded CDR>}]}
// Usage: node read_mcap.js FILE indexed|stream
//   indexed: McapIndexedReader (footer, summary, statistics: what tools do to open a file fast);
//   stream:  McapStreamReader over the bytes as they are (recovers a file cut by a crash up to its
//            last complete record; "complete" says whether the end magic was reached).
// Node resolves the packages from NODE_PATH (the test's npm folder).
"use strict";
const fs = require("fs");
const { McapIndexedReader, McapStreamReader } = require("@mcap/core");
const { parse } = require("@foxglove/rosmsg");
const { MessageReader } = require("@foxglove/rosmsg2-serialization");

const [file, mode] = process.argv.slice(2);
const bytes = new Uint8Array(fs.readFileSync(file));
const toJson = (v) => JSON.stringify(v, (k, x) => (typeof x === "bigint" ? x.toString() : x));
const readers = new Map(); // schema id -> MessageReader
const schemas = new Map();
const channels = new Map();
const messages = [];

function readerFor(channel) {
  const schema = schemas.get(channel.schemaId);
  if (!readers.has(schema.id)) {
    const text = new TextDecoder().decode(schema.data);
    readers.set(schema.id, new MessageReader(parse(text, { ros2: true })));
  }
  return readers.get(schema.id);
}
function addMessage(m) {
  const channel = channels.get(m.channelId);
  messages.push({
    topic: channel.topic,
    sequence: m.sequence,
    log_time_ns: m.logTime,
    data: readerFor(channel).readMessage(m.data),
  });
}
function describe(extra) {
  return toJson({
    mode,
    ...extra,
    schemas: [...schemas.values()].map((s) => ({ id: s.id, name: s.name, encoding: s.encoding,
                                                 data: new TextDecoder().decode(s.data) })),
    channels: [...channels.values()].map((c) => ({ id: c.id, topic: c.topic, schema_id: c.schemaId,
                                                   message_encoding: c.messageEncoding,
                                                   metadata: Object.fromEntries(c.metadata) })),
    messages,
  });
}

async function indexed() {
  const readable = {
    size: async () => BigInt(bytes.byteLength),
    read: async (offset, length) => bytes.subarray(Number(offset), Number(offset + length)),
  };
  const reader = await McapIndexedReader.Initialize({ readable });
  for (const [id, s] of reader.schemasById) schemas.set(id, s);
  for (const [id, c] of reader.channelsById) channels.set(id, c);
  // An unchunked file has no chunk indexes, so readMessages() finds nothing through the index:
  // the data section is read as a stream, as tools do for unindexed messages.
  const stream = new McapStreamReader({ validateCrcs: true });
  stream.append(bytes);
  for (let r; (r = stream.nextRecord()); ) if (r.type === "Message") addMessage(r);
  const st = reader.statistics;
  return describe({
    complete: stream.done(),
    bytes_left: stream.bytesRemaining(),
    statistics: st && { message_count: st.messageCount, channel_count: st.channelCount,
                        schema_count: st.schemaCount,
                        channel_message_counts: Object.fromEntries(st.channelMessageCounts) },
    footer: { summary_start: reader.footer.summaryStart, summary_crc: reader.footer.summaryCrc },
  });
}

function stream() {
  const s = new McapStreamReader({ validateCrcs: true });
  s.append(bytes);
  for (let r; (r = s.nextRecord()); ) {
    if (r.type === "Schema") schemas.set(r.id, r);
    else if (r.type === "Channel") channels.set(r.id, r);
    else if (r.type === "Message") addMessage(r);
  }
  return describe({ complete: s.done(), bytes_left: s.bytesRemaining() });
}

(async () => {
  try {
    process.stdout.write((mode === "indexed" ? await indexed() : stream()) + "\n");
  } catch (e) {
    process.stderr.write(`read_mcap.js: ${file}: ${e.stack || e}\n`);
    process.exit(1);
  }
})();
