// SPDX-License-Identifier: GPL-3.0-or-later
//
// Flamenco job type "Occlusion Analysis": which objects the scene camera ever sees over a
// frame range, analyzed in chunks on the farm's workers and merged into one report; or
// (`job` BAKE) the shot baked in chunks and merged into the blend file's bake.
//
// Install: copy this file into the `scripts/` folder next to the flamenco-manager
// executable and restart the Manager (Flamenco manual, "Job Types").  Every worker needs
// Blender 4.2+ with the Occlusion Culled Viewport extension installed, and the merge task
// a checkout of this repository with its venv (`make venv`) on shared storage.
//
// Tasks:
//   analyze-A-B  one per chunk of `chunk_size` frames (task type "blender"):
//                {blender} {blenderArgs} --addons MOD FILE --python-exit-code 1 --python-expr
//                "import bpy; assert bpy.ops.occ.analyze(frame_start=A, frame_end=B, frame_step=S,
//                 rule='R', filepath='OUT/chunks/chunk_A_B.json') == {'FINISHED'}"
//   merge        after every chunk (task type "misc"):
//                PYTHON -c "<python -m core, from CHECKOUT>" merge OUT/chunks --out OUT
//                -> OUT/report.json and OUT/report.csv, exactly the report of one run.
// With `job` BAKE or BAKE_RENDER:
//   bake-A-B     one per chunk of `chunk_size` frames (every frame: a bake has no step):
//                ... --python-expr "import bpy; assert bpy.ops.occ.bake_shot(frame_start=A,
//                 frame_end=B, filepath='OUT/chunks/bake_A_B.json') == {'FINISHED'}"
//   merge        after every chunk (task type "blender"): opens FILE, occ.bake_merge(directory=
//                'OUT/chunks') (exactly the bake of one run), BAKE_RENDER: occ.bake_render() (Apply
//                to Render: a plain `blender -a` of the file renders with the bake), and saves
//                FILE in place.
// `python tools/flamenco/compile_job.js` (node) prints the tasks this file authors for
// given settings; tests/blender/test_farm.py runs every command of them.

const ADDON_MODULE = "bl_ext.user_default.occlusion_culled_viewport";

const JOB_TYPE = {
    label: "Occlusion Analysis",
    description: "Which objects the scene camera ever sees: occ.analyze in chunks of frames, merged into one report",
    settings: [
        // The Flamenco add-on fills in the blend file it submits.
        { key: "blendfile", type: "string", required: true, visible: "web",
          description: "Path of the blend file to analyze" },
        { key: "frame_start", type: "int32", required: true, eval: "C.scene.frame_start",
          evalInfo: { showLinkButton: true, description: "Scene frame start" },
          description: "First frame of the range" },
        { key: "frame_end", type: "int32", required: true, eval: "C.scene.frame_end",
          evalInfo: { showLinkButton: true, description: "Scene frame end" },
          description: "Last frame of the range (included)" },
        { key: "frame_step", type: "int32", default: 1, eval: "C.scene.frame_step",
          description: "Analyze every n-th frame" },
        { key: "chunk_size", type: "int32", default: 50, visible: "submission",
          description: "Frames per analyze task" },
        { key: "job", type: "string", default: "ANALYZE", choices: ["ANALYZE", "BAKE", "BAKE_RENDER"],
          visible: "submission",
          description: "ANALYZE: a report of what the camera sees; BAKE: Bake Shot in chunks, merged into the " +
                       "blend file (saved in place); BAKE_RENDER: the same, applied to the render" },
        { key: "rule", type: "string", default: "AUTO", choices: ["AUTO", "SEEN", "RENDER"],
          visible: "submission",
          description: "What counts as visible: occ.analyze's rule (SEEN: a pixel of it is seen; RENDER: also its shadows)" },
        { key: "output_dir", type: "string", subtype: "dir_path", required: true, visible: "submission",
          eval: "__import__('os').path.join(__import__('bpy').path.abspath('//'), 'occlusion_analysis')",
          description: "Folder of the report: chunks/ holds the chunks, report.json and report.csv the merged report" },
        { key: "checkout", type: "string", subtype: "dir_path", required: true, visible: "submission",
          default: "{occ_checkout}",
          description: "This repository's checkout on shared storage, for the merge (`python -m core merge`)" },
        { key: "python", type: "string", default: "", visible: "submission",
          description: "Python of the checkout's venv (default: CHECKOUT/.venv/bin/python)" },
        { key: "addon_module", type: "string", default: ADDON_MODULE, visible: "hidden",
          description: "Module of the installed extension (enabled with --addons)" },
    ],
};

function compileJob(job) {
    if ((job.settings.job || "ANALYZE") !== "ANALYZE") {
        compileBake(job);
        return;
    }
    const s = job.settings;
    const chunks = frameChunks(s.frame_start, s.frame_end, s.frame_step || 1, s.chunk_size);
    const chunkDir = path.join(s.output_dir, "chunks");
    const merge = author.Task("merge", "misc");
    for (const [a, b] of chunks) {
        const task = author.Task(`analyze-${a}-${b}`, "blender");
        task.addCommand(blenderCommand(s,
            analyzeExpr(a, b, s.frame_step || 1, s.rule, path.join(chunkDir, `chunk_${a}_${b}.json`))));
        job.addTask(task);
        merge.addDependency(task);
    }
    merge.addCommand(author.Command("exec", {
        exe: s.python || path.join(s.checkout, ".venv", "bin", "python"),
        args: ["-c", runCore(s.checkout), "merge", chunkDir, "--out", s.output_dir],
    }));
    job.addTask(merge);
}

// The shot baked per chunk (`occ.bake_shot` writing a chunk file), then merged into the file.
function compileBake(job) {
    const s = job.settings;
    const chunkDir = path.join(s.output_dir, "chunks");
    const merge = author.Task("merge", "blender");
    for (const [a, b] of frameChunks(s.frame_start, s.frame_end, 1, s.chunk_size)) {
        const task = author.Task(`bake-${a}-${b}`, "blender");
        task.addCommand(blenderCommand(s, "import bpy; assert bpy.ops.occ.bake_shot(" +
            `frame_start=${a}, frame_end=${b}, filepath=${pyString(path.join(chunkDir, `bake_${a}_${b}.json`))}) ` +
            "== {'FINISHED'}"));
        job.addTask(task);
        merge.addDependency(task);
    }
    const render = s.job === "BAKE_RENDER" ? "assert bpy.ops.occ.bake_render() == {'FINISHED'}; " : "";
    merge.addCommand(blenderCommand(s, "import bpy; " +
        `assert bpy.ops.occ.bake_merge(directory=${pyString(chunkDir)}) == {'FINISHED'}; ` +
        render + "assert bpy.ops.wm.save_mainfile() == {'FINISHED'}"));
    job.addTask(merge);
}

// Blender on the job's file with the extension enabled, running `expr` (a failure fails the task).
function blenderCommand(s, expr) {
    return author.Command("blender-render", {
        exe: "{blender}",
        exeArgs: "{blenderArgs}",
        argsBefore: ["--addons", s.addon_module],
        blendfile: s.blendfile,
        args: ["--python-exit-code", "1", "--python-expr", expr],
    });
}

// [[first, last], ...]: chunks of `size` analyzed frames (`step` apart), each range inclusive.
function frameChunks(start, end, step, size) {
    if (!(step >= 1) || !(size >= 1)) {
        throw `frame_step and chunk_size must be 1 or more, got ${step} and ${size}`;
    }
    if (end < start) {
        throw `empty frame range ${start}..${end}`;
    }
    const chunks = [];
    for (let a = start; a <= end; a += size * step) {
        chunks.push([a, Math.min(a + size * step - 1, end)]);
    }
    return chunks;
}

// A Python string literal (JSON strings are Python strings, escapes included).
function pyString(text) {
    return JSON.stringify(String(text));
}

function analyzeExpr(a, b, step, rule, report) {
    return "import bpy; assert bpy.ops.occ.analyze(" +
        `frame_start=${a}, frame_end=${b}, frame_step=${step}, rule=${pyString(rule)}, ` +
        `filepath=${pyString(report)}) == {'FINISHED'}`;
}

// `python -m core` run from the checkout, whatever the worker's working directory.
function runCore(checkout) {
    return `import runpy, sys; sys.path.insert(0, ${pyString(checkout)}); ` +
        'runpy.run_module("core", run_name="__main__", alter_sys=True)';
}
