// The dynamic objects of a PRT export (meshes whose extras.prt has dynamic true) and the one the keys move: Tab picks
// the next; the arrow keys move it along glTF's X (Blender's X) and Z (Blender's −Y: Up moves it away from a camera
// looking along −Z), Page Up/Down along Y (Blender's Z, up), [ and ] turn it about the vertical through its centre;
// Shift takes a fifth of a step. A box outlines the object moved. Each object is shaded from the probes at its
// bounding box's centre, or at each vertex where its extras say probe_light "vertex", with the light turned into its
// frame (probes.js), as the add-on's display shades it.
import * as THREE from "three";
import {lightAt, lightInFrame, vertexRadiance} from "./probes.js";
import {fitted} from "./sh.js";
import {RADIANCE_ATTRIBUTE, attributeName, litPerVertex} from "./prt_material.js";

const TURN = 15 * Math.PI / 180;
export const MOVES = {ArrowRight: [1, 0, 0], ArrowLeft: [-1, 0, 0], ArrowUp: [0, 0, -1], ArrowDown: [0, 0, 1],
                      PageUp: [0, 1, 0], PageDown: [0, -1, 0]};
export const TURNS = {BracketLeft: 1, BracketRight: -1};  // by the key's place: Shift+[ types {

export class Mover {
  // `meshes`: the PRT meshes (three.js Mesh with userData.layout); `step`: one key's move in scene units.
  constructor(meshes, volumes, step, outline) {
    this.volumes = volumes;
    this.step = step;
    this.objects = [];  // {node, meshes, centre (node frame), name}
    for (const mesh of meshes.filter((m) => m.userData.layout.dynamic)) {
      const node = mesh.userData.node;
      let entry = this.objects.find((object) => object.node === node);
      if (!entry) this.objects.push(entry = {node, meshes: [], name: node.name, box: new THREE.Box3()});
      entry.meshes.push(mesh);
      if (litPerVertex(mesh.userData.layout)) {
        mesh.userData.rows = transferRows(mesh);
        const count = mesh.geometry.getAttribute("position").count;
        mesh.geometry.setAttribute(RADIANCE_ATTRIBUTE, new THREE.BufferAttribute(new Float32Array(3 * count), 3));
      }
      mesh.geometry.computeBoundingBox();
      entry.box.union(mesh.geometry.boundingBox);  // the primitives share their node's frame
    }
    this.active = 0;
    this.outline = new THREE.BoxHelper(undefined, 0xffd020);
    this.outline.visible = outline && this.objects.length > 0;
    this.lit = new Map();  // node → the volume lighting it (null: the distant light)
  }

  get moving() {
    return this.objects[this.active] || null;
  }

  next() {
    if (this.objects.length) this.active = (this.active + 1) % this.objects.length;
  }

  // Moves (key in MOVES) or turns (code in TURNS) the active object; false for any other key.
  press(key, code, fine) {
    const object = this.moving;
    if (!object || !(key in MOVES || code in TURNS)) return false;
    const scale = fine ? 0.2 : 1;
    if (key in MOVES) {
      object.node.position.add(new THREE.Vector3(...MOVES[key]).multiplyScalar(this.step * scale));
    } else {  // about the world's vertical through the centre, which stays where it is
      const centre = this.centre(object);
      const turn = new THREE.Quaternion().setFromAxisAngle(new THREE.Vector3(0, 1, 0), TURNS[code] * TURN * scale);
      object.node.quaternion.premultiply(turn);
      object.node.updateMatrixWorld(true);
      object.node.position.add(centre.sub(this.centre(object)));
    }
    object.node.updateMatrixWorld(true);
    return true;
  }

  centre(object) {
    object.node.updateMatrixWorld(true);
    return object.box.getCenter(new THREE.Vector3()).applyMatrix4(object.node.matrixWorld);
  }

  // Sets each dynamic mesh's light: `totals(order)` the distant light [3][n²] in glTF's frame, at the order the mesh
  // is lit by (its extras' light_order, below its transfer's); `setLight` the material's writer (prt_material.js).
  relight(totals, setLight) {
    for (const object of this.objects) {
      const centre = this.centre(object).toArray();
      const rotation = new THREE.Matrix4().extractRotation(object.node.matrixWorld).elements;  // column-major
      const turn = [0, 1, 2].map((i) => [0, 1, 2].map((j) => rotation[4 * j + i]));
      for (const mesh of object.meshes) {
        const {layout} = mesh.userData;
        const distant = totals(layout.light_order || layout.order);
        const found = lightAt(this.volumes, centre, distant);
        this.lit.set(object.node, found.volume);
        if (mesh.userData.rows) {
          const {rows, stride} = mesh.userData.rows;
          const attribute = mesh.geometry.getAttribute(RADIANCE_ATTRIBUTE);
          attribute.array.set(vertexRadiance(this.volumes, worldPositions(mesh), rows, stride, layout.channels,
                                             distant, turn, layout.order));
          attribute.needsUpdate = true;
        } else {
          setLight(mesh.material, layout, fitted(lightInFrame(found.light || distant, turn), layout.order ** 2));
        }
      }
    }
    if (this.moving) this.outline.setFromObject(this.moving.node);
  }

  describe() {
    const object = this.moving;
    if (!object) return null;
    const volume = this.lit.get(object.node);
    const where = object.meshes.some((mesh) => mesh.userData.rows) ? "per vertex" : "at its centre";
    return `Moving ${object.name} (Tab ${this.active + 1}/${this.objects.length}; arrows, PgUp/PgDn, [ ]) · ` +
      `lit ${where} by ${volume ? `the probes of ${volume.name}` : "the distant light"}`;
  }

  state() {
    const object = this.moving;
    if (!object) return null;
    const volume = this.lit.get(object.node);
    return {name: object.name, matrixWorld: object.node.matrixWorld.toArray(), centre: this.centre(object).toArray(),
            volume: volume ? volume.name : null};
  }
}

// {rows, stride}: the mesh's transfer, one row of 4·vec4s floats per vertex in its packing (its VEC4 attributes side
// by side, or its data texture's texels at each vertex's index).
function transferRows(mesh) {
  const layout = mesh.userData.layout, geometry = mesh.geometry;
  const count = geometry.getAttribute("position").count, stride = 4 * layout.vec4s;
  const rows = new Float32Array(count * stride);
  if (layout.layout === "texture") {
    const texels = mesh.material.uniforms.uTransfer.value.image.data;
    const index = geometry.getAttribute(attributeName(layout.index_attribute));
    for (let v = 0; v < count; v++) {
      const start = Math.round(index.getX(v)) * stride;
      rows.set(texels.subarray(start, start + stride), v * stride);
    }
  } else {
    layout.attributes.forEach((name, j) => {
      const values = geometry.getAttribute(attributeName(name));
      for (let v = 0; v < count; v++) {
        for (let t = 0; t < 4; t++) rows[v * stride + 4 * j + t] = values.getComponent(v, t);
      }
    });
  }
  return {rows, stride};
}

// Float64Array(3·V): the mesh's vertices in glTF world space as it stands now.
function worldPositions(mesh) {
  const position = mesh.geometry.getAttribute("position"), point = new THREE.Vector3();
  const out = new Float64Array(3 * position.count);
  for (let v = 0; v < position.count; v++) {
    point.fromBufferAttribute(position, v).applyMatrix4(mesh.matrixWorld);
    out.set([point.x, point.y, point.z], 3 * v);
  }
  return out;
}
