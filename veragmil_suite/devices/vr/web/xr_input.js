// One pose message per XR frame: the headset's pose and both controllers' grip poses and buttons, in the XR
// reference space (metres; x right, y up, z toward the user). Field meanings are documented in vr_protocol.py.

import { SCHEMA_VERSION } from "./link.js";

const clamp = (x, lo, hi) => Math.min(hi, Math.max(lo, Number.isFinite(x) ? x : 0));

function poseOf(transform) {
  const p = transform.position;
  const q = transform.orientation;
  return { p: [p.x, p.y, p.z], q: [q.x, q.y, q.z, q.w] };
}

// xr-standard gamepad mapping: buttons 0 trigger, 1 squeeze, 3 thumbstick press, 4 A/X, 5 B/Y; axes 2, 3 the
// thumbstick (y positive when pulled back, so it is flipped: the message's stick y is positive forward).
function controllerOf(frame, refSpace, source) {
  const pose = source.gripSpace ? frame.getPose(source.gripSpace, refSpace) : null;
  const gp = source.gamepad;
  const button = (i) => (gp && gp.buttons[i]) || { value: 0, pressed: false };
  const axis = (i) => (gp && gp.axes.length > i ? gp.axes[i] : 0);
  const state = {
    p: null,
    q: null,
    emulated: !!pose && pose.emulatedPosition,
    trigger: clamp(button(0).value, 0, 1),
    squeeze: clamp(button(1).value, 0, 1),
    stick: [clamp(axis(2), -1, 1), clamp(-axis(3), -1, 1)],
    stick_press: !!button(3).pressed,
    a: !!button(4).pressed,
    b: !!button(5).pressed,
  };
  if (pose) Object.assign(state, poseOf(pose.transform));
  return state;
}

export function poseMessage(frame, refSpace, seq, time) {
  const session = frame.session;
  const viewer = frame.getViewerPose(refSpace);
  const msg = {
    v: SCHEMA_VERSION,
    type: "pose",
    seq,
    t: time,
    visible: session.visibilityState === "visible",
    head: viewer ? poseOf(viewer.transform) : null,
    left: null,
    right: null,
  };
  for (const source of session.inputSources) {
    if (source.handedness === "left" || source.handedness === "right") {
      if (source.gamepad || source.gripSpace) msg[source.handedness] = controllerOf(frame, refSpace, source);
    }
  }
  return msg;
}
