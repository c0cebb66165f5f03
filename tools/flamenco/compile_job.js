// SPDX-License-Identifier: GPL-3.0-or-later
//
// Compile a Flamenco job type offline, as Flamenco Manager would, and print the tasks it
// authors as JSON: a dry run of the farm job, and what tests/blender/test_farm.py runs.
//
//   node tools/flamenco/compile_job.js tools/flamenco/occlusion_analyze.js '{"blendfile": ..., ...}'
//
// Prints {"settings": {...}, "tasks": [{"name", "type", "commands": [{"name", "parameters"}],
// "dependencies": [task names]}]}.  Settings missing from the JSON take the job type's
// defaults; a required one missing is an error, as on the Manager.  Only what the job
// compilers use of Flamenco's API is here: author.Task / author.Command, job.addTask,
// task.addCommand / addDependency, path.join / dirname / basename, print.

"use strict";

const fs = require("fs");
const nodePath = require("path");
const vm = require("vm");

function compile(scriptPath, given) {
    const tasks = [];
    const author = {
        Task(name, type) {
            const task = { name, type, commands: [], dependencies: [] };
            return {
                _task: task,
                addCommand(cmd) { task.commands.push(cmd); },
                addDependency(other) { task.dependencies.push(other._task.name); },
            };
        },
        Command(name, parameters) { return { name, parameters }; },
    };
    const path = {
        join: (...parts) => nodePath.posix.join(...parts),
        dirname: (p) => nodePath.posix.dirname(p),
        basename: (p) => nodePath.posix.basename(p),
    };
    const context = vm.createContext({ author, path, print: (...a) => console.error(...a) });
    vm.runInContext(fs.readFileSync(scriptPath, "utf8"), context, { filename: scriptPath });
    const jobType = vm.runInContext("JOB_TYPE", context);
    const settings = {};
    for (const s of jobType.settings) {
        if (s.key in given) {
            settings[s.key] = given[s.key];
        } else if ("default" in s) {
            settings[s.key] = s.default;
        } else if (s.required) {
            throw new Error(`setting '${s.key}' is required`);
        }
        if (s.choices && s.key in settings && !s.choices.includes(settings[s.key])) {
            throw new Error(`setting '${s.key}' must be one of ${s.choices.join(", ")}`);
        }
    }
    const job = { settings, addTask(t) { tasks.push(t._task); } };
    context.compileJob(job);
    return { settings, tasks };
}

const [scriptPath, settingsJson] = process.argv.slice(2);
if (!scriptPath) {
    console.error("usage: node compile_job.js JOB_TYPE.js '{\"setting\": value, ...}'");
    process.exit(2);
}
try {
    process.stdout.write(JSON.stringify(compile(scriptPath, JSON.parse(settingsJson || "{}")), null, 1) + "\n");
} catch (e) {
    console.error(`error: ${e && e.message ? e.message : e}`);
    process.exit(2);
}
