// The WebSocket link to the simulator: hello/authentication, pose messages out, status and camera frames in,
// reconnection after Wi-Fi drops, reloads and server restarts. The schema is documented in vr_protocol.py.

export const SCHEMA_VERSION = 1;
const FRAME_HEADER_BYTES = 20; // "<2sBBIdHH": magic "VF", version, panels, frame id, sim time, width, height
const CLOSE_UNAUTHORIZED = 4401;
const CLOSE_SUPERSEDED = 4000;
const CLOSE_FINISHED = 4100; // the program is done with the headset: nothing to reconnect to
const MAX_BUFFERED_BYTES = 32 * 1024; // poses wait no longer than this behind a slow link: newer ones follow

export function parseFrame(buffer) {
  const view = new DataView(buffer);
  if (buffer.byteLength < FRAME_HEADER_BYTES || view.getUint8(0) !== 0x56 || view.getUint8(1) !== 0x46) {
    throw new Error("not a camera frame");
  }
  return {
    version: view.getUint8(2),
    panels: view.getUint8(3),
    frameId: view.getUint32(4, true),
    simTime: view.getFloat64(8, true),
    width: view.getUint16(16, true),
    height: view.getUint16(18, true),
    jpeg: new Uint8Array(buffer, FRAME_HEADER_BYTES),
  };
}

export class Link extends EventTarget {
  constructor(url, token) {
    super();
    this.url = url;
    this.token = token || null;
    this.ws = null;
    this.config = null;
    this.connected = false;
    this.retryDelay = 500;
    this.stopped = false;
    this.sent = 0;
    this.skipped = 0;
  }

  connect() {
    this.stopped = false;
    const ws = new WebSocket(this.url);
    ws.binaryType = "arraybuffer";
    this.ws = ws;
    ws.onopen = () => {
      ws.send(JSON.stringify({ v: SCHEMA_VERSION, type: "hello", token: this.token, client: navigator.userAgent }));
    };
    ws.onmessage = (event) => this._receive(event.data);
    ws.onclose = (event) => {
      if (this.ws !== ws) return;
      this.connected = false;
      this.dispatchEvent(new CustomEvent("close", { detail: { code: event.code, reason: event.reason } }));
      if (event.code === CLOSE_UNAUTHORIZED) {
        this.dispatchEvent(new CustomEvent("unauthorized", { detail: event.reason }));
        return; // a new token is needed before trying again
      }
      if (event.code === CLOSE_FINISHED) this.stopped = true;
      if (event.code === CLOSE_SUPERSEDED || this.stopped) return; // another page took over, or it is over
      setTimeout(() => this.connect(), this.retryDelay);
      this.retryDelay = Math.min(this.retryDelay * 2, 3000);
    };
  }

  close() {
    this.stopped = true;
    if (this.ws) this.ws.close();
  }

  _receive(data) {
    if (data instanceof ArrayBuffer) {
      try {
        this.dispatchEvent(new CustomEvent("frame", { detail: parseFrame(data) }));
      } catch (e) {
        console.warn(e);
      }
      return;
    }
    let msg;
    try {
      msg = JSON.parse(data);
    } catch (e) {
      return;
    }
    if (msg.type === "welcome") {
      this.connected = true;
      this.retryDelay = 500;
      this.config = msg.config;
      this.dispatchEvent(new CustomEvent("welcome", { detail: msg.config }));
    } else if (msg.type === "ping") {
      this._send({ v: SCHEMA_VERSION, type: "pong", id: msg.id });
    } else if (msg.type === "status") {
      this.dispatchEvent(new CustomEvent("status", { detail: msg }));
    } else if (msg.type === "error") {
      this.dispatchEvent(new CustomEvent("servererror", { detail: msg.reason }));
    }
  }

  _send(obj) {
    if (!this.ws || this.ws.readyState !== WebSocket.OPEN) return false;
    this.ws.send(JSON.stringify(obj));
    return true;
  }

  // A pose message; skipped (not queued) while the link is backed up, since a newer pose follows.
  sendPose(msg) {
    if (!this.connected || this.ws.bufferedAmount > MAX_BUFFERED_BYTES) {
      this.skipped++;
      return false;
    }
    const ok = this._send(msg);
    if (ok) this.sent++;
    return ok;
  }
}
