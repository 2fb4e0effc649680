// Prints what viewer/probes.js vertexRadiance computes for tests/test_gltf_probe_vertices.py: stdin {volumes
// [{volume (probe_volumes entry), matrices (flat)}], positions (flat, glTF world), transfer (flat rows), stride,
// channels, light ([3][n²]), turn (3 × 3), order (the transfer's)} → the radiance, 3 floats a vertex.
import {ProbeVolume, vertexRadiance} from "../../viewer/probes.js";

let text = "";
process.stdin.on("data", (chunk) => { text += chunk; });
process.stdin.on("end", () => {
  const {volumes, positions, transfer, stride, channels, light, turn, order} = JSON.parse(text);
  const probes = volumes.map(({volume, matrices}) => new ProbeVolume(volume, Float32Array.from(matrices)));
  const radiance = vertexRadiance(probes, Float64Array.from(positions), Float32Array.from(transfer), stride,
                                  channels, light, turn, order);
  console.log(JSON.stringify(Array.from(radiance)));
});
