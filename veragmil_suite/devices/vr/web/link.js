// The WebSocket link to the simulator: hello/authentication, pose messages out, status and camera frames in,
// reconnection after Wi-Fi drops, reloads and server restarts. The schema is documented in vr_protocol.py.

export const SCHEMA_VERSION = 1;
const FRAME_HEADER_BYTES = 20; // "<2sBBIdHH": magic "VF", version, panels, frame id, sim time, width, height
// version 2: a u16 byte count and a timing block ("<IIq8d": step, flags, pose seq, eight monotonic times of the
// simulator's machine) come before the JPEG; skipped by its count, so fields appended later change nothing here
const FRAME_VERSION_TIMED = 2;
const TIMING_BYTES = 80;
const TIMES = ["poseReceived", "action", "captured", "renderStart", "rendered", "encoded", "published", "sent"];
const CLOSE_UNAUTHORIZED = 4401;
const CLOSE_SUPERSEDED = 4000;
const CLOSE_FINISHED = 4100; // the program is done with the headset: nothing to reconnect to
const MAX_BUFFERED_BYTES = 32 * 1024; // poses wait no longer than this behind a slow link: newer ones follow

export function parseFrame(buffer) {
  const view = new DataView(buffer);
  if (buffer.byteLength < FRAME_HEADER_BYTES || view.getUint8(0) !== 0x56 || view.getUint8(1) !== 0x46) {
    throw new Error("not a camera frame");
  }
  const frame = {
    version: view.getUint8(2),
    panels: view.getUint8(3),
    frameId: view.getUint32(4, true),
    simTime: view.getFloat64(8, true),
    width: view.getUint16(16, true),
    height: view.getUint16(18, true),
  };
  let start = FRAME_HEADER_BYTES;
  if (frame.version >= FRAME_VERSION_TIMED) {
    if (buffer.byteLength < start + 2) throw new Error("frame shorter than its timing block");
    const n = view.getUint16(start, true);
    start += 2;
    if (n < TIMING_BYTES || buffer.byteLength < start + n) throw new Error("frame shorter than its timing block");
    const step = view.getUint32(start, true);
    frame.timing = {
      step: step === 0xffffffff ? null : step,
      midStep: (view.getUint32(start + 4, true) & 1) !== 0,
      poseSeq: Number(view.getBigInt64(start + 8, true)),
    };
    TIMES.forEach((name, i) => {
      frame.timing[name] = view.getFloat64(start + 16 + 8 * i, true);
    });
    start += n;
  }
  frame.jpeg = new Uint8Array(buffer, start);
  return frame;
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
    this.finished = false; // the program said its last word (a final status): nothing to reconnect to
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
      if (event.code === CLOSE_FINISHED) this.finished = true;
      const detail = { code: event.code, reason: event.reason, finished: this.finished };
      this.dispatchEvent(new CustomEvent("close", { detail }));
      if (event.code === CLOSE_UNAUTHORIZED) {
        this.dispatchEvent(new CustomEvent("unauthorized", { detail: event.reason }));
        return; // a new token is needed before trying again
      }
      if (this.finished) this.stopped = true;
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
      if (msg.final) this._finish();
    } else if (msg.type === "error") {
      this.dispatchEvent(new CustomEvent("servererror", { detail: msg.reason }));
    }
  }

  // The page closes a finished session itself: the server's socket then holds no unread poses when it closes, so the
  // close handshake completes (a server closing first under a stream of poses resets the connection, and the browser
  // reports an abnormal closure instead of the finish).
  _finish() {
    this.finished = true;
    this.stopped = true;
    this.connected = false; // no pose goes out after the close
    if (this.ws) this.ws.close(CLOSE_FINISHED, "finished");
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
