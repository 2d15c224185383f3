// morphoid report viewer: the scan (left) and one nearest reference
// (right) in the same pose, turned together by dragging, zoomed by the
// wheel. Plain WebGL 1, no external code: the page must work offline.
// The scene is the JSON in #scene-data (arrays as base64 little-endian).
(function () {
  "use strict";
  var status = document.getElementById("viewer-check");
  function report(drawn, text) {
    status.setAttribute("data-drawn", String(drawn));
    status.textContent = text;
  }
  var data = JSON.parse(document.getElementById("scene-data").textContent);
  var canvas = document.getElementById("viewer");
  var gl = canvas.getContext("webgl", { antialias: true, preserveDrawingBuffer: true });
  if (!gl) {
    report(0, "3D view unavailable: this browser has no WebGL.");
    return;
  }

  function bytes(b64) {
    var s = atob(b64), out = new Uint8Array(s.length);
    for (var i = 0; i < s.length; i++) out[i] = s.charCodeAt(i);
    return out;
  }
  function floats(b64) { return new Float32Array(bytes(b64).buffer); }
  function indices(b64) { return new Uint32Array(bytes(b64).buffer); }

  // Smooth normals per vertex, then one unindexed triangle list (WebGL 1
  // has 16-bit indices only).
  function soup(v, f, c) {
    var nv = v.length / 3, n = new Float32Array(v.length), i, k;
    for (i = 0; i < f.length; i += 3) {
      var a = f[i] * 3, b = f[i + 1] * 3, d = f[i + 2] * 3;
      var ux = v[b] - v[a], uy = v[b + 1] - v[a + 1], uz = v[b + 2] - v[a + 2];
      var wx = v[d] - v[a], wy = v[d + 1] - v[a + 1], wz = v[d + 2] - v[a + 2];
      var cx = uy * wz - uz * wy, cy = uz * wx - ux * wz, cz = ux * wy - uy * wx;
      for (k = 0; k < 3; k++) {
        var o = f[i + k] * 3;
        n[o] += cx; n[o + 1] += cy; n[o + 2] += cz;
      }
    }
    var pos = new Float32Array(f.length * 3), nor = new Float32Array(f.length * 3),
        col = new Float32Array(f.length * 3);
    for (i = 0; i < f.length; i++) {
      var s = f[i];
      if (s >= nv) continue;
      for (k = 0; k < 3; k++) {
        pos[i * 3 + k] = v[s * 3 + k];
        nor[i * 3 + k] = n[s * 3 + k];
        col[i * 3 + k] = c ? c[s * 3 + k] / 255 : 0.8;
      }
    }
    return { pos: pos, nor: nor, col: col, count: f.length };
  }

  function buffer(array) {
    var b = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, b);
    gl.bufferData(gl.ARRAY_BUFFER, array, gl.STATIC_DRAW);
    return b;
  }
  function upload(m) {
    return { pos: buffer(m.pos), nor: buffer(m.nor), col: buffer(m.col), count: m.count };
  }

  var vs = [
    "attribute vec3 p; attribute vec3 n; attribute vec3 c;",
    "uniform mat3 R; uniform vec3 centre; uniform float scale; uniform float flat_;",
    "uniform float pointSize; varying vec3 colour;",
    "void main() {",
    "  vec3 q = R * (p - centre) * scale;",
    "  vec3 m = normalize(R * n + vec3(1e-9));",
    "  float light = mix(0.35 + 0.65 * abs(m.z), 1.0, flat_);",
    "  colour = c * light;",
    "  gl_PointSize = pointSize;",
    "  gl_Position = vec4(q.x, q.y, -0.45 * q.z - 0.02 * flat_, 1.0);",
    "}"].join("\n");
  var fs = [
    "precision mediump float; varying vec3 colour;",
    "void main() { gl_FragColor = vec4(colour, 1.0); }"].join("\n");
  function shader(type, src) {
    var s = gl.createShader(type);
    gl.shaderSource(s, src);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  }
  var prog = gl.createProgram();
  gl.attachShader(prog, shader(gl.VERTEX_SHADER, vs));
  gl.attachShader(prog, shader(gl.FRAGMENT_SHADER, fs));
  gl.linkProgram(prog);
  if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(prog));
  gl.useProgram(prog);
  var loc = {
    p: gl.getAttribLocation(prog, "p"), n: gl.getAttribLocation(prog, "n"),
    c: gl.getAttribLocation(prog, "c"), R: gl.getUniformLocation(prog, "R"),
    centre: gl.getUniformLocation(prog, "centre"), scale: gl.getUniformLocation(prog, "scale"),
    flat_: gl.getUniformLocation(prog, "flat_"), pointSize: gl.getUniformLocation(prog, "pointSize")
  };

  var scanV = floats(data.scan.v), scanF = indices(data.scan.f);
  var scanPlain = upload(soup(scanV, scanF, null));
  var pairs = data.pairs.map(function (p) {
    return {
      name: p.name,
      scan: upload(soup(scanV, scanF, bytes(p.carried))),
      ref: upload(soup(floats(p.v), indices(p.f), bytes(p.c)))
    };
  });
  var lmPos = new Float32Array(data.landmarks.length * 3);
  data.landmarks.forEach(function (l, i) { lmPos.set(l, i * 3); });
  var lmCol = new Float32Array(lmPos.length);
  for (var i = 0; i < lmCol.length; i += 3) { lmCol[i] = 1; lmCol[i + 1] = 0.1; lmCol[i + 2] = 0.6; }
  var landmarks = { pos: buffer(lmPos), nor: buffer(lmPos), col: buffer(lmCol), count: data.landmarks.length };

  var cam = data.camera, yaw = 0, pitch = 0, zoom = 1;
  var choice = document.getElementById("viewer-reference");
  var colouring = document.getElementById("viewer-colours");

  // The camera frame (rows right, up, toward the viewer), turned by the
  // user's yaw and pitch about the screen axes.
  function rotation() {
    var r = cam.right, u = cam.up;
    var t = [r[1] * u[2] - r[2] * u[1], r[2] * u[0] - r[0] * u[2], r[0] * u[1] - r[1] * u[0]];
    var cy = Math.cos(yaw), sy = Math.sin(yaw), cp = Math.cos(pitch), sp = Math.sin(pitch);
    var Y = [[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]], P = [[1, 0, 0], [0, cp, -sp], [0, sp, cp]];
    var F = [r, u, t], M = [[0, 0, 0], [0, 0, 0], [0, 0, 0]], A = [[0, 0, 0], [0, 0, 0], [0, 0, 0]];
    var a, b, k;
    for (a = 0; a < 3; a++) for (b = 0; b < 3; b++) for (k = 0; k < 3; k++) A[a][b] += P[a][k] * Y[k][b];
    for (a = 0; a < 3; a++) for (b = 0; b < 3; b++) for (k = 0; k < 3; k++) M[a][b] += A[a][k] * F[k][b];
    // Column-major for WebGL.
    return new Float32Array([M[0][0], M[1][0], M[2][0], M[0][1], M[1][1], M[2][1], M[0][2], M[1][2], M[2][2]]);
  }

  function draw(mesh, mode, flat) {
    [["p", mesh.pos], ["n", mesh.nor], ["c", mesh.col]].forEach(function (x) {
      gl.bindBuffer(gl.ARRAY_BUFFER, x[1]);
      gl.enableVertexAttribArray(loc[x[0]]);
      gl.vertexAttribPointer(loc[x[0]], 3, gl.FLOAT, false, 0, 0);
    });
    gl.uniform1f(loc.flat_, flat);
    gl.uniform1f(loc.pointSize, 7.0);
    gl.drawArrays(mode, 0, mesh.count);
  }

  function frame() {
    var w = canvas.width, h = canvas.height, half = Math.floor(w / 2);
    var side = Math.min(half, h);
    gl.viewport(0, 0, w, h);
    gl.clearColor(1, 1, 1, 1);
    gl.enable(gl.DEPTH_TEST);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.uniformMatrix3fv(loc.R, false, rotation());
    gl.uniform3fv(loc.centre, cam.centre);
    gl.uniform1f(loc.scale, zoom / cam.half);
    var pair = pairs[Number(choice.value) || 0];
    var coloured = colouring.checked;
    gl.viewport(0, (h - side) / 2, side, side);
    draw(pair && coloured ? pair.scan : scanPlain, gl.TRIANGLES, 0);
    if (landmarks.count > 0) draw(landmarks, gl.POINTS, 1);
    if (pair) {
      gl.viewport(half, (h - side) / 2, side, side);
      draw(pair.ref, gl.TRIANGLES, 0);
    }
  }

  // What the page itself checks: how many pixels differ from the
  // background after the first frame (a blank canvas is a failure).
  function check() {
    var w = canvas.width, h = canvas.height, px = new Uint8Array(w * h * 4), drawn = 0;
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    for (var i = 0; i < px.length; i += 4) {
      if (px[i] < 250 || px[i + 1] < 250 || px[i + 2] < 250) drawn++;
    }
    report(drawn, "3D view: drag to turn, wheel to zoom (" + drawn + " of " + w * h + " pixels drawn).");
  }

  var dragging = null;
  canvas.addEventListener("mousedown", function (e) { dragging = [e.clientX, e.clientY]; });
  window.addEventListener("mouseup", function () { dragging = null; });
  window.addEventListener("mousemove", function (e) {
    if (!dragging) return;
    yaw += (e.clientX - dragging[0]) * 0.01;
    pitch += (e.clientY - dragging[1]) * 0.01;
    dragging = [e.clientX, e.clientY];
    frame();
  });
  canvas.addEventListener("wheel", function (e) {
    e.preventDefault();
    zoom = Math.min(8, Math.max(0.2, zoom * (e.deltaY < 0 ? 1.1 : 1 / 1.1)));
    frame();
  }, { passive: false });
  choice.addEventListener("change", frame);
  colouring.addEventListener("change", frame);
  frame();
  check();
})();
