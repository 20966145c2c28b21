"""Node mode is a transcription of the shared OSL headers: fail when their code has changed
since (node_mode.TRANSCRIBED_FROM), and check that node mode reads its constants from them.

    blender -b --factory-startup --python-exit-code 1 --python tests/blender/test_transcription.py

On failure: diff the named source, update addon/node_mode.py to match, run test_parity.py, and
record the printed fingerprint in node_mode.TRANSCRIBED_FROM.
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import loom_testlib as lt  # noqa: E402


def main():
    lt.enable_addon()
    from loom import node_mode, osl_source

    d = osl_source.osl_dir()
    assert d is not None, "OSL sources not found next to the add-on"
    changed = []
    for rel, fp in sorted(node_mode.TRANSCRIBED_FROM.items()):
        now = osl_source.code_fingerprint(os.path.join(d, rel))
        status = "ok" if now == fp else "CHANGED"
        print(f"loom-test: {rel}: transcribed {fp}, now {now} {status}")
        if now != fp:
            changed.append(f"{rel} (now {now})")
    k = node_mode.constants()  # raises if a constant node mode needs is gone
    print("loom-test: constants from the headers: "
          + ", ".join(f"{n}={k[n]:g}" for n in node_mode.REQUIRED_CONSTANTS))
    assert not changed, ("shader code changed since node mode was transcribed: "
                         + ", ".join(changed) + "; see this test's docstring")


lt.run(main)
