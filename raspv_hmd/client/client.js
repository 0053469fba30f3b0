// RASPV headset client: shows the phosphene stream, sends head orientation, body motion and
// mode keys back to the bridge (protocol reference: docs/hmd.md). Plain JS, no dependencies.
//
// URL options: ?token=… (required when the bridge is not on loopback), role=watch,
// stereo=1, green=1, format=levels|raw|png (default: levels — the page draws the phosphenes
// itself from one weight per phosphene, levels_renderer.js; raw/png: images), draw=webgl|cpu (how
// the page draws levels; default: WebGL with a graphics processor, else its own thread),
// overlay=0, orientation=1 (phone motion sensors turn the head), refresh=N (present at N Hz: the
// headset's refresh, when the browser's frame callback runs slower than the panel — below).
// Frames: head orientation relative to the avatar base (x forward, y left, z up); roll/pitch/yaw
// in radians, pitch > 0 looks down, yaw > 0 looks left.
"use strict";
(() => {
  const HEADER_BYTES = 40;
  const FORMAT_RAW = 0, FORMAT_PNG = 1, FORMAT_LEVELS = 2;
  const WINDOW = 3;                          // frames in flight before an ack (the page shows the newest; 2 starved a 50 Hz stream at a 60 Hz page)
  const LINEAR = 0.5, ANGULAR = 1.0;         // m/s, rad/s (Shift doubles them)
  const TWIST_PERIOD_MS = 100;               // resend while moving (the bridge stops after 0.5 s)
  const DRAG_RAD_PER_PX = 0.25 * Math.PI / 180;
  const MAX_YAW = Math.PI / 2, MAX_PITCH = Math.PI / 3;
  const STICK_DEADZONE = 0.15, STICK_HEAD_RATE = Math.PI / 2;   // rad/s at full deflection
  const VIEWER_KEYS = new Set("+-*/vVnNoOlLjJ.,123456789tTy".split(""));   // t/T/y: highlight
  const MOVE_KEYS = {
    w: [1, 0], arrowup: [1, 0], s: [-1, 0], arrowdown: [-1, 0],
    a: [0, 1], arrowleft: [0, 1], d: [0, -1], arrowright: [0, -1],
  };

  const params = new URLSearchParams(location.search);
  const $ = (id) => document.getElementById(id);
  let view = $("view");
  // The levels stream unless the URL asks for images; drawn with WebGL where a graphics processor
  // does it, else on the page's thread (WebGL in software costs more than it saves).
  const askedFormat = params.get("format") || "", askedDraw = params.get("draw") || "";
  let levels = null, gpuDraw = false;
  if ((askedFormat === "" || askedFormat === "levels") && window.RaspvLevels) {
    if (askedDraw !== "cpu") {
      const probe = RaspvLevels.contextFor(document.createElement("canvas"));
      const useGl = probe && (askedDraw === "webgl" || RaspvLevels.hardware(probe));
      if (probe) { const lose = probe.getExtension("WEBGL_lose_context"); if (lose) lose.loseContext(); }
      const gl = useGl ? RaspvLevels.contextFor(view) : null;
      try { levels = gl ? RaspvLevels.create(gl) : null; gpuDraw = !!levels; } catch (e) { levels = null; }
      if (gl && !levels) { const fresh = view.cloneNode(true); view.replaceWith(fresh); view = fresh; }
    }
    if (!levels) { levels = RaspvLevels.createCpu(); RaspvLevels.loadKernels("levels_kernels.wasm"); }
  }
  const ctx = gpuDraw ? null : view.getContext("2d", { alpha: false });
  const frameCanvas = document.createElement("canvas");       // the newest decoded image frame
  const frameCtx = frameCanvas.getContext("2d");

  // Everything the page knows; exposed read-only for tests and curious users.
  const S = {
    connected: false, role: null, clientId: null, format: null, closedFor: null,
    stereo: params.get("stereo") === "1", green: params.get("green") === "1",
    framesReceived: 0, framesShown: 0, framesReplaced: 0, lastShownSeq: 0, size: null,
    drawsLevels: !!levels, drawer: levels ? (gpuDraw ? "webgl" : "cpu") : null, drawMs: 0, presentMs: 0,
    get accumulation() { return levels ? levels.accumulation : null; }, spritesMapId: null,
    framesFallback: 0, framesNoData: 0, lastNoData: false, bytesReceived: 0, spritesBytes: 0, localRing: false,
    rttMs: null, ageMs: null, fps: 0, refreshHz: null, twistsSent: 0, headsSent: 0, keysSent: 0,
    head: { roll: 0, pitch: 0, yaw: 0 }, headQuaternion: null, twist: { linear: 0, angular: 0 },
    lastStatus: "", xr: false, orientation: false,
    instructions: null, trialId: null, startedId: null, experimentSent: [],
    view: null, fieldOffset: [0, 0],          // display geometry (bridge "view"); eye gaze: the field's shift [px]
  };
  window.raspvClient = S;
  // the phosphene image the page drew last (levels stream), for tests: {width, height, pixels, seq, stamp}
  S.readImage = () => {
    if (!levels || !readyMeta || readyMeta.fmt !== FORMAT_LEVELS) return null;
    const img = levels.readImage();
    return img && Object.assign(img, { seq: readyMeta.seq, stamp: readyMeta.stamp, pixels: Array.from(img.pixels) });
  };

  S.sendControl = (obj) => { if (S.role !== "control") return false; send(obj); return true; };   // gaze.js
  // what the view canvas shows (the page's own drawer): grey rows of the first eye, for tests
  S.readShown = () => {
    if (!ctx || !levels || !levels.sprites) return null;
    const w = levels.sprites.width, h = levels.sprites.height, d = ctx.getImageData(0, 0, w, h).data;
    const pixels = new Array(w * h);
    for (let i = 0; i < w * h; i++) pixels[i] = Math.max(d[4 * i], d[4 * i + 1], d[4 * i + 2]);
    return { width: w, height: h, pixels, seq: readyMeta ? readyMeta.seq : 0, offset: S.fieldOffset };
  };

  const JITTER_FRAMES = Math.max(1, Math.round(Number(params.get("jitter"))) || 2);   // frames held for the next animation frames (onFrame)
  let ws = null, pending = [], behind = 0, decoding = false, readySeq = 0, readyMeta = null;
  let headDirty = false, lastTwistSent = 0, xrSession = null, xrGl = null;
  let clockOffset = null, bestRtt = Infinity;
  const rtts = [];
  const keysDown = new Set();
  let shift = false, stickHead = [0, 0], stickBody = [0, 0], lastTick = performance.now();
  // The presentation clock. By default the browser's frame callback: a WebXR session's frames run
  // at the headset's refresh, a flat page's at its monitor's. ?refresh=N presents on a clock of N Hz
  // of its own (e.g. 90: a headset's refresh) for a browser whose frame callback is slower than the
  // panel — headless chromium calls back at 60 Hz; with --disable-frame-rate-limit it composites
  // each drawn frame at once. S.fps counts frames the browser *composited* either way: with the
  // clock a drawn frame counts at the frame callback that follows it, two draws before one
  // callback count once (so a browser that cannot keep N shows its own rate, not N).
  const REFRESH_HZ = Math.min(240, Math.max(0, Number(params.get("refresh")) || 0));
  S.refreshHz = REFRESH_HZ || null;

  // ---- connection -------------------------------------------------------------------------
  function connect() {
    const scheme = location.protocol === "https:" ? "wss:" : "ws:";
    ws = new WebSocket(`${scheme}//${location.host}/ws`);
    ws.binaryType = "arraybuffer";
    setState("connecting…", "");
    ws.onopen = () => {
      send({ type: "hello", protocol: 1, token: params.get("token") || "", name: navigator.userAgent.slice(0, 60),
             role: params.get("role") === "watch" ? "watch" : "control",
             format: levels ? "levels" : (askedFormat || "auto"), window: WINDOW });
    };
    ws.onmessage = (ev) => (typeof ev.data === "string" ? onText(ev.data) : onFrame(ev.data));
    ws.onclose = () => {
      S.connected = false; S.role = null;
      if (S.closedFor) { setState(`disconnected: ${S.closedFor}`, "bad"); return; }
      setState("disconnected — retrying", "bad");
      setTimeout(connect, 1000);
    };
  }

  function send(obj) {
    if (ws && ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify(obj));
  }

  function onText(text) {
    let m;
    try { m = JSON.parse(text); } catch (e) { return; }
    if (m.type === "welcome") {
      S.connected = true; S.clientId = m.client_id; S.format = m.format; setRole(m.role);
    } else if (m.type === "role") {
      setRole(m.role);
    } else if (m.type === "pong") {
      const now = performance.now(), rtt = now - m.t;
      rtts.push(rtt); if (rtts.length > 10) rtts.shift();
      S.rttMs = median(rtts);
      if (rtt <= bestRtt * 1.5 || clockOffset === null) {      // NTP-style offset from a fast exchange
        bestRtt = Math.min(bestRtt, rtt);
        clockOffset = m.server_time - (Date.now() - rtt / 2) / 1000;
      }
    } else if (m.type === "status") {
      showMessage(m.text, m.ok !== false);
    } else if (m.type === "refused") {
      showMessage(`refused (${m.code}): ${m.reason}`, false);
    } else if (m.type === "instructions") {
      showInstructions(m);
    } else if (m.type === "view") {
      S.view = m;                                           // where gaze directions land on the display
    } else if (m.type === "cues") {
      if (window.raspvAudio) window.raspvAudio.update(m);     // audio_cues.js
    } else if (m.type === "bye") {
      if (/token|full/.test(m.reason)) S.closedFor = m.reason;
      showMessage(`server: ${m.reason}`, false);
    }
  }

  function setRole(role) {
    S.role = role;
    setState(role === "control" ? "connected — controlling" : "connected — watching", role === "control" ? "ok" : "watch");
  }

  let lastSprites = null, lastLevelsFrame = null;
  function onFrame(buf) {
    if (levels && buf.byteLength >= 4 && String.fromCharCode(...new Uint8Array(buf, 0, 4)) === RaspvLevels.SPRITES_MAGIC) {
      const sp = RaspvLevels.parseSprites(buf);          // the sprite atlas of a new map (once per map)
      if (!sp) { showMessage("a sprites message could not be read", false); return; }
      lastSprites = sp;
      S.spritesBytes += buf.byteLength;
      levels.setSprites(sp);
      S.spritesMapId = sp.mapId;
      return;
    }
    if (buf.byteLength < HEADER_BYTES) return;
    S.framesReceived++;
    S.bytesReceived += buf.byteLength;
    // Frames wait for the page's next animation frame in a queue of JITTER_FRAMES: two that
    // arrive within one display interval (a late timer, a busy core) are both shown, on consecutive
    // animation frames, instead of the first being replaced unseen; when the page falls behind for
    // longer, the oldest are dropped, so a frame never waits more than that many intervals.
    pending.push(buf);
    while (pending.length > JITTER_FRAMES) { pending.shift(); S.framesReplaced++; }
  }

  // ---- decoding ---------------------------------------------------------------------------
  const GREY = new Uint32Array(256), GREEN = new Uint32Array(256);
  for (let v = 0; v < 256; v++) { GREY[v] = 0xff000000 | (v << 16) | (v << 8) | v; GREEN[v] = 0xff000000 | (v << 8); }

  function decodePending() {
    if (!pending.length || decoding) return;
    behind = pending.length > 1 ? behind + 1 : 0;
    if (behind > JITTER_FRAMES) { S.framesReplaced += pending.length - 1; pending.splice(0, pending.length - 1); behind = 0; }
    const buf = pending.shift();
    const dv = new DataView(buf);
    const magic = String.fromCharCode(...new Uint8Array(buf, 0, 4));
    if (magic !== "RSPV") return;
    const fmt = dv.getUint8(5), channels = dv.getUint8(6), greenFrame = (dv.getUint8(7) & 1) === 1;
    const w = dv.getUint32(8, true), h = dv.getUint32(12, true), seq = dv.getUint32(16, true);
    const n = dv.getUint32(20, true), stamp = dv.getFloat64(24, true), sent = dv.getFloat64(32, true);
    const meta = { seq, w, h, stamp, sent, fmt };
    const green = S.green || greenFrame;
    if (fmt === FORMAT_LEVELS) {
      if (!levels) return;
      const frame = RaspvLevels.parseFrame(buf, HEADER_BYTES);
      if (!gpuDraw) levels.green = green;
      const t0 = performance.now();
      if (!frame || !levels.draw(frame)) return;        // drawn into the page's phosphene image
      S.drawMs = 0.9 * S.drawMs + 0.1 * (performance.now() - t0);
      lastLevelsFrame = frame;
      meta.green = greenFrame;
      meta.offset = frame.fieldOffset;
      S.fieldOffset = frame.fieldOffset;
      S.size = `${w}×${h}`;
      S.lastNoData = frame.noData;
      if (frame.noData) S.framesNoData++;
      else if (frame.fallback) S.framesFallback++;
      ready(meta);
    } else if (fmt === FORMAT_RAW) {
      if (n !== w * h * channels) return;
      setFrameSize(w, h);
      const img = frameCtx.createImageData(w, h);
      const out = new Uint32Array(img.data.buffer), src = new Uint8Array(buf, HEADER_BYTES, n);
      if (channels === 1) {
        const lut = green ? GREEN : GREY;
        for (let i = 0; i < out.length; i++) out[i] = lut[src[i]];
      } else {
        const g = green;
        for (let i = 0, j = 0; i < out.length; i++, j += 3) {
          out[i] = g ? 0xff000000 | (src[j + 1] << 8) : 0xff000000 | (src[j + 2] << 16) | (src[j + 1] << 8) | src[j];
        }
      }
      frameCtx.putImageData(img, 0, 0);
      ready(meta);
    } else if (fmt === FORMAT_PNG) {
      decoding = true;
      createImageBitmap(new Blob([new Uint8Array(buf, HEADER_BYTES, n)], { type: "image/png" })).then((bmp) => {
        setFrameSize(w, h);
        frameCtx.globalCompositeOperation = "copy";
        frameCtx.drawImage(bmp, 0, 0);
        bmp.close();
        if (green) {                              // keep only the green channel
          frameCtx.globalCompositeOperation = "multiply";
          frameCtx.fillStyle = "#00ff00";
          frameCtx.fillRect(0, 0, w, h);
        }
        frameCtx.globalCompositeOperation = "source-over";
        ready(meta);
      }).catch(() => showMessage("a PNG frame could not be decoded", false))
        .finally(() => { decoding = false; });
    }
  }

  function setFrameSize(w, h) {
    if (frameCanvas.width !== w || frameCanvas.height !== h) { frameCanvas.width = w; frameCanvas.height = h; }
    S.size = `${w}×${h}`;
  }

  let lastFrameAt = performance.now();
  function ready(meta) { readySeq = meta.seq; readyMeta = meta; lastFrameAt = performance.now(); S.localRing = false; }

  // No frame for NO_FRAMES_MS (the bridge or the network gone): never freeze on the last image.
  // With the levels stream the page blinks the no-data ring itself (its phosphenes came with the
  // sprites); with images it goes dark.
  const NO_FRAMES_MS = 500;
  function watchFrames(now) {
    if (now - lastFrameAt < NO_FRAMES_MS || !readyMeta) return;
    if (levels && lastSprites) {
      const frame = RaspvLevels.ringFrame(lastSprites, now);
      if (frame && levels.draw(frame)) {
        S.localRing = true; S.lastNoData = true;
        readyMeta = { seq: readyMeta.seq, w: lastSprites.width, h: lastSprites.height, stamp: readyMeta.stamp,
                      fmt: FORMAT_LEVELS, green: lastSprites.green, local: true };
        lastLevelsFrame = frame;
        viewDirty = true;
        return;
      }
    }
    readyMeta = null;                          // images: dark rather than frozen
    viewDirty = true;
  }

  // ---- drawing ----------------------------------------------------------------------------
  function resize() {
    const dpr = window.devicePixelRatio || 1;
    const w = Math.round(view.clientWidth * dpr), h = Math.round(view.clientHeight * dpr);
    if (view.width !== w || view.height !== h) { view.width = w; view.height = h; }
  }

  function fit(x, y, w, h) {                     // the frame scaled into a box, centred
    const fw = readyMeta ? readyMeta.w : frameCanvas.width, fh = readyMeta ? readyMeta.h : frameCanvas.height;
    const s = Math.min(w / fw, h / fh);
    const dw = fw * s, dh = fh * s;
    return [x + (w - dw) / 2, y + (h - dh) / 2, dw, dh];
  }

  function boxes(width, height) {                  // where the frame goes: one box, or one per eye
    if (!S.stereo) return [fit(0, 0, width, height)];
    return [fit(0, 0, width / 2, height), fit(width / 2, 0, width / 2, height)];
  }

  // The page's own drawing of the levels (no WebGL): the canvas takes the image's size (twice as
  // wide in stereo) and CSS fits it to the window.
  let shiftedBefore = false;
  function presentNative() {
    const sp = levels.sprites, image = levels.image();
    const w = sp.width, h = sp.height, eyes = S.stereo ? 2 : 1;
    if (view.width !== w * eyes || view.height !== h) { view.width = w * eyes; view.height = h; }
    if (!view.classList.contains("native")) view.classList.add("native");
    const [ox, oy] = (readyMeta && readyMeta.offset) || [0, 0];      // eye gaze: the field drawn shifted
    if (ox || oy || shiftedBefore) { ctx.fillStyle = "#000"; ctx.fillRect(0, 0, view.width, view.height); }
    shiftedBefore = !!(ox || oy);
    for (let e = 0; e < eyes; e++) {
      if (!ox && !oy) ctx.putImageData(image, e * w, 0);
      else if (Math.abs(ox) < w && Math.abs(oy) < h) {
        ctx.putImageData(image, e * w + ox, oy, Math.max(0, -ox), Math.max(0, -oy), w - Math.abs(ox), h - Math.abs(oy));
      }
    }
  }

  // boxes [x, y, w, h] of the image → the same moved by the field's offset, clipped to themselves
  function shiftedBoxes(boxes) {
    const o = readyMeta && readyMeta.offset;
    if (!o || (!o[0] && !o[1]) || !readyMeta.w) return boxes;
    return boxes.map(([x, y, w, h]) => { const s = w / readyMeta.w; return [x + o[0] * s, y + o[1] * s, w, h, [x, y, w, h]]; });
  }

  function present() {
    if (readySeq <= S.lastShownSeq && !viewDirty) return;
    viewDirty = false;
    if (!gpuDraw && levels && readyMeta && readyMeta.fmt === FORMAT_LEVELS) {
      const t0 = performance.now();
      presentNative();
      S.presentMs = 0.9 * S.presentMs + 0.1 * (performance.now() - t0);
      shown();
      return;
    }
    if (view.classList.contains("native")) view.classList.remove("native");
    resize();
    if (gpuDraw) {                                // WebGL: the levels image, or an image frame as a texture
      levels.clear(null);
      if (readyMeta) {
        const green = S.green || !!readyMeta.green;
        if (readyMeta.fmt === FORMAT_LEVELS) levels.present(shiftedBoxes(boxes(view.width, view.height)), green, null, view.height);
        else levels.presentImage(frameCanvas, boxes(view.width, view.height), S.green, null, view.height);
      }
      shown();
      return;
    }
    ctx.fillStyle = "#000";
    ctx.fillRect(0, 0, view.width, view.height);
    if (readyMeta) {
      ctx.imageSmoothingEnabled = true;
      if (S.stereo) {
        const half = view.width / 2;
        ctx.drawImage(frameCanvas, ...fit(0, 0, half, view.height));
        ctx.drawImage(frameCanvas, ...fit(half, 0, half, view.height));
      } else {
        ctx.drawImage(frameCanvas, ...fit(0, 0, view.width, view.height));
      }
    }
    shown();
  }

  function shown() {
    if (!readyMeta || readySeq <= S.lastShownSeq) return;
    S.lastShownSeq = readySeq;
    S.framesShown++;
    if (REFRESH_HZ && !xrSession) { drawnSinceComposite = true; if (!compositeWatch) compositeWatch = requestAnimationFrame(composited); }
    else fpsCount++;
    if (clockOffset !== null) S.ageMs = Date.now() - (readyMeta.stamp - clockOffset) * 1000;
    send({ type: "ack", seq: readySeq });
  }
  let viewDirty = true, fpsCount = 0, fpsSince = performance.now(), drawnSinceComposite = false, compositeWatch = 0;
  function composited() {                      // the browser's frame after a draw on the refresh clock
    compositeWatch = 0;
    if (drawnSinceComposite) { drawnSinceComposite = false; fpsCount++; }
  }

  // ---- head -------------------------------------------------------------------------------
  function clamp(v, lo, hi) { return Math.max(lo, Math.min(hi, v)); }

  function setHead(roll, pitch, yaw) {
    S.head = { roll, pitch: clamp(pitch, -MAX_PITCH, MAX_PITCH), yaw: clamp(yaw, -MAX_YAW, MAX_YAW) };
    headDirty = true;
  }

  let drag = null;
  view.addEventListener("pointerdown", (e) => {
    if (S.orientation) return;
    drag = { x: e.clientX, y: e.clientY };
    view.setPointerCapture(e.pointerId);
    view.classList.add("dragging");
    view.focus();
  });
  view.addEventListener("pointermove", (e) => {
    if (!drag) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    drag = { x: e.clientX, y: e.clientY };
    // mouse-look: moving right looks right (yaw decreases), moving down looks down (pitch grows)
    setHead(0, S.head.pitch + dy * DRAG_RAD_PER_PX, S.head.yaw - dx * DRAG_RAD_PER_PX);
  });
  const endDrag = () => { drag = null; view.classList.remove("dragging"); };
  view.addEventListener("pointerup", endDrag);
  view.addEventListener("pointercancel", endDrag);

  // Device orientation (phones in a viewer): W3C Z-X'-Y'' angles → head relative to the heading
  // the phone had when enabled (or at 'r').
  const qmul = (a, b) => [
    a[3] * b[0] + a[0] * b[3] + a[1] * b[2] - a[2] * b[1],
    a[3] * b[1] - a[0] * b[2] + a[1] * b[3] + a[2] * b[0],
    a[3] * b[2] + a[0] * b[1] - a[1] * b[0] + a[2] * b[3],
    a[3] * b[3] - a[0] * b[0] - a[1] * b[1] - a[2] * b[2]];
  const axisAngle = (ax, ay, az, a) => [ax * Math.sin(a / 2), ay * Math.sin(a / 2), az * Math.sin(a / 2), Math.cos(a / 2)];
  const DEVICE_TO_HEAD = [-0.5, 0.5, 0.5, 0.5];    // head x = −device z, y = −device x, z = device y
  let headingOffset = null;

  function orientationQuaternion(alpha, beta, gamma, screenAngle) {
    const d = Math.PI / 180, x = beta * d / 2, y = gamma * d / 2, z = alpha * d / 2;
    const cX = Math.cos(x), cY = Math.cos(y), cZ = Math.cos(z), sX = Math.sin(x), sY = Math.sin(y), sZ = Math.sin(z);
    let q = [sX * cY * cZ - cX * sY * sZ, cX * sY * cZ + sX * cY * sZ, cX * cY * sZ + sX * sY * cZ, cX * cY * cZ - sX * sY * sZ];
    q = qmul(q, axisAngle(0, 0, 1, -screenAngle * d));       // screen rotated to landscape
    return qmul(q, DEVICE_TO_HEAD);                           // earth ← head
  }
  const yawOf = (q) => Math.atan2(2 * (q[3] * q[2] + q[0] * q[1]), 1 - 2 * (q[1] * q[1] + q[2] * q[2]));

  function onOrientation(e) {
    if (!S.orientation || e.alpha === null || e.beta === null || e.gamma === null) return;
    const angle = (screen.orientation && screen.orientation.angle) || window.orientation || 0;
    const q = orientationQuaternion(e.alpha, e.beta, e.gamma, angle);
    if (headingOffset === null) headingOffset = yawOf(q);
    const rel = qmul(axisAngle(0, 0, 1, -headingOffset), q);
    S.headQuaternion = rel;
    sendHead({ type: "head", q: rel });
  }

  async function toggleOrientation() {
    if (!S.orientation && typeof DeviceOrientationEvent.requestPermission === "function") {
      try { if (await DeviceOrientationEvent.requestPermission() !== "granted") return; } catch (e) { return; }
    }
    S.orientation = !S.orientation;
    headingOffset = null;
    S.headQuaternion = null;
    setHead(0, 0, 0);                          // either way, start from straight ahead
    $("orient").setAttribute("aria-pressed", String(S.orientation));
  }

  function sendHead(msg) {
    if (S.role !== "control") return;
    send(msg);
    S.headsSent++;
  }

  // ---- body -------------------------------------------------------------------------------
  function currentTwist() {
    let f = 0, t = 0;
    for (const k of keysDown) { const m = MOVE_KEYS[k]; if (m) { f += m[0]; t += m[1]; } }
    const gain = shift ? 2 : 1;
    let linear = clamp(f, -1, 1) * LINEAR * gain, angular = clamp(t, -1, 1) * ANGULAR * gain;
    if (linear === 0 && angular === 0) { linear = stickBody[0] * LINEAR * 2; angular = stickBody[1] * ANGULAR * 2; }
    return { linear, angular };
  }

  function updateTwist(now) {
    const tw = currentTwist();
    const moving = tw.linear !== 0 || tw.angular !== 0;
    const changed = tw.linear !== S.twist.linear || tw.angular !== S.twist.angular;
    if (S.role === "control" && (changed || (moving && now - lastTwistSent >= TWIST_PERIOD_MS))) {
      send({ type: "twist", linear: tw.linear, angular: tw.angular });
      S.twistsSent++;
      lastTwistSent = now;
    }
    S.twist = tw;
  }

  const dead = (v) => (Math.abs(v) < STICK_DEADZONE ? 0 : v);
  function pollGamepads(dt) {
    stickBody = [0, 0]; stickHead = [0, 0];
    const pads = navigator.getGamepads ? Array.from(navigator.getGamepads()).filter(Boolean) : [];
    if (xrSession) for (const src of xrSession.inputSources) if (src.gamepad) pads.push(src.gamepad);
    for (const p of pads) {
      const xrPad = p.mapping === "xr-standard";
      const [lx, ly] = xrPad ? [p.axes[2] || 0, p.axes[3] || 0] : [p.axes[0] || 0, p.axes[1] || 0];
      if (dead(lx) || dead(ly)) stickBody = [-dead(ly), -dead(lx)];
      if (!xrPad && p.axes.length >= 4 && (dead(p.axes[2]) || dead(p.axes[3]))) stickHead = [dead(p.axes[2]), dead(p.axes[3])];
    }
    if ((stickHead[0] || stickHead[1]) && !S.orientation && !xrSession) {
      setHead(0, S.head.pitch + stickHead[1] * STICK_HEAD_RATE * dt, S.head.yaw - stickHead[0] * STICK_HEAD_RATE * dt);
    }
  }

  // ---- keyboard ---------------------------------------------------------------------------
  window.addEventListener("keydown", (e) => {
    if (e.ctrlKey || e.metaKey || e.altKey) return;
    shift = e.shiftKey;
    const k = e.key.length === 1 ? e.key : e.key.toLowerCase();      // "ArrowUp" → "arrowup"
    if (MOVE_KEYS[k.toLowerCase()]) { keysDown.add(k.toLowerCase()); e.preventDefault(); return; }
    if (e.repeat) return;
    if (k === "enter" && S.instructions && S.instructions.waiting) { startTrial(); e.preventDefault(); return; }
    if (k === "escape" && S.trialId) { experiment("abort", S.trialId); S.trialId = null; e.preventDefault(); return; }
    if (k === " ") { keysDown.clear(); e.preventDefault(); return; }
    if (VIEWER_KEYS.has(k)) {
      if (S.role === "control") { send({ type: "key", key: k }); S.keysSent++; } else showMessage("watching: keys go to the controlling client", false);
      e.preventDefault(); return;
    }
    if (k === "g") toggle("green");
    else if (k === "x") toggle("stereo");
    else if (k === "f") fullscreen();
    else if (k === "h") toggleHelp();
    else if (k === "r") { headingOffset = null; setHead(0, 0, 0); }
    else if (k === "c") send({ type: "control", want: S.role !== "control" });
  });
  window.addEventListener("keyup", (e) => {
    shift = e.shiftKey;
    keysDown.delete(e.key.toLowerCase());
  });
  window.addEventListener("blur", () => keysDown.clear());      // never keep walking unattended

  function toggle(name) {
    S[name] = !S[name];
    $(name).setAttribute("aria-pressed", String(S[name]));
    viewDirty = true;                          // green applies from the next decoded frame
  }
  function toggleHelp() { $("help").hidden = !$("help").hidden; }

  // ---- experiments: instructions, start and abort (docs/experiments.md) -------------------------
  function showInstructions(m) {
    S.instructions = { id: m.id || "", title: m.title || "", text: m.text || "", waiting: !!m.waiting };
    if (!m.waiting && m.id && S.startedId === m.id) S.trialId = m.id;     // the trial we started runs
    $("instructions-title").textContent = S.instructions.title;
    $("instructions-text").textContent = S.instructions.text;
    $("instructions-start").hidden = !S.instructions.waiting;
    $("instructions").hidden = !(S.instructions.waiting || S.instructions.text);
  }
  function experiment(action, id) {
    if (S.role !== "control") { showMessage("watching: only the controlling client starts trials", false); return; }
    send({ type: "experiment", action, id });
    S.experimentSent.push(action);
  }
  function startTrial() {
    if (!S.instructions || !S.instructions.waiting) return;
    experiment("start", S.instructions.id);
    S.startedId = S.instructions.id;
    S.trialId = S.instructions.id;
    $("instructions-start").hidden = true;
  }
  $("instructions-start").onclick = startTrial;
  function fullscreen() {
    if (document.fullscreenElement) document.exitFullscreen(); else document.documentElement.requestFullscreen().catch(() => {});
  }

  // ---- WebXR ------------------------------------------------------------------------------
  async function setupXR() {
    if (!navigator.xr || !navigator.xr.isSessionSupported) return;
    try { if (!(await navigator.xr.isSessionSupported("immersive-vr"))) return; } catch (e) { return; }
    $("vr").hidden = false;
  }

  async function enterXR() {
    if (xrSession) { xrSession.end(); return; }
    try {
      const session = await navigator.xr.requestSession("immersive-vr", { optionalFeatures: ["local"] });
      const glCanvas = document.createElement("canvas");
      const gl = glCanvas.getContext(levels ? "webgl2" : "webgl", { xrCompatible: true, alpha: false });
      if (!gl) throw new Error("no WebGL");
      session.updateRenderState({ baseLayer: new XRWebGLLayer(session, gl) });
      const space = await session.requestReferenceSpace("local");
      // the levels stream is drawn in the XR context too (textures are not shared between contexts)
      const xrLevels = levels && gpuDraw ? RaspvLevels.create(gl) : null;
      let xrSprites = null, xrDrawn = null;
      xrGl = xrLevels ? null : makeQuadRenderer(gl);
      xrSession = session; S.xr = true;
      $("vr").textContent = "Exit VR";
      session.addEventListener("end", () => { xrSession = null; xrGl = null; S.xr = false; S.headQuaternion = null; $("vr").textContent = "Enter VR"; startLoop(); });
      const onXRFrame = (t, frame) => {
        if (!xrSession) return;
        session.requestAnimationFrame(onXRFrame);
        const pose = frame.getViewerPose(space);
        if (pose) {
          const o = pose.transform.orientation;
          sendHead({ type: "head", q: [o.x, o.y, o.z, o.w], frame: "xr" });      // every XR frame
          S.headQuaternion = [-o.z, -o.x, o.y, o.w];                           // base convention
        }
        step(t);
        const layer = session.renderState.baseLayer;
        gl.bindFramebuffer(gl.FRAMEBUFFER, layer.framebuffer);
        gl.clearColor(0, 0, 0, 1); gl.clear(gl.COLOR_BUFFER_BIT);
        if (readyMeta && pose) {
          const eyes = pose.views.map((v) => layer.getViewport(v));
          if (xrLevels) {
            const H = layer.framebufferHeight || gl.drawingBufferHeight;
            const toBoxes = () => eyes.map((vp) => [vp.x, H - vp.y - vp.height, vp.width, vp.height]);
            if (readyMeta.fmt === FORMAT_LEVELS && lastLevelsFrame) {
              if (xrSprites !== lastSprites) { xrLevels.setSprites(lastSprites); xrSprites = lastSprites; }
              if (xrDrawn !== lastLevelsFrame) { xrLevels.draw(lastLevelsFrame); xrDrawn = lastLevelsFrame; }
              xrLevels.present(shiftedBoxes(toBoxes()), S.green || !!readyMeta.green, layer.framebuffer, H);
            } else {
              xrLevels.presentImage(frameCanvas, toBoxes(), S.green, layer.framebuffer, H);
            }
          } else {
            if (readyMeta.fmt === FORMAT_LEVELS && levels) paintFrameCanvas();   // the page's own drawing
            xrGl.upload(frameCanvas);
            for (const vp of eyes) xrGl.draw(vp.x, vp.y, vp.width, vp.height);
          }
        }
        shown();
      };
      session.requestAnimationFrame(onXRFrame);
    } catch (e) {
      showMessage(`VR session failed: ${e.message || e}`, false);
    }
  }

  function paintFrameCanvas() {                // the page-drawn levels image into frameCanvas (XR upload)
    const sp = levels.sprites;
    setFrameSize(sp.width, sp.height);
    const [ox, oy] = (readyMeta && readyMeta.offset) || [0, 0];      // eye gaze: the field drawn shifted
    frameCtx.fillStyle = "#000"; frameCtx.fillRect(0, 0, sp.width, sp.height);
    if (Math.abs(ox) < sp.width && Math.abs(oy) < sp.height) {
      frameCtx.putImageData(levels.image(), ox, oy, Math.max(0, -ox), Math.max(0, -oy), sp.width - Math.abs(ox), sp.height - Math.abs(oy));
    }
  }

  function makeQuadRenderer(gl) {              // one textured quad filling each eye's viewport
    const sh = (type, src) => { const s = gl.createShader(type); gl.shaderSource(s, src); gl.compileShader(s); return s; };
    const prog = gl.createProgram();
    gl.attachShader(prog, sh(gl.VERTEX_SHADER, "attribute vec2 p; varying vec2 uv; void main(){ uv = vec2(p.x + 1.0, 1.0 - p.y) * 0.5; gl_Position = vec4(p, 0.0, 1.0); }"));
    gl.attachShader(prog, sh(gl.FRAGMENT_SHADER, "precision mediump float; varying vec2 uv; uniform sampler2D t; void main(){ gl_FragColor = texture2D(t, uv); }"));
    gl.linkProgram(prog);
    const buf = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, buf);
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 1, -1, -1, 1, 1, 1]), gl.STATIC_DRAW);
    const tex = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, tex);
    for (const [k, v] of [[gl.TEXTURE_MIN_FILTER, gl.LINEAR], [gl.TEXTURE_MAG_FILTER, gl.LINEAR], [gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE], [gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE]]) gl.texParameteri(gl.TEXTURE_2D, k, v);
    let uploaded = 0;
    return {
      upload(source) {
        if (uploaded === readySeq) return;
        gl.bindTexture(gl.TEXTURE_2D, tex);
        gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA, gl.RGBA, gl.UNSIGNED_BYTE, source);
        uploaded = readySeq;
      },
      draw(x, y, w, h) {
        gl.viewport(x, y, w, h);
        gl.useProgram(prog);
        gl.bindBuffer(gl.ARRAY_BUFFER, buf);
        const loc = gl.getAttribLocation(prog, "p");
        gl.enableVertexAttribArray(loc);
        gl.vertexAttribPointer(loc, 2, gl.FLOAT, false, 0, 0);
        gl.bindTexture(gl.TEXTURE_2D, tex);
        gl.drawArrays(gl.TRIANGLE_STRIP, 0, 4);
      },
    };
  }

  // ---- status -----------------------------------------------------------------------------
  function setState(text, cls) { const el = $("state"); el.textContent = text; el.className = cls; }
  function showMessage(text, ok) { S.lastStatus = text; const el = $("message"); el.textContent = text; el.className = ok ? "" : "bad"; }
  function median(a) { const s = [...a].sort((x, y) => x - y); return s[Math.floor(s.length / 2)]; }

  // The status line changes at most STATUS_MS apart and only when its text does: a text node
  // replaced every frame is a relayout and a repaint of the overlay over the phosphenes each frame.
  const STATUS_MS = 250;
  let statusAt = -Infinity;
  function updateStatus(now) {
    if (now - fpsSince >= 1000) {
      S.fps = fpsCount * 1000 / (now - fpsSince); fpsCount = 0; fpsSince = now;
      // the wearer's page tells the display what it composited: the spv node refuses a rate the
      // page cannot keep, with the reason (raspv_spv/page_presentation.py)
      const refresh = REFRESH_HZ || (xrSession && xrSession.frameRate) || 0;
      if (S.role === "control" && S.connected) send({ type: "presented", fps: Math.round(S.fps * 100) / 100, refresh });
    }
    if (now - statusAt < STATUS_MS) return;
    statusAt = now;
    const parts = [];
    if (S.size) parts.push(`${S.size} ${S.format || ""}`);
    parts.push(`${S.fps.toFixed(1)} fps`);
    if (S.rttMs !== null) parts.push(`RTT ${S.rttMs.toFixed(1)} ms`);
    if (S.ageMs !== null) parts.push(`frame age ${Math.max(0, S.ageMs).toFixed(0)} ms`);
    setText($("rates"), parts.join(" · "));
  }
  function setText(el, text) { if (el.textContent !== text) el.textContent = text; }

  // ---- main loop --------------------------------------------------------------------------
  function step(now) {
    const dt = Math.min(0.1, (now - lastTick) / 1000);
    lastTick = now;
    pollGamepads(dt);
    updateTwist(now);
    if (headDirty && !S.orientation && !xrSession) {
      sendHead({ type: "head", rpy: [S.head.roll, S.head.pitch, S.head.yaw] });
      headDirty = false;
    }
    decodePending();
    watchFrames(now);
    updateStatus(now);
  }

  function tick(now) {
    if (xrSession) return;                    // the XR frame loop takes over
    step(now);
    present();
    requestAnimationFrame(tick);
  }

  // ?refresh=N: the same on a clock of N Hz, phase-locked (a late callback does not shift the
  // ones after it; one later than a whole period starts the clock again from now)
  let refreshAt = 0;
  function refreshTick() {
    if (xrSession) return;
    const now = performance.now(), period = 1000 / REFRESH_HZ;
    step(now);
    present();
    refreshAt = refreshAt + period > now ? refreshAt + period : now + period;
    setTimeout(refreshTick, Math.max(0, refreshAt - performance.now()));
  }

  function startLoop() {
    if (REFRESH_HZ) { refreshAt = performance.now(); setTimeout(refreshTick, 0); }
    else requestAnimationFrame(tick);
  }

  setInterval(() => send({ type: "ping", t: performance.now() }), 1000);
  window.addEventListener("resize", () => { viewDirty = true; });
  window.addEventListener("deviceorientation", onOrientation);
  if (params.get("overlay") === "0") document.body.classList.add("hide-overlay");
  $("stereo").setAttribute("aria-pressed", String(S.stereo));
  $("green").setAttribute("aria-pressed", String(S.green));
  $("stereo").onclick = () => toggle("stereo");
  $("green").onclick = () => toggle("green");
  $("fullscreen").onclick = fullscreen;
  $("helpbutton").onclick = toggleHelp;
  $("vr").onclick = enterXR;
  if ("DeviceOrientationEvent" in window && (navigator.maxTouchPoints > 0 || params.get("orientation") === "1")) {
    $("orient").hidden = false;
    $("orient").onclick = toggleOrientation;
    if (params.get("orientation") === "1") toggleOrientation();
  }
  setupXR();
  connect();
  startLoop();
  view.focus();
})();
