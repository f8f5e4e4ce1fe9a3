// The official Foxglove WebSocket client (@foxglove/ws-protocol) against `simbot foxglove`, as
// Lichtblick and other ws-protocol apps connect: subprotocol foxglove.websocket.v1 only.
//
//   node foxglove_client.mjs URL TOPIC TIMEOUT_S
//
// Waits for TOPIC to be advertised, subscribes, decodes its first message with the channel's own
// ros2msg schema (@foxglove/rosmsg + @foxglove/rosmsg2-serialization, what the apps use), and prints
// one JSON line: the negotiated subprotocol, every advertised topic, the decoded scan's fields and
// the raw payload (base64) so that the test can check both against the bus. Exit 1 on a timeout.
import wsProtocol from "@foxglove/ws-protocol"; // CommonJS: its exports come as one default
import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";
import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol;

const [url, topic, timeoutS] = process.argv.slice(2);
const ws = new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
const client = new FoxgloveClient({ ws });
const channels = new Map();
const readers = new Map();

setTimeout(() => {
  console.error(`no message on ${topic} within ${timeoutS} s; advertised: ${[...channels.keys()].join(" ")}`);
  process.exit(1);
}, Number(timeoutS) * 1000);

client.on("error", (error) => console.error(`client error: ${error.message}`));
client.on("advertise", (advertised) => {
  for (const channel of advertised) {
    channels.set(channel.topic, channel);
    if (channel.topic === topic) {
      const reader = new MessageReader(parse(channel.schema, { ros2: true }));
      readers.set(client.subscribe(channel.id), reader);
    }
  }
});
client.on("message", ({ subscriptionId, data }) => {
  const scan = readers.get(subscriptionId).readMessage(data);
  const payload = Buffer.from(data.buffer, data.byteOffset, data.byteLength).toString("base64");
  console.log(JSON.stringify({
    subprotocol: ws.protocol,
    topics: [...channels.keys()].sort(),
    schemaName: channels.get(topic).schemaName,
    frame_id: scan.header.frame_id,
    stamp: [scan.header.stamp.sec, scan.header.stamp.nanosec],
    angle_min: scan.angle_min,
    angle_max: scan.angle_max,
    range_max: scan.range_max,
    ranges: Array.from(scan.ranges, (r) => (Number.isFinite(r) ? r : String(r))), // JSON has no Infinity
    payload,
  }));
  client.close();
  process.exit(0);
});
