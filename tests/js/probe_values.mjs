// Prints what viewer/probes.js computes for tests/test_gltf_probes.py: stdin {volume (probe_volumes entry), matrices
// (flat), points (glTF world), light ([3][n²]), turn (3 × 3)} → {weights, lights (null outside), in_frame}.
import {ProbeVolume, lightAt, lightInFrame, trilinearWeights} from "../../viewer/probes.js";

let text = "";
process.stdin.on("data", (chunk) => { text += chunk; });
process.stdin.on("end", () => {
  const {volume, matrices, points, light, turn} = JSON.parse(text);
  const probes = new ProbeVolume(volume, Float32Array.from(matrices));
  const weights = points.map((point) => {
    const local = probes.local(point);
    return local && trilinearWeights(local, volume.resolution, volume.valid);
  });
  const lights = points.map((point) => {
    const found = lightAt([probes], point, light).light;
    return found && found.map((channel) => Array.from(channel));
  });
  console.log(JSON.stringify({weights, lights, in_frame: lightInFrame(light, turn).map((c) => Array.from(c))}));
});
