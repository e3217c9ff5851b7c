// The page: load the embedded model and wasm (no fetch: works from file:// and offline), then either steer
// live (keyboard / buttons) or, with ?selftest=1, run the scripted program and write a JSON report.
import * as ort from 'onnxruntime-web/wasm';
import { Character, gaussian, lagStep } from './character.js';
import { Scene } from './scene.js';

const $ = (id) => document.getElementById(id);

function bytes(b64) {
  const bin = atob(b64), u = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) u[i] = bin.charCodeAt(i);
  return u;
}

async function load() {
  const A = window.MOGLOW_ASSETS;
  ort.env.wasm.numThreads = 1; // no SharedArrayBuffer from file://; one thread is enough for this model
  ort.env.wasm.proxy = false;
  ort.env.wasm.wasmBinary = bytes(A.wasm).buffer; // passed in memory: nothing is fetched
  const session = await ort.InferenceSession.create(bytes(A.model), { executionProviders: ['wasm'] });
  return { session, demo: A.demo, loadedBytes: A.wasm.length * 3 / 4 + A.model.length * 3 / 4 };
}

const median = (a) => { const s = [...a].sort((x, y) => x - y); return s.length ? s[s.length >> 1] : NaN; };

function panel(cmd, measured, fps, stepMs) {
  $('cmd-speed').textContent = cmd[0].toFixed(2);
  $('cmd-turn').textContent = cmd[2].toFixed(2);
  $('meas-speed').textContent = measured.toFixed(2);
  if (fps !== null) $('fps').textContent = fps.toFixed(0);
  if (stepMs !== null) $('step-ms').textContent = stepMs.toFixed(2);
}

async function selftest(ch, scene, demo, firstFrameMs) {
  const st = demo.selftest, fps = demo.fps, errors = [];
  // the commands through the page's own controller, checked against the exported sequence
  let c = demo.start_controls[demo.tau - 1].map((v, k) => v * demo.std[63 + k] + demo.mean[63 + k]);
  const controls = [];
  for (const ph of st.phases) for (let i = 0; i < Math.round(ph.seconds * fps); i++) controls.push(c = lagStep(c, ph.command, fps, demo.control_lag));
  const ctlDiff = Math.max(...controls.map((u, t) => Math.max(...u.map((v, k) => Math.abs(v - st.controls_raw[t][k])))));
  if (!(ctlDiff < 1e-6)) errors.push(`page controller differs from the exported commands by ${ctlDiff}`);
  const stepMs = [], roots = [], yaws = [], diffs = [];
  const t0 = performance.now();
  for (let t = 0; t < controls.length; t++) {
    stepMs.push(await ch.step(controls[t], Float32Array.from(st.z[t])));
    scene.draw(ch.world, 1);
    scene.sync();
    roots.push([...ch.root]);
    yaws.push(ch.yaw);
    let d = 0;
    for (let i = 0; i < 63; i++) d = Math.max(d, Math.abs(ch.local[i] - st.torch_local_m[t][i]));
    diffs.push(d);
    if (t % 20 === 19) { panel(controls[t], 0, null, median(stepMs)); await new Promise((r) => setTimeout(r, 0)); }
  }
  const seconds = (performance.now() - t0) / 1000;
  const speed = {}, command = {};
  let start = 0, heading = null;
  for (const ph of st.phases) {
    const n = Math.round(ph.seconds * fps), a = start + (n >> 1), b = start + n - 1; // the phase's second half
    let path = 0;
    for (let t = a + 1; t <= b; t++) path += Math.hypot(roots[t][0] - roots[t - 1][0], roots[t][1] - roots[t - 1][1]);
    speed[ph.name] = path * fps / (b - a);
    command[ph.name] = Math.hypot(ph.command[0], ph.command[1]);
    if (ph.command[2] !== 0) heading = yaws[start + n - 1] - (start > 0 ? yaws[start - 1] : 0);
    start += n;
  }
  const report = {
    parity_max_abs_m: Math.max(...diffs.slice(0, 60)), // the rollout's first 60 frames (3 s)
    parity_rollout_max_abs_m: Math.max(...diffs), // all frames
    parity_parting_frame: diffs.findIndex((d) => d > 1e-4),
    fps: controls.length / seconds, step_ms_median: median(stepMs), frames: controls.length,
    speed_by_phase: speed, command_by_phase: command, heading_change_rad: heading,
    first_frame_ms: firstFrameMs, embedded_bytes: window.MOGLOW_EMBEDDED_BYTES || null,
    backend: `onnxruntime-web ${ort.env.versions.web || ''} wasm, 1 thread`, errors,
  };
  for (const [k, v] of Object.entries(report)) if (typeof v === 'number' && !Number.isFinite(v)) errors.push(`${k} is ${v}`);
  return report;
}

function live(ch, scene, demo) {
  const target = [Number(new URLSearchParams(location.search).get('speed')) || 0, 0, 0], keys = new Set();
  let c = demo.start_controls[demo.tau - 1].map((v, k) => v * demo.std[63 + k] + demo.mean[63 + k]);
  const set = (what) => {
    if (what === 'faster') target[0] = Math.min(4, [0, 1.2, 3, 4].find((s) => s > target[0] + 1e-9) ?? 4);
    if (what === 'slower') target[0] = Math.max(-0.8, [...[-0.8, 0, 1.2, 3]].reverse().find((s) => s < target[0] - 1e-9) ?? -0.8);
    if (what === 'stop') { target[0] = 0; target[2] = 0; }
    if (what === 'left') target[2] = Math.min(1.2, target[2] + 0.4);
    if (what === 'right') target[2] = Math.max(-1.2, target[2] - 0.4);
  };
  const map = { ArrowUp: 'faster', KeyW: 'faster', ArrowDown: 'slower', KeyS: 'slower', ArrowLeft: 'left', KeyA: 'left',
    ArrowRight: 'right', KeyD: 'right', Space: 'stop' };
  window.addEventListener('keydown', (e) => { if (map[e.code] && !keys.has(e.code)) { set(map[e.code]); e.preventDefault(); } keys.add(e.code); });
  window.addEventListener('keyup', (e) => keys.delete(e.code));
  for (const w of ['faster', 'slower', 'left', 'right', 'stop']) $(`btn-${w}`).addEventListener('click', () => set(w));
  let last = performance.now(), acc = 0, busy = false, frames = 0, fpsT = last, fps = null;
  const stepMs = [], prev = [...ch.root];
  let measured = 0;
  const tick = async (now) => {
    requestAnimationFrame(tick);
    acc += Math.min(0.25, (now - last) / 1000);
    last = now;
    if (!busy && acc >= 1 / demo.fps) { // the model runs at the data's 20 frames per second
      busy = true;
      acc -= 1 / demo.fps;
      c = lagStep(c, target, demo.fps, demo.control_lag);
      prev[0] = ch.root[0]; prev[1] = ch.root[1];
      stepMs.push(await ch.step(c, gaussian(ch.D)));
      if (stepMs.length > 100) stepMs.shift();
      measured = 0.8 * measured + 0.2 * Math.hypot(ch.root[0] - prev[0], ch.root[1] - prev[1]) * demo.fps;
      busy = false;
    }
    scene.draw(ch.world);
    frames++;
    if (now - fpsT > 1000) { fps = frames * 1000 / (now - fpsT); frames = 0; fpsT = now; }
    panel(target, measured, fps, median(stepMs));
  };
  requestAnimationFrame(tick);
}

async function main() {
  const report = $('selftest');
  try {
    const { session, demo } = await load();
    const ch = new Character(session, demo);
    const scene = new Scene($('view'), demo.parents);
    await ch.step(demo.start_controls[demo.tau - 1].map((v, k) => v * demo.std[63 + k] + demo.mean[63 + k]), new Float32Array(ch.D));
    scene.draw(ch.world, 1);
    scene.sync();
    const firstFrameMs = performance.now(); // since the navigation started
    if (new URLSearchParams(location.search).get('selftest') === '1') {
      // the self-test starts from the standing start again: a fresh character
      const fresh = new Character(session, demo);
      $('status').textContent = 'self-test running...';
      const r = await selftest(fresh, scene, demo, firstFrameMs);
      report.textContent = JSON.stringify(r, null, 1);
      $('status').textContent = r.errors.length ? 'self-test: errors' : 'self-test done';
      live(fresh, scene, demo);
    } else {
      $('status').textContent = 'ready: steer with the arrow keys';
      live(ch, scene, demo);
    }
  } catch (e) {
    report.textContent = JSON.stringify({ errors: [String(e && e.stack || e)] });
    $('status').textContent = `error: ${e}`;
  }
}

main();
