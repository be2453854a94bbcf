// The VR teleoperation page: connects to the simulator, shows its camera (on this page and on a panel in VR),
// and in an immersive session sends the headset's and controllers' poses every XR frame.

import { Link } from "./link.js";
import { fromRotationTranslation, fromYawTranslation, yawOf } from "./mat4.js";
import { QuadRenderer } from "./quad_renderer.js";
import { poseMessage } from "./xr_input.js";

const PANEL_DISTANCE = 1.2; // metres in front of the operator
const PANEL_HEIGHT = 0.6;
const PANEL_DROP = 0.15; // below eye level, so the hands stay in view above it
const STATUS_ASPECT = 1024 / 64; // the status canvas

// Counters for whoever debugs this page (devtools) and for the browser test.
const stats = {
  connected: false,
  framesReceived: 0,
  framesDecoded: 0,
  framesDroppedBeforeDecode: 0,
  framesDrawn: 0,
  xrFrames: 0,
  posesSent: 0,
  statusReceived: 0,
  lastFrame: null, // the newest frame's header (its timing block in the simulator's clock, see link.js)
  // this page's part of the latency, mean ms: frame received -> decoded (waiting behind a decode included) and,
  // in VR, decoded -> uploaded by the next XR frame; what the simulator's side costs is in lastFrame.timing
  latency: { decoded: 0, receivedToDecodedMs: 0, drawn: 0, decodedToDrawnMs: 0 },
  lastStatus: null,
  finalText: null, // the program's last word when the session is over ("N demos saved to FILE")
  finished: false,
  inXR: false,
  error: null,
};
window.vrTeleop = { stats };

const $ = (id) => document.getElementById(id);
const statusEl = $("status");
const pairForm = $("pair");
const tokenInput = $("token");
const enterButton = $("enter-vr");
const xrNote = $("xr-note");
const preview = $("preview");
const previewContext = preview.getContext("2d");

const params = new URLSearchParams(location.search);
let token = params.get("token") || sessionStorage.getItem("vr-token");
const link = new Link((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws", token);

// ---------------------------------------------------------------- camera frames: decode the newest only
let bitmap = null;
let bitmapVersion = 0;
let bitmapDecodedAt = 0;
let decoding = false;
let pending = null;

function addMean(name, count, ms) {
  const l = stats.latency;
  l[count]++;
  l[name] += (ms - l[name]) / l[count];
}

async function decode(frame) {
  decoding = true;
  try {
    const next = await createImageBitmap(new Blob([frame.jpeg], { type: "image/jpeg" }));
    if (bitmap) bitmap.close();
    bitmap = next;
    bitmapVersion++;
    bitmapDecodedAt = performance.now();
    addMean("receivedToDecodedMs", "decoded", bitmapDecodedAt - frame.receivedAt);
    stats.framesDecoded++;
    if (!stats.inXR) drawPreview();
  } catch (e) {
    stats.error = String(e);
  }
  decoding = false;
  if (pending) {
    const next = pending;
    pending = null;
    decode(next);
  }
}

function drawPreview() {
  if (preview.width !== bitmap.width || preview.height !== bitmap.height) {
    preview.width = bitmap.width;
    preview.height = bitmap.height;
  }
  previewContext.drawImage(bitmap, 0, 0);
}

link.addEventListener("frame", (event) => {
  event.detail.receivedAt = performance.now();
  const { jpeg, receivedAt, ...header } = event.detail;
  stats.framesReceived++;
  stats.lastFrame = header;
  if (decoding) {
    if (pending) stats.framesDroppedBeforeDecode++;
    pending = event.detail;
  } else {
    decode(event.detail);
  }
});

// ---------------------------------------------------------------- status line
let statusVersion = 0;
let lastRecenter = null;
let placePanel = true;

function showStatus(text) {
  statusEl.textContent = text;
  statusVersion++;
}

link.addEventListener("welcome", (event) => {
  stats.connected = true;
  pairForm.hidden = true;
  showStatus(`connected (camera ${event.detail.camera})`);
});
link.addEventListener("status", (event) => {
  const msg = event.detail;
  stats.statusReceived++;
  stats.lastStatus = msg;
  if (lastRecenter !== null && msg.recenter !== lastRecenter) placePanel = true;
  lastRecenter = msg.recenter;
  if (msg.final) stats.finalText = msg.text;
  showStatus(msg.text);
});
link.addEventListener("close", (event) => {
  stats.connected = false;
  const code = event.detail.code;
  stats.finished = event.detail.finished;
  if (stats.finished) showStatus(`finished: ${stats.finalText || "the program closed the session"}`);
  else showStatus(code === 4000 ? "another page took over the connection" : "disconnected: reconnecting…");
});
link.addEventListener("unauthorized", () => {
  pairForm.hidden = false;
  showStatus("enter the pairing token shown in the simulator's terminal");
});
link.addEventListener("servererror", (event) => showStatus(`server: ${event.detail}`));

pairForm.addEventListener("submit", (event) => {
  event.preventDefault();
  token = tokenInput.value.trim();
  sessionStorage.setItem("vr-token", token);
  link.token = token;
  link.connect();
});

// ---------------------------------------------------------------- immersive session
let session = null;

async function enterVR() {
  session = await navigator.xr.requestSession("immersive-vr", { optionalFeatures: ["local-floor"] });
  const canvas = document.createElement("canvas");
  const gl = canvas.getContext("webgl2", { xrCompatible: true, antialias: false });
  if (!gl) throw new Error("WebGL2 is not available");
  if (gl.makeXRCompatible) await gl.makeXRCompatible();
  session.updateRenderState({ baseLayer: new XRWebGLLayer(session, gl) });
  let refSpace;
  try {
    refSpace = await session.requestReferenceSpace("local-floor");
  } catch (e) {
    refSpace = await session.requestReferenceSpace("local");
  }
  const renderer = new QuadRenderer(gl);
  const panelTexture = renderer.createTexture();
  const statusTexture = renderer.createTexture();
  const statusCanvas = document.createElement("canvas");
  statusCanvas.width = 1024;
  statusCanvas.height = 64;
  const statusContext = statusCanvas.getContext("2d");
  let uploadedBitmap = 0;
  let uploadedStatus = -1;
  let aspect = 4 / 3;
  let panel = null;
  let seq = 0;
  let lastSend = -Infinity;
  stats.inXR = true;
  placePanel = true;

  session.addEventListener("end", () => {
    stats.inXR = false;
    session = null;
    enterButton.textContent = "Enter VR";
  });
  enterButton.textContent = "Exit VR";

  function drawStatus() {
    const s = stats.lastStatus;
    statusContext.fillStyle = stats.finished ? "#203a60" : !stats.connected ? "#602020" : s && s.engaged ? "#1d5a2a" : "#202430";
    statusContext.fillRect(0, 0, statusCanvas.width, statusCanvas.height);
    statusContext.fillStyle = "#f0f0f0";
    statusContext.font = "28px sans-serif";
    statusContext.textBaseline = "middle";
    statusContext.fillText(statusEl.textContent, 16, statusCanvas.height / 2, statusCanvas.width - 32);
  }

  function onFrame(time, frame) {
    const s = frame.session;
    s.requestAnimationFrame(onFrame);
    stats.xrFrames++;
    const sendHz = (link.config && link.config.send_hz) || 100;
    if (time - lastSend >= 1000 / sendHz - 1) {
      lastSend = time;
      if (link.sendPose(poseMessage(frame, refSpace, seq, time))) {
        seq++;
        stats.posesSent++;
      }
    }
    const viewer = frame.getViewerPose(refSpace);
    if (!viewer) return;
    if (placePanel) {
      // world-locked in front of the operator's current facing; the recenter button moves it here again
      const p = viewer.transform.position;
      const yaw = yawOf([viewer.transform.orientation.x, viewer.transform.orientation.y,
        viewer.transform.orientation.z, viewer.transform.orientation.w]);
      const centre = [p.x - PANEL_DISTANCE * Math.sin(yaw), p.y - PANEL_DROP, p.z - PANEL_DISTANCE * Math.cos(yaw)];
      panel = { yaw, centre };
      placePanel = false;
    }
    if (bitmap && uploadedBitmap !== bitmapVersion) {
      renderer.upload(panelTexture, bitmap);
      addMean("decodedToDrawnMs", "drawn", performance.now() - bitmapDecodedAt);
      uploadedBitmap = bitmapVersion;
      aspect = bitmap.width / bitmap.height;
    }
    if (uploadedStatus !== statusVersion) {
      drawStatus();
      renderer.upload(statusTexture, statusCanvas);
      uploadedStatus = statusVersion;
    }
    const width = PANEL_HEIGHT * aspect;
    const statusHeight = width / STATUS_ASPECT;
    const below = [panel.centre[0], panel.centre[1] - PANEL_HEIGHT / 2 - statusHeight, panel.centre[2]];
    const items = [
      { kind: "quad", model: fromYawTranslation(panel.yaw, panel.centre), size: [width, PANEL_HEIGHT, 1], texture: panelTexture },
      { kind: "quad", model: fromYawTranslation(panel.yaw, below), size: [width, statusHeight, 1], texture: statusTexture },
    ];
    const engaged = stats.lastStatus && stats.lastStatus.engaged;
    const mainHand = (link.config && link.config.hand) || "right";
    for (const source of s.inputSources) {
      const pose = source.gripSpace && frame.getPose(source.gripSpace, refSpace);
      if (!pose) continue;
      const t = pose.transform;
      const color = source.handedness === mainHand ? (engaged ? [0.2, 0.9, 0.3, 1] : [0.8, 0.8, 0.8, 1]) : [0.4, 0.5, 0.9, 1];
      items.push({
        kind: "box",
        model: fromRotationTranslation([t.orientation.x, t.orientation.y, t.orientation.z, t.orientation.w],
          [t.position.x, t.position.y, t.position.z]),
        size: [0.04, 0.04, 0.1],
        color,
      });
    }
    const layer = s.renderState.baseLayer;
    gl.bindFramebuffer(gl.FRAMEBUFFER, layer.framebuffer);
    gl.clearColor(0.06, 0.06, 0.09, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    for (const view of viewer.views) {
      const vp = layer.getViewport(view);
      gl.viewport(vp.x, vp.y, vp.width, vp.height);
      renderer.draw(view.projectionMatrix, view.transform.inverse.matrix, items);
    }
    if (uploadedBitmap > 0) stats.framesDrawn++;
  }
  session.requestAnimationFrame(onFrame);
}

enterButton.addEventListener("click", async () => {
  if (session) {
    session.end();
    return;
  }
  try {
    await enterVR();
  } catch (e) {
    stats.error = String(e);
    showStatus(`could not enter VR: ${e.message || e}`);
    session = null;
  }
});

async function checkXR() {
  if (!window.isSecureContext) {
    xrNote.textContent = "WebXR needs a secure context: open this page as http://localhost (USB) or over https.";
    return;
  }
  if (!navigator.xr) {
    xrNote.textContent = "This browser has no WebXR: open the page in the headset's browser.";
    return;
  }
  const supported = await navigator.xr.isSessionSupported("immersive-vr").catch(() => false);
  enterButton.disabled = !supported;
  xrNote.textContent = supported ? "" : "This browser cannot start an immersive VR session.";
}

if (token) tokenInput.value = token;
link.connect();
checkXR();
