// End-to-end drive of the VR page in headless Chromium with Meta's WebXR emulator (iwer), for test_vr_browser.py.
//
//   node e2e_vr.mjs <page url> <steps json>
//
// Opens our real page served by our server, lets it connect and show camera frames, enters the immersive
// session, then for each step squeezes the emulated right controller, moves it by [dx, dy, dz] metres (XR frame)
// over one second, holds, releases; a step may also long-press a button and wait for a status text. The page itself knows nothing of iwer: the emulator is injected before any
// page script runs and installed over Chromium's own navigator.xr (forceInstall). Prints one JSON line: the page's
// counters, per-move timings, and console errors.

import fs from "node:fs";
import { createRequire } from "node:module";
import os from "node:os";
import path from "node:path";
import { chromium } from "playwright-core";

const require = createRequire(import.meta.url);
const [url, movesJson] = process.argv.slice(2);
const moves = JSON.parse(movesJson || "[[0.1, 0, 0]]");
// every wait is on the page, the server or the simulation doing its part, not on how fast: a loaded host resets a scene
// (a new episode's pile) and steps it several times slower than an idle one
const WAIT_MS = 90000;
const FLAGS = [
  "--headless",
  "--no-sandbox",
  "--disable-gpu",
  "--disable-quic",
  "--no-first-run",
  "--disable-background-networking",
  "--disable-component-update",
  "--disable-sync",
];

const userDataDir = fs.mkdtempSync(path.join(os.tmpdir(), "vr-e2e-chromium-"));
const result = { moves: [], errors: [] };
const context = await chromium.launchPersistentContext(userDataDir, {
  executablePath: "/usr/bin/chromium",
  headless: true,
  args: FLAGS,
  viewport: { width: 800, height: 450 },
});
try {
  const page = context.pages()[0] || (await context.newPage());
  page.on("pageerror", (e) => result.errors.push(String(e)));
  page.on("console", (m) => {
    if (m.type() === "error") result.errors.push(m.text());
  });
  await page.addInitScript({ path: require.resolve("iwer/build/iwer.min.js") });
  await page.addInitScript(() => {
    const device = new IWER.XRDevice(IWER.metaQuest3);
    device.installRuntime({ forceInstall: true });
    window.__emulatedHeadset = device;
  });
  await page.goto(url);
  const stats = () => window.vrTeleop.stats;
  // waits until fn(arg) holds in the page; a timeout names what was awaited and the status line the page showed
  const until = async (what, fn, arg = null) => {
    try {
      await page.waitForFunction(fn, arg, { timeout: WAIT_MS });
    } catch (e) {
      const status = await page.evaluate(() => document.getElementById("status")?.textContent);
      throw new Error(`waiting for ${what}, the status line says "${status}": ${e.message}`);
    }
  };
  await until("the connection", () => window.vrTeleop && window.vrTeleop.stats.connected);
  await until("3 camera frames", () => window.vrTeleop.stats.framesDecoded >= 3);
  result.framesBeforeXR = await page.evaluate(() => window.vrTeleop.stats.framesDecoded);
  await until("Enter VR", () => !document.getElementById("enter-vr").disabled);
  await page.click("#enter-vr");
  await until("20 XR frames", () => window.vrTeleop.stats.inXR && window.vrTeleop.stats.xrFrames > 20);
  for (const step of moves) {
    // a step is a hand move [dx, dy, dz], or {move, press, waitFor}: the move, then a long press of a button
    // ("a-button", "b-button"), then waiting until the status line contains waitFor
    const move = Array.isArray(step) ? step : step.move;
    const t0 = Date.now();
    if (move) {
      await page.evaluate(() => window.__emulatedHeadset.controllers.right.updateButtonValue("squeeze", 1));
      await until("engaged", () => window.vrTeleop.stats.lastStatus && window.vrTeleop.stats.lastStatus.engaged);
      await page.evaluate(async (d) => {
        const c = window.__emulatedHeadset.controllers.right;
        const start = [c.position.x, c.position.y, c.position.z];
        for (let k = 1; k <= 50; k++) {
          c.position.set(start[0] + (d[0] * k) / 50, start[1] + (d[1] * k) / 50, start[2] + (d[2] * k) / 50);
          await new Promise((r) => setTimeout(r, 20));
        }
      }, move);
      await page.waitForTimeout(1500); // hold: the arm settles
      await page.evaluate(() => window.__emulatedHeadset.controllers.right.updateButtonValue("squeeze", 0));
      await until("released", () => !window.vrTeleop.stats.lastStatus.engaged);
      await page.waitForTimeout(500);
    }
    if (step.press) {
      await page.evaluate((b) => window.__emulatedHeadset.controllers.right.updateButtonValue(b, 1), step.press);
      await page.waitForTimeout(1000); // a long press: a brush of the thumb does nothing
      await page.evaluate((b) => window.__emulatedHeadset.controllers.right.updateButtonValue(b, 0), step.press);
    }
    if (step.waitFor) {
      await until(`"${step.waitFor}"`, (text) => document.getElementById("status").textContent.includes(text),
        step.waitFor);
    }
    result.moves.push({ move, press: step.press || null, ms: Date.now() - t0 });
  }
  result.stats = await page.evaluate(stats);
} finally {
  await context.close();
  fs.rmSync(userDataDir, { recursive: true, force: true });
}
console.log(JSON.stringify(result));
