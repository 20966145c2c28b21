// SPDX-License-Identifier: GPL-3.0-or-later
// A Flamenco job type (put this file in the Manager's scripts/ folder): renders a .blend with
// Loom materials on a farm. One task first bakes the atlases the file lacks (a material whose
// atlas is missing or stale: `loom.bake_all` with only_missing), collects them beside the .blend
// (//loom/<atlas>/, `loom.collect_atlases`) and saves it; the render tasks, chunks of the frame
// range, wait for it. Every worker needs Blender with the Loom extension installed (its package
// carries loom-bake). A .blend already collected (File > External Data > Collect Loom Atlases)
// bakes nothing there.

const JOB_TYPE = {
  label: "Loom: Bake Missing Atlases, Render",
  settings: [
    { key: "frames", type: "string", required: true,
      eval: "f'{C.scene.frame_start}-{C.scene.frame_end}'",
      evalInfo: { showLinkButton: true, description: "Scene frame range" },
      description: "Frames to render, e.g. '1-30' or '3, 5-10'" },
    { key: "chunk_size", type: "int32", default: 1, propargs: { min: 1 }, visible: "submission",
      description: "Frames per render task" },
    { key: "render_output_root", type: "string", subtype: "dir_path", required: true,
      visible: "submission", description: "Folder the frames go into (a job folder is added)" },
    { key: "render_output_path", type: "string", subtype: "file_path", editable: false,
      eval: "str(Path(abspath(settings.render_output_root), jobname, '######'))",
      description: "Where the frames are written" },
    { key: "blendfile", type: "string", required: true, visible: "web",
      description: "The .blend to render" },
    { key: "format", type: "string", required: true, visible: "web",
      eval: "C.scene.render.image_settings.file_format" },
  ],
};

// What the bake task runs in Blender: bake what is missing (exit 1 if any bake fails), collect
// the atlases beside the .blend and save it.
const BAKE_MISSING_PY = [
  "import bpy",
  "r = bpy.ops.loom.bake_all(only_missing=True)",
  "m = [x.name for x in bpy.data.materials if getattr(x, 'loom', None) and x.loom.atlas_problem]",
  "assert not m, f'Loom atlases still missing: {m}'",
  "bpy.ops.loom.collect_atlases()",
  "bpy.ops.wm.save_mainfile()",
].join("; ");

function compileJob(job) {
  const settings = job.settings;
  if (["FFMPEG", "AVI_RAW", "AVI_JPEG"].indexOf(settings.format) >= 0)
    throw `this job type renders images, not "${settings.format}"`;
  if (!settings.render_output_path) throw "no render_output_path setting";
  if (!(settings.chunk_size >= 1)) throw `chunk_size must be 1 or more, not ${settings.chunk_size}`;

  const bake = author.Task("loom-bake-missing", "blender");
  bake.addCommand(author.Command("blender-render", {
    exe: "{blender}",
    exeArgs: "{blenderArgs}",
    argsBefore: [],
    blendfile: settings.blendfile,
    args: ["--python-exit-code", "1", "--python-expr", BAKE_MISSING_PY],
  }));
  job.addTask(bake);

  const output = settings.render_output_path;
  for (const chunk of frameChunker(settings.frames, settings.chunk_size)) {
    const task = author.Task(`render-${chunk}`, "blender");
    task.addCommand(author.Command("blender-render", {
      exe: "{blender}",
      exeArgs: "{blenderArgs}",
      argsBefore: [],
      blendfile: settings.blendfile,
      args: ["--render-output", output, "--render-format", settings.format,
             "--render-frame", chunk.replaceAll("-", "..")],
    }));
    task.addDependency(bake);
    job.addTask(task);
  }
}
