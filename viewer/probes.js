// The probe volumes of a PRT export (the scene's extras.prt.probe_volumes, docs/reference/gltf-extras.md) and the
// light they give a dynamic object, as the add-on's display computes it: the trilinear blend of the valid probes
// around the object's centre (core/probe_grid.py, ported line for line), Σ w_p T_p L, then turned into the object's
// frame (blender/relighting.py light_in_frame), or at each of its vertices (vertexRadiance, Blender's Probe Light
// Per Vertex). Plain arrays, no three.js, so node runs it in the tests.
import {bandMatrices, fitted, rotate, rotateByBands} from "./sh.js";

export class ProbeVolume {
  // `volume`: one entry of probe_volumes; `matrices`: its float32 buffer view (P × C × N² × n²), n its order (the
  // distant light's), N its received_order (the arriving light's).
  constructor(volume, matrices) {
    this.name = volume.name;
    this.order = volume.order;
    this.receivedOrder = volume.received_order;
    this.channels = volume.channels;
    this.resolution = volume.resolution;
    this.valid = volume.valid;
    this.matrices = matrices;
    const p = volume.placement;  // 16 floats by rows: cube [−1, 1]³ → glTF world
    const A = [[p[0], p[1], p[2]], [p[4], p[5], p[6]], [p[8], p[9], p[10]]];
    this.origin = [p[3], p[7], p[11]];
    this.inverse = inverse3(A);
    this.size = Math.abs(determinant3(A));
  }

  // The point (glTF world) in the cube's frame, or null outside the cube.
  local(point) {
    const local = [0, 0, 0];
    return this.localInto(point[0], point[1], point[2], local) ? local : null;
  }

  // Writes the point (x, y, z) in the cube's frame into `out` (3 numbers); whether the cube holds it. Allocates
  // nothing: vertexRadiance calls it for every vertex.
  localInto(x, y, z, out) {
    const dx = x - this.origin[0], dy = y - this.origin[1], dz = z - this.origin[2];
    for (let i = 0; i < 3; i++) {
      const row = this.inverse[i];
      out[i] = row[0] * dx + row[1] * dy + row[2] * dz;
    }
    return Math.abs(out[0]) <= 1 && Math.abs(out[1]) <= 1 && Math.abs(out[2]) <= 1;
  }

  // Float64Array(P·3·N²): every probe's light T_p L (probe after probe, channel after channel) under the distant
  // light [3][n²], kept for the last light (probe_volumes.lights): a light change costs one product per probe, a
  // moving object none.
  probeLights(light) {
    const n2 = this.order * this.order, r2 = this.receivedOrder * this.receivedOrder, count = this.valid.length;
    const key = light.map((c) => Array.from(c)).join();
    if (this.lastLight && this.lastLight.key === key) return this.lastLight.lights;
    const lights = new Float64Array(count * 3 * r2);
    for (let probe = 0; probe < count; probe++) {
      for (let c = 0; c < 3; c++) {
        const start = (probe * this.channels + (this.channels === 1 ? 0 : c)) * r2 * n2, row = (probe * 3 + c) * r2;
        for (let i = 0; i < r2; i++) {
          let sum = 0;
          for (let j = 0; j < n2; j++) sum += this.matrices[start + i * n2 + j] * light[c][j];
          lights[row + i] = sum;
        }
      }
    }
    this.lastLight = {key, lights};
    return lights;
  }

  // probeLights turned into an object's frame by the band blocks `blocks` (sh.js bandMatrices): a rotation is
  // linear, so the blend of these is the blended light turned (blender/relighting.py dynamic_radiance).
  turnedLights(light, blocks) {
    const lights = this.probeLights(light), r2 = this.receivedOrder * this.receivedOrder;
    const out = new Float64Array(lights.length);
    for (let row = 0; row < lights.length; row += r2) {
      out.set(rotateByBands(lights.subarray(row, row + r2), blocks), row);
    }
    return out;
  }

  // [3][N²]: the light arriving where the probes `indices` carry `weights`, each colour channel through its own
  // matrix (a grey volume's one matrix for all three).
  incoming(indices, weights, light) {
    const n2 = this.order * this.order, r2 = this.receivedOrder * this.receivedOrder, block = r2 * n2;
    return [0, 1, 2].map((c) => {
      const out = new Float64Array(r2);
      const channel = this.channels === 1 ? 0 : c;
      indices.forEach((probe, q) => {
        const w = weights[q];
        if (w === 0) return;
        const start = (probe * this.channels + channel) * block;
        for (let i = 0; i < r2; i++) {
          let sum = 0;
          for (let j = 0; j < n2; j++) sum += this.matrices[start + i * n2 + j] * light[c][j];
          out[i] += w * sum;
        }
      });
      return out;
    });
  }
}

export async function loadVolumes(extras, parser) {
  const volumes = [];
  for (const volume of extras.probe_volumes || []) {
    const buffer = await parser.getDependency("bufferView", volume.bufferView);
    volumes.push(new ProbeVolume(volume, new Float32Array(buffer)));
  }
  return volumes;
}

// {indices, weights} of the 8 probes of the cell around `local` (the cube's frame), trilinear, over the valid ones
// only and rescaled to sum to 1 (all zero where none is valid); a point beyond the probes' lattice is clamped onto it.
export function trilinearWeights(local, resolution, valid) {
  const indices = new Array(8), weights = new Array(8);
  fillTrilinear(local, resolution, valid, indices, weights);
  return {indices, weights};
}

// trilinearWeights into `indices` and `weights` (8 each, corners x slowest), allocating nothing.
const LOW = new Int32Array(3), FRACTION = new Float64Array(3), STRIDES = new Int32Array(3);
function fillTrilinear(local, resolution, valid, indices, weights) {
  STRIDES[0] = resolution[1] * resolution[2], STRIDES[1] = resolution[2], STRIDES[2] = 1;
  let base = 0, total = 0;
  for (let axis = 0; axis < 3; axis++) {
    const n = resolution[axis];
    const grid = Math.min(Math.max((local[axis] + 1) * n / 2 - 0.5, 0), n - 1);
    LOW[axis] = Math.min(Math.floor(grid), Math.max(n - 2, 0));
    FRACTION[axis] = grid - LOW[axis];
    base += LOW[axis] * STRIDES[axis];
  }
  for (let corner = 0; corner < 8; corner++) {
    let index = base, weight = 1;
    for (let axis = 0; axis < 3; axis++) {
      const step = (corner >> (2 - axis)) & 1;  // an axis of one probe repeats it, with weight 0 on the repeat
      if (step && LOW[axis] + 1 < resolution[axis]) index += STRIDES[axis];
      weight *= step ? FRACTION[axis] : 1 - FRACTION[axis];
    }
    indices[corner] = index;
    weights[corner] = valid[index] ? weight : 0;
    total += weights[corner];
  }
  if (total > 0) for (let corner = 0; corner < 8; corner++) weights[corner] /= total;
}

// {light, volume}: what arrives at `point` (glTF world) from the distant light [3][n²] through the smallest volume
// of the light's order whose cube holds it, or {light: null} where none does.
export function lightAt(volumes, point, light) {
  const order = Math.round(Math.sqrt(light[0].length));
  let best = null, local = null;
  for (const volume of volumes) {
    const inside = volume.order === order ? volume.local(point) : null;
    if (inside && (best === null || volume.size < best.size)) [best, local] = [volume, inside];
  }
  if (best === null) return {light: null, volume: null};
  const {indices, weights} = trilinearWeights(local, best.resolution, best.valid);
  return {light: best.incoming(indices, weights, light), volume: best};
}

// Float32Array(3·V): the radiance at V vertices of a dynamic object lit per vertex (blender/relighting.py
// dynamic_radiance): each vertex, at `positions` (glTF world, 3·V floats), takes the light arriving there from the
// distant light [3][n²], Σ w_p T_p L through the smallest volume of the light's order whose cube holds it (the
// distant light outside every one), turned into the object's frame by `turn` (3 × 3 rows, its world rotation), and
// shades its transfer row with it: `transfer` holds V rows of `stride` floats in the mesh's packing (channel-major,
// `order`² coefficients a channel; `channels` 1: one transfer for every colour). Each light is fitted to the
// transfer's order (sh.js fitted). The probes' lights are formed and turned once per call, so a vertex costs the
// sum of its 8 probes' lights and one product per colour.
export function vertexRadiance(volumes, positions, transfer, stride, channels, light, turn, order) {
  const n2 = order * order, lightOrder = Math.round(Math.sqrt(light[0].length));
  const back = [0, 1, 2].map((i) => [0, 1, 2].map((j) => turn[j][i]));
  const usable = volumes.filter((volume) => volume.order === lightOrder);
  const turned = usable.map((volume) => volume.turnedLights(light, bandMatrices(volume.receivedOrder, back)));
  const strides = usable.map((volume) => volume.receivedOrder * volume.receivedOrder);
  const blocks = bandMatrices(order, back);
  const distant = new Float64Array(3 * n2);
  fitted(light, n2).forEach((channel, c) => distant.set(rotateByBands(channel, blocks), c * n2));
  const count = positions.length / 3, radiance = new Float32Array(3 * count), blended = new Float64Array(3 * n2);
  const local = [0, 0, 0], mine = [0, 0, 0], indices = new Array(8), weights = new Array(8);
  for (let v = 0; v < count; v++) {
    const x = positions[3 * v], y = positions[3 * v + 1], z = positions[3 * v + 2];
    let best = -1;
    for (let index = 0; index < usable.length; index++) {
      if (usable[index].localInto(x, y, z, mine) && (best < 0 || usable[index].size < usable[best].size)) {
        best = index;
        local[0] = mine[0], local[1] = mine[1], local[2] = mine[2];
      }
    }
    let arriving = distant;
    if (best >= 0) {
      fillTrilinear(local, usable[best].resolution, usable[best].valid, indices, weights);
      blended.fill(0);
      const lights = turned[best], r2 = strides[best], shared = Math.min(n2, r2);
      for (let q = 0; q < 8; q++) {
        const w = weights[q], start = indices[q] * 3 * r2;
        if (w === 0) continue;
        for (let c = 0; c < 3; c++) {
          for (let i = 0; i < shared; i++) blended[c * n2 + i] += w * lights[start + c * r2 + i];
        }
      }
      arriving = blended;
    }
    for (let c = 0; c < 3; c++) {
      const row = v * stride + (channels === 1 ? 0 : c * n2);
      let sum = 0;
      for (let i = 0; i < n2; i++) sum += transfer[row + i] * arriving[c * n2 + i];
      radiance[3 * v + c] = sum;
    }
  }
  return radiance;
}

// The light [3][n²] (glTF world) as an object turned by `turn` (3 × 3 rows, its world rotation) sees it in its own
// frame: L(R·ω), the coefficients rotated by Rᵀ.
export function lightInFrame(light, turn) {
  const back = [0, 1, 2].map((i) => [0, 1, 2].map((j) => turn[j][i]));
  return light.map((channel) => rotate(channel, back));
}

function determinant3(A) {
  return A[0][0] * (A[1][1] * A[2][2] - A[1][2] * A[2][1]) - A[0][1] * (A[1][0] * A[2][2] - A[1][2] * A[2][0]) +
    A[0][2] * (A[1][0] * A[2][1] - A[1][1] * A[2][0]);
}

function inverse3(A) {
  const det = determinant3(A);
  const cofactor = (i, j) => {
    const rows = [0, 1, 2].filter((r) => r !== i), cols = [0, 1, 2].filter((c) => c !== j);
    const minor = A[rows[0]][cols[0]] * A[rows[1]][cols[1]] - A[rows[0]][cols[1]] * A[rows[1]][cols[0]];
    return ((i + j) % 2 ? -minor : minor);
  };
  return [0, 1, 2].map((i) => [0, 1, 2].map((j) => cofactor(j, i) / det));
}
