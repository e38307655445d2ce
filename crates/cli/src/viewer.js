// coarsen's report viewer: input and output meshes, embedded in the page, drawn with
// WebGL 1 (no library, no network). Orbit: drag; zoom: wheel; the controls above the
// canvas switch side by side / overlaid, the wire, and the colouring.
(function () {
  "use strict";
  var status = document.getElementById("viewer-status");
  function say(text) { status.textContent = text; }
  function bytes(id) {
    var el = document.getElementById(id);
    var bin = atob(el.textContent.trim());
    var out = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
    return { data: out, el: el };
  }
  // A list of varints (seven bits a byte, low first), as many as the element says.
  function varints(id) {
    var b = bytes(id), d = b.data, n = +b.el.dataset.count, out = new Uint32Array(n), at = 0;
    for (var i = 0; i < n; i++) {
      var x = 0, shift = 0, c;
      do { c = d[at++]; x += (c & 127) * Math.pow(2, shift); shift += 7; } while (c & 128);
      out[i] = x;
    }
    return out;
  }
  // A mesh: positions as u16 triples over its box, faces as zigzag varint deltas, then one
  // byte per face of distance (0..255 over the map's range).
  function decode(id) {
    var b = bytes(id), d = b.data, el = b.el;
    var nv = +el.dataset.vertices, nf = +el.dataset.faces;
    var lo = el.dataset.min.split(",").map(Number), hi = el.dataset.max.split(",").map(Number);
    var pos = new Float32Array(3 * nv), at = 0;
    for (var v = 0; v < nv; v++) {
      for (var k = 0; k < 3; k++) {
        var q = d[at] | (d[at + 1] << 8); at += 2;
        pos[3 * v + k] = lo[k] + (hi[k] - lo[k]) * q / 65535;
      }
    }
    var faces = new Uint32Array(3 * nf), prev = 0;
    for (var i = 0; i < 3 * nf; i++) {
      var x = 0, shift = 0, c;
      do { c = d[at++]; x += (c & 127) * Math.pow(2, shift); shift += 7; } while (c & 128);
      var delta = (x % 2) ? -(x + 1) / 2 : x / 2;
      prev += delta; faces[i] = prev;
    }
    var distance = d.subarray(at, at + nf);
    return { nv: nv, nf: nf, pos: pos, faces: faces, distance: distance, name: el.dataset.name };
  }
  // Blue (good) to grey to red (bad), as the report's pictures.
  var STOPS = [[0.23, 0.3, 0.75], [0.55, 0.69, 1.0], [0.87, 0.87, 0.87], [0.96, 0.6, 0.48], [0.71, 0.02, 0.15]];
  function badness(t) {
    t = Math.min(1, Math.max(0, t)) * 4;
    var i = Math.min(3, Math.floor(t)), f = t - i, a = STOPS[i], b = STOPS[i + 1];
    return [a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), a[2] + f * (b[2] - a[2])];
  }
  function sub(p, a, b) { return [p[3 * a] - p[3 * b], p[3 * a + 1] - p[3 * b + 1], p[3 * a + 2] - p[3 * b + 2]]; }
  function cross(u, v) { return [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]; }
  function len(u) { return Math.hypot(u[0], u[1], u[2]); }
  function angle(u, v) { var l = len(u) * len(v); return l > 0 ? Math.acos(Math.max(-1, Math.min(1, (u[0] * v[0] + u[1] * v[1] + u[2] * v[2]) / l))) : 0; }
  // Per-face smallest angle (degrees) and per-vertex angle deficit over a third of the
  // area around the vertex (discrete Gaussian curvature).
  function shape(m) {
    var minAngle = new Float32Array(m.nf), deficit = new Float64Array(m.nv), area = new Float64Array(m.nv);
    for (var v = 0; v < m.nv; v++) deficit[v] = 2 * Math.PI;
    for (var f = 0; f < m.nf; f++) {
      var a = m.faces[3 * f], b = m.faces[3 * f + 1], c = m.faces[3 * f + 2];
      var A = angle(sub(m.pos, b, a), sub(m.pos, c, a)), B = angle(sub(m.pos, a, b), sub(m.pos, c, b)), C = Math.PI - A - B;
      minAngle[f] = Math.min(A, B, C) * 180 / Math.PI;
      var ar = len(cross(sub(m.pos, b, a), sub(m.pos, c, a))) / 6;
      deficit[a] -= A; deficit[b] -= B; deficit[c] -= C;
      area[a] += ar; area[b] += ar; area[c] += ar;
    }
    var edges = 0;
    for (f = 0; f < m.nf; f++) {
      edges += Math.sqrt(2 * len(cross(sub(m.pos, m.faces[3 * f + 1], m.faces[3 * f]), sub(m.pos, m.faces[3 * f + 2], m.faces[3 * f]))) / 2);
    }
    m.edge = m.nf ? edges / m.nf : 0;
    var curv = new Float32Array(m.nv);
    for (v = 0; v < m.nv; v++) curv[v] = area[v] > 0 ? deficit[v] / area[v] : 0;
    m.minAngle = minAngle; m.curvature = curv;
  }
  // A distinct colour for label `l`: hues a golden-ratio turn apart, two lightnesses.
  function labelColour(l) {
    var h = (l * 0.6180339887) % 1, s = l % 2 ? 0.55 : 0.65, v = l % 2 ? 0.75 : 0.95;
    var i = Math.floor(h * 6), f = h * 6 - i, p = v * (1 - s), q = v * (1 - f * s), t = v * (1 - (1 - f) * s);
    return [[v, t, p], [q, v, p], [p, v, t], [p, q, v], [t, p, v], [v, p, q]][i % 6];
  }
  // Each vertex of `m` labelled by the nearest vertex of `to` (a grid of `to`'s vertices,
  // searched in growing shells): the region of the input each output vertex stands for.
  function nearestLabels(m, to) {
    var lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity], k, v;
    for (v = 0; v < to.nv; v++) for (k = 0; k < 3; k++) { lo[k] = Math.min(lo[k], to.pos[3 * v + k]); hi[k] = Math.max(hi[k], to.pos[3 * v + k]); }
    var side = Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / Math.max(1, Math.cbrt(to.nv)) || 1;
    var cell = function (p, k) { return Math.floor((p - lo[k]) / side); };
    var grid = new Map(), key = function (i, j, l) { return ((i + 1024) * 4096 + (j + 1024)) * 4096 + (l + 1024); };
    for (v = 0; v < to.nv; v++) {
      var g = key(cell(to.pos[3 * v], 0), cell(to.pos[3 * v + 1], 1), cell(to.pos[3 * v + 2], 2));
      if (!grid.has(g)) grid.set(g, []);
      grid.get(g).push(v);
    }
    var labels = new Uint32Array(m.nv);
    for (v = 0; v < m.nv; v++) {
      var p = [m.pos[3 * v], m.pos[3 * v + 1], m.pos[3 * v + 2]], c = [0, 1, 2].map(function (k) { return cell(p[k], k); });
      var best = -1, bestD = Infinity;
      for (var r = 0; r < 64 && (best < 0 || (r - 1) * side < Math.sqrt(bestD)); r++) {
        for (var i = -r; i <= r; i++) for (var j = -r; j <= r; j++) for (var l = -r; l <= r; l++) {
          if (Math.max(Math.abs(i), Math.abs(j), Math.abs(l)) !== r) continue;
          var list = grid.get(key(c[0] + i, c[1] + j, c[2] + l));
          if (!list) continue;
          list.forEach(function (u) {
            var d = Math.pow(to.pos[3 * u] - p[0], 2) + Math.pow(to.pos[3 * u + 1] - p[1], 2) + Math.pow(to.pos[3 * u + 2] - p[2], 2);
            if (d < bestD) { bestD = d; best = u; }
          });
        }
      }
      labels[v] = Math.max(best, 0);
    }
    return labels;
  }
  function robustRange(values) {
    var s = Array.prototype.slice.call(values).filter(isFinite).sort(function (x, y) { return x - y; });
    if (!s.length) return [0, 1];
    var q = function (p) { return s[Math.round((s.length - 1) * p)]; };
    var r = Math.max(Math.abs(q(0.02)), Math.abs(q(0.98))) || 1;
    return [-r, r];
  }
  // Corner colours for a colouring: plain, distance, min_angle, curvature, regions, clusters.
  function colours(m, mode, curvRange) {
    var out = new Float32Array(9 * m.nf);
    for (var f = 0; f < m.nf; f++) {
      for (var k = 0; k < 3; k++) {
        var col;
        if (mode === "distance") col = badness(m.distance[f] / 255);
        else if (mode === "min_angle") col = badness(1 - m.minAngle[f] / 60);
        else if (mode === "curvature") {
          var t = (m.curvature[m.faces[3 * f + k]] - curvRange[0]) / (curvRange[1] - curvRange[0]);
          col = badness(t);
        } else if (mode === "regions") col = labelColour(m.labels[m.faces[3 * f + k]]);
        else if (mode === "clusters" && m.faceClusters) col = labelColour(m.faceClusters[f]);
        else if (mode === "clusters" && m.vertexClusters) col = labelColour(m.vertexClusters[m.faces[3 * f + k]]);
        else col = m.plain;
        out.set(col, 9 * f + 3 * k);
      }
    }
    return out;
  }
  var canvas = document.getElementById("viewer");
  var gl = canvas.getContext("webgl", { preserveDrawingBuffer: true, antialias: true });
  if (!gl) { say("WebGL is not available in this browser: the pictures above show the meshes."); return; }
  var deriv = gl.getExtension("OES_standard_derivatives");
  var VS = "attribute vec3 p; attribute vec3 n; attribute vec3 c; attribute vec3 w;" +
    "uniform mat4 mvp; uniform mat3 rot; varying vec3 vn; varying vec3 vc; varying vec3 vw;" +
    "void main(){ gl_Position = mvp * vec4(p, 1.0); vn = rot * n; vc = c; vw = w; }";
  var FS = (deriv ? "#extension GL_OES_standard_derivatives : enable\n" : "") +
    "precision mediump float; varying vec3 vn; varying vec3 vc; varying vec3 vw; uniform float wire; uniform float alpha;" +
    "void main(){ vec3 l = normalize(vec3(-0.35, 0.45, 0.8)); float s = 0.35 + 0.65 * abs(dot(normalize(vn), l));" +
    " vec3 col = vc * s;" +
    (deriv ? " vec3 d = fwidth(vw); vec3 e = smoothstep(vec3(0.0), d * 1.2, vw); float edge = 1.0 - min(min(e.x, e.y), e.z);"
      : " float edge = step(min(min(vw.x, vw.y), vw.z), 0.02);") +
    " col = mix(col, vec3(0.08), edge * wire); gl_FragColor = vec4(col, alpha); }";
  function shader(type, src) {
    var s = gl.createShader(type); gl.shaderSource(s, src); gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  }
  var prog = gl.createProgram();
  gl.attachShader(prog, shader(gl.VERTEX_SHADER, VS));
  gl.attachShader(prog, shader(gl.FRAGMENT_SHADER, FS));
  gl.linkProgram(prog);
  gl.useProgram(prog);
  var loc = {};
  ["p", "n", "c", "w"].forEach(function (a) { loc[a] = gl.getAttribLocation(prog, a); });
  ["mvp", "rot", "wire", "alpha"].forEach(function (u) { loc[u] = gl.getUniformLocation(prog, u); });
  function buffer(data) { var b = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, b); gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW); return b; }
  // Unshared corners: flat normals, per-face colours and the barycentric wire.
  function upload(m) {
    var p = new Float32Array(9 * m.nf), n = new Float32Array(9 * m.nf), w = new Float32Array(9 * m.nf);
    for (var f = 0; f < m.nf; f++) {
      var a = m.faces[3 * f], b = m.faces[3 * f + 1], c = m.faces[3 * f + 2];
      var nn = cross(sub(m.pos, b, a), sub(m.pos, c, a)), l = len(nn) || 1;
      [a, b, c].forEach(function (v, k) {
        for (var j = 0; j < 3; j++) { p[9 * f + 3 * k + j] = m.pos[3 * v + j]; n[9 * f + 3 * k + j] = nn[j] / l; }
        w[9 * f + 3 * k + k] = 1;
      });
    }
    m.buf = { p: buffer(p), n: buffer(n), w: buffer(w), c: gl.createBuffer() };
  }
  var meshes = [decode("mesh-input"), decode("mesh-output")];
  meshes[0].plain = [0.72, 0.72, 0.76]; meshes[1].plain = [0.55, 0.75, 0.95];
  meshes.forEach(function (m) { shape(m); upload(m); });
  var curvRange = robustRange(meshes[1].curvature);
  meshes[0].labels = nearestLabels(meshes[0], meshes[1]);
  meshes[1].labels = new Uint32Array(meshes[1].nv).map(function (_, i) { return i; });
  // The first clustering's clusters, when the run made some: per input face, and per
  // output vertex the cluster of the input face nearest it.
  if (document.getElementById("clusters-input")) {
    meshes[0].faceClusters = varints("clusters-input");
    meshes[1].vertexClusters = varints("clusters-output");
  }
  var lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  meshes.forEach(function (m) { for (var i = 0; i < m.pos.length; i++) { lo[i % 3] = Math.min(lo[i % 3], m.pos[i]); hi[i % 3] = Math.max(hi[i % 3], m.pos[i]); } });
  var centre = [0, 1, 2].map(function (k) { return (lo[k] + hi[k]) / 2; });
  var radius = Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / 2 || 1;
  var view = { yaw: +canvas.dataset.yaw || 0, pitch: 0.25, zoom: 1, mode: "side", wire: true, colour: "plain" };
  function setColours() { meshes.forEach(function (m) { gl.bindBuffer(gl.ARRAY_BUFFER, m.buf.c); gl.bufferData(gl.ARRAY_BUFFER, colours(m, view.colour, curvRange), gl.STATIC_DRAW); }); }
  // Rotation (yaw about y, then pitch about x) and an orthographic projection.
  function matrices(aspect) {
    var cy = Math.cos(view.yaw), sy = Math.sin(view.yaw), cp = Math.cos(view.pitch), sp = Math.sin(view.pitch);
    var r = [cy, sp * sy, -cp * sy, 0, cp, sp, sy, -sp * cy, cp * cy]; // columns
    var s = view.zoom / radius, sx = aspect > 1 ? s / aspect : s, syy = aspect > 1 ? s : s * aspect;
    var t = [0, 1, 2].map(function (k) { return -(r[k] * centre[0] + r[3 + k] * centre[1] + r[6 + k] * centre[2]); });
    var mvp = new Float32Array([
      sx * r[0], syy * r[1], -0.5 * s * r[2], 0,
      sx * r[3], syy * r[4], -0.5 * s * r[5], 0,
      sx * r[6], syy * r[7], -0.5 * s * r[8], 0,
      sx * t[0], syy * t[1], -0.5 * s * t[2], 1]);
    return { mvp: mvp, rot: new Float32Array(r) };
  }
  // The wire fades on a mesh whose edges are short on screen (`scale`: pixels per unit),
  // so that a dense mesh shows its shape rather than a dark blot.
  function drawMesh(m, alpha, scale) {
    var px = m.edge * scale;
    gl.uniform1f(loc.wire, view.wire ? 0.1 + 0.5 * Math.min(1, Math.max(0, (px - 2) / 6)) : 0);
    [["p", m.buf.p], ["n", m.buf.n], ["c", m.buf.c], ["w", m.buf.w]].forEach(function (a) {
      gl.bindBuffer(gl.ARRAY_BUFFER, a[1]); gl.enableVertexAttribArray(loc[a[0]]);
      gl.vertexAttribPointer(loc[a[0]], 3, gl.FLOAT, false, 0, 0);
    });
    gl.uniform1f(loc.alpha, alpha);
    gl.drawArrays(gl.TRIANGLES, 0, 3 * m.nf);
  }
  var drawn = 0;
  function draw() {
    var W = canvas.width, H = canvas.height;
    gl.clearColor(0.97, 0.97, 0.96, 1); gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);
    var panes = view.mode === "side" ? [[0, 0, W / 2, H, [meshes[0]]], [W / 2, 0, W / 2, H, [meshes[1]]]] : [[0, 0, W, H, meshes]];
    panes.forEach(function (pane) {
      gl.viewport(pane[0], pane[1], pane[2], pane[3]);
      var m = matrices(pane[2] / pane[3]);
      gl.uniformMatrix4fv(loc.mvp, false, m.mvp); gl.uniformMatrix3fv(loc.rot, false, m.rot);
      var scale = view.zoom / radius * Math.min(pane[2], pane[3]) / 2;
      pane[4].forEach(function (mesh) { drawMesh(mesh, 1, scale); });
    });
    drawn++;
    var px = new Uint8Array(4);
    gl.readPixels(W >> 2, H >> 1, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
    say("WebGL: drawn " + drawn + " times, " + (meshes[0].nf + meshes[1].nf) + " triangles" + (deriv ? "" : " (no derivatives: plain wire)") +
      "; pixel at the input's centre " + px[0] + "," + px[1] + "," + px[2]);
  }
  var frame = 0;
  function redraw() { if (!frame) frame = requestAnimationFrame(function () { frame = 0; draw(); }); }
  var drag = null;
  canvas.addEventListener("mousedown", function (e) { drag = [e.clientX, e.clientY]; });
  window.addEventListener("mouseup", function () { drag = null; });
  window.addEventListener("mousemove", function (e) {
    if (!drag) return;
    view.yaw += (e.clientX - drag[0]) * 0.01;
    view.pitch = Math.max(-1.5, Math.min(1.5, view.pitch + (e.clientY - drag[1]) * 0.01));
    drag = [e.clientX, e.clientY]; redraw();
  });
  canvas.addEventListener("wheel", function (e) { e.preventDefault(); view.zoom *= Math.exp(-e.deltaY * 0.001); redraw(); }, { passive: false });
  document.querySelectorAll("#viewer-controls [name]").forEach(function (c) {
    c.addEventListener("change", function () {
      view[c.name] = c.type === "checkbox" ? c.checked : c.value;
      if (c.name === "colour") setColours();
      redraw();
    });
  });
  // The address may set the view: `#turn=DEGREES&colour=distance&mode=overlay&wire=0`.
  location.hash.slice(1).split("&").forEach(function (kv) {
    var p = kv.split("="), key = p[0], value = decodeURIComponent(p[1] || "");
    if (["turn", "wire", "colour", "mode"].indexOf(key) < 0) return;
    if (key === "turn") view.yaw += (+value || 0) * Math.PI / 180;
    else if (key === "wire") view.wire = value !== "0";
    else if (key === "colour" || key === "mode") view[key] = value;
    var controls = document.querySelectorAll("#viewer-controls [name=" + key + "]");
    var control = Array.prototype.filter.call(controls, function (c) { return key !== "mode" || c.value === value; })[0];
    if (control && key === "mode") control.checked = true;
    else if (control && key === "colour") control.value = value;
    else if (control && key === "wire") control.checked = view.wire;
  });
  window.coarsenViewer = { view: view, draw: draw };
  setColours();
  draw();
})();
