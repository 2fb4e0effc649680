// Prints the viewer's light sums (viewer/lights.js) for tests/test_gltf.py: stdin {extras, order, steps}, each step
// [light index, Δθ, Δφ] (radians) as the keys turn them → [3][order²] after each step.
import {LightSet} from "../../viewer/lights.js";

let text = "";
process.stdin.on("data", (chunk) => { text += chunk; });
process.stdin.on("end", () => {
  const {extras, order, steps} = JSON.parse(text);
  const lights = new LightSet(extras);
  const totals = steps.map(([index, deltaTheta, deltaPhi]) => {
    lights.select(index);
    lights.turn(deltaTheta, deltaPhi);
    return lights.total(order).map((channel) => Array.from(channel));
  });
  console.log(JSON.stringify(totals));
});
