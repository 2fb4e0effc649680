// Prints the PRT shader's light uniform (viewer/prt_material.js setLight) for tests/test_gltf.py: stdin {layout,
// total} → the uniform's floats, 3 rows of 4·vec4s (one per output colour channel).
import {setLight} from "../../viewer/prt_material.js";

let text = "";
process.stdin.on("data", (chunk) => { text += chunk; });
process.stdin.on("end", () => {
  const {layout, total} = JSON.parse(text);
  const material = {uniforms: {uLight: {value: new Float32Array(3 * 4 * layout.vec4s)}}};
  setLight(material, layout, total);
  console.log(JSON.stringify(Array.from(material.uniforms.uLight.value)));
});
