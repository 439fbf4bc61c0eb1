// Read an MCAP file the way Foxglove does (@mcap/core's indexed reader, @mcap/support's
// decompressors, @foxglove/rosmsg's ROS 2 .msg parser, @foxglove/rosmsg2-serialization's CDR
// reader) and print per channel: topic, schema, encodings, metadata, messages decoded and the
// first message. Exit 1 when a channel's schema or a message cannot be decoded.
//   cd tools/foxglove-check && npm install && node verify.mjs ../../runs/first/run.mcap
import { McapIndexedReader } from "@mcap/core";
import { FileHandleReadable } from "@mcap/nodejs";
import { loadDecompressHandlers } from "@mcap/support";
import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";
import { open } from "node:fs/promises";

const handle = await open(process.argv[2], "r");
const reader = await McapIndexedReader.Initialize({
  readable: new FileHandleReadable(handle),
  decompressHandlers: await loadDecompressHandlers(),
});
const readers = new Map();
const out = {};
for (const [id, ch] of reader.channelsById) {
  const schema = reader.schemasById.get(ch.schemaId);
  out[ch.topic] = { schema: schema?.name, schemaEncoding: schema?.encoding,
                    messageEncoding: ch.messageEncoding, metadata: Object.fromEntries(ch.metadata),
                    count: 0, sample: null };
  if (schema?.encoding === "ros2msg") {
    const defs = parse(new TextDecoder().decode(schema.data), { ros2: true });
    readers.set(id, new MessageReader(defs));
  }
}
let failures = 0;
for await (const msg of reader.readMessages()) {
  const ch = reader.channelsById.get(msg.channelId);
  const entry = out[ch.topic];
  let decoded;
  try {
    if (readers.has(msg.channelId)) decoded = readers.get(msg.channelId).readMessage(msg.data);
    else if (ch.messageEncoding === "json") decoded = JSON.parse(new TextDecoder().decode(msg.data));
    else throw new Error(`no decoder for ${ch.messageEncoding}`);
  } catch (error) {
    failures += 1;
    if (failures <= 5) console.error(`${ch.topic}: message ${entry.count + 1}: ${error.message}`);
  }
  entry.count += 1;
  if (entry.sample === null && decoded !== undefined) {
    const s = { ...decoded };
    if (s.data && s.data.length !== undefined) s.data = `<${s.data.length} bytes, starts ${Array.from(s.data.slice(0, 4)).map((b) => b.toString(16)).join(" ")}>`;
    entry.sample = s;
  }
}
console.log(JSON.stringify({ file: process.argv[2], profile: reader.header.profile, library: reader.header.library, channels: out }, (k, v) => typeof v === "bigint" ? v.toString() : v, 2));
await handle.close();
if (failures > 0) {
  console.error(`${failures} messages could not be decoded`);
  process.exit(1);
}
