"""What the scripts in blend/ share: the Loom add-on's API, from an installed extension or
this checkout's addon/."""

import os
import sys
import tempfile
import traceback

import bpy

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def loom_api():
    """loom.api from the enabled add-on, else the installed extension (enabled now), else this
    checkout's addon/ through a temporary local extension repository."""
    try:
        import loom.api

        return loom.api
    except ImportError:
        pass
    import addon_utils

    for mod in addon_utils.modules():
        if mod.__name__.endswith(".loom") and mod.__name__.startswith("bl_ext."):
            addon_utils.enable(mod.__name__, default_set=True)
            import loom.api

            return loom.api
    tmp = tempfile.mkdtemp(prefix="loom-ext-")
    os.symlink(os.path.join(REPO, "addon"), os.path.join(tmp, "loom"))
    bpy.context.preferences.extensions.repos.new(name="loom_dev", module="loom_dev",
                                                 custom_directory=tmp, source="USER")
    addon_utils.enable("bl_ext.loom_dev.loom", default_set=True)
    import loom.api

    return loom.api


def run(main):
    """Run a script's main(): an exception is printed and exits 1 (blender -b would otherwise
    exit 0 after a failed --python script)."""
    try:
        main()
    except SystemExit:
        raise
    except Exception:
        traceback.print_exc()
        sys.exit(1)
