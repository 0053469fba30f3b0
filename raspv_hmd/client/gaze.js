// RASPV headset client: eye gaze from the page (protocol: docs/hmd.md "gaze"). The mouse stands in
// for an eye tracker — with mouse gaze on ("e", or ?gaze=mouse) the eye looks where the pointer is
// on the phosphene display, while dragging still turns the head — and a fixation-target
// calibration ("k") corrects the page's gaze. Samples go to the bridge as `gaze` messages (unit
// direction in the head frame: x forward, y left, z up; at most 120 per second).
// Display geometry (K_P) comes from the bridge's "view" message: a point (u, v) of the phosphene
// image looks along ((u − w/2)/f, (v − h/2)/f, 1) in the display's optical frame.
"use strict";
(() => {
  const S = window.raspvClient;
  if (!S) return;
  const MIN_INTERVAL_MS = 1000 / 120;          // samples sent at most this often
  const CAL_TARGETS = [[0, 0], [-10, -7], [10, -7], [10, 7], [-10, 7]];   // [yaw, pitch] deg: yaw > 0 left, pitch > 0 down
  const CAL_SETTLE_MS = 900, CAL_COLLECT_MS = 600;   // per target: time to look there, then samples averaged
  const DEG = Math.PI / 180;
  const params = new URLSearchParams(location.search);
  const view = () => document.getElementById("view");
  let targetEl = null;

  const G = {
    source: params.get("gaze") === "mouse" ? "mouse" : "off",
    sent: 0, last: null, lastRaw: null,      // the newest sent / measured gaze [yaw, pitch] deg
    calibration: null,                       // {matrix: 2×3, rmsDeg, points} or null
    calibrating: false,
  };
  window.raspvGaze = G;

  // ---- geometry ----------------------------------------------------------------------------
  // the image's box on the page [left, top, scale] for the eye under clientX (CSS px)
  function imageBox(clientX) {
    const v = S.view, el = view();
    if (!v || !el) return null;
    const r = el.getBoundingClientRect(), eyes = S.stereo ? 2 : 1;
    if (el.classList.contains("native")) {               // the canvas is the image (×2 in stereo), CSS contain
      const s = Math.min(r.width / (v.width * eyes), r.height / v.height);
      const left = r.left + (r.width - v.width * eyes * s) / 2, top = r.top + (r.height - v.height * s) / 2;
      const eye = eyes === 2 && clientX >= left + v.width * s ? 1 : 0;
      return [left + eye * v.width * s, top, s];
    }
    const bw = r.width / eyes, eye = eyes === 2 && clientX >= r.left + bw ? 1 : 0;   // one fitted box per eye
    const s = Math.min(bw / v.width, r.height / v.height);
    return [r.left + eye * bw + (bw - v.width * s) / 2, r.top + (r.height - v.height * s) / 2, s];
  }

  function pointToAngles(u, v) {              // image px → [yaw, pitch] deg (Fick, head frame)
    const f = S.view.focal_px, x = (u - S.view.width / 2) / f, y = (v - S.view.height / 2) / f;
    // optical (x right, y down, z forward) → head: (1, −x, −y)
    return [Math.atan2(-x, 1) / DEG, Math.atan2(y, Math.hypot(1, x)) / DEG];
  }

  function anglesToPoint(yaw, pitch) {        // [yaw, pitch] deg → image px
    const d = direction(yaw, pitch), f = S.view.focal_px;
    return [S.view.width / 2 - f * d[1] / d[0], S.view.height / 2 - f * d[2] / d[0]];
  }

  function direction(yaw, pitch) {
    const y = yaw * DEG, p = pitch * DEG;
    return [Math.cos(p) * Math.cos(y), Math.cos(p) * Math.sin(y), -Math.sin(p)];
  }

  G.clientPoint = (yaw, pitch) => {           // where [yaw, pitch] is on the page (CSS px), for tests
    const box = imageBox(-Infinity);
    if (!box) return null;
    const [u, v] = anglesToPoint(yaw, pitch);
    return [box[0] + u * box[2], box[1] + v * box[2]];
  };

  // ---- calibration: an affine map of measured → true angles, least squares --------------------
  function corrected(a) {
    const m = G.calibration && G.calibration.matrix;
    if (!m) return a;
    return [m[0][0] * a[0] + m[0][1] * a[1] + m[0][2], m[1][0] * a[0] + m[1][1] * a[1] + m[1][2]];
  }

  function solve3(A, b) {                     // 3×3 linear system (Gaussian elimination, partial pivoting)
    const M = A.map((row, i) => [...row, b[i]]);
    for (let c = 0; c < 3; c++) {
      let p = c;
      for (let r = c + 1; r < 3; r++) if (Math.abs(M[r][c]) > Math.abs(M[p][c])) p = r;
      [M[c], M[p]] = [M[p], M[c]];
      if (Math.abs(M[c][c]) < 1e-12) return null;
      for (let r = 0; r < 3; r++) {
        if (r === c) continue;
        const k = M[r][c] / M[c][c];
        for (let j = c; j < 4; j++) M[r][j] -= k * M[c][j];
      }
    }
    return M.map((row, i) => row[3] / M[i][i]);
  }

  function fit(points) {                      // points: [{measured: [a, b], target: [a, b]}] → 2×3 or null
    const AtA = [[0, 0, 0], [0, 0, 0], [0, 0, 0]], Atb = [[0, 0, 0], [0, 0, 0]];
    for (const { measured, target } of points) {
      const row = [measured[0], measured[1], 1];
      for (let i = 0; i < 3; i++) {
        for (let j = 0; j < 3; j++) AtA[i][j] += row[i] * row[j];
        for (let k = 0; k < 2; k++) Atb[k][i] += row[i] * target[k];
      }
    }
    const rows = [solve3(AtA, Atb[0]), solve3(AtA, Atb[1])];
    return rows[0] && rows[1] ? rows : null;
  }

  const median = (a) => { const s = [...a].sort((x, y) => x - y); return s[Math.floor(s.length / 2)]; };
  const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));

  function showTarget(yaw, pitch) {
    if (!targetEl) { targetEl = document.createElement("div"); targetEl.id = "gaze-target"; document.body.appendChild(targetEl); }
    const p = G.clientPoint(yaw, pitch);
    if (!p) return;
    targetEl.style.left = `${p[0]}px`;
    targetEl.style.top = `${p[1]}px`;
    targetEl.hidden = false;
  }

  G.calibrate = async () => {
    if (G.calibrating || !S.view) return null;
    G.calibrating = true;
    G.calibration = null;
    const points = [];
    try {
      for (const target of CAL_TARGETS) {
        G.target = target;
        showTarget(...target);
        await sleep(CAL_SETTLE_MS);
        const got = [];
        G.collect = got;                      // a still pointer is a steady fixation: sampled at 60 Hz too
        const still = setInterval(() => { if (G.lastRaw && G.source !== "off") got.push(G.lastRaw); }, 16);
        await sleep(CAL_COLLECT_MS);
        clearInterval(still);
        G.collect = null;
        if (!got.length && G.lastRaw && G.source !== "off") got.push(G.lastRaw);   // timers throttled: where it rests
        if (got.length) points.push({ target, measured: [median(got.map((a) => a[0])), median(got.map((a) => a[1]))] });
      }
    } finally {
      G.calibrating = false;
      G.target = null;
      if (targetEl) targetEl.hidden = true;
    }
    const matrix = points.length >= 3 ? fit(points) : null;
    if (!matrix) { S.lastStatus = "gaze calibration: too few fixations (look at each target)"; return null; }
    let sq = 0;
    for (const { measured, target } of points) {
      const m = [matrix[0][0] * measured[0] + matrix[0][1] * measured[1] + matrix[0][2],
                 matrix[1][0] * measured[0] + matrix[1][1] * measured[1] + matrix[1][2]];
      sq += (m[0] - target[0]) ** 2 + (m[1] - target[1]) ** 2;
    }
    G.calibration = { matrix, rmsDeg: Math.sqrt(sq / points.length), points: points.length };
    const el = document.getElementById("message");
    if (el) el.textContent = `gaze calibrated on ${points.length} targets: ${G.calibration.rmsDeg.toFixed(2)}° residual`;
    return G.calibration;
  };

  // ---- samples ------------------------------------------------------------------------------
  let lastSentAt = 0, pendingAngles = null, timer = null;
  function measured(angles) {                 // a raw sample of the page's source [yaw, pitch] deg
    G.lastRaw = angles;
    if (G.collect) G.collect.push(angles);
    pendingAngles = corrected(angles);
    const wait = MIN_INTERVAL_MS - (performance.now() - lastSentAt);
    if (wait <= 0) flush();
    else if (!timer) timer = setTimeout(flush, wait);
  }

  function flush() {
    timer = null;
    if (!pendingAngles) return;
    const a = pendingAngles;
    pendingAngles = null;
    if (S.sendControl({ type: "gaze", dir: direction(a[0], a[1]), t: Date.now() / 1000 })) {
      G.sent++;
      G.last = a;
      lastSentAt = performance.now();
    }
  }

  function setSource(source) {
    G.source = source;
    if (source === "off") { pendingAngles = [0, 0]; flush(); }   // eyes straight ahead again
    const b = document.getElementById("gazebutton");
    if (b) b.setAttribute("aria-pressed", String(source !== "off"));
  }
  G.setSource = setSource;

  view().addEventListener("pointermove", (e) => {
    if (G.source !== "mouse" || e.buttons !== 0 || !S.view) return;   // dragging turns the head instead
    const box = imageBox(e.clientX);
    if (!box) return;
    measured(pointToAngles((e.clientX - box[0]) / box[2], (e.clientY - box[1]) / box[2]));
  });
  window.addEventListener("keydown", (e) => {
    if (e.ctrlKey || e.metaKey || e.altKey || e.repeat) return;
    if (e.key === "e") setSource(G.source === "mouse" ? "off" : "mouse");
    else if (e.key === "k") G.calibrate();
  });
  const button = document.getElementById("gazebutton");
  if (button) { button.onclick = () => setSource(G.source === "mouse" ? "off" : "mouse"); button.setAttribute("aria-pressed", String(G.source !== "off")); }
})();
