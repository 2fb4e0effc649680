// The dynamic objects of a PRT export (meshes whose extras.prt has dynamic true) and the one the keys move: Tab picks
// the next; the arrow keys move it along glTF's X (Blender's X) and Z (Blender's −Y: Up moves it away from a camera
// looking along −Z), Page Up/Down along Y (Blender's Z, up), [ and ] turn it about the vertical through its centre;
// Shift takes a fifth of a step. A box outlines the object moved. Each object is shaded from the probes at its
// bounding box's centre, with the light turned into its frame (probes.js), as the add-on's display shades it.
import * as THREE from "three";
import {lightAt, lightInFrame} from "./probes.js";

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

  // Sets each dynamic mesh's light: `totals(order)` the distant light [3][n²] in glTF's frame; `setLight` the
  // material's writer (prt_material.js).
  relight(totals, setLight) {
    for (const object of this.objects) {
      const centre = this.centre(object).toArray();
      const rotation = new THREE.Matrix4().extractRotation(object.node.matrixWorld).elements;  // column-major
      const turn = [0, 1, 2].map((i) => [0, 1, 2].map((j) => rotation[4 * j + i]));
      for (const mesh of object.meshes) {
        const {layout} = mesh.userData;
        const distant = totals(layout.order);
        const found = lightAt(this.volumes, centre, distant);
        this.lit.set(object.node, found.volume);
        setLight(mesh.material, layout, lightInFrame(found.light || distant, turn));
      }
    }
    if (this.moving) this.outline.setFromObject(this.moving.node);
  }

  describe() {
    const object = this.moving;
    if (!object) return null;
    const volume = this.lit.get(object.node);
    return `Moving ${object.name} (Tab ${this.active + 1}/${this.objects.length}; arrows, PgUp/PgDn, [ ]) · ` +
      `lit by ${volume ? `the probes of ${volume.name}` : "the distant light"}`;
  }

  state() {
    const object = this.moving;
    if (!object) return null;
    const volume = this.lit.get(object.node);
    return {name: object.name, matrixWorld: object.node.matrixWorld.toArray(), centre: this.centre(object).toArray(),
            volume: volume ? volume.name : null};
  }
}
