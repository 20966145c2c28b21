"""Properties > Material > Loom."""

from bpy.types import Panel

from . import bakery, material, preferences


class MATERIAL_PT_loom(Panel):
    bl_label = "Loom Cloth"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "material"

    @classmethod
    def poll(cls, context):
        return context.object is not None and hasattr(context.object.data, "materials")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        mat = context.material
        if mat is None or not material.is_loom_material(mat):
            col = layout.column()
            col.operator("loom.material_new", text="New Loom Material", icon="ADD").adopt = False
            if mat is not None:
                op = col.operator("loom.material_new", text="Let Loom Rebuild This Material")
                op.adopt = True
            return
        s = mat.loom
        wm = context.window_manager
        prefs = preferences.get(context)
        if bakery.find_loom_bake(prefs.loom_bake_path if prefs else None) is None:
            row = layout.row()
            row.alert = True
            row.label(text="loom-bake not found: see the add-on's preferences", icon="ERROR")
        warning = material.uv_warning(context.object)
        if warning:
            layout.label(text=warning, icon="ERROR")

        col = layout.column()
        col.prop(s, "source", expand=True)
        if s.source == "PRESET":
            col.prop(s, "preset")
        else:
            col.prop(s, "spec_path")
        col.prop(s, "model")
        col.prop(s, "quality")
        col.prop(s, "mode")
        col.prop(s, "scale_mode")
        if s.scale_mode == "REPEATS":
            col.prop(s, "repeats")
        else:
            col.prop(s, "size_factor")

        row = layout.row(align=True)
        if wm.loom_bake_running:
            row.prop(wm, "loom_bake_progress", text=wm.loom_bake_status or "Baking", slider=True)
            row.operator("loom.bake_cancel", text="", icon="CANCEL")
        else:
            row.scale_y = 1.3
            row.operator("loom.bake_assign", icon="RENDER_STILL")
            row.operator("loom.bake_all", text="All", icon="RENDERLAYERS")
            layout.operator("loom.assign_atlas", icon="FILE_FOLDER")
            if wm.loom_bake_status:
                layout.label(text=wm.loom_bake_status, icon="INFO")

        if s.atlas_problem:
            warn = layout.box().column()
            warn.alert = True
            warn.label(text=f"Atlas {s.atlas_problem}", icon="ERROR")
            warn.label(text="Rendering a plain fallback; the material's nodes are kept")
            warn.label(text="Re-bake bakes the atlas again and rebuilds this material's nodes")
            warn.operator("loom.bake_assign", text="Re-bake", icon="FILE_REFRESH")
        if s.atlas_dir:
            box = layout.box()
            box.label(text=f"Atlas: {s.atlas_dir}", icon="TEXTURE")
            if s.mode_used:
                box.label(text=f"Mode: {s.mode_used.lower()}")
            if s.status:
                box.label(text=s.status)
            box.operator("loom.scene_needs", icon="VIEWZOOM")
            row = box.row(align=True)
            row.operator("loom.fibers_update", icon="STRANDS")
            row.operator("loom.fibers_remove", text="", icon="X")
            box.prop(context.scene, "loom_fibers_follow_camera")
            for line in s.needs_report.splitlines():
                box.label(text=line)
            # A Script node renders black where OSL cannot run (e.g. after switching the
            # device to a non-OptiX GPU): say so and offer the rebuild.
            if s.mode_used == "OSL":
                ok, why = material.osl_support(context.scene)
                if not ok:
                    warn = box.column()
                    warn.alert = True
                    warn.label(text=f"OSL cannot run now: {why}", icon="ERROR")
                    op = warn.operator("loom.assign_atlas", text="Rebuild (Auto)")
                    op.directory = s.atlas_dir


classes = (MATERIAL_PT_loom,)
