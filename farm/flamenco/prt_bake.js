// SPDX-License-Identifier: GPL-3.0-or-later
//
// Flamenco job type "PRT Bake": one PRT bake spread over the farm. N tasks each bake one shard
// (`blender -b FILE --command prt bake --shard K/N --out PART.npz`), and one merge task, which depends on all of
// them, stores the bake as one Blender would (`--command prt merge PARTS... --output OUT.blend`). With the setting
// "PRT command" (e.g. `prt`, the command setup.sh installs with the bpy module) the tasks run that command instead
// (`prt bake FILE --shard K/N ...`).
//
// Install: copy this file into the `scripts` folder next to the flamenco-manager executable and restart the
// Manager. Every Worker's Blender needs the PRT extension enabled. See the manual, docs/farms.md.

const JOB_TYPE = {
    label: "PRT Bake",
    description: "Bake PRT transfer in shards over the farm, then merge them into one .blend",
    settings: [
        // Set by the Blender add-on on submission.
        { key: "blendfile", type: "string", required: true, visible: "web",
          description: "Path of the .blend file to bake" },
        { key: "shards", type: "int32", default: 4, propargs: { min: 1, max: 10000 }, visible: "submission",
          description: "Tasks the bake is split into; each bakes one shard, the merge task all of them" },
        { key: "parts_dir", type: "string", subtype: "dir_path", required: true, visible: "submission",
          eval: "str(Path(abspath('//prt_parts'), jobname))",
          description: "Shared folder for the shards' part files" },
        { key: "output", type: "string", subtype: "file_path", required: true, visible: "submission",
          eval: "str(Path(abspath('//'), jobname + '_baked.blend'))",
          description: "Where the merge task saves the baked .blend file" },
        { key: "objects", type: "string", default: "", visible: "submission",
          description: "Comma-separated receivers; empty: every visible mesh" },
        { key: "prt_command", type: "string", default: "", visible: "submission",
          description: "How Workers run PRT: empty for their Blender (with the PRT extension enabled); else a " +
                       "command such as prt (the bpy module's), split at spaces" },
        // The bake's settings: the names and defaults of prt_addon/core/settings.py.
        { key: "mode", type: "string", default: "shadowed", choices: ["unshadowed", "shadowed", "interreflected"],
          visible: "submission", description: "What the transfer holds" },
        { key: "order", type: "int32", default: 4, propargs: { min: 1, max: 10 }, visible: "submission",
          description: "SH bands (order n stores n² coefficients)" },
        { key: "samples", type: "int32", default: 256, propargs: { min: 8 }, visible: "submission",
          description: "Rays per vertex (the first round when a target error is set)" },
        { key: "target_error", type: "float", default: 0.0, propargs: { min: 0.0, max: 1.0 }, visible: "submission",
          description: "Sample each vertex until its estimated relative error is below this (0: off)" },
        { key: "max_samples", type: "int32", default: 16384, propargs: { min: 8 }, visible: "submission",
          description: "Ray budget per vertex when a target error is set" },
        { key: "seed", type: "int32", default: 0, propargs: { min: 0 }, visible: "submission",
          description: "Random seed: the same seed gives the same bake" },
        { key: "bounces", type: "string", default: "auto", visible: "submission",
          description: "Interreflection bounces: a whole number, or auto" },
        { key: "bounce_tolerance", type: "float", default: 0.001, visible: "submission",
          description: "Relative error that auto bounces may leave out" },
        { key: "ray_engine", type: "string", default: "auto", choices: ["auto", "embree", "bvhtree"],
          visible: "submission",
          description: "What casts the rays; auto: Embree where installed, else BVHTree (the shards must agree)" },
    ],
};

const BAKE_SETTINGS = ["mode", "order", "samples", "target_error", "max_samples", "seed", "bounces",
                       "bounce_tolerance", "ray_engine"];

function compileJob(job) {
    const settings = job.settings;
    const shards = settings.shards;
    const options = bakeOptions(settings);
    const bakeTasks = [];
    const parts = [];
    for (let shard = 1; shard <= shards; shard++) {
        const part = `${settings.parts_dir}/part-${shard}-of-${shards}.npz`;
        const task = author.Task(`bake-${shard}-of-${shards}`, "blender");
        task.addCommand(prtCommand(settings, "bake", ["--shard", `${shard}/${shards}`, "--out", part].concat(options)));
        job.addTask(task);
        bakeTasks.push(task);
        parts.push(part);
    }
    const merge = author.Task("merge", "blender");
    merge.addCommand(prtCommand(settings, "merge", parts.concat(["--output", settings.output])));
    for (const task of bakeTasks) {
        merge.addDependency(task);
    }
    job.addTask(merge);
}

// `{blender} {blenderArgs} FILE --command prt COMMAND ARGS...`: the Worker's Blender opens the file, then runs the
// add-on's command. With a PRT command: `PRT COMMAND FILE ARGS...`, run as it is (exec, no shell).
function prtCommand(settings, command, prtArgs) {
    const words = (settings.prt_command || "").trim().split(/\s+/).filter((word) => word !== "");
    if (words.length === 0) {
        return author.Command("blender-render", {
            exe: "{blender}",
            exeArgs: "{blenderArgs}",
            argsBefore: [],
            blendfile: settings.blendfile,
            args: ["--command", "prt", command].concat(prtArgs),
        });
    }
    return author.Command("exec", {
        exe: words[0],
        args: words.slice(1).concat([command, settings.blendfile], prtArgs),
    });
}

function bakeOptions(settings) {
    const options = [];
    for (const key of BAKE_SETTINGS) {
        options.push("--" + key.replace(/_/g, "-"), String(settings[key]));
    }
    if (settings.objects) {
        options.push("--objects", settings.objects);
    }
    return options;
}
