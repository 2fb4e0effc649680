// The SH lights of an export (the scene's extras.prt.lights), turned as the add-on's Drive Lights turns them and
// summed in glTF's frame on the CPU: a sun's zonal lobe placed along its direction (no rotation matrix), an
// environment's coefficients turned by the full SH rotation, a sky as it is; then the export's window.
import {axisRotation, blenderToGltf, directionFromAngles, multiply, rotate, windowFactors, zonalToSh} from "./sh.js";

export const MAX_LIGHTS = 8;
export const DEGREE = Math.PI / 180;
const IDENTITY = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];
const TO_GLTF = [[1, 0, 0], [0, 0, 1], [0, -1, 0]];  // glTF (x, y, z) = Blender (x, z, -y)
const FROM_GLTF = [[1, 0, 0], [0, 0, -1], [0, 1, 0]];

export class LightSet {
  constructor(extras) {
    this.window = extras.window || "none";
    this.windowStrengths = extras.window_strengths || {};  // "tapered": the export's Auto strength per order
    this.lights = extras.lights.map((light) => ({...light, turn: IDENTITY}));
    this.active = Math.min(extras.active_light || 0, Math.max(0, this.lights.length - 1));
  }

  // Keys 1-8: light `index` becomes the active one; a key beyond the lights adds suns up to it (as many as SHDemo's 8).
  select(index) {
    if (index < 0 || index >= MAX_LIGHTS) return;
    while (this.lights.length <= index) this.lights.push(this.newSun(this.lights.length));
    this.active = index;
  }

  // Keep only the first `count` lights, or add suns up to `count` (the benchmark's 1 and 8 lights).
  resize(count) {
    this.lights = this.lights.slice(0, count);
    if (count > 0) this.select(count - 1);
    this.active = 0;
  }

  // A sun like the first one (else a point sun of irradiance 1), spread around the azimuth.
  newSun(index) {
    const model = this.lights.find((light) => light.kind === "sun");
    const order = model ? model.zonal.length : 10;
    const zonal = model ? model.zonal : Array.from({length: order}, (_, l) => Math.sqrt((2 * l + 1) / (4 * Math.PI)));
    return {kind: "sun", theta: 45 * DEGREE, phi: (-60 + 45 * index) * DEGREE, zonal, turn: IDENTITY,
            angular_radius: model ? model.angular_radius : 0, rgb: model ? model.rgb : [1, 1, 1]};
  }

  // Q/A and W/E: θ and φ of the active sun (θ within 0-180°, φ wrapped into −180°..180°); an environment turns
  // about Blender's Z by Δφ and Y by Δθ as in Drive Lights (rotation Rz(Δφ)·Ry(Δθ)·R); a sky has nothing to turn.
  turn(deltaTheta, deltaPhi) {
    const light = this.lights[this.active];
    if (!light) return;
    if (light.kind === "sun") {
      light.theta = Math.min(Math.PI, Math.max(0, light.theta + deltaTheta));
      light.phi = Math.atan2(Math.sin(light.phi + deltaPhi), Math.cos(light.phi + deltaPhi));
    } else if (light.kind === "environment") {
      light.turn = multiply(multiply(axisRotation([0, 0, 1], deltaPhi), axisRotation([0, 1, 0], deltaTheta)),
                            light.turn);
    }
  }

  // The lights' sum at `order` as [3][order²] in glTF's frame, windowed as the export was.
  total(order) {
    const n2 = order * order;
    const total = [0, 1, 2].map(() => new Float64Array(n2));
    for (const light of this.lights) {
      const add = (channel, coefficients) => coefficients.forEach((v, k) => { total[channel][k] += v; });
      if (light.kind === "sun") {
        const lobe = zonalToSh(light.zonal.slice(0, order), sunDirection(light));
        light.rgb.forEach((rgb, c) => add(c, lobe.map((v) => rgb * v)));
      } else {
        const turn = multiply(multiply(TO_GLTF, light.turn), FROM_GLTF);
        light.coefficients.forEach((channel, c) => add(c, rotate(channel.slice(0, n2), turn)));
      }
    }
    const factors = windowFactors(order, this.window, this.windowStrengths[order] ?? 1);
    for (let l = 0; l < order; l++) {
      for (let k = l * l; k < (l + 1) * (l + 1); k++) total.forEach((channel) => { channel[k] *= factors[l]; });
    }
    return total;
  }

  // [{direction (glTF), rgb, active}] of the suns: Blinn-Phong's lights and the light vectors drawn.
  suns() {
    return this.lights.flatMap((light, index) => light.kind === "sun" ?
      [{direction: sunDirection(light), rgb: light.rgb, active: index === this.active}] : []);
  }

  // Mean radiance of the sky and environments (their constant term), Blinn-Phong's ambient light.
  ambient() {
    const y00 = 0.5 / Math.sqrt(Math.PI);
    const ambient = [0, 0, 0];
    for (const light of this.lights) {
      if (light.kind !== "sun") light.coefficients.forEach((channel, c) => { ambient[c] += channel[0] * y00; });
    }
    return ambient;
  }

  describe() {
    const light = this.lights[this.active];
    if (!light) return "no lights";
    const head = `Light ${this.active + 1} of ${this.lights.length} (keys 1-8): ${light.kind}`;
    const rgb = light.rgb.map((v) => +v.toFixed(3)).join(", ");
    if (light.kind === "sun") {
      return `${head} θ ${(light.theta / DEGREE).toFixed(1)}° φ ${(light.phi / DEGREE).toFixed(1)}°, ` +
        `radius ${(light.angular_radius / DEGREE).toFixed(1)}°, irradiance (${rgb})`;
    }
    return `${head}, ${light.kind === "sky" ? "radiance" : "×"} (${rgb})`;
  }
}

function sunDirection(light) {
  return blenderToGltf(directionFromAngles(light.theta, light.phi));
}
