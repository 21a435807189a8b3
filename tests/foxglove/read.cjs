// Foxglove's ROS 2 decoding stack: @mcap/core reads the file, @foxglove/rosmsg parses the
// ros2msg schema, @foxglove/rosmsg2-serialization decodes the CDR. Prints one JSON line per
// message of the topic: {log_time, message}.
const fs = require("fs");
const fzstd = require("fzstd");
const { McapIndexedReader } = require("@mcap/core");
const { parse } = require("@foxglove/rosmsg");
const { MessageReader } = require("@foxglove/rosmsg2-serialization");

async function main() {
  const [file, topic] = process.argv.slice(2);
  const data = fs.readFileSync(file);
  const readable = {
    size: async () => BigInt(data.length),
    read: async (offset, length) => data.subarray(Number(offset), Number(offset + length)),
  };
  const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers: {
    zstd: (buf, size) => fzstd.decompress(buf, new Uint8Array(Number(size))) } });
  const readers = new Map();
  for await (const m of reader.readMessages({ topics: [topic] })) {
    const ch = reader.channelsById.get(m.channelId);
    if (!readers.has(ch.id)) {
      const schema = reader.schemasById.get(ch.schemaId);
      const defs = parse(new TextDecoder().decode(schema.data), { ros2: true });
      readers.set(ch.id, new MessageReader(defs));
    }
    const msg = readers.get(ch.id).readMessage(m.data);
    process.stdout.write(JSON.stringify({ log_time: m.logTime.toString(), message: msg },
      (k, v) => (typeof v === "bigint" ? v.toString() : v)) + "\n");
  }
}
main().catch((e) => { console.error(String(e)); process.exit(1); });
