// skin-sim view page: three.js scene of the layered tissue, plots, diagnostics, parameters, bag timeline.
// Wire format: skin_sim_node/view/frames.py. Units on the wire are SI; the scene is in mm.
import * as THREE from "three";
import { OrbitControls } from "/static/vendor/OrbitControls.js";

const $ = (id) => document.getElementById(id);
// LAYER_RGBA of msgs_schema/convert.py: epidermis, dermis, fat
const LAYER_RGB = [[0.95, 0.79, 0.65], [0.85, 0.47, 0.48], [0.96, 0.88, 0.56]];
const state = { frames: 0, gridFrames: 0, force: null, depth: null, info: null, mode: "", diag: null, lastParam: null };
window.skinView = state; // read by the browser test and the benchmark
let dirty = true; // the scene changed since the last render

// --- scene --------------------------------------------------------------------------------
const host = $("scene");
const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
// WebGL on the CPU (SwiftShader: no GPU, e.g. headless CI) pays per pixel: half resolution there, full elsewhere
const gl = renderer.getContext(), dbg = gl.getExtension("WEBGL_debug_renderer_info");
state.glRenderer = dbg ? gl.getParameter(dbg.UNMASKED_RENDERER_WEBGL) : "unknown";
const software = /swiftshader|llvmpipe|software/i.test(state.glRenderer);
renderer.setPixelRatio(parseFloat(new URLSearchParams(location.search).get("pixel_ratio") || (software ? 0.5 : window.devicePixelRatio)));
host.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x1d2127);
const camera = new THREE.PerspectiveCamera(40, 1, 1, 2000);
camera.up.set(0, 0, 1);
// framed on the middle of the sheet, close enough to see a punch-sized dent (it decays within a few mm of the
// tool: the membranes' foundation) and the cut-away layers; scroll out for the whole 120 mm sheet
camera.position.set(-32, -50, 34);
const controls = new OrbitControls(camera, renderer.domElement);
controls.target.set(0, 0, -3);
controls.update();
scene.add(new THREE.HemisphereLight(0xffffff, 0x404050, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
sun.position.set(-60, -80, 120);
scene.add(sun);

function resize() {
  const w = host.clientWidth, h = host.clientHeight;
  renderer.setSize(w, h);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}
window.addEventListener("resize", resize);
resize();

renderer.localClippingEnabled = true;
const cut = new THREE.Plane(new THREE.Vector3(0, 1, 0), 1e4); // cut-away: hides the sheet in front of the tool (y < tool y)
let toolY = 0; // mm
let lastHeader = null; // the newest frame's header (a display change redraws the tool from it)
let meshes = null, nx = 0, ny = 0, rest = null, lastGrid = null;
function buildMeshes(gx, gy) {
  if (meshes) meshes.forEach((m) => { scene.remove(m); m.geometry.dispose(); });
  nx = gx; ny = gy; rest = null;
  const idx = [];
  for (let r = 0; r < ny - 1; r++)
    for (let c = 0; c < nx - 1; c++) {
      const a = r * nx + c;
      idx.push(a, a + 1, a + nx + 1, a, a + nx + 1, a + nx);
    }
  coloured = "";
  meshes = [0, 1, 2].map((layer) => {
    const g = new THREE.BufferGeometry();
    g.setAttribute("position", new THREE.BufferAttribute(new Float32Array(nx * ny * 3), 3));
    g.setAttribute("color", new THREE.BufferAttribute(new Float32Array(nx * ny * 3), 3));
    g.setIndex(idx);
    const mat = new THREE.MeshStandardMaterial({ vertexColors: true, side: THREE.DoubleSide, roughness: 0.8,
      transparent: layer === 0, opacity: layer === 0 ? 0.6 : 1.0, clippingPlanes: [cut] });
    const m = new THREE.Mesh(g, mat);
    scene.add(m);
    return m;
  });
}

// the z scale exaggerates depth into the tissue only: a tool lifted 5 mm is drawn 5 mm above the surface
const zDraw = (zmm, zs) => (zmm < 0 ? zmm * zs : zmm);
const MIN_BAND_MM = 0.5; // a cut band is drawn at least this thick (the 0.075 mm epidermis would be under a pixel)

function colourmap(v) { // 0..1 -> dark blue .. yellow (viridis-like, 3 stops)
  const s = Math.min(1, Math.max(0, v));
  if (s < 0.5) { const u = s / 0.5; return [0.27 * (1 - u) + 0.13 * u, 0.0 * (1 - u) + 0.57 * u, 0.33 * (1 - u) + 0.55 * u]; }
  const u = (s - 0.5) / 0.5; return [0.13 * (1 - u) + 0.99 * u, 0.57 * (1 - u) + 0.91 * u, 0.55 * (1 - u) + 0.14 * u];
}

let coloured = ""; // colour mode the vertex colours were last written for
function updateMeshes(grid) { // grid: Float32Array (ny, nx, 3) in m
  lastGrid = grid;
  if (!rest) rest = Float32Array.from(grid);
  for (let i = 0; i < grid.length; i++) if (grid[i] > rest[i]) rest[i] = grid[i]; // rest = highest seen: the tool only pushes in
  const info = state.info, sx = info.sheet_m[0] * 1e3, sy = info.sheet_m[1] * 1e3;
  const zs = parseFloat($("zscale").value) || 1, byDisp = $("colour").value === "disp";
  const recolour = byDisp || coloured !== "layer";
  let maxd = 1e-9;
  if (byDisp) for (let i = 0; i < grid.length; i++) maxd = Math.max(maxd, rest[i] - grid[i]);
  for (let layer = 0; layer < 3; layer++) {
    const geom = meshes[layer].geometry, pos = geom.attributes.position.array, col = geom.attributes.color.array;
    if (!meshes[layer].visible) continue;
    for (let r = 0; r < ny; r++)
      for (let c = 0; c < nx; c++) {
        const v = r * nx + c, g = v * 3 + layer;
        pos[v * 3] = -sx / 2 + (c + 0.5) * sx / nx;
        pos[v * 3 + 1] = -sy / 2 + (r + 0.5) * sy / ny;
        pos[v * 3 + 2] = zDraw(grid[g] * 1e3, zs);
        if (recolour) {
          const rgb = byDisp ? colourmap((rest[g] - grid[g]) / maxd) : LAYER_RGB[layer];
          col[v * 3] = rgb[0]; col[v * 3 + 1] = rgb[1]; col[v * 3 + 2] = rgb[2];
        }
      }
    geom.attributes.position.needsUpdate = true;
    geom.attributes.color.needsUpdate = recolour;
    geom.computeVertexNormals();
  }
  coloured = byDisp ? "disp" : "layer";
  $("disp-scale").style.display = byDisp ? "block" : "none";
  if (byDisp) { $("disp-min").textContent = "0"; $("disp-max").textContent = `${(maxd * 1e3).toFixed(3)} mm deeper than rest`; }
  state.dispMaxMm = byDisp ? maxd * 1e3 : null;
  updateCurtain();
}

// the cut face: three coloured bands (epidermis, dermis, fat) in the plane y = tool y, from the last grid
const curtain = [0, 1, 2].map((layer) => {
  const c = new THREE.Color().setRGB(...LAYER_RGB[layer], THREE.SRGBColorSpace);
  const m = new THREE.Mesh(new THREE.BufferGeometry(), new THREE.MeshBasicMaterial({ color: c, side: THREE.DoubleSide }));
  m.visible = false; scene.add(m); return m;
});
let curtainN = 0;
function updateCurtain() {
  const show = !!(lastGrid && state.info && $("cutaway").checked && tool.visible);
  curtain.forEach((m) => { m.visible = show; });
  state.cutBands = show;
  if (!show) return;
  const info = state.info, sx = info.sheet_m[0] * 1e3, sy = info.sheet_m[1] * 1e3, zs = parseFloat($("zscale").value) || 1;
  const r = Math.min(ny - 1, Math.max(0, Math.floor((toolY + sy / 2) / sy * ny)));
  const bottom = -1e3 * (info.thickness_m || [0, 0, 0]).reduce((a, b) => a + b, 0);
  if (curtainN !== nx) { // (re)build the strips' index once per grid size
    curtainN = nx;
    const idx = [];
    for (let c = 0; c < nx - 1; c++) idx.push(2 * c, 2 * c + 1, 2 * c + 3, 2 * c, 2 * c + 3, 2 * c + 2);
    curtain.forEach((m) => { m.geometry.setAttribute("position", new THREE.BufferAttribute(new Float32Array(nx * 6), 3)); m.geometry.setIndex(idx); });
  }
  for (let c = 0; c < nx; c++) {
    const x = -sx / 2 + (c + 0.5) * sx / nx, g = (r * nx + c) * 3;
    const z0 = zDraw(lastGrid[g] * 1e3, zs);
    const z1 = Math.min(zDraw(lastGrid[g + 1] * 1e3, zs), z0 - MIN_BAND_MM);
    const z2 = Math.min(zDraw(lastGrid[g + 2] * 1e3, zs), z1 - MIN_BAND_MM);
    const z3 = Math.min(zDraw(bottom, zs), z2 - MIN_BAND_MM);
    [[z0, z1], [z1, z2], [z2, z3]].forEach(([top, bot], layer) => {
      const p = curtain[layer].geometry.attributes.position.array;
      p.set([x, toolY + 0.02, top, x, toolY + 0.02, bot], c * 6);
    });
  }
  curtain.forEach((m) => { m.geometry.attributes.position.needsUpdate = true; m.geometry.computeBoundingSphere(); });
}
for (const [id, i] of [["show-surface", 0], ["show-i1", 1], ["show-i2", 2]])
  $(id).addEventListener("change", () => { if (meshes) { meshes[i].visible = $(id).checked; coloured = ""; if (lastGrid) updateMeshes(lastGrid); } dirty = true; });
for (const id of ["colour", "zscale", "cutaway"])
  $(id).addEventListener("change", () => {
    cut.constant = $("cutaway").checked && tool.visible ? -toolY : 1e4;
    coloured = ""; if (lastGrid) updateMeshes(lastGrid);
    if (lastHeader && state.info) { updateTool(lastHeader); updateHands(lastHeader); } // the needle and its track follow the z scale
    dirty = true;
  });

// tool as configured (tissue.tool.shape): a flat punch is a cylinder whose face is the tip; a sphere sits on its tip.
// Its origin is the tip. The force arrow stands beside it (on the tool's axis the shaft hid it), unlit cyan.
const toolMat = new THREE.MeshStandardMaterial({ color: 0x7f9cc4, metalness: 0.2, roughness: 0.6 }); // steel blue: told apart from skin and the cyan arrow
const SHAFT_MM = 30;
const tip = new THREE.Mesh(new THREE.SphereGeometry(1, 24, 16), toolMat);
const punch = new THREE.Mesh(new THREE.CylinderGeometry(1, 1, 1, 32), toolMat);
const shaft = new THREE.Mesh(new THREE.CylinderGeometry(1, 1, 1, 16), toolMat);
punch.rotation.x = shaft.rotation.x = Math.PI / 2;
const tool = new THREE.Group();
tool.add(tip, punch, shaft);
tool.visible = false;
scene.add(tool);
const ARROW_RGB = 0x00e5ff, MM_PER_N = 4, ARROW_MAX_MM = 30, ARROW_MIN_MM = 3;
const arrowMat = new THREE.MeshBasicMaterial({ color: ARROW_RGB });
const arrowShaft = new THREE.Mesh(new THREE.CylinderGeometry(0.6, 0.6, 1, 12), arrowMat);
const arrowHead = new THREE.Mesh(new THREE.ConeGeometry(1.8, 4, 16), arrowMat);
arrowShaft.rotation.x = arrowHead.rotation.x = Math.PI / 2;
const arrow = new THREE.Group();
arrow.add(arrowShaft, arrowHead);
arrow.visible = false;
scene.add(arrow);
function setArrowOn(shaftM, headM, lenMm) { // total length lenMm, pointing +z from the group's origin
  const head = Math.min(4, lenMm * 0.4);
  shaftM.scale.set(1, lenMm - head, 1); shaftM.position.set(0, 0, (lenMm - head) / 2);
  const k = Math.max(0.5, head / 4); // a short arrow keeps a head no wider than its proportion
  headM.scale.set(k, head / 4, k); headM.position.set(0, 0, lenMm - head / 2);
}
const setArrow = (lenMm) => setArrowOn(arrowShaft, arrowHead, lenMm);
const patch = new THREE.Mesh(new THREE.RingGeometry(0.8, 1.0, 48), new THREE.MeshBasicMaterial({ color: 0xff5252, side: THREE.DoubleSide }));
patch.visible = false;
scene.add(patch);
// the friction's anchor (issue 30, tool/contact_model's friction_anchor_m): where the skin under the tool is at rest;
// the tool's offset from it is the skin's stretch. A small yellow disc on the surface, and a line to the tool's tip.
const anchorMat = new THREE.MeshBasicMaterial({ color: 0xffd600, side: THREE.DoubleSide });
const anchorDot = new THREE.Mesh(new THREE.CircleGeometry(0.5, 24), anchorMat);
anchorDot.visible = false;
scene.add(anchorDot);
const anchorLine = new THREE.Line(new THREE.BufferGeometry().setFromPoints([new THREE.Vector3(), new THREE.Vector3()]),
  new THREE.LineBasicMaterial({ color: 0xffd600 }));
anchorLine.visible = false;
scene.add(anchorLine);
$("arrow-scale").textContent = `${MM_PER_N} mm per N (${ARROW_MIN_MM}-${ARROW_MAX_MM} mm)`;

function surfaceAt(x, y) { // surface height (m) under (x, y) m, from the last grid
  if (!lastGrid || !state.info) return 0;
  const [sx, sy] = state.info.sheet_m;
  const c = Math.min(nx - 1, Math.max(0, Math.floor((x + sx / 2) / sx * nx)));
  const r = Math.min(ny - 1, Math.max(0, Math.floor((y + sy / 2) / sy * ny)));
  return lastGrid[(r * nx + c) * 3];
}

const TIP_LAYERS = ["epidermis", "dermis", "fat"];
function depthReached(depthM) { // the layer whose rest depth range holds the tool's depth (the interfaces at rest)
  if (!(depthM > 0)) return "none (not in contact)";
  const th = state.info.thickness_m || [0, 0, 0];
  let k = 0, bottom = th[0];
  while (k < 2 && depthM > bottom) bottom += th[++k];
  const top = bottom - th[k];
  return `${TIP_LAYERS[k]} (its rest depth ${(top * 1e3).toFixed(3)}-${(bottom * 1e3).toFixed(3)} mm)`;
}

// --- the needle (tool.shape 'needle'; tissue/needle, skin_sim_msgs/msg/NeedleState) ---------------------------------
// The needle: a cylinder of needle.outer_diameter_m from the tip back NEEDLE_BACK_MM along the axis. The track: from the
// entry along the axis to the deepest insertion of this track (thin, grey), and over it each punctured layer's segment
// (crossing_m[i] to crossing_m[i + 1], up to the deepest insertion) in the layer's colour, thicker than the needle so
// the colour rings it; intact layers ahead are not coloured. Drawn over the tissue (no depth test, like an X-ray), so
// the track shows in the cut and through the surface. The z scale applies as to everything below the rest surface.
const NEEDLE_BACK_MM = 30;
const needleMat = new THREE.MeshStandardMaterial({ color: 0xd8dde3, metalness: 0.5, roughness: 0.35, depthTest: false });
const trackMat = new THREE.MeshBasicMaterial({ color: 0x8a9099, depthTest: false });
const segMats = LAYER_RGB.map((rgb) => new THREE.MeshBasicMaterial({ color: new THREE.Color().setRGB(...rgb, THREE.SRGBColorSpace), depthTest: false }));
const needleGroup = new THREE.Group();
scene.add(needleGroup);
function tube(mat, order, parent = needleGroup) {
  const m = new THREE.Mesh(new THREE.CylinderGeometry(1, 1, 1, 16), mat);
  m.renderOrder = order; m.visible = false; parent.add(m); return m;
}
const needleTubes = [tube(needleMat, 12), tube(needleMat, 12)]; // tip to the rest surface, and above it (unscaled z)
const edgeMat = new THREE.MeshBasicMaterial({ color: 0x15181d, depthTest: false }); // a dark rim: told apart from the cut's bands
function trackTubes(parent = needleGroup) { // a needle's track: the grey line, each punctured layer's segment and its rim
  return { track: tube(trackMat, 10, parent), segs: [0, 1, 2].map((i) => tube(segMats[i], 11, parent)),
    edges: [0, 1, 2].map(() => tube(edgeMat, 10, parent)) };
}
const firstTrack = trackTubes(), trackTube = firstTrack.track, segTubes = firstTrack.segs;
const EDGE_MM = 0.12;
const Y_AXIS = new THREE.Vector3(0, 1, 0);
function placeTube(m, a, b, r) { // the unit cylinder (along its y) from a to b (drawn mm), radius r mm
  const d = new THREE.Vector3().subVectors(b, a), len = d.length();
  m.visible = len > 1e-6;
  if (!m.visible) return;
  m.position.copy(a).addScaledVector(d, 0.5);
  m.quaternion.setFromUnitVectors(Y_AXIS, d.divideScalar(len));
  m.scale.set(r, len, r);
}
const drawPt = (p, zs) => new THREE.Vector3(p[0] * 1e3, p[1] * 1e3, zDraw(p[2] * 1e3, zs)); // m (tissue frame) -> drawn mm
const along = (p, axis, s) => [p[0] + axis[0] * s, p[1] + axis[1] * s, p[2] + axis[2] * s];
function poseAxis(q) { // R(q) (0, 0, -1): the needle's axis from tool/pose (msgs_schema/topics.py); frames.pose_axis
  if (!q) return [0, 0, -1];
  const n = Math.hypot(...q) || 1, [x, y, z, w] = q.map((c) => c / n);
  return [-2 * (x * z + w * y), -2 * (y * z - w * x), -(1 - 2 * (x * x + y * y))];
}
function drawTrack(nd, zs, rmm, tubes, rec) { // a needle's track (tubes: trackTubes()) into rec.track and rec.segments
  tubes.track.visible = false; tubes.segs.forEach((m) => { m.visible = false; }); tubes.edges.forEach((m) => { m.visible = false; });
  if (!(nd && nd.inserted && nd.deepest_m > 0)) return rec;
  const end = nd.deepest_m, cr = nd.crossing_m;
  placeTube(tubes.track, drawPt(nd.entry_m, zs), drawPt(along(nd.entry_m, nd.axis, end), zs), Math.max(0.08, rmm * 0.45));
  rec.track = { entryM: nd.entry_m, endM: along(nd.entry_m, nd.axis, end), lengthM: end };
  for (let i = 0; i < Math.min(nd.ruptured_layers, 3, cr.length); i++) {
    const s0 = cr[i], s1 = Math.min(i + 1 < cr.length ? cr[i + 1] : end, end);
    if (!(s1 > s0)) continue;
    const a = drawPt(along(nd.entry_m, nd.axis, s0), zs), b = drawPt(along(nd.entry_m, nd.axis, s1), zs), r = Math.max(0.25, rmm * 1.8);
    placeTube(tubes.segs[i], a, b, r);
    placeTube(tubes.edges[i], a, b, r + EDGE_MM);
    rec.segments.push({ layer: i, s0M: s0, s1M: s1 });
  }
  return rec;
}
function updateNeedle(h, zs) { // true when a needle is drawn
  const nd = h.needle, shape = state.info.tool_shape;
  const on = !!nd || (shape === "needle" && !!h.tool);
  needleGroup.visible = on;
  $("needle-info").style.display = on ? "block" : "none";
  if (!on) { state.needle = null; return false; }
  const rmm = (state.info.needle_outer_diameter_m || 0.819e-3) * 1e3 / 2;
  const tipM = nd ? nd.tip_m : h.tool, axis = nd ? nd.axis : poseAxis(h.tool_q);
  // the shaft, split where it crosses the rest surface (z = 0): the z scale bends it there as it bends the tissue
  const backM = along(tipM, axis, -NEEDLE_BACK_MM * 1e-3);
  const pts = [tipM];
  if ((tipM[2] < 0) !== (backM[2] < 0)) { const t = tipM[2] / (tipM[2] - backM[2]); pts.push(along(tipM, axis, -t * NEEDLE_BACK_MM * 1e-3)); }
  pts.push(backM);
  needleTubes.forEach((m, i) => { if (i + 1 < pts.length) placeTube(m, drawPt(pts[i], zs), drawPt(pts[i + 1], zs), rmm); else m.visible = false; });
  const rec = { tipM, axis, backM, angleDeg: Math.acos(Math.min(1, Math.max(-1, -axis[2]))) * 180 / Math.PI, track: null, segments: [] };
  drawTrack(nd, zs, rmm, firstTrack, rec);
  state.needle = rec;
  // the text overlay: gauge and diameter, insertion, dimple, punctured layers, the axial force's parts
  const g = state.info.needle_gauge, dmm = (2 * rmm).toFixed(3);
  const lines = [`needle ${g ? `${g} G, ` : ""}${dmm} mm outer diameter${state.info.needle_diameter_source ? ` (${state.info.needle_diameter_source})` : ""}` +
    `, ${rec.angleDeg.toFixed(1)}\u00b0 from vertical`];
  if (nd) {
    const names = TIP_LAYERS.slice(0, nd.ruptured_layers);
    lines.push(`insertion ${(nd.insertion_m * 1e3).toFixed(2)} mm (deepest ${(nd.deepest_m * 1e3).toFixed(2)} mm) \u00b7 dimple ${(nd.dimple_m * 1e3).toFixed(2)} mm`);
    lines.push(`punctured ${nd.ruptured_layers} of 3${names.length ? ` (${names.join(", ")})` : ""}${nd.inserted ? "" : " \u00b7 no track"}`);
    lines.push(`axial: dimple ${nd.dimple_force_n.toFixed(3)} N \u00b7 cutting ${nd.cutting_force_n.toFixed(3)} N \u00b7 friction ${nd.friction_force_n.toFixed(3)} N \u00b7 |F| ${Math.hypot(...nd.force_n).toFixed(3)} N`);
  } else lines.push("no tissue/needle from the node: drawn from tool/pose");
  $("needle-info").textContent = lines.join("\n");
  state.needleText = $("needle-info").textContent;
  return true;
}
window.skinViewNeedle = () => { // for tests: what is drawn, read back from the scene's meshes (drawn mm)
  needleGroup.updateMatrixWorld(true);
  const ends = (m) => m.visible && needleGroup.visible
    ? [new THREE.Vector3(0, -0.5, 0), new THREE.Vector3(0, 0.5, 0)].map((v) => m.localToWorld(v).toArray()) : null;
  return { visible: needleGroup.visible, zscale: parseFloat($("zscale").value) || 1, radiusMm: needleTubes[0].scale.x,
    needle: needleTubes.map(ends), track: ends(trackTube), segments: segTubes.map(ends),
    segmentColours: segMats.map((m) => m.color.getHexString()), rec: state.needle,
    hands: Object.fromEntries(handDraw.map((d) => { // a second hand's needle track (drawn mm), as the first's
      d.tubes.track.parent.updateMatrixWorld(true);
      const e = (m) => (m.visible ? [new THREE.Vector3(0, -0.5, 0), new THREE.Vector3(0, 0.5, 0)].map((v) => m.localToWorld(v).toArray()) : null);
      return [d.spec.ns, { track: e(d.tubes.track), segments: d.tubes.segs.map(e), rec: state.handTracks[d.spec.ns] || null }];
    })) };
};

let shownShape = "";
function updateTool(h) {
  const zs = parseFloat($("zscale").value) || 1, rmm = state.info.tool_radius_m * 1e3;
  const needle = updateNeedle(h, zs), shape = needle ? "needle" : state.info.tool_shape || "flat";
  if (shape !== shownShape) { // geometry of the configured tool (a needle: the needle group instead)
    shownShape = shape;
    const flat = shape === "flat";
    tip.visible = shape === "sphere"; punch.visible = flat;
    tip.scale.setScalar(rmm); tip.position.set(0, 0, rmm);
    punch.scale.set(rmm, SHAFT_MM, rmm); punch.position.set(0, 0, SHAFT_MM / 2);
    shaft.visible = shape === "sphere";
    shaft.scale.set(rmm * 0.6, SHAFT_MM, rmm * 0.6); shaft.position.set(0, 0, rmm + SHAFT_MM / 2);
    state.toolShape = shape === "sphere" ? "sphere" : flat ? "cylinder" : "needle";
  }
  if (h.tool) {
    const [x, y, z] = h.tool.map((v) => v * 1e3);
    tool.visible = true;
    tool.position.set(x, y, zDraw(z, zs));
    toolY = y;
    cut.constant = $("cutaway").checked ? -y : 1e4;
    state.toolZDrawnMm = zDraw(z, zs);
    $("tip-layer").textContent = depthReached(h.depth_m);
  }
  const f = h.force_max !== undefined ? h.force_max : h.force ? h.force[2] : 0;
  const at = h.tool ? h.tool : [0, 0, 0];
  const zsurf = zDraw(surfaceAt(at[0], at[1]) * 1e3, zs);
  arrow.visible = f > 1e-4;
  state.arrowLenMm = 0;
  if (arrow.visible) {
    const len = Math.min(ARROW_MAX_MM, Math.max(ARROW_MIN_MM, f * MM_PER_N));
    arrow.position.set(at[0] * 1e3 + arrowSide(h, 0) * (rmm + 4), at[1] * 1e3, Math.max(zsurf, 0) + 0.5);
    setArrow(len);
    state.arrowLenMm = len;
  }
  placeArrowLabel(f);
  patch.visible = f > 1e-4 && shownShape !== "needle"; // a needle's contact is its tip, drawn
  if (patch.visible) { patch.position.set(at[0] * 1e3, at[1] * 1e3, zsurf + 0.05); patch.scale.setScalar(rmm); }
  anchorDot.visible = anchorLine.visible = !!h.anchor && shownShape !== "needle";
  state.anchorMm = null;
  if (anchorDot.visible) {
    const [ax, ay] = h.anchor.map((v) => v * 1e3);
    anchorDot.position.set(ax, ay, zsurf + 0.1);
    anchorLine.geometry.setFromPoints([new THREE.Vector3(ax, ay, zsurf + 0.1), new THREE.Vector3(at[0] * 1e3, at[1] * 1e3, zsurf + 0.1)]);
    state.anchorMm = [ax, ay];
  }
  updateCurtain();
}
function placeArrowLabel(f) { // "0.740 N" at the arrow's head, in screen coordinates (two hands: "right 0.740 N")
  const hands = state.info && state.info.hands;
  placeLabel($("arrow-label"), arrow, state.arrowLenMm, `${hands ? `${handName(hands[0], 0)} ` : ""}${f.toFixed(3)} N`);
}
function placeLabel(el, arrowObj, lenMm, text) {
  if (!arrowObj.visible) { el.style.display = "none"; return; }
  const p = arrowObj.position.clone();
  p.z += lenMm + 1;
  p.project(camera);
  el.style.display = "block";
  el.style.left = `${Math.min(host.clientWidth - 80, Math.max(0, (p.x + 1) / 2 * host.clientWidth + 6))}px`;
  el.style.top = `${Math.min(host.clientHeight - 40, Math.max(24, (1 - p.y) / 2 * host.clientHeight - 8))}px`;
  el.textContent = text;
}

// --- two hands (issue 32): the second hand's tool, force arrow and label, contact patch and friction anchor ----------
// The first hand is drawn as a single hand's tool (above: the frame's top-level fields, its needle with track and
// overlay); the second from the frame's hands[1], with the node's second_tool_shape / second_tool_radius_m: the same
// steel-blue punch or sphere, or a needle's shaft with its track from its <hand>/tissue/needle (drawTrack, as the first
// hand's; the text overlay is the first hand's only). Its arrow
// is orange and stands on the side away from the other tool, as the first hand's does then.
const HAND_RGB = [ARROW_RGB, 0xff9100];
const handName = (spec, i) => spec.ns || `hand ${i + 1}`;
let handDraw = [], handsKey = "null"; // drawing objects of state.info.hands[1:], and the hands they were built for
function arrowSide(h, i) { // +1: the arrow beside the tool at +x; two hands: on the side away from the other hand
  if (!h.hands || h.hands.length < 2) return 1;
  const me = h.hands[i].tool, other = h.hands[1 - i].tool;
  if (!me || !other || me[0] === other[0]) return 1;
  return me[0] > other[0] ? 1 : -1;
}
function buildHands(hands) {
  handDraw.forEach((d) => { d.objects.forEach((o) => scene.remove(o)); d.label.remove(); });
  handDraw = (hands || []).slice(1).map((spec, k) => {
    const i = k + 1, rmm = spec.radius_m * 1e3, rgb = HAND_RGB[i % HAND_RGB.length];
    const tp = new THREE.Mesh(tip.geometry, toolMat), pu = new THREE.Mesh(punch.geometry, toolMat), sh = new THREE.Mesh(shaft.geometry, toolMat);
    pu.rotation.x = sh.rotation.x = Math.PI / 2;
    tp.visible = spec.shape === "sphere"; pu.visible = spec.shape === "flat"; sh.visible = spec.shape === "sphere";
    tp.scale.setScalar(rmm); tp.position.set(0, 0, rmm);
    pu.scale.set(rmm, SHAFT_MM, rmm); pu.position.set(0, 0, SHAFT_MM / 2);
    sh.scale.set(rmm * 0.6, SHAFT_MM, rmm * 0.6); sh.position.set(0, 0, rmm + SHAFT_MM / 2);
    const group = new THREE.Group();
    group.add(tp, pu, sh); group.visible = false;
    const needles = [0, 1].map(() => { const m = new THREE.Mesh(new THREE.CylinderGeometry(1, 1, 1, 16), needleMat); m.renderOrder = 12; m.visible = false; return m; });
    const trackGroup = new THREE.Group(); // its needle's track (from its <hand>/tissue/needle), drawn as the first hand's
    const tubes = trackTubes(trackGroup);
    const mat = new THREE.MeshBasicMaterial({ color: rgb });
    const aShaft = new THREE.Mesh(arrowShaft.geometry, mat), aHead = new THREE.Mesh(arrowHead.geometry, mat);
    aShaft.rotation.x = aHead.rotation.x = Math.PI / 2;
    const arr = new THREE.Group();
    arr.add(aShaft, aHead); arr.visible = false;
    const pat = new THREE.Mesh(patch.geometry, patch.material); pat.visible = false;
    const dot = new THREE.Mesh(anchorDot.geometry, anchorMat); dot.visible = false;
    const line = new THREE.Line(new THREE.BufferGeometry().setFromPoints([new THREE.Vector3(), new THREE.Vector3()]), anchorLine.material);
    line.visible = false;
    const label = document.createElement("div");
    label.className = "hand-label"; label.dataset.hand = spec.ns;
    label.style.color = `#${rgb.toString(16).padStart(6, "0")}`;
    host.appendChild(label);
    const objects = [group, ...needles, trackGroup, arr, pat, dot, line];
    objects.forEach((o) => scene.add(o));
    return { spec, i, group, needles, tubes, arr, aShaft, aHead, pat, dot, line, label, objects, lenMm: 0, text: "" };
  });
  // the per-hand force read-out in the side panel (a single hand: hidden; #force alone, as before)
  const el = $("hand-forces");
  el.style.display = hands ? "block" : "none";
  $("force-hand").textContent = hands ? `(${handName(hands[0], 0)})` : "";
  el.innerHTML = (hands || []).map((spec, i) => `<div><span class="sw" style="background: #${HAND_RGB[i % HAND_RGB.length].toString(16).padStart(6, "0")}"></span>` +
    `${handName(spec, i)} (${spec.shape === "needle" ? "needle" : `${spec.shape}, radius ${(spec.radius_m * 1e3).toFixed(2)} mm`}): <span class="hand-force" data-hand="${spec.ns}">-</span> N</div>`).join("") +
    (hands && state.info.tools_source ? `<div id="tools-source" class="note">tools from ${state.info.tools_source}</div>` : ""); // a two-hand bag's tools
  state.handForces = {}; state.handDepthM = {}; state.handArrowLenMm = {}; state.handLabels = {}; state.handTools = {}; state.handTracks = {};
}
function updateHands(h) { // the second hand's drawing and every hand's read-out, from the frame's hands
  const hands = state.info && state.info.hands;
  if (!hands) return;
  const zs = parseFloat($("zscale").value) || 1;
  (h.hands || []).forEach((hh, i) => {
    const f = hh.force_max !== undefined ? hh.force_max : hh.force ? hh.force[2] : null;
    state.handForces[hh.ns] = f;
    state.handDepthM[hh.ns] = hh.depth_m !== undefined ? hh.depth_m : null;
    const el = document.querySelector(`.hand-force[data-hand="${hh.ns}"]`);
    if (el) el.textContent = f !== null ? f.toFixed(4) : "-";
  });
  const first = hands[0];
  state.handArrowLenMm[first.ns] = state.arrowLenMm; state.handTools[first.ns] = h.tool ? state.toolShape : null;
  state.handLabels[first.ns] = arrow.visible ? $("arrow-label").textContent : "";
  handDraw.forEach((d) => {
    const hh = (h.hands || [])[d.i] || {}, spec = d.spec, rmm = spec.radius_m * 1e3;
    const f = hh.force_max !== undefined ? hh.force_max : hh.force ? hh.force[2] : 0;
    const at = hh.tool || [0, 0, 0];
    d.group.visible = !!hh.tool && spec.shape !== "needle";
    if (d.group.visible) d.group.position.set(at[0] * 1e3, at[1] * 1e3, zDraw(at[2] * 1e3, zs));
    const needleOn = spec.shape === "needle" && (!!hh.needle || !!hh.tool);
    d.needles.forEach((m) => { m.visible = false; });
    if (needleOn) { // the shaft from the tip back NEEDLE_BACK_MM, split at the rest surface (the z scale bends it there)
      const tipM = hh.needle ? hh.needle.tip_m : hh.tool, axis = hh.needle ? hh.needle.axis : poseAxis(hh.tool_q);
      const backM = along(tipM, axis, -NEEDLE_BACK_MM * 1e-3), pts = [tipM];
      if ((tipM[2] < 0) !== (backM[2] < 0)) { const t = tipM[2] / (tipM[2] - backM[2]); pts.push(along(tipM, axis, -t * NEEDLE_BACK_MM * 1e-3)); }
      pts.push(backM);
      const r = (state.info.needle_outer_diameter_m || 0.819e-3) * 1e3 / 2;
      for (let k = 0; k + 1 < pts.length; k++) placeTube(d.needles[k], drawPt(pts[k], zs), drawPt(pts[k + 1], zs), r);
    }
    const rec = drawTrack(needleOn ? hh.needle : null, zs, (state.info.needle_outer_diameter_m || 0.819e-3) * 1e3 / 2, d.tubes,
      { track: null, segments: [] });
    state.handTracks[spec.ns] = rec.track ? rec : null;
    state.handTools[spec.ns] = d.group.visible ? (spec.shape === "sphere" ? "sphere" : "cylinder") : needleOn ? "needle" : null;
    const zsurf = zDraw(surfaceAt(at[0], at[1]) * 1e3, zs);
    d.arr.visible = f > 1e-4;
    d.lenMm = 0;
    if (d.arr.visible) {
      d.lenMm = Math.min(ARROW_MAX_MM, Math.max(ARROW_MIN_MM, f * MM_PER_N));
      d.arr.position.set(at[0] * 1e3 + arrowSide(h, d.i) * (rmm + 4), at[1] * 1e3, Math.max(zsurf, 0) + 0.5);
      setArrowOn(d.aShaft, d.aHead, d.lenMm);
    }
    d.text = `${handName(spec, d.i)} ${f.toFixed(3)} N`;
    placeLabel(d.label, d.arr, d.lenMm, d.text);
    state.handArrowLenMm[spec.ns] = d.lenMm;
    state.handLabels[spec.ns] = d.arr.visible ? d.label.textContent : "";
    d.pat.visible = f > 1e-4 && spec.shape !== "needle";
    if (d.pat.visible) { d.pat.position.set(at[0] * 1e3, at[1] * 1e3, zsurf + 0.05); d.pat.scale.setScalar(rmm); }
    d.dot.visible = d.line.visible = !!hh.anchor && spec.shape !== "needle";
    if (d.dot.visible) {
      const [ax, ay] = hh.anchor.map((v) => v * 1e3);
      d.dot.position.set(ax, ay, zsurf + 0.1);
      d.line.geometry.setFromPoints([new THREE.Vector3(ax, ay, zsurf + 0.1), new THREE.Vector3(at[0] * 1e3, at[1] * 1e3, zsurf + 0.1)]);
    }
  });
}
const placeHandLabels = () => handDraw.forEach((d) => placeLabel(d.label, d.arr, d.lenMm, d.text));

// --- plots --------------------------------------------------------------------------------
const hist = { t: [], f: [], d: [], hands: [] }; // live: rolling, last HIST_S seconds; hands: each hand's {f, d} (two hands)
const HIST_S = 10;
let timeline = null;
const PLOT_RGB = ["#4fc3f7", "#ff9100"]; // the first hand's line (a single hand's), the second hand's (its arrow's orange)
function drawPlot(canvas, xs, ys, xlabel, cursor, more = []) {
  // more: further lines [{xs, ys, label, cursor}] (a two-hand bag: every hand's, each labelled in its colour)
  const ctx = canvas.getContext("2d"), W = canvas.width, H = canvas.height;
  ctx.clearRect(0, 0, W, H);
  ctx.fillStyle = "#889"; ctx.font = "10px sans-serif";
  const lines = more.length ? more : [{ xs, ys, cursor }];
  const allX = lines.flatMap((l) => l.xs), allY = lines.flatMap((l) => l.ys);
  if (!allX.length) return;
  let x0 = Math.min(...allX), x1 = Math.max(...allX), y1 = Math.max(0.01, ...allY);
  if (x1 - x0 < 1e-9) x1 = x0 + 1;
  const X = (x) => 30 + (x - x0) / (x1 - x0) * (W - 36), Y = (y) => H - 14 - y / y1 * (H - 22);
  ctx.fillText(`${y1.toFixed(3)} N`, 2, 10); ctx.fillText(xlabel, W - 60, H - 2);
  ctx.fillText(x0.toFixed(2), 30, H - 2);
  lines.forEach((l, k) => {
    ctx.strokeStyle = PLOT_RGB[k % PLOT_RGB.length]; ctx.beginPath();
    l.xs.forEach((x, i) => (i ? ctx.lineTo(X(x), Y(l.ys[i])) : ctx.moveTo(X(x), Y(l.ys[i]))));
    ctx.stroke();
    if (l.label) { ctx.fillStyle = PLOT_RGB[k % PLOT_RGB.length]; ctx.fillText(l.label, W - 60, 10 + 11 * k); }
  });
  lines.forEach((l, k) => { // the cursor (red); each further hand's in its line's colour, dashed
    if (l.cursor === undefined) return;
    ctx.strokeStyle = k ? PLOT_RGB[k % PLOT_RGB.length] : "#ff5252"; ctx.setLineDash(k ? [3, 3] : []);
    ctx.beginPath(); ctx.moveTo(X(l.cursor), 0); ctx.lineTo(X(l.cursor), H); ctx.stroke();
  });
  ctx.setLineDash([]);
  return lines.map((l) => l.label || "");
}
let plotH = null, plotsDirty = false;
function plots(h) { // records every frame; the canvases are redrawn with the scene, at most RENDER_HZ
  plotH = h; plotsDirty = true;
  if (timeline) return;
  const t = performance.now() / 1e3;
  hist.t.push(t); hist.f.push(h.force_max !== undefined ? h.force_max : h.force ? h.force[2] : 0); hist.d.push((h.depth_m || 0) * 1e3);
  // a two-hand node: each hand's force and depth too, on the same times (a hand without a sample yet: 0, as above)
  const specs = (state.info && state.info.hands) || [];
  if (hist.hands.length !== specs.length) hist.hands = specs.map(() => ({ f: hist.t.slice(1).map(() => 0), d: hist.t.slice(1).map(() => 0) }));
  hist.hands.forEach((l, k) => {
    const hh = (h.hands || [])[k] || {};
    l.f.push(hh.force_max !== undefined ? hh.force_max : hh.force ? hh.force[2] : 0); l.d.push((hh.depth_m || 0) * 1e3);
  });
  while (hist.t.length && hist.t[0] < t - HIST_S) { hist.t.shift(); hist.f.shift(); hist.d.shift(); hist.hands.forEach((l) => { l.f.shift(); l.d.shift(); }); }
}
function drawPlots() {
  const h = plotH;
  if (timeline) {
    // a two-hand bag: every hand's force, a line each (labelled with its hand), each hand's own depth cursor
    const hands = timeline.hands || [], mm = (d) => (d !== undefined ? d * 1e3 : undefined);
    const byT = hands.map((l, k) => ({ xs: l.t_s, ys: l.force_n, label: l.ns || `hand ${k + 1}`, cursor: k ? undefined : h.t_s }));
    const byD = hands.map((l, k) => ({ xs: l.depth_m.map((d) => d * 1e3), ys: l.force_n, label: l.ns || `hand ${k + 1}`,
      cursor: mm(((h.hands || [])[k] || {}).depth_m) }));
    state.plotLabels = drawPlot($("plot-t"), timeline.t_s, timeline.force_n, "t (s)", h.t_s, byT);
    state.plotDepthLabels = drawPlot($("plot-d"), timeline.depth_m.map((d) => d * 1e3), timeline.force_n, "depth (mm)", mm(h.depth_m), byD);
    return;
  }
  const t = performance.now() / 1e3, ts = hist.t.map((x) => x - t);
  // a two-hand node: every hand's force, a line each labelled with its hand, as a two-hand bag's (a single hand: as before)
  const specs = (state.info && state.info.hands) || [], two = specs.length > 1 && hist.hands.length === specs.length;
  const byT = two ? hist.hands.map((l, k) => ({ xs: ts, ys: l.f, label: handName(specs[k], k) })) : [];
  const byD = two ? hist.hands.map((l, k) => ({ xs: l.d, ys: l.f, label: handName(specs[k], k) })) : [];
  state.plotLabels = drawPlot($("plot-t"), ts, hist.f, "t (s)", undefined, byT);
  state.plotDepthLabels = drawPlot($("plot-d"), hist.d, hist.f, "depth (mm)", undefined, byD);
}

// --- diagnostics --------------------------------------------------------------------------
function showDiag(d) {
  state.diag = d;
  $("diag-level").textContent = ["OK", "WARN", "ERROR", "STALE"][d.level] + ": " + d.message;
  const rows = Object.entries(d.values).concat(Object.entries(d.regime).map(([k, v]) => ["regime " + k, v]))
    .concat(Object.entries(d.counts).map(([k, v]) => ["count " + k, v]));
  $("diag").innerHTML = rows.map(([k, v]) => `<tr><td class="k">${k}</td><td>${v}</td></tr>`).join("");
}

// --- parameters ---------------------------------------------------------------------------
let paramList = [];
let paramRetry = null;
async function loadParams() {
  clearTimeout(paramRetry);
  let r;
  try { r = await (await fetch("/api/params")).json(); }
  catch (e) { r = { ok: false, reason: `view server: ${e}`, retry: true }; }
  if (!r.ok) {
    $("param-node").textContent = ""; $("params").innerHTML = `<div>${r.reason}</div>`;
    if (r.retry) paramRetry = setTimeout(loadParams, 2000); // the node's services may not be discovered yet
    return;
  }
  $("param-node").textContent = r.node;
  paramList = r.params;
  renderParams();
}
function renderParams() {
  const all = $("param-all").checked;
  $("params").innerHTML = paramList.filter((p) => all || p.tunable).map((p) =>
    `<div class="prow" title="${p.description.replace(/"/g, "&quot;")}"><span class="pname">${p.name}</span>` +
    `<input type="text" data-name="${p.name}" value="${p.value}"> <button data-set="${p.name}">set</button></div>`).join("");
}
$("param-all").addEventListener("change", renderParams);
$("params").addEventListener("click", (e) => { const n = e.target.dataset.set; if (n) setParam(n); });
$("params").addEventListener("keydown", (e) => { if (e.key === "Enter" && e.target.dataset.name) setParam(e.target.dataset.name); });
async function setParam(name) {
  const input = document.querySelector(`input[data-name="${name}"]`);
  const r = await (await fetch("/api/param", { method: "POST", body: JSON.stringify({ name, value: input.value }) })).json();
  state.lastParam = r;
  const el = $("param-result");
  el.className = r.ok ? "good" : "bad";
  el.textContent = r.ok ? `${name} = ${r.value}: ${r.reason}` : `${name} rejected: ${r.reason}`;
  if (!r.ok) input.value = r.value !== undefined ? r.value : input.value;
}
window.skinViewCamera = (pos, target) => { // for screenshots: frame the scene (drawn mm)
  camera.position.set(...pos); controls.target.set(...target); controls.update(); dirty = true; return true;
};
window.skinViewSetParam = async (name, value) => { // for tests: type into the page's field and press set
  document.querySelector(`input[data-name="${name}"]`).value = value;
  await setParam(name);
  return state.lastParam;
};

// --- timeline (bag) -----------------------------------------------------------------------
let scrubbing = false;
$("scrub").addEventListener("input", () => {
  scrubbing = true;
  fetch("/api/seek", { method: "POST", body: JSON.stringify({ t_s: parseFloat($("scrub").value) }) }).finally(() => { scrubbing = false; });
});
$("play").addEventListener("click", () => fetch("/api/play", { method: "POST", body: JSON.stringify({ on: $("play").textContent === "play" }) }));
function step(dir) {
  if (!timeline || !timeline.grid_t_s.length) return;
  const t = parseFloat($("scrub").value), g = timeline.grid_t_s;
  const next = dir > 0 ? g.find((x) => x > t + 1e-6) : [...g].reverse().find((x) => x < t - 1e-6);
  if (next !== undefined) fetch("/api/seek", { method: "POST", body: JSON.stringify({ t_s: next }) });
}
$("step-back").addEventListener("click", () => step(-1));
$("step-fwd").addEventListener("click", () => step(1));

// --- stream -------------------------------------------------------------------------------
let fpsCount = 0;
setInterval(() => { // held for a screenshot: the overlay keeps the rate it had, not the frames the hold let in
  if (!state.hold) { $("fps").textContent = fpsCount; state.fps = fpsCount; }
  fpsCount = 0;
}, 1000);
const heldQueue = [];
window.skinViewRelease = () => { state.hold = false; heldQueue.splice(0).forEach(onFrame); state.heldFrames = 0; return true; };
function onFrame(buf) {
  // held (state.hold, set by Browser.hold_when for a screenshot): keep the frame shown and queue the new ones; a
  // frame sends its grid only when the grid changed, so a dropped frame would leave a stale grid after the hold
  if (state.hold) { heldQueue.push(buf); state.heldFrames = heldQueue.length; return; }
  const dv = new DataView(buf), n = dv.getUint32(4, true);
  const h = JSON.parse(new TextDecoder().decode(new Uint8Array(buf, 8, n)));
  if (h.grid) {
    if (!meshes || h.grid.nx !== nx || h.grid.ny !== ny) buildMeshes(h.grid.nx, h.grid.ny);
    updateMeshes(new Float32Array(buf, 8 + n, h.grid.nx * h.grid.ny * 3));
    state.gridFrames++;
    $("grids").textContent = state.gridFrames;
  }
  state.frames++; fpsCount++;
  state.force = h.force_max !== undefined ? h.force_max : h.force ? h.force[2] : null;
  state.forceNewest = h.force ? h.force[2] : null;
  state.depth = h.depth_m;
  state.t_s = h.t_s;
  $("force").textContent = state.force !== null ? state.force.toFixed(4) : "-";
  $("depth").textContent = h.depth_m !== undefined ? (h.depth_m * 1e3).toFixed(2) : "-";
  $("layers").textContent = h.layers !== undefined ? h.layers : h.stress_pa ? h.stress_pa.filter((s) => s > 0).length : "-";
  lastHeader = h;
  updateTool(h);
  updateHands(h);
  plots(h);
  dirty = true;
  // the grid drawn and the tool may be from different instants (grids come at the display rate): say by how much
  let gdt = h.grid_dt_s;
  if (gdt === undefined && timeline && h.grid_index !== undefined && h.t_s !== undefined) gdt = timeline.grid_t_s[h.grid_index] - h.t_s;
  state.gridDtS = gdt;
  $("grid-dt").textContent = gdt === undefined ? "-" : `${gdt >= 0 ? "+" : ""}${(gdt * 1e3).toFixed(0)} ms`;
  if (h.t_s !== undefined) {
    $("play").textContent = h.playing ? "pause" : "play";
    if (!scrubbing) $("scrub").value = h.t_s;
    $("tlabel").textContent = `${h.t_s.toFixed(3)} / ${h.duration_s.toFixed(3)} s`;
  }
}
function connect() {
  const ws = new WebSocket(`ws://${location.host}/ws`);
  ws.binaryType = "arraybuffer";
  ws.onmessage = (e) => {
    if (typeof e.data !== "string") return onFrame(e.data);
    const m = JSON.parse(e.data);
    if (m.type === "info") {
      state.info = m; state.mode = m.mode; shownShape = "";
      if (JSON.stringify(m.hands || null) !== handsKey) { handsKey = JSON.stringify(m.hands || null); buildHands(m.hands); }
      const th = (m.thickness_m || []).map((t) => (t * 1e3).toFixed(3));
      $("legend-note").textContent = th.length ? `thickness ${th.join(" / ")} mm; in the cut each band is drawn at least ${MIN_BAND_MM} mm` : "";
      $("mode").textContent = m.mode === "bag" ? `bag ${m.bags.join(", ")}` : `live ${m.namespace}`;
      if (m.mode === "bag") { $("timeline").style.display = "block"; $("scrub").max = m.duration_s; }
      loadParams();
    } else if (m.type === "timeline") timeline = m;
    else if (m.type === "diag") showDiag(m);
  };
  ws.onclose = () => { $("mode").textContent = "disconnected: retrying"; setTimeout(connect, 1000); };
}
connect();
// render on demand only: a page that redraws an unchanged scene 60 times a second costs a CPU core under SwiftShader
controls.addEventListener("change", () => { dirty = true; if (arrow.visible) placeArrowLabel(state.force || 0); placeHandLabels(); });
window.addEventListener("resize", () => { dirty = true; });
// at most RENDER_HZ redraws: leaves the main thread time to take frames when WebGL runs on the CPU (no GPU)
// (10 when WebGL runs on the CPU: at 30 Hz SwiftShader took 1.5 of this machine's 2 cores from the haptic node)
const RENDER_HZ = parseFloat(new URLSearchParams(location.search).get("render_hz") || (software ? "10" : "30"));
let lastRender = 0, lastPlots = 0;
(function loop(now) {
  requestAnimationFrame(loop);
  if (dirty && now - lastRender >= 1000 / RENDER_HZ - 2) {
    dirty = false; lastRender = now;
    renderer.render(scene, camera);
    state.renders = (state.renders || 0) + 1;
    state.renderedFrames = state.frames; // the frames received up to this render (tests wait for a frame's render)
    state.renderedCut = state.cutBands; state.renderedColour = coloured;
  }
  if (plotsDirty && now - lastPlots >= 1000 / RENDER_HZ - 2) { // 2D canvases cost CPU too: same cap
    plotsDirty = false; lastPlots = now;
    drawPlots();
  }
})(0);
