// RASPV headset client: spatial audio cues of the navigation assistant (WebAudio, no dependencies).
//
// The bridge sends `cues` messages (docs/hmd.md): positions of the next waypoint, the nearest
// obstacle ahead and a staircase, relative to the listener (x forward, y left, z up, metres).
// Each cue is an oscillator → envelope gain → HRTF PannerNode → switch gain → master:
//   waypoint  a short 880 Hz sine blip every 0.7 s: walk towards it (a double 220 Hz beep when the
//             DWA finds no admissible velocity: stop);
//   obstacle  330 Hz triangle beeps that quicken as the obstacle comes closer (parking sensor);
//   stairs    a three-note square arpeggio, rising for stairs up, falling for stairs down.
// In the "base" frame the listener turns with the head orientation this page sends (drag, phone
// or XR), so turning the head moves the sounds at once. Switches: m all audio, b waypoint,
// p obstacle, t stairs; URL audio=1 starts it, cues=waypoint,obstacle,stairs picks the cues.
// window.raspvAudio.graph() reads the live audio graph (AudioParam values) for tests.
"use strict";
(() => {
  const params = new URLSearchParams(location.search);
  const KINDS = ["waypoint", "obstacle", "stairs"];
  const KEYS = { b: "waypoint", p: "obstacle", t: "stairs" };
  const STALE_S = 1.0;                 // cues older than this fall silent
  const LOOKAHEAD_S = 0.25;            // blips are scheduled this far ahead
  const chosen = (params.get("cues") || KINDS.join(",")).split(",");
  const A = {
    enabled: false, state: "off", frame: null, messages: 0, lastMessage: null,
    on: Object.fromEntries(KINDS.map((k) => [k, chosen.includes(k)])),
  };
  let ctx = null, master = null, analyser = null, cues = null, lastCues = null, lastCuesAt = -Infinity;

  // ---- geometry: protocol frame (x forward, y left, z up) → WebAudio (x right, y up, z back) --
  const toWA = (p) => [-p[1], p[2], -p[0]];
  function rotate(q, v) {                      // v rotated by unit quaternion q = [x, y, z, w]
    const [x, y, z, w] = q;
    const tx = 2 * (y * v[2] - z * v[1]), ty = 2 * (z * v[0] - x * v[2]), tz = 2 * (x * v[1] - y * v[0]);
    return [v[0] + w * tx + (y * tz - z * ty), v[1] + w * ty + (z * tx - x * tz), v[2] + w * tz + (x * ty - y * tx)];
  }
  function rpyQuaternion(roll, pitch, yaw) {   // as raspv_hmd.protocol.rpy_to_quaternion
    const cr = Math.cos(roll / 2), sr = Math.sin(roll / 2), cp = Math.cos(pitch / 2), sp = Math.sin(pitch / 2);
    const cy = Math.cos(yaw / 2), sy = Math.sin(yaw / 2);
    return [sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy];
  }
  function headQuaternion() {                  // head relative to the base, as the page sends it
    const S = window.raspvClient;
    if (!S) return [0, 0, 0, 1];
    if (S.headQuaternion) return S.headQuaternion;
    return rpyQuaternion(S.head.roll, S.head.pitch, S.head.yaw);
  }

  // ---- the audio graph --------------------------------------------------------------------
  function makeCue(kind) {
    const osc = ctx.createOscillator();
    osc.type = { waypoint: "sine", obstacle: "triangle", stairs: "square" }[kind];
    osc.frequency.value = { waypoint: 880, obstacle: 330, stairs: 523.25 }[kind];
    const envelope = ctx.createGain();
    envelope.gain.value = 0;
    const panner = new PannerNode(ctx, { panningModel: "HRTF", distanceModel: "inverse", refDistance: 1,
                                         maxDistance: 50, rolloffFactor: 0.5 });
    const sw = ctx.createGain();
    sw.gain.value = A.on[kind] ? 1 : 0;
    osc.connect(envelope).connect(panner).connect(sw).connect(master);
    osc.start();
    return { kind, osc, envelope, panner, sw, active: false, nextAt: 0, period: 0, distance: null, direction: null,
             stop: false };
  }

  function start() {
    if (!ctx) {
      const AC = window.AudioContext || window.webkitAudioContext;
      if (!AC) { A.state = "unsupported"; return; }
      ctx = new AC();
      master = ctx.createGain();
      master.gain.value = 0.6;
      master.connect(ctx.destination);
      analyser = ctx.createAnalyser();           // a tap on the output: what the ears get
      analyser.fftSize = 2048;
      master.connect(analyser);
      cues = Object.fromEntries(KINDS.map((k) => [k, makeCue(k)]));
      setInterval(schedule, 50);
    }
    A.enabled = true;
    master.gain.setValueAtTime(0.6, ctx.currentTime);
    if (ctx.state === "suspended") ctx.resume().catch(() => {});
    if (lastCues) apply(lastCues);
    updateButton();
  }

  function stop() {
    A.enabled = false;
    if (ctx) master.gain.setValueAtTime(0, ctx.currentTime);
    updateButton();
  }

  function setSwitch(kind, on) {
    A.on[kind] = on;
    if (cues) cues[kind].sw.gain.setValueAtTime(on ? 1 : 0, ctx.currentTime);
  }

  // ---- cues from the bridge ---------------------------------------------------------------
  function update(m) {
    A.messages++;
    A.lastMessage = m;
    lastCues = m;
    lastCuesAt = performance.now() / 1000;
    if (ctx) apply(m);
  }

  function apply(m) {
    A.frame = m.frame;
    const t = ctx.currentTime;
    for (const kind of KINDS) {
      const c = cues[kind], cue = m[kind];
      c.active = !!cue;
      if (!cue) continue;
      const [x, y, z] = toWA(cue.position);
      c.panner.positionX.setValueAtTime(x, t);
      c.panner.positionY.setValueAtTime(y, t);
      c.panner.positionZ.setValueAtTime(z, t);
      c.distance = cue.distance !== undefined ? cue.distance : Math.hypot(...cue.position);
      if (kind === "waypoint") { c.stop = m.has_path && m.feasible === false; c.period = c.stop ? 0.5 : 0.7; }
      if (kind === "obstacle") c.period = 0.1 + 0.7 * Math.min(1, c.distance / (m.proximity_range || 1.5));
      if (kind === "stairs") { c.period = 1.5; c.direction = cue.direction; }
    }
    orientListener(t);
  }

  function orientListener(t) {
    const L = ctx.listener;
    let fwd = [1, 0, 0], up = [0, 0, 1];
    if (A.frame === "base") { const q = headQuaternion(); fwd = rotate(q, fwd); up = rotate(q, up); }
    const f = toWA(fwd), u = toWA(up);
    if (L.forwardX) {
      L.forwardX.setValueAtTime(f[0], t); L.forwardY.setValueAtTime(f[1], t); L.forwardZ.setValueAtTime(f[2], t);
      L.upX.setValueAtTime(u[0], t); L.upY.setValueAtTime(u[1], t); L.upZ.setValueAtTime(u[2], t);
    } else {
      L.setOrientation(f[0], f[1], f[2], u[0], u[1], u[2]);
    }
  }

  function blip(c, at) {
    const g = c.envelope.gain;
    if (c.kind === "stairs") {                 // three notes, rising or falling
      const notes = c.direction === "down" ? [783.99, 659.25, 523.25] : [523.25, 659.25, 783.99];
      notes.forEach((f, i) => {
        const s = at + i * 0.12;
        c.osc.frequency.setValueAtTime(f, s);
        g.setValueAtTime(0, s); g.linearRampToValueAtTime(0.35, s + 0.01); g.linearRampToValueAtTime(0, s + 0.1);
      });
      return;
    }
    if (c.kind === "waypoint") {               // walk towards it; or, when DWA finds no safe velocity, stop
      const notes = c.stop ? [[220, 0], [220, 0.12]] : [[880, 0]];
      for (const [f, dt] of notes) {
        c.osc.frequency.setValueAtTime(f, at + dt);
        g.setValueAtTime(0, at + dt); g.linearRampToValueAtTime(0.8, at + dt + 0.005); g.linearRampToValueAtTime(0, at + dt + 0.06);
      }
      return;
    }
    g.setValueAtTime(0, at); g.linearRampToValueAtTime(0.8, at + 0.005); g.linearRampToValueAtTime(0, at + 0.05);
  }

  function schedule() {
    A.state = ctx ? ctx.state : "off";
    if (!ctx || !A.enabled) return;
    const now = ctx.currentTime;
    const fresh = performance.now() / 1000 - lastCuesAt < STALE_S;
    if (lastCues) orientListener(now);
    for (const kind of KINDS) {
      const c = cues[kind];
      if (!fresh || !c.active || !A.on[kind]) { c.nextAt = 0; continue; }
      if (c.nextAt < now) c.nextAt = now + 0.02;
      while (c.nextAt < now + LOOKAHEAD_S) { blip(c, c.nextAt); c.nextAt += c.period; }
    }
  }

  // ---- what the page exposes: the live graph -----------------------------------------------
  function graph() {
    const out = { state: ctx ? ctx.state : "off", enabled: A.enabled, frame: A.frame, messages: A.messages,
                  master: master ? master.gain.value : 0, level: 0, cues: {} };
    if (!ctx) return out;
    const samples = new Float32Array(analyser.fftSize);
    analyser.getFloatTimeDomainData(samples);
    out.level = Math.sqrt(samples.reduce((a, v) => a + v * v, 0) / samples.length);   // RMS of the output
    const L = ctx.listener;
    out.listener = L.forwardX ? { forward: [L.forwardX.value, L.forwardY.value, L.forwardZ.value],
                                  up: [L.upX.value, L.upY.value, L.upZ.value] } : null;
    for (const kind of KINDS) {
      const c = cues[kind];
      out.cues[kind] = { on: A.on[kind], switchGain: c.sw.gain.value, envelope: c.envelope.gain.value,
                         active: c.active, type: c.osc.type,
                         frequency: c.osc.frequency.value, period: c.period, direction: c.direction, stop: c.stop,
                         position: [c.panner.positionX.value, c.panner.positionY.value, c.panner.positionZ.value],
                         panningModel: c.panner.panningModel };
    }
    return out;
  }

  // ---- switches ---------------------------------------------------------------------------
  function updateButton() {
    const b = document.getElementById("audio");
    if (b) b.setAttribute("aria-pressed", String(A.enabled));
  }
  function toggle() { if (A.enabled) stop(); else start(); }

  window.addEventListener("keydown", (e) => {
    if (e.ctrlKey || e.metaKey || e.altKey || e.repeat) return;
    if (e.key === "m") toggle();
    else if (KEYS[e.key]) setSwitch(KEYS[e.key], !A.on[KEYS[e.key]]);
    else if (ctx && ctx.state === "suspended" && A.enabled) ctx.resume().catch(() => {});
  });
  window.addEventListener("pointerdown", () => { if (ctx && ctx.state === "suspended" && A.enabled) ctx.resume().catch(() => {}); });
  const button = document.getElementById("audio");    // this script loads after the page's body
  if (button) button.onclick = toggle;

  window.raspvAudio = { update, start, stop, toggle, setSwitch, graph, state: A };
  if (params.get("audio") === "1") start();
})();
