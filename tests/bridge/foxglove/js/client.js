// A Foxglove WebSocket protocol client for tests/bridge/foxglove (run by node 20).
// It offers ONLY the subprotocol "foxglove.websocket.v1" (FoxgloveClient.SUPPORTED_SUBPROTOCOL,
// what Lichtblick and @foxglove/ws-protocol clients offer), subscribes to the topics named in
// FG_TOPICS, decodes each first message with its advertised ros2msg schema
// (@foxglove/rosmsg + @foxglove/rosmsg2-serialization, what Foxglove uses), then publishes
// FG_GOAL (JSON of a geometry_msgs/msg/PoseStamped) on /move_base_simple/goal as CDR.
// Output: one JSON object per line on stdout.
"use strict";
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const { parse } = require("@foxglove/rosmsg");
const { MessageReader, MessageWriter } = require("@foxglove/rosmsg2-serialization");
const WebSocket = require("ws");

const url = process.argv[2];
const topics = (process.env.FG_TOPICS || "/camera/image_raw,/map").split(",");
const goal = process.env.FG_GOAL ? JSON.parse(process.env.FG_GOAL) : null;
const goalSchema = process.env.FG_GOAL_SCHEMA || "";
const goalTopic = process.env.FG_GOAL_TOPIC || "/move_base_simple/goal";
const out = (obj) => process.stdout.write(JSON.stringify(obj) + "\n");

const ws = new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
const client = new FoxgloveClient({ ws });
const readers = new Map(); // subscription id -> {topic, reader}
const decoded = new Set();
let published = false;

function summary(topic, msg) {
  if (msg.info !== undefined && msg.data !== undefined) {
    let occupied = 0;
    for (const v of msg.data) if (v > 50) occupied++;
    return { topic, kind: "OccupancyGrid", frame_id: msg.header.frame_id, width: msg.info.width,
      height: msg.info.height, resolution: msg.info.resolution, cells: msg.data.length, occupied };
  }
  if (msg.encoding !== undefined && msg.step !== undefined) {
    let sum = 0;
    for (const v of msg.data) sum += v;
    return { topic, kind: "Image", frame_id: msg.header.frame_id, width: msg.width,
      height: msg.height, encoding: msg.encoding, bytes: msg.data.length, sum,
      stamp: msg.header.stamp };
  }
  return { topic, kind: "other", keys: Object.keys(msg) };
}

function publishGoal() {
  if (published || goal === null) return;
  published = true;
  const channel = client.advertise({ topic: goalTopic, encoding: "cdr",
    schemaName: "geometry_msgs/msg/PoseStamped", schema: goalSchema, schemaEncoding: "ros2msg" });
  const writer = new MessageWriter(parse(goalSchema, { ros2: true }));
  const data = writer.writeMessage(goal);
  // a Foxglove user clicks once; send a few times a second as a held "Publish" would
  let n = 0;
  const timer = setInterval(() => {
    client.sendMessage(channel, data);
    n++;
    out({ published: goalTopic, count: n, bytes: data.length });
    if (n >= Number(process.env.FG_GOAL_REPEAT || 1)) {
      clearInterval(timer);
      setTimeout(() => { out({ done: true }); process.exit(0); }, 300);
    }
  }, 300);
}

client.on("open", () => out({ open: true, protocol: ws.protocol }));
client.on("serverInfo", (info) => out({ serverInfo: info.name, capabilities: info.capabilities }));
client.on("status", (s) => out({ status: s.level, message: s.message }));
client.on("error", (e) => out({ error: String(e) }));
client.on("close", (e) => { out({ closed: true, code: e.code }); process.exit(0); });
client.on("advertise", (channels) => {
  for (const ch of channels) {
    if (!topics.includes(ch.topic)) continue;
    const reader = new MessageReader(parse(ch.schema, { ros2: true }));
    const id = client.subscribe(ch.id);
    readers.set(id, { topic: ch.topic, reader });
    out({ subscribed: ch.topic, schemaName: ch.schemaName, encoding: ch.encoding,
      schemaEncoding: ch.schemaEncoding });
  }
});
client.on("message", ({ subscriptionId, timestamp, data }) => {
  const sub = readers.get(subscriptionId);
  if (sub === undefined || decoded.has(sub.topic)) return;
  decoded.add(sub.topic);
  const msg = sub.reader.readMessage(data);
  out({ ...summary(sub.topic, msg), timestamp: String(timestamp) });
  if (topics.every((t) => decoded.has(t))) publishGoal();
});
setTimeout(() => { out({ timeout: true, decoded: [...decoded] }); process.exit(2); },
  Number(process.env.FG_TIMEOUT_MS || 20000));
