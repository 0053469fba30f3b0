// RASPV levels stream: the page draws the phosphenes (raspv_spv/sprite_atlas.py is the reference).
//
// The bridge sends the sprite atlas once per phosphene map (every sprite as a patch of one
// half-float texture) and then, per frame, one weight per phosphene. Each frame is drawn as the
// server's renderer draws it: every lit sprite's patch times its weight, summed in floats on the
// coarse grid (and at full resolution for the fine sprites), the coarse sum upsampled
// bilinearly (half-pixel centres, edges clamped: OpenCV's INTER_LINEAR), the two added, rounded
// and saturated to 8 bits. Two drawers with one interface (setSprites, draw, readImage):
//  - create(gl): WebGL 2, for a browser with a graphics processor (the sums in a float
//    framebuffer, presented as a texture: fitted, stereo, green);
//  - createCpu(): typed arrays on the page's own thread, for a browser that renders WebGL in
//    software (SwiftShader, llvmpipe: there every WebGL frame costs a read-back to the
//    compositor, measured 76 % of a core for 22 frames/s on this 2-core machine). The image
//    goes to a 2D canvas of its own size with putImageData; CSS scales it.
"use strict";
window.RaspvLevels = (() => {
  const SPRITES_MAGIC = "RSPS", SPRITES_HEADER = 44, LEVELS_HEADER = 12, WEIGHT_SCALE = 16384;
  const FRAME_FALLBACK = 1, FRAME_NO_DATA = 2, FRAME_OFFSET = 4;

  function contextFor(canvas, options) {
    const gl = canvas.getContext("webgl2", Object.assign({ alpha: false, antialias: false, depth: false,
      preserveDrawingBuffer: false }, options || {}));
    if (!gl || !gl.getExtension("EXT_color_buffer_float")) return null;
    return gl;
  }

  function parseSprites(buf) {
    if (buf.byteLength < SPRITES_HEADER) return null;
    const dv = new DataView(buf);
    if (String.fromCharCode(...new Uint8Array(buf, 0, 4)) !== SPRITES_MAGIC) return null;
    const u32 = (o) => dv.getUint32(o, true);
    const sp = { levels: dv.getUint8(5), green: (dv.getUint8(6) & 1) === 1, numLevels: dv.getUint8(7),
      mapId: u32(8), width: u32(12), height: u32(16), scale: u32(20), coarseW: u32(24), coarseH: u32(28),
      count: u32(32), atlasW: u32(36), atlasH: u32(40) };
    const tableBytes = 32 * sp.count, atlasBytes = 2 * sp.atlasW * sp.atlasH;
    const ringAt = SPRITES_HEADER + tableBytes + atlasBytes;
    if (buf.byteLength < ringAt + 4) return null;
    const ringN = dv.getUint32(ringAt, true);
    if (buf.byteLength !== ringAt + 4 + ringN) return null;
    sp.patches = new Int32Array(buf.slice(SPRITES_HEADER, SPRITES_HEADER + tableBytes));
    sp.atlas = new Uint16Array(buf.slice(SPRITES_HEADER + tableBytes, ringAt));
    sp.ring = new Uint8Array(buf.slice(ringAt + 4));      // the no-data ring's phosphenes (may be empty)
    return sp;
  }

  function parseFrame(buf, offset) {                 // the payload after the frame header
    const dv = new DataView(buf, offset);
    if (dv.byteLength < LEVELS_HEADER) return null;
    const mapId = dv.getUint32(0, true), count = dv.getUint32(4, true), levels = dv.getUint8(8), flags = dv.getUint8(9);
    const shifted = (flags & FRAME_OFFSET) !== 0;           // eye gaze: the field drawn shifted (i16 dx, dy at the end)
    const need = LEVELS_HEADER + 2 * count + (levels > 1 ? count : 0) + (shifted ? 4 : 0);
    if (dv.byteLength !== need) return null;
    const start = offset + LEVELS_HEADER;
    const weights = new Uint16Array(buf.slice(start, start + 2 * count));
    const spriteLevels = levels > 1 ? new Uint8Array(buf, start + 2 * count, count) : null;
    const fieldOffset = shifted ? [dv.getInt16(need - 4, true), dv.getInt16(need - 2, true)] : [0, 0];
    return { mapId, count, levels, flags, weights, spriteLevels, fieldOffset,
             noData: (flags & FRAME_NO_DATA) !== 0, fallback: (flags & FRAME_FALLBACK) !== 0 };
  }

  function program(gl, vs, fs) {
    const sh = (type, src) => {
      const s = gl.createShader(type); gl.shaderSource(s, src); gl.compileShader(s);
      if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
      return s;
    };
    const p = gl.createProgram();
    gl.attachShader(p, sh(gl.VERTEX_SHADER, vs)); gl.attachShader(p, sh(gl.FRAGMENT_SHADER, fs));
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
    return p;
  }

  const SPRITE_VS = `#version 300 es
    in vec2 corner; in vec4 rect; in vec2 atlasAt; in float weight;
    uniform vec2 gridSize;
    out vec2 texel; out float w;
    void main() {
      vec2 p = rect.xy + corner * rect.zw;          // grid px; framebuffer row = image row
      texel = atlasAt + corner * rect.zw; w = weight;
      gl_Position = vec4(p / gridSize * 2.0 - 1.0, 0.0, 1.0);
    }`;
  const SPRITE_FS = `#version 300 es
    precision highp float; precision highp sampler2D;
    in vec2 texel; in float w; uniform sampler2D atlas; out vec4 colour;
    void main() { colour = vec4(texelFetch(atlas, ivec2(floor(texel)), 0).r * w, 0.0, 0.0, 1.0); }`;
  const FULL_VS = `#version 300 es
    const vec2 P[3] = vec2[3](vec2(-1.0, -1.0), vec2(3.0, -1.0), vec2(-1.0, 3.0));
    void main() { gl_Position = vec4(P[gl_VertexID], 0.0, 1.0); }`;
  const COMPOSE_FS = `#version 300 es
    precision highp float; precision highp sampler2D;
    uniform sampler2D coarse; uniform sampler2D fine; uniform float scale; uniform bool hasFine;
    out vec4 colour;
    void main() {
      ivec2 d = ivec2(gl_FragCoord.xy);                // image pixel (column, row)
      ivec2 size = textureSize(coarse, 0);
      vec2 s = (vec2(d) + 0.5) / scale - 0.5;          // INTER_LINEAR source position
      vec2 f = s - floor(s);
      ivec2 a = ivec2(floor(s));
      ivec2 lo = clamp(a, ivec2(0), size - 1), hi = clamp(a + 1, ivec2(0), size - 1);
      if (a.x < 0) f.x = 0.0;
      if (a.y < 0) f.y = 0.0;
      float v = mix(mix(texelFetch(coarse, ivec2(lo.x, lo.y), 0).r, texelFetch(coarse, ivec2(hi.x, lo.y), 0).r, f.x),
                    mix(texelFetch(coarse, ivec2(lo.x, hi.y), 0).r, texelFetch(coarse, ivec2(hi.x, hi.y), 0).r, f.x), f.y);
      if (hasFine) v += texelFetch(fine, d, 0).r;
      float g = clamp(floor(v + 0.5), 0.0, 255.0) / 255.0;
      colour = vec4(g, g, g, 1.0);
    }`;
  // texture row 0 (the image's top row, as drawn above or uploaded from a canvas) at the box's top
  const PRESENT_VS = `#version 300 es
    const vec2 P[4] = vec2[4](vec2(-1.0, -1.0), vec2(1.0, -1.0), vec2(-1.0, 1.0), vec2(1.0, 1.0));
    out vec2 uv;
    void main() { vec2 p = P[gl_VertexID]; uv = vec2(p.x + 1.0, 1.0 - p.y) * 0.5; gl_Position = vec4(p, 0.0, 1.0); }`;
  const PRESENT_FS = `#version 300 es
    precision mediump float; in vec2 uv; uniform sampler2D image; uniform bool green; out vec4 colour;
    void main() { vec4 c = texture(image, uv); colour = green ? vec4(0.0, c.g, 0.0, 1.0) : vec4(c.rgb, 1.0); }`;

  function create(gl) {
    const blendable32 = !!gl.getExtension("EXT_float_blend");
    const ACC = blendable32 ? gl.R32F : gl.R16F;       // accumulation: float32 where it can blend, else half
    const sprite = program(gl, SPRITE_VS, SPRITE_FS);
    const compose = program(gl, FULL_VS, COMPOSE_FS);
    const present = program(gl, PRESENT_VS, PRESENT_FS);
    const corners = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, corners);
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([0, 0, 1, 0, 0, 1, 1, 1]), gl.STATIC_DRAW);
    const instances = gl.createBuffer();
    const vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    const loc = (n) => gl.getAttribLocation(sprite, n);
    gl.bindBuffer(gl.ARRAY_BUFFER, corners);
    gl.enableVertexAttribArray(loc("corner"));
    gl.vertexAttribPointer(loc("corner"), 2, gl.FLOAT, false, 0, 0);
    gl.bindBuffer(gl.ARRAY_BUFFER, instances);
    for (const [name, size, off] of [["rect", 4, 0], ["atlasAt", 2, 16], ["weight", 1, 24]]) {
      gl.enableVertexAttribArray(loc(name));
      gl.vertexAttribPointer(loc(name), size, gl.FLOAT, false, 28, off);
      gl.vertexAttribDivisor(loc(name), 1);
    }
    gl.bindVertexArray(null);
    const emptyVao = gl.createVertexArray();
    let sp = null, atlasTex = null, grids = [], image = null, colToPatch = null, buffers = [], drawn = 0;
    const upload = gl.createTexture();                  // image frames (fallback), presented the same way

    function texture(internal, format, type, w, h, data, filter) {
      const t = gl.createTexture();
      gl.bindTexture(gl.TEXTURE_2D, t);
      gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
      gl.texImage2D(gl.TEXTURE_2D, 0, internal, w, h, 0, format, type, data);
      for (const [k, v] of [[gl.TEXTURE_MIN_FILTER, filter], [gl.TEXTURE_MAG_FILTER, filter],
        [gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE], [gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE]]) gl.texParameteri(gl.TEXTURE_2D, k, v);
      return t;
    }
    function target(internal, format, type, w, h, filter) {
      const tex = texture(internal, format, type, w, h, null, filter);
      const fb = gl.createFramebuffer();
      gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
      gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, tex, 0);
      if (gl.checkFramebufferStatus(gl.FRAMEBUFFER) !== gl.FRAMEBUFFER_COMPLETE) throw new Error("framebuffer incomplete");
      gl.bindFramebuffer(gl.FRAMEBUFFER, null);
      return { tex, fb, w, h };
    }
    function release() {
      for (const t of [atlasTex, image && image.tex, ...grids.map((g) => g && g.tex)]) if (t) gl.deleteTexture(t);
      for (const f of [image && image.fb, ...grids.map((g) => g && g.fb)]) if (f) gl.deleteFramebuffer(f);
      grids = []; image = null; atlasTex = null;
    }

    function setSprites(s) {
      release();
      sp = s;
      atlasTex = texture(gl.R16F, gl.RED, gl.HALF_FLOAT, s.atlasW, s.atlasH, s.atlas, gl.NEAREST);
      grids = [target(ACC, gl.RED, gl.FLOAT, s.coarseW, s.coarseH, gl.NEAREST), null];
      colToPatch = new Int32Array(maxColumn(s) + 1).fill(-1);
      let fine = false;
      for (let p = 0; p < s.count; p++) { colToPatch[s.patches[8 * p]] = p; fine = fine || s.patches[8 * p + 1] === 1; }
      grids[1] = fine ? target(ACC, gl.RED, gl.FLOAT, s.width, s.height, gl.NEAREST) : null;
      image = target(gl.RGBA8, gl.RGBA, gl.UNSIGNED_BYTE, s.width, s.height, gl.LINEAR);
      buffers = [new Float32Array(7 * s.count), new Float32Array(7 * s.count)];
    }
    function maxColumn(s) { let m = 0; for (let p = 0; p < s.count; p++) m = Math.max(m, s.patches[8 * p]); return m; }

    function draw(frame) {                              // → false when the frame is not of these sprites
      if (!sp || frame.mapId !== sp.mapId) return false;
      const n = [0, 0], P = sp.patches, W = frame.weights, L = sp.levels, SL = frame.spriteLevels;
      for (let i = 0; i < frame.count; i++) {
        const w = W[i];
        if (w === 0) continue;
        let col = i;
        if (L > 1) { const l = SL ? SL[i] : 0; if (l === 0) continue; col = i * L + Math.min(l, L) - 1; }
        const p = col < colToPatch.length ? colToPatch[col] : -1;
        if (p < 0) continue;
        const g = P[8 * p + 1], b = buffers[g], o = 7 * n[g]++;
        b[o] = P[8 * p + 2]; b[o + 1] = P[8 * p + 3]; b[o + 2] = P[8 * p + 4]; b[o + 3] = P[8 * p + 5];
        b[o + 4] = P[8 * p + 6]; b[o + 5] = P[8 * p + 7]; b[o + 6] = w / WEIGHT_SCALE;
      }
      gl.disable(gl.DEPTH_TEST); gl.disable(gl.SCISSOR_TEST);
      gl.useProgram(sprite);
      gl.activeTexture(gl.TEXTURE0); gl.bindTexture(gl.TEXTURE_2D, atlasTex);
      gl.uniform1i(gl.getUniformLocation(sprite, "atlas"), 0);
      gl.enable(gl.BLEND); gl.blendFunc(gl.ONE, gl.ONE); gl.blendEquation(gl.FUNC_ADD);
      gl.bindVertexArray(vao);
      for (const g of [0, 1]) {
        const t = grids[g];
        if (!t) continue;
        gl.bindFramebuffer(gl.FRAMEBUFFER, t.fb);
        gl.viewport(0, 0, t.w, t.h);
        gl.clearColor(0, 0, 0, 0); gl.clear(gl.COLOR_BUFFER_BIT);
        if (!n[g]) continue;
        gl.bindBuffer(gl.ARRAY_BUFFER, instances);
        gl.bufferData(gl.ARRAY_BUFFER, buffers[g].subarray(0, 7 * n[g]), gl.STREAM_DRAW);
        gl.uniform2f(gl.getUniformLocation(sprite, "gridSize"), t.w, t.h);
        gl.drawArraysInstanced(gl.TRIANGLE_STRIP, 0, 4, n[g]);
      }
      gl.bindVertexArray(emptyVao);
      gl.disable(gl.BLEND);
      gl.bindFramebuffer(gl.FRAMEBUFFER, image.fb);
      gl.viewport(0, 0, image.w, image.h);
      gl.useProgram(compose);
      gl.activeTexture(gl.TEXTURE0); gl.bindTexture(gl.TEXTURE_2D, grids[0].tex);
      gl.activeTexture(gl.TEXTURE1); gl.bindTexture(gl.TEXTURE_2D, grids[1] ? grids[1].tex : grids[0].tex);
      gl.uniform1i(gl.getUniformLocation(compose, "coarse"), 0);
      gl.uniform1i(gl.getUniformLocation(compose, "fine"), 1);
      gl.uniform1f(gl.getUniformLocation(compose, "scale"), sp.scale);
      gl.uniform1i(gl.getUniformLocation(compose, "hasFine"), grids[1] ? 1 : 0);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
      gl.bindFramebuffer(gl.FRAMEBUFFER, null);
      gl.activeTexture(gl.TEXTURE0);
      drawn = n[0] + n[1];
      return true;
    }

    // Show a texture in boxes [x, y, w, h] (px from the top-left) of the framebuffer ``fb`` (null:
    // the canvas) of height ``fbHeight``; a box's optional 5th element [x, y, w, h] clips it (a
    // field shifted by eye gaze stays inside its eye's box).
    function show(tex, boxes, green, fb, fbHeight) {
      gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
      gl.useProgram(present);
      gl.bindVertexArray(emptyVao);
      gl.activeTexture(gl.TEXTURE0); gl.bindTexture(gl.TEXTURE_2D, tex);
      gl.uniform1i(gl.getUniformLocation(present, "image"), 0);
      gl.uniform1i(gl.getUniformLocation(present, "green"), green ? 1 : 0);
      for (const [x, y, w, h, clip] of boxes) {
        if (clip) {
          gl.enable(gl.SCISSOR_TEST);
          gl.scissor(Math.round(clip[0]), Math.round(fbHeight - clip[1] - clip[3]), Math.round(clip[2]), Math.round(clip[3]));
        }
        gl.viewport(Math.round(x), Math.round(fbHeight - y - h), Math.round(w), Math.round(h));
        gl.drawArrays(gl.TRIANGLE_STRIP, 0, 4);
        if (clip) gl.disable(gl.SCISSOR_TEST);
      }
    }
    return {
      get sprites() { return sp; },
      get drawn() { return drawn; },
      accumulation: blendable32 ? "float32" : "float16",
      setSprites, draw,
      clear(fb, r, g, b) { gl.bindFramebuffer(gl.FRAMEBUFFER, fb || null); gl.clearColor(r || 0, g || 0, b || 0, 1); gl.clear(gl.COLOR_BUFFER_BIT); },
      present(boxes, green, fb, fbHeight) { if (image) show(image.tex, boxes, green, fb || null, fbHeight); },
      presentImage(source, boxes, green, fb, fbHeight) {       // a decoded image frame (canvas)
        gl.bindTexture(gl.TEXTURE_2D, upload);
        gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
        gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA, gl.RGBA, gl.UNSIGNED_BYTE, source);
        for (const [k, v] of [[gl.TEXTURE_MIN_FILTER, gl.LINEAR], [gl.TEXTURE_MAG_FILTER, gl.LINEAR],
          [gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE], [gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE]]) gl.texParameteri(gl.TEXTURE_2D, k, v);
        show(upload, boxes, green, fb || null, fbHeight);
      },
      readImage() {                                     // the last drawn image, rows top first (grey)
        if (!image) return null;
        const px = new Uint8Array(4 * image.w * image.h);
        gl.bindFramebuffer(gl.FRAMEBUFFER, image.fb);
        gl.readPixels(0, 0, image.w, image.h, gl.RGBA, gl.UNSIGNED_BYTE, px);
        gl.bindFramebuffer(gl.FRAMEBUFFER, null);
        const out = new Uint8Array(image.w * image.h);
        for (let i = 0; i < out.length; i++) out[i] = px[4 * i];
        return { width: image.w, height: image.h, pixels: out };
      },
    };
  }
  // The no-data ring from the sprites alone (the bridge's frames stopped): its phosphenes at full
  // level, blinking at 2 Hz like the spv node's (raspv_spv/no_data.py).
  function ringFrame(sp, nowMs) {
    if (!sp || !sp.ring || !sp.ring.length) return null;
    const n = sp.ring.length, on = (nowMs / 1000 * 2) % 1 < 0.5;
    const weights = new Uint16Array(n), spriteLevels = sp.levels > 1 ? new Uint8Array(n) : null;
    for (let i = 0; i < n; i++) {
      if (!on || !sp.ring[i]) continue;
      weights[i] = WEIGHT_SCALE;
      if (spriteLevels) spriteLevels[i] = Math.max(1, sp.numLevels - 1);
    }
    return { mapId: sp.mapId, count: n, levels: sp.levels, flags: FRAME_NO_DATA, weights, spriteLevels,
             noData: true, fallback: false };
  }
  // Half floats → float32, once (the atlas arrives as IEEE binary16 bits).
  let HALF = null;
  function halfTable() {
    if (HALF) return HALF;
    HALF = new Float32Array(65536);
    for (let h = 0; h < 65536; h++) {
      const sign = h & 0x8000 ? -1 : 1, e = (h >> 10) & 31, m = h & 1023;
      HALF[h] = sign * (e === 0 ? m * 5.960464477539063e-8 : e === 31 ? (m ? NaN : Infinity) : (1 + m / 1024) * 2 ** (e - 15));
    }
    return HALF;
  }

  // The page's drawing kernels (levels_kernels.wat, WebAssembly SIMD): ~10× the speed of the same
  // loops in JavaScript. Loaded once; until then (or where WebAssembly is not allowed) the
  // JavaScript loops below draw the same image.
  let KERNELS = null;
  async function loadKernels(url) {
    try {
      const memory = new WebAssembly.Memory({ initial: 1 });
      const bytes = await (await fetch(url)).arrayBuffer();
      const { instance } = await WebAssembly.instantiate(bytes, { env: { memory } });
      KERNELS = { memory, ...instance.exports };
    } catch (e) {
      KERNELS = null;
    }
    return KERNELS;
  }

  const GREY_LUT = new Uint32Array(256), GREEN_LUT = new Uint32Array(256);
  for (let v = 0; v < 256; v++) { GREY_LUT[v] = 0xff000000 | (v << 16) | (v << 8) | v; GREEN_LUT[v] = 0xff000000 | (v << 8); }

  function createCpu() {
    let sp = null, colToPatch = null, drawn = 0, green = false, image = null;
    // typed arrays: in the kernels' memory (k set) or plain JavaScript arrays
    let k = null, atlasF, acc, fine, out, lut, xs0, xs1, fxs, ys0, ys1, fys;
    let ptr = {};

    // INTER_LINEAR source columns/rows and weights for an upsampling by an integer factor
    function axis(n, size, scale, a, b, f) {
      for (let d = 0; d < n; d++) {
        const s = (d + 0.5) / scale - 0.5, i = Math.floor(s);
        f[d] = i < 0 ? 0 : s - i;
        a[d] = Math.min(Math.max(i, 0), size - 1);
        b[d] = Math.min(Math.max(i + 1, 0), size - 1);
      }
    }

    function layout(s, hasFine) {                       // where every array lives
      const n = s.width * s.height, cn = s.coarseW * s.coarseH;
      const sizes = [["lut", 256], ["atlas", s.atlas.length], ["acc", cn], ["fine", hasFine ? n : 0], ["out", n],
        ["xs0", s.width], ["xs1", s.width], ["fx", s.width], ["ys0", s.height], ["ys1", s.height], ["fy", s.height],
        ["row", s.coarseW]];
      k = KERNELS;
      let bytes = 0;
      ptr = {};
      for (const [name, count] of sizes) { ptr[name] = bytes; bytes += 4 * count + 16; }
      let buf;
      if (k) {
        const need = Math.ceil(bytes / 65536) - k.memory.buffer.byteLength / 65536;
        if (need > 0) k.memory.grow(need);
        buf = k.memory.buffer;
      } else {
        buf = new ArrayBuffer(bytes);
      }
      const F = (name, count) => new Float32Array(buf, ptr[name], count), I = (name, count) => new Int32Array(buf, ptr[name], count);
      lut = new Uint32Array(buf, ptr.lut, 256);
      atlasF = F("atlas", s.atlas.length); acc = F("acc", cn); fine = hasFine ? F("fine", n) : null;
      out = new Uint32Array(buf, ptr.out, n);
      xs0 = I("xs0", s.width); xs1 = I("xs1", s.width); fxs = F("fx", s.width);
      ys0 = I("ys0", s.height); ys1 = I("ys1", s.height); fys = F("fy", s.height);
      image = new ImageData(new Uint8ClampedArray(buf, ptr.out, 4 * n), s.width, s.height);
    }

    function setSprites(s) {
      sp = s;
      let maxCol = 0, hasFine = false;
      for (let p = 0; p < s.count; p++) { maxCol = Math.max(maxCol, s.patches[8 * p]); hasFine = hasFine || s.patches[8 * p + 1] === 1; }
      colToPatch = new Int32Array(maxCol + 1).fill(-1);
      for (let p = 0; p < s.count; p++) colToPatch[s.patches[8 * p]] = p;
      layout(s, hasFine);
      const H16 = halfTable();
      for (let i = 0; i < atlasF.length; i++) atlasF[i] = H16[s.atlas[i]];
      if (s.scale > 1) { axis(s.width, s.coarseW, s.scale, xs0, xs1, fxs); axis(s.height, s.coarseH, s.scale, ys0, ys1, fys); }
    }

    function addJs(target, tw, p, w) {
      const P = sp.patches, AW = sp.atlasW;
      const x = P[8 * p + 2], y = P[8 * p + 3], pw = P[8 * p + 4], ph = P[8 * p + 5], ax = P[8 * p + 6], ay = P[8 * p + 7];
      for (let j = 0; j < ph; j++) {
        let o = (y + j) * tw + x, a = (ay + j) * AW + ax;
        const end = o + pw;
        while (o < end) target[o++] += w * atlasF[a++];
      }
    }

    function composeJs() {                              // (round half to even, as the kernels and OpenCV)
      const n = out.length, L = lut, rnd = (v) => { const r = Math.round(v); return (r - v === 0.5 && r % 2) ? r - 1 : r; };
      const q = (v) => { const r = rnd(v); return r < 0 ? 0 : r > 255 ? 255 : r; };
      if (sp.scale === 1) {
        for (let i = 0; i < n; i++) out[i] = L[q(acc[i] + (fine ? fine[i] : 0))];
        return;
      }
      const CW = sp.coarseW;
      for (let y = 0, o = 0; y < sp.height; y++) {
        const r0 = ys0[y] * CW, r1 = ys1[y] * CW, fy = fys[y], gy = 1 - fy;
        for (let x = 0; x < sp.width; x++, o++) {
          const a = xs0[x], b = xs1[x], fx = fxs[x];
          const top = acc[r0 + a] + (acc[r0 + b] - acc[r0 + a]) * fx;
          const bottom = acc[r1 + a] + (acc[r1 + b] - acc[r1 + a]) * fx;
          out[o] = L[q(top * gy + bottom * fy + (fine ? fine[o] : 0))];
        }
      }
    }

    function draw(frame) {                              // → false when the frame is not of these sprites
      if (!sp || frame.mapId !== sp.mapId) return false;
      if (k !== KERNELS) setSprites(sp);                // the kernels arrived: move the arrays into their memory
      acc.fill(0);
      if (fine) fine.fill(0);
      if (!k) lut.set(green ? GREEN_LUT : GREY_LUT);
      const W = frame.weights, L = sp.levels, SL = frame.spriteLevels, P = sp.patches;
      let n = 0;
      for (let i = 0; i < frame.count; i++) {
        if (W[i] === 0) continue;
        let col = i;
        if (L > 1) { const l = SL ? SL[i] : 0; if (l === 0) continue; col = i * L + Math.min(l, L) - 1; }
        const p = col < colToPatch.length ? colToPatch[col] : -1;
        if (p < 0) continue;
        const isFine = P[8 * p + 1] === 1, w = W[i] / WEIGHT_SCALE;
        if (k) {
          k.add(isFine ? ptr.fine : ptr.acc, isFine ? sp.width : sp.coarseW, ptr.atlas, sp.atlasW,
                P[8 * p + 2], P[8 * p + 3], P[8 * p + 4], P[8 * p + 5], P[8 * p + 6], P[8 * p + 7], w);
        } else {
          addJs(isFine ? fine : acc, isFine ? sp.width : sp.coarseW, p, w);
        }
        n++;
      }
      if (!k) composeJs();
      else if (sp.scale === 1) k.compose(ptr.acc, fine ? ptr.fine : 0, out.length, green ? 1 : 0, ptr.out);
      else k.compose_up(ptr.acc, sp.coarseW, fine ? ptr.fine : 0, sp.width, sp.height, ptr.xs0, ptr.xs1, ptr.fx,
                        ptr.ys0, ptr.ys1, ptr.fy, green ? 1 : 0, ptr.row, ptr.out);
      drawn = n;
      return true;
    }

    return {
      get sprites() { return sp; },
      get drawn() { return drawn; },
      get accumulation() { return k ? "float32 (WebAssembly SIMD)" : "float32 (JavaScript)"; },
      set green(g) { green = !!g; },
      setSprites, draw,
      image() { return image; },                        // the last image, RGBA (grey or green), for putImageData
      readImage() {                                     // its grey levels, rows top first
        if (!image) return null;
        const px = new Uint8Array(sp.width * sp.height), rgba = image.data, ch = green ? 1 : 0;
        for (let i = 0; i < px.length; i++) px[i] = rgba[4 * i + ch];
        return { width: sp.width, height: sp.height, pixels: px };
      },
    };
  }

  // Is this WebGL context drawn by a graphics processor? (Software renderers make the page slower
  // with WebGL than without it.)
  function hardware(gl) {
    const info = gl.getExtension("WEBGL_debug_renderer_info");
    const name = String(info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER));
    return !/swiftshader|llvmpipe|softpipe|software|microsoft basic render/i.test(name);
  }

  return { contextFor, parseSprites, parseFrame, create, createCpu, loadKernels, hardware, ringFrame, SPRITES_MAGIC };
})();
