// PRT viewer: loads a GLB exported by PRT for Blender and relights it live like the original SHDemo.
// Keys: 1-8 select a light (adding suns up to it), Q/A θ −/+5°, W/E φ −/+5° (Shift: 1°), F1 Blinn-Phong, F2 PRT,
// T textures, N normals, L light vectors; drag to orbit. A dynamic object (lit from the probe volumes): Tab picks
// one, arrows and PgUp/PgDn move it, [ ] turn it (mover.js). URL parameters: file (default scene.glb), light (1-8),
// theta and phi (degrees, the active sun's), lights (keep or add up to N), textures (0/1), mode (prt/phong),
// outline (0: no box around the object the keys move).
import * as THREE from "three";
import {GLTFLoader} from "three/addons/loaders/GLTFLoader.js";
import {OrbitControls} from "three/addons/controls/OrbitControls.js";
import {VertexNormalsHelper} from "three/addons/helpers/VertexNormalsHelper.js";
import {DEGREE, LightSet} from "./lights.js";
import {MAX_SUNS, attributeName, prtMaterial, setLight} from "./prt_material.js";
import {Mover} from "./mover.js";
import {loadVolumes} from "./probes.js";

const STEP = 5 * DEGREE, FINE_STEP = 1 * DEGREE;
const MODES = {1: "Blinn-Phong (F1)", 2: "PRT (F2)"};
const params = new URLSearchParams(location.search);
const readout = document.getElementById("readout");

const renderer = new THREE.WebGLRenderer({antialias: true, alpha: true, preserveDrawingBuffer: true});
renderer.setPixelRatio(1);
renderer.setClearColor(0x000000, 0);
renderer.setSize(innerWidth, innerHeight);
document.body.appendChild(renderer.domElement);

const state = {mode: params.get("mode") === "phong" ? 1 : 2, textures: params.get("textures") !== "0",
               normals: false, vectors: false, fps: 0, frames: 0, vertices: 0, error: null};
const scene = new THREE.Scene();
let camera, controls, lights, mover, meshes = [], normalHelpers = [], arrows = new THREE.Group(), centre, size;

async function load(url) {
  const gltf = await new GLTFLoader().loadAsync(url);
  const extras = gltf.scene.userData.prt || (gltf.parser.json.scenes[gltf.parser.json.scene || 0].extras || {}).prt;
  if (!extras) throw new Error(`${url} has no PRT extras: export it with prt export --gltf`);
  lights = new LightSet(extras);
  if (params.has("lights")) lights.resize(Number(params.get("lights")));
  if (params.has("light")) lights.select(Number(params.get("light")) - 1);
  aimActive(params.get("theta"), params.get("phi"));
  scene.add(gltf.scene);
  const parts = [];
  gltf.scene.traverse((object) => { if (object.isMesh) parts.push(object); });
  for (const mesh of parts) await makePrt(mesh, gltf.parser);
  gltf.scene.updateMatrixWorld(true);
  const box = new THREE.Box3().setFromObject(gltf.scene);
  centre = box.getCenter(new THREE.Vector3());
  size = box.getSize(new THREE.Vector3()).length();
  mover = new Mover(meshes, await loadVolumes(extras, gltf.parser), size / 40, params.get("outline") !== "0");
  scene.add(mover.outline);
  camera = gltf.cameras[0] || defaultCamera();
  camera.aspect = innerWidth / innerHeight;
  camera.updateProjectionMatrix();
  controls = orbit(camera);
  for (const mesh of meshes) {
    const helper = new VertexNormalsHelper(mesh, size * 0.01, 0x4080ff);
    helper.visible = false;
    normalHelpers.push(helper);
    scene.add(helper);
  }
  scene.add(arrows);
  relight();
}

// The mesh's PRT material from its extras (glTF meshes carry them; three.js puts them in the mesh's userData).
async function makePrt(mesh, parser) {
  const layout = mesh.userData.prt || (mesh.parent && mesh.parent.userData.prt) || findLayout(mesh, parser);
  if (!layout) return;
  let transfer = null;
  if (layout.layout === "texel_maps") return;  // shaded per texel in Blender: its COLOR_0 shows it (docs/export.md)
  if (layout.layout === "texture") {
    const buffer = await parser.getDependency("bufferView", layout.texture.bufferView);
    transfer = new THREE.DataTexture(new Float32Array(buffer), layout.texture.width, layout.texture.height,
                                     THREE.RGBAFormat, THREE.FloatType);
    transfer.needsUpdate = true;
  } else if (!layout.attributes.every((name) => mesh.geometry.getAttribute(attributeName(name)))) {
    return;
  }
  const map = mesh.material.map || null;
  mesh.material = prtMaterial(layout, map, transfer);
  mesh.userData.layout = layout;
  const association = parser.associations.get(mesh);  // a mesh of several primitives: its group is the node
  mesh.userData.node = association && association.nodes !== undefined ? mesh : mesh.parent;
  meshes.push(mesh);
  state.vertices += mesh.geometry.getAttribute("position").count;
}

function findLayout(mesh, parser) {
  const association = parser.associations.get(mesh);
  const definition = association && parser.json.meshes[association.meshes];
  return definition && definition.extras && definition.extras.prt;
}

function defaultCamera() {
  const fallback = new THREE.PerspectiveCamera(40, 1, size / 1000, size * 10);
  fallback.position.copy(centre).add(new THREE.Vector3(0, size * 0.4, size));
  fallback.lookAt(centre);
  return fallback;
}

// Drag orbits about the point where the camera's view axis passes nearest the scene's centre, so the first view
// is the export's camera exactly.
function orbit(view) {
  const forward = view.getWorldDirection(new THREE.Vector3());
  const position = view.getWorldPosition(new THREE.Vector3());
  const along = Math.max(centre.clone().sub(position).dot(forward), size * 0.1);
  const orbitControls = new OrbitControls(view, renderer.domElement);
  orbitControls.target.copy(position.add(forward.multiplyScalar(along)));
  orbitControls.update();
  return orbitControls;
}

function aimActive(theta, phi) {
  const light = lights.lights[lights.active];
  if (!light || light.kind !== "sun") return;
  if (theta !== null) light.theta = Number(theta) * DEGREE;
  if (phi !== null) light.phi = Number(phi) * DEGREE;
}

// New light sums for every mesh (one per order), the Blinn-Phong suns, the arrows and the switches.
function relight() {
  const totals = new Map();
  const suns = lights.suns().slice(0, MAX_SUNS);
  const ambient = lights.ambient();
  for (const mesh of meshes) {
    const {layout} = mesh.userData;
    const order = layout.light_order || layout.order;  // a dynamic mesh's light is below its transfer's order
    if (!totals.has(order)) totals.set(order, lights.total(order));
    const uniforms = mesh.material.uniforms;
    if (!layout.dynamic) setLight(mesh.material, layout, totals.get(layout.order));
    uniforms.uMode.value = state.mode;
    uniforms.uTextures.value = state.textures;
    uniforms.uSuns.value = suns.length;
    suns.forEach((sun, i) => {
      uniforms.uSunDirection.value[i].fromArray(sun.direction);
      uniforms.uSunIrradiance.value[i].fromArray(sun.rgb);
    });
    uniforms.uAmbient.value.fromArray(ambient);
  }
  mover.relight((order) => totals.get(order), setLight);
  arrows.clear();
  for (const sun of suns) {
    const direction = new THREE.Vector3().fromArray(sun.direction);
    arrows.add(new THREE.ArrowHelper(direction, centre, size * 0.4, sun.active ? 0xffd020 : 0xff8020));
  }
  arrows.visible = state.vectors;
  normalHelpers.forEach((helper) => { helper.visible = state.normals; });
  showReadout();
}

function showReadout() {
  const on = (flag) => (flag ? "on" : "off");
  readout.textContent = [
    lights.describe(),
    `${MODES[state.mode]} · textures ${on(state.textures)} (T) · normals ${on(state.normals)} (N) · ` +
      `light vectors ${on(state.vectors)} (L)`,
    `${state.fps.toFixed(1)} fps · ${state.vertices} vertices · drag to orbit`,
    ...(mover.moving ? [mover.describe()] : []),
  ].join("\n");
}

const KEYS = {
  F1: () => { state.mode = 1; }, F2: () => { state.mode = 2; },
  t: () => { state.textures = !state.textures; }, n: () => { state.normals = !state.normals; },
  l: () => { state.vectors = !state.vectors; },
};
const TURNS = {q: [-1, 0], a: [1, 0], w: [0, -1], e: [0, 1]};

addEventListener("keydown", (event) => {
  if (!camera) return;  // still loading
  const key = event.key.length === 1 ? event.key.toLowerCase() : event.key;
  if (key === "Tab") {
    mover.next();
  } else if (mover.press(key, event.code, event.shiftKey)) {
    // moved or turned
  } else if (key >= "1" && key <= "8") {
    lights.select(Number(key) - 1);
  } else if (TURNS[key]) {
    const step = event.shiftKey ? FINE_STEP : STEP;
    lights.turn(TURNS[key][0] * step, TURNS[key][1] * step);
  } else if (KEYS[key]) {
    KEYS[key]();
  } else {
    return;
  }
  event.preventDefault();
  relight();
  renderer.render(scene, camera);  // now, so what a key did is on screen before the next animation frame
});

addEventListener("resize", () => {
  renderer.setSize(innerWidth, innerHeight);
  if (camera) {
    camera.aspect = innerWidth / innerHeight;
    camera.updateProjectionMatrix();
  }
});

let counted = 0, since = performance.now();
function frame(now) {
  requestAnimationFrame(frame);
  if (!camera) return;
  renderer.render(scene, camera);
  state.frames++;
  counted++;
  if (now - since >= 500) {
    state.fps = (1000 * counted) / (now - since);
    counted = 0;
    since = now;
    showReadout();
  }
}

// Frames per second with the active light turned every frame (the CPU sums and turns every light, then the GPU
// shades): each frame is finished (one pixel read back) before the next, so the count is work, not the display's
// refresh rate.
function benchmark(frames) {
  const gl = renderer.getContext();
  const pixel = new Uint8Array(4);
  const start = performance.now();
  for (let i = 0; i < frames; i++) {
    lights.turn(0, 0.5 * DEGREE);
    relight();
    renderer.render(scene, camera);
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);
  }
  return (1000 * frames) / (performance.now() - start);
}

window.prtViewer = {
  ready: false,
  state: () => ({...state, active: lights.active, lights: lights.lights.map(({kind, theta, phi}) => ({kind, theta, phi})),
                 readout: readout.textContent, moving: mover.state()}),
  benchmark,
};

load(params.get("file") || "scene.glb").then(() => {
  renderer.render(scene, camera);
  window.prtViewer.ready = true;
  requestAnimationFrame(frame);
}).catch((error) => {
  state.error = String(error);
  readout.textContent = `Could not load: ${error}`;
  window.prtViewer.ready = true;
});
