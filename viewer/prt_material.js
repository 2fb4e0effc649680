// The PRT shader for a mesh exported by PRT for Blender (`prt export --gltf`), reusable on its own: each vertex forms
// Σ_k L_k T_k from its transfer (VEC4 attributes, or texels of a float data texture indexed by _PRT_INDEX) and the
// light's SH coefficients, which the CPU sums and turns (lights.js); the fragment multiplies by the albedo texture
// and encodes sRGB. uMode 1 is local Blinn-Phong lighting by the same suns, for comparison (SHDemo's F1). A dynamic
// object lit per vertex (extras.prt.probe_light "vertex") reads its radiance from RADIANCE_ATTRIBUTE instead, which
// the CPU forms from the probes (probes.js vertexRadiance): each vertex has a light of its own.
import * as THREE from "three";

export const MAX_SUNS = 8;
export const RADIANCE_ATTRIBUTE = "prt_radiance";

// Whether the mesh (its extras.prt) is a dynamic object lit per vertex through the probes.
export function litPerVertex(layout) {
  return Boolean(layout.dynamic) && layout.probe_light === "vertex";
}

// The mesh's extras.prt (order, channels, vec4s, layout, attributes | texture) → a ShaderMaterial. `map`: the albedo
// texture or null; `transfer`: the DataTexture of a texture layout.
export function prtMaterial(layout, map, transfer) {
  const vec4s = layout.vec4s;
  return new THREE.ShaderMaterial({
    vertexShader: vertexShader(layout),
    fragmentShader: FRAGMENT_SHADER,
    side: THREE.DoubleSide,
    uniforms: {
      uLight: {value: new Float32Array(3 * vec4s * 4)},
      uTransfer: {value: transfer},
      uMode: {value: 2},
      uTextures: {value: true},
      uMap: {value: map},
      uHasMap: {value: map !== null},
      uSuns: {value: 0},
      uSunDirection: {value: Array.from({length: MAX_SUNS}, () => new THREE.Vector3())},
      uSunIrradiance: {value: Array.from({length: MAX_SUNS}, () => new THREE.Vector3())},
      uAmbient: {value: new THREE.Vector3()},
    },
  });
}

// Writes the light total ([3][n²], glTF frame) in the mesh's packing: output channel c reads floats c·4·vec4s ...,
// where a grey transfer meets every light channel and a coloured one its own channel only.
export function setLight(material, layout, total) {
  const n2 = layout.order * layout.order, row = 4 * layout.vec4s;
  const light = material.uniforms.uLight.value;
  light.fill(0);
  for (let c = 0; c < 3; c++) {
    const offset = c * row + (layout.channels === 1 ? 0 : c * n2);
    for (let k = 0; k < n2; k++) light[offset + k] = total[c][k];
  }
}

function vertexShader(layout) {
  const vec4s = layout.vec4s;
  const accumulate = (t) => `radiance += vec3(dot(${t}, uLight[j]), dot(${t}, uLight[${vec4s} + j]), ` +
    `dot(${t}, uLight[${2 * vec4s} + j]));`;
  let declarations, body;
  if (litPerVertex(layout)) {
    declarations = `attribute vec3 ${RADIANCE_ATTRIBUTE};`;
    body = `radiance = ${RADIANCE_ATTRIBUTE};`;
  } else if (layout.layout === "texture") {
    const width = layout.texture.width;
    declarations = `attribute float ${attributeName(layout.index_attribute)};\nuniform highp sampler2D uTransfer;`;
    body = `int base = int(${attributeName(layout.index_attribute)} + 0.5) * ${vec4s};
  for (int j = 0; j < ${vec4s}; j++) {
    int texel = base + j;
    vec4 t = texelFetch(uTransfer, ivec2(texel % ${width}, texel / ${width}), 0);
    ${accumulate("t")}
  }`;
  } else {
    const names = layout.attributes.map(attributeName);
    declarations = names.map((name) => `attribute vec4 ${name};`).join("\n");
    body = names.map((name, j) => `{ const int j = ${j}; ${accumulate(name)} }`).join("\n  ");
  }
  return `uniform vec4 uLight[${3 * vec4s}];
${declarations}
varying vec3 vRadiance;
varying vec3 vNormal;
varying vec3 vPosition;
varying vec2 vUv;
void main() {
  vec3 radiance = vec3(0.0);
  ${body}
  vRadiance = radiance;
  vec4 world = modelMatrix * vec4(position, 1.0);
  vPosition = world.xyz;
  vNormal = normalize(mat3(modelMatrix) * normal);
  vUv = uv;
  gl_Position = projectionMatrix * viewMatrix * world;
}`;
}

// three.js's GLTFLoader keeps custom attributes under their lower-cased glTF names.
export function attributeName(gltfName) {
  return gltfName.toLowerCase();
}

const FRAGMENT_SHADER = `
uniform int uMode;
uniform bool uTextures;
uniform bool uHasMap;
uniform sampler2D uMap;
uniform int uSuns;
uniform vec3 uSunDirection[${MAX_SUNS}];
uniform vec3 uSunIrradiance[${MAX_SUNS}];
uniform vec3 uAmbient;
varying vec3 vRadiance;
varying vec3 vNormal;
varying vec3 vPosition;
varying vec2 vUv;
const float PI = 3.141592653589793;
vec3 srgb(vec3 linear) {
  vec3 c = clamp(linear, 0.0, 1.0);
  return mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}
void main() {
  vec3 albedo = (uTextures && uHasMap) ? texture2D(uMap, vUv).rgb : vec3(1.0);
  vec3 colour;
  if (uMode == 2) {
    colour = albedo * vRadiance;
  } else {  // Blinn-Phong: diffuse albedo/π · E · cos, a white highlight, the sky's mean radiance as ambient
    vec3 n = normalize(vNormal) * (gl_FrontFacing ? 1.0 : -1.0);
    vec3 v = normalize(cameraPosition - vPosition);
    colour = albedo * uAmbient;
    for (int i = 0; i < ${MAX_SUNS}; i++) {
      if (i >= uSuns) break;
      vec3 l = uSunDirection[i];
      float cosine = max(dot(n, l), 0.0);
      float highlight = cosine > 0.0 ? pow(max(dot(n, normalize(l + v)), 0.0), 32.0) : 0.0;
      colour += uSunIrradiance[i] / PI * (albedo * cosine + 0.25 * highlight);
    }
  }
  gl_FragColor = vec4(srgb(max(colour, 0.0)), 1.0);
}`;
