"""Node mode is a transcription of the shared OSL headers: fail when their code has changed
since (the TRANSCRIBED_FROM of node_mode, node_mode_raywave, node_raywave_lobes, node_wave,
node_texel_guard, node_visibility, node_average and node_fitted), and check that node mode reads its constants from them.

    blender -b --factory-startup --python-exit-code 1 --python tests/blender/test_transcription.py

On failure: diff the named source, update the named module (addon/<module>.py) to match, run test_parity.py (on a surface and on ray-wave atlases),
and record the printed fingerprint in that module's TRANSCRIBED_FROM.
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import loom_testlib as lt  # noqa: E402


def main():
    lt.enable_addon()
    from loom import (node_average, node_fitted, node_mode, node_mode_raywave, node_raywave_lobes,
                      node_texel_guard, node_visibility, node_wave, osl_source)

    d = osl_source.osl_dir()
    assert d is not None, "OSL sources not found next to the add-on"
    changed = []
    for module in (node_mode, node_mode_raywave, node_raywave_lobes, node_wave, node_texel_guard,
                   node_visibility, node_average, node_fitted):
        for rel, fp in sorted(module.TRANSCRIBED_FROM.items()):
            now = osl_source.code_fingerprint(os.path.join(d, rel))
            status = "ok" if now == fp else "CHANGED"
            print(f"loom-test: {module.__name__}: {rel}: transcribed {fp}, now {now} {status}")
            if now != fp:
                changed.append(f"{rel} in {module.__name__} (now {now})")
        if hasattr(module, "constants"):  # the group builders: they pass K to the others
            k = module.constants()  # raises if a constant node mode needs is gone
            print(f"loom-test: {module.__name__}: constants from the headers: "
                  + ", ".join(f"{n}={k[n]:g}" for n in module.REQUIRED_CONSTANTS))
    assert not changed, ("shader code changed since node mode was transcribed: "
                         + ", ".join(changed) + "; see this test's docstring")


lt.run(main)
