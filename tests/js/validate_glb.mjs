// Khronos' glTF validator (npm gltf-validator, a dev dependency of viewer/) on one GLB: prints its report as JSON.
// Run from viewer/ so node finds the package there.
import {readFile} from "node:fs/promises";
import {createRequire} from "node:module";

const validator = createRequire(`${process.cwd()}/package.json`)("gltf-validator");
const bytes = new Uint8Array(await readFile(process.argv[2]));
const report = await validator.validateBytes(bytes, {maxIssues: 100});
console.log(JSON.stringify(report));
