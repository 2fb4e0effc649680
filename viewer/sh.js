// Spherical-harmonic maths of the add-on (prt_addon/core: sh.py, rotation.py, lobes.py, shading.py), ported line
// for line so the viewer turns lights exactly as Blender does; tests/test_gltf.py checks it against the Python.
// Real SH with the Condon-Shortley phase, k = l(l+1) + m, "order n" = n bands, n² coefficients.

const SQRT2 = Math.SQRT2;

// Y_k(d) for k < order², d a unit vector [x, y, z] (sh.evaluate): normalised Legendre recurrences in z and
// sin^m θ e^{imφ} = (x + iy)^m, so no angles and exact values at the poles.
export function evaluate(order, d) {
  const [x, y, z] = d;
  const values = new Float64Array(order * order);
  let powerRe = 1, powerIm = 0, sectoral = 1 / Math.sqrt(4 * Math.PI);
  for (let m = 0; m < order; m++) {
    if (m > 0) {
      [powerRe, powerIm] = [x * powerRe - y * powerIm, x * powerIm + y * powerRe];
      sectoral *= -Math.sqrt((2 * m + 1) / (2 * m));
    }
    const write = (l, legendre) => {
      const centre = l * (l + 1);
      if (m === 0) {
        values[centre] = legendre;
      } else {
        values[centre + m] = legendre * SQRT2 * powerRe;
        values[centre - m] = legendre * SQRT2 * powerIm;
      }
    };
    let older = sectoral;
    write(m, older);
    if (m + 1 >= order) continue;
    let old = Math.sqrt(2 * m + 3) * z * sectoral;
    write(m + 1, old);
    for (let l = m + 2; l < order; l++) {
      const a = Math.sqrt((4 * l * l - 1) / (l * l - m * m));
      const b = Math.sqrt(((l - 1) ** 2 - m * m) / (4 * (l - 1) ** 2 - 1));
      [older, old] = [old, a * (z * old - b * older)];
      write(l, old);
    }
  }
  return values;
}

// The zonal lobe z_l about +Z turned to point along d (rotation.zonal_to_sh): f_lm = sqrt(4π/(2l+1)) z_l Y_lm(d).
export function zonalToSh(zonal, d) {
  const order = zonal.length;
  const values = evaluate(order, d);
  for (let l = 0; l < order; l++) {
    const scale = Math.sqrt(4 * Math.PI / (2 * l + 1)) * zonal[l];
    for (let k = l * l; k < (l + 1) * (l + 1); k++) values[k] *= scale;
  }
  return values;
}

// Rotation blocks of a 3×3 rotation matrix (rows) for bands l < order (rotation.band_matrices): Ivanic-Ruedenberg
// recurrences with the 1998 errata, products of matrix entries only.
export function bandMatrices(order, R) {
  const blocks = [[[1]], bandOne(R)].slice(0, order);
  for (let l = 2; l < order; l++) blocks.push(nextBand(l, blocks[l - 1], blocks[1]));
  return blocks;
}

// Coefficients of f(Rᵀω) from those of f (rotation.rotate): a lobe at d ends up at R·d.
export function rotate(coefficients, R) {
  return rotateByBands(coefficients, bandMatrices(Math.round(Math.sqrt(coefficients.length)), R));
}

// rotate() with the rotation's band blocks (bandMatrices) made once, for many coefficient vectors.
// [3][count]: the light [3][m] cut to its first `count` coefficients, or followed by zeros up to it (the same
// light to another order, as core/sh.py fitted).
export function fitted(light, count) {
  return light.map((channel) => Float64Array.from({length: count}, (_, k) => (k < channel.length ? channel[k] : 0)));
}

export function rotateByBands(coefficients, blocks) {
  const rotated = new Float64Array(coefficients.length);
  blocks.forEach((block, l) => {
    const start = l * l;
    for (let i = 0; i < block.length; i++) {
      let sum = 0;
      for (let j = 0; j < block.length; j++) sum += block[i][j] * coefficients[start + j];
      rotated[start + i] = sum;
    }
  });
  return rotated;
}

function bandOne(R) {  // Y_1,(-1, 0, 1) ∝ (-y, z, -x): R permuted and signed
  const axes = [1, 2, 0], signs = [-1, 1, -1];
  return axes.map((a, i) => axes.map((b, j) => signs[i] * R[a][b] * signs[j]));
}

function nextBand(l, previous, one) {
  const size = 2 * l + 1;
  const p = pTerms(l, previous, one);
  const [u, v, w] = uvw(l);
  const block = [];
  for (let m = -l; m <= l; m++) {
    const terms = [[0, m, 1.0], ...vTerms(m), ...wTerms(m)];
    const scales = [u, v, v, w, w];
    const row = new Array(size).fill(0);
    terms.forEach(([i, a, factor], t) => {
      for (let n = 0; n < size; n++) row[n] += scales[t][m + l][n] * factor * p[i + 1][a + l + 1][n];
    });
    block.push(row);
  }
  return block;
}

// I&R's P(i, a, b) for i = -1, 0, 1 as [3][2l+3][2l+1], rows a = -l-1..l+1 (rows with |a| >= l stay zero).
function pTerms(l, previous, one) {
  const size = 2 * l + 1, inner = 2 * l - 1;
  const p = [0, 1, 2].map(() => Array.from({length: size + 2}, () => new Array(size).fill(0)));
  for (let i = 0; i < 3; i++) {
    for (let a = 0; a < inner; a++) {
      const row = p[i][a + 2], prev = previous[a];
      for (let b = 0; b < inner; b++) row[b + 1] = one[i][1] * prev[b];
      row[size - 1] = one[i][2] * prev[inner - 1] - one[i][0] * prev[0];
      row[0] = one[i][2] * prev[0] + one[i][0] * prev[inner - 1];
    }
  }
  return p;
}

function uvw(l) {  // I&R Table 1 over (m, m')
  const u = [], v = [], w = [];
  for (let m = -l; m <= l; m++) {
    const absM = Math.abs(m), atZero = m === 0 ? 1 : 0;
    const [ur, vr, wr] = [[], [], []];
    for (let mp = -l; mp <= l; mp++) {
      const denominator = Math.abs(mp) < l ? (l + mp) * (l - mp) : 2 * l * (2 * l - 1);
      ur.push(Math.sqrt((l + m) * (l - m) / denominator));
      vr.push(0.5 * Math.sqrt((1 + atZero) * (l + absM - 1) * (l + absM) / denominator) * (1 - 2 * atZero));
      wr.push(-0.5 * Math.sqrt(Math.max(0, (l - absM - 1) * (l - absM)) / denominator) * (1 - atZero));
    }
    u.push(ur); v.push(vr); w.push(wr);
  }
  return [u, v, w];
}

function vTerms(m) {  // [i, a, factor] per I&R Table 2 as corrected in 1998
  if (m === 0) return [[1, 1, 1.0], [-1, -1, 1.0]];
  if (m > 0) return [[1, m - 1, Math.sqrt(1 + (m === 1 ? 1 : 0))], [-1, 1 - m, -(m !== 1 ? 1 : 0)]];
  return [[1, m + 1, m !== -1 ? 1 : 0], [-1, -m - 1, Math.sqrt(1 + (m === -1 ? 1 : 0))]];
}

function wTerms(m) {
  if (m === 0) return [[1, 0, 0.0], [-1, 0, 0.0]];
  if (m > 0) return [[1, m + 1, 1.0], [-1, -m - 1, 1.0]];
  return [[1, m - 1, 1.0], [-1, 1 - m, -1.0]];
}

// Per-band factors against ringing (lobes.window): hanning (1 + cos(πl/n))/2, lanczos sinc(l/n), tapered Hanning's
// to the power `strength`.
export function windowFactors(order, kind, strength = 1) {
  return Array.from({length: order}, (_, l) => {
    const x = l / order;
    if (kind === "hanning") return 0.5 * (1 + Math.cos(Math.PI * x));
    if (kind === "tapered") return Math.pow(0.5 * (1 + Math.cos(Math.PI * x)), strength);
    if (kind === "lanczos") return x === 0 ? 1 : Math.sin(Math.PI * x) / (Math.PI * x);
    return 1;
  });
}

// θ from the zenith, φ from +X towards +Y, in Blender's frame (shading.direction_from_angles), then into glTF's
// (x, y, z) = Blender (x, z, -y), the frame of the exported coefficients.
export function directionFromAngles(theta, phi) {
  const s = Math.sin(theta);
  return [s * Math.cos(phi), s * Math.sin(phi), Math.cos(theta)];
}

export function blenderToGltf([x, y, z]) {
  return [x, z, -y];
}

// A rotation by `angle` about a unit axis (Rodrigues), as rows.
export function axisRotation([x, y, z], angle) {
  const c = Math.cos(angle), s = Math.sin(angle), t = 1 - c;
  return [[t * x * x + c, t * x * y - s * z, t * x * z + s * y],
          [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
          [t * x * z - s * y, t * y * z + s * x, t * z * z + c]];
}

export function multiply(A, B) {
  return A.map((row) => [0, 1, 2].map((j) => row[0] * B[0][j] + row[1] * B[1][j] + row[2] * B[2][j]));
}
