// A Foxglove WebSocket protocol client for tests/bridge/foxglove/test_js_graph_assets.py (node 20).
// Offers ONLY "foxglove.websocket.v1". Fetches each URI of FG_ASSETS (comma separated) with
// fetchAsset (request ids 1, 2, ...), subscribes to the connection graph and prints every
// update; exits 0 once an update shows FG_WAIT_TOPIC published (the test makes it appear
// after the first update) and every asset has been answered.
// Output: one JSON object per line on stdout.
"use strict";
const crypto = require("crypto");
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const WebSocket = require("ws");

const url = process.argv[2];
const assets = (process.env.FG_ASSETS || "").split(",").filter((s) => s.length > 0);
const waitTopic = process.env.FG_WAIT_TOPIC || "/appeared";
const out = (obj) => process.stdout.write(JSON.stringify(obj) + "\n");

const ws = new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
const client = new FoxgloveClient({ ws });
const answered = new Set();
let sawTopic = false;

function maybeDone() {
  if (sawTopic && answered.size === assets.length) {
    out({ done: true });
    process.exit(0);
  }
}

client.on("open", () => out({ open: true, protocol: ws.protocol }));
client.on("serverInfo", (info) => {
  out({ serverInfo: info.name, capabilities: info.capabilities });
  assets.forEach((uri, i) => client.fetchAsset(uri, i + 1));
  client.subscribeConnectionGraph();
});
client.on("status", (s) => out({ status: s.level, message: s.message }));
client.on("error", (e) => out({ error: String(e) }));
client.on("close", (e) => { out({ closed: true, code: e.code }); process.exit(0); });
client.on("fetchAssetResponse", (r) => {
  answered.add(r.requestId);
  if (r.status === 0) {
    const bytes = new Uint8Array(r.data.buffer, r.data.byteOffset, r.data.byteLength);
    const sha256 = crypto.createHash("sha256").update(bytes).digest("hex");
    out({ asset: r.requestId, status: 0, bytes: bytes.length, sha256 });
  } else {
    out({ asset: r.requestId, status: r.status, error: r.error });
  }
  maybeDone();
});
client.on("connectionGraphUpdate", (u) => {
  out({ graph: true, publishedTopics: u.publishedTopics, subscribedTopics: u.subscribedTopics,
    advertisedServices: u.advertisedServices, removedTopics: u.removedTopics,
    removedServices: u.removedServices });
  if (u.publishedTopics.some((t) => t.name === waitTopic && t.publisherIds.length > 0)) {
    sawTopic = true;
  }
  maybeDone();
});
setTimeout(() => { out({ timeout: true, answered: [...answered], sawTopic }); process.exit(2); },
  Number(process.env.FG_TIMEOUT_MS || 20000));
