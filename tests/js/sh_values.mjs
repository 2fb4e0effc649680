// Prints the viewer's SH maths (viewer/sh.js) for the inputs on stdin, for tests/test_gltf.py to compare with the
// add-on's Python: {order, directions, zonal, rotation, coefficients} → {evaluate, zonal, rotated, hanning, lanczos,
// tapered (strength 0.37, the Auto window's kind)}.
import {evaluate, rotate, windowFactors, zonalToSh} from "../../viewer/sh.js";

let text = "";
process.stdin.on("data", (chunk) => { text += chunk; });
process.stdin.on("end", () => {
  const input = JSON.parse(text);
  const list = (values) => Array.from(values);
  console.log(JSON.stringify({
    evaluate: input.directions.map((d) => list(evaluate(input.order, d))),
    zonal: input.directions.map((d) => list(zonalToSh(input.zonal, d))),
    rotated: list(rotate(input.coefficients, input.rotation)),
    hanning: windowFactors(input.order, "hanning"),
    lanczos: windowFactors(input.order, "lanczos"),
    tapered: windowFactors(input.order, "tapered", 0.37),
  }));
});
