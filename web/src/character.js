// One MoGlow character: the exported sampling step (course_lib/export.py) run by onnxruntime-web, the history
// and LSTM state kept here, and the root path integrated from the control as representations.decode_positions
// does it (positions_control: joints in the floor frame + forward, sideways m/s and yaw rate rad/s).
import * as ort from 'onnxruntime-web/wasm';

export class Character {
  constructor(session, demo) {
    this.session = session;
    this.d = demo;
    this.D = demo.pose_dim;
    this.tau = demo.tau;
    this.history = Float32Array.from(demo.start_poses.flat()); // (tau, D) standardised
    this.controls = Float32Array.from(demo.start_controls.flat()); // (tau, 3) standardised
    this.h = new Float32Array(demo.layers * demo.hidden);
    this.c = new Float32Array(demo.layers * demo.hidden);
    this.root = [0, 0]; // floor position (x, z) in metres
    this.yaw = 0; // heading, rad, unwrapped; + turns left (towards +x from +z)
    this.local = new Float64Array(63); // joints in the floor frame, metres
    this.world = new Float64Array(63);
    this.free = demo.fixed.map((f, i) => (f ? -1 : i)).filter((i) => i >= 0); // feature index of each modelled value
  }

  // control: raw (forward m/s, sideways m/s, yaw rate rad/s); z: Float32Array(D) latent -> ms of the model step
  async step(control, z) {
    const { mean, std, fps } = this.d;
    const ctrl = new Float32Array((this.tau + 1) * 3);
    ctrl.set(this.controls);
    for (let k = 0; k < 3; k++) ctrl[this.tau * 3 + k] = (control[k] - mean[63 + k]) / std[63 + k];
    const L = this.d.layers, H = this.d.hidden;
    const feeds = {
      history: new ort.Tensor('float32', this.history, [1, this.tau, this.D]),
      controls: new ort.Tensor('float32', ctrl, [1, this.tau + 1, 3]),
      z: new ort.Tensor('float32', z, [1, this.D]),
      h: new ort.Tensor('float32', this.h, [L, 1, H]),
      c: new ort.Tensor('float32', this.c, [L, 1, H]),
    };
    const t0 = performance.now();
    const out = await this.session.run(feeds);
    const ms = performance.now() - t0;
    const x = out.pose.data;
    this.h = Float32Array.from(out.h_next.data);
    this.c = Float32Array.from(out.c_next.data);
    this.history.copyWithin(0, this.D);
    this.history.set(x, (this.tau - 1) * this.D);
    this.controls = ctrl.slice(3);
    // root: p_t = p_{t-1} + R_y(yaw_{t-1}) (sideways, forward) / fps, then yaw_t = yaw_{t-1} + yaw_rate / fps
    const s = Math.sin(this.yaw), co = Math.cos(this.yaw);
    const side = control[1] / fps, fwd = control[0] / fps;
    this.root[0] += co * side + s * fwd;
    this.root[1] += -s * side + co * fwd;
    this.yaw += control[2] / fps;
    for (let i = 0; i < 63; i++) this.local[i] = mean[i]; // the fixed values (Hips x, z) are their mean
    this.free.forEach((f, j) => { this.local[f] = x[j] * std[f] + mean[f]; });
    const s2 = Math.sin(this.yaw), c2 = Math.cos(this.yaw);
    for (let j = 0; j < 21; j++) {
      const lx = this.local[3 * j], ly = this.local[3 * j + 1], lz = this.local[3 * j + 2];
      this.world[3 * j] = c2 * lx + s2 * lz + this.root[0];
      this.world[3 * j + 1] = ly;
      this.world[3 * j + 2] = -s2 * lx + c2 * lz + this.root[1];
    }
    return ms;
  }
}

// the page's controller: commands reach the model through c += a (target - c), a = 1 - exp(-1 / (fps lag))
// (course_lib.export.control_sequence is the same formula; the self-test's parity checks they agree)
export function lagStep(c, target, fps, lag) {
  const a = 1 - Math.exp(-1 / (fps * lag));
  return c.map((v, k) => v + a * (target[k] - v));
}

export function gaussian(n) { // z ~ N(0, I), Box-Muller
  const z = new Float32Array(n);
  for (let i = 0; i < n; i += 2) {
    const r = Math.sqrt(-2 * Math.log(1 - Math.random())), t = 2 * Math.PI * Math.random();
    z[i] = r * Math.cos(t);
    if (i + 1 < n) z[i + 1] = r * Math.sin(t);
  }
  return z;
}
