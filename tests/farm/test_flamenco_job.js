// farm/flamenco/loom_render.js as Flamenco's Manager runs it: the file evaluated with the
// globals the Manager provides (author, frameChunker, print; stand-ins here that record what the
// job type does), then compileJob on a job. Checks: the settings Flamenco needs, one bake task
// that runs Blender with --python-exit-code and Loom's bake/collect/save, render tasks covering
// the frames in chunks, each depending on the bake task; bad settings refused.
//   node tests/farm/test_flamenco_job.js farm/flamenco/loom_render.js
"use strict";
const fs = require("fs");
const vm = require("vm");
const assert = require("assert");

function frameChunker(frames, size) {  // Flamenco's semantics: "1-10" in chunks of `size`
  const list = [];
  for (const part of String(frames).split(",")) {
    const [a, b] = part.trim().split("-").map(Number);
    for (let f = a; f <= (b === undefined ? a : b); f++) list.push(f);
  }
  const chunks = [];
  for (let i = 0; i < list.length; i += size) {
    const c = list.slice(i, i + size);
    chunks.push(c.length > 1 ? `${c[0]}-${c[c.length - 1]}` : `${c[0]}`);
  }
  return chunks;
}
const author = {
  Task: (name, type) => ({ name, type, commands: [], deps: [],
    addCommand(c) { this.commands.push(c); }, addDependency(t) { this.deps.push(t); } }),
  Command: (type, params) => ({ type, params }),
};
const sandbox = { author, frameChunker, print: () => {}, console };
vm.createContext(sandbox);
vm.runInContext(fs.readFileSync(process.argv[2], "utf8") + "\nthis.JOB_TYPE = JOB_TYPE;",
                sandbox, { filename: process.argv[2] });

const keys = sandbox.JOB_TYPE.settings.map((s) => s.key);
for (const k of ["frames", "chunk_size", "render_output_root", "render_output_path", "blendfile",
                 "format"])
  assert(keys.includes(k), `setting ${k} missing`);
assert.strictEqual(typeof sandbox.compileJob, "function");

function compile(settings) {
  const job = { settings, tasks: [], addTask(t) { this.tasks.push(t); } };
  sandbox.compileJob(job);
  return job.tasks;
}
const base = { frames: "1-5", chunk_size: 2, render_output_path: "/out/job/######",
               blendfile: "/shared/shot.blend", format: "OPEN_EXR" };
const tasks = compile({ ...base });
assert.strictEqual(tasks.length, 4, "one bake task and three render chunks");
const bake = tasks[0];
assert.strictEqual(bake.name, "loom-bake-missing");
const bargs = bake.commands[0].params.args;
assert.strictEqual(bake.commands[0].params.blendfile, "/shared/shot.blend");
const plain = (x) => JSON.parse(JSON.stringify(x));  // (arrays of the job file's own realm)
assert.deepStrictEqual(plain(bargs.slice(0, 3)), ["--python-exit-code", "1", "--python-expr"]);
for (const step of ["bpy.ops.loom.bake_all(only_missing=True)", "bpy.ops.loom.collect_atlases()",
                    "bpy.ops.wm.save_mainfile()"])
  assert(bargs[3].includes(step), `the bake task does not run ${step}`);
const renders = tasks.slice(1);
assert.deepStrictEqual(renders.map((t) => t.name), ["render-1-2", "render-3-4", "render-5"]);
for (const t of renders) {
  assert.deepStrictEqual(t.deps, [bake], `${t.name} does not wait for the bake`);
  const a = t.commands[0].params.args;
  assert.strictEqual(a[a.indexOf("--render-output") + 1], "/out/job/######");
  assert.strictEqual(a[a.indexOf("--render-format") + 1], "OPEN_EXR");
}
assert.strictEqual(renders[0].commands[0].params.args.slice(-1)[0], "1..2");
assert.throws(() => compile({ ...base, format: "FFMPEG" }), /renders images/);
assert.throws(() => compile({ ...base, chunk_size: 0 }), /chunk_size/);
assert.throws(() => compile({ ...base, render_output_path: "" }), /render_output_path/);
console.log(`flamenco job: ${tasks.length} tasks, renders wait for ${bake.name}: PASS`);
