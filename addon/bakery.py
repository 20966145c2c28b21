"""Talking to ``loom-bake``: finding it, listing presets, the atlas cache, and bake jobs.

No ``bpy`` in this module: the same code drives the modal operator (polled from a timer), the
blocking ``loom.api.bake`` used by scripts and CI, and can be tested outside Blender.

A bake is two ``loom-bake`` runs:

1. ``loom-bake check SPEC --quality Q`` prints the spec's canonical JSON. Its SHA-256 is the
   cache key, so equal specs (a preset name and a file holding the same preset, or two files
   that differ only in formatting) share one atlas.
2. ``loom-bake bake SPEC -o CACHE/<name>-<quality>-<key> --quality Q --progress=json`` writes
   the atlas (or reuses it when a valid atlas of this spec already sits there), printing one JSON
   object per line: ``{"stage": ..., "fraction": ...}`` while working and finally
   ``{"atlas": ..., "reused": ..., "seconds": ..., "bytes": ...}``.

Processes are read by daemon threads into a queue (``poll()`` never blocks; portable, unlike
non-blocking pipes, which Windows lacks), and a job can be cancelled at any time: the process is
killed and the partial output is loom-bake's own business (it publishes atlases atomically).
"""

from __future__ import annotations

import hashlib
import json
import os
import queue
import re
import shutil
import subprocess
import threading
import time
from dataclasses import dataclass, field

QUALITIES = ("draft", "preview", "final", "reference")
# Shown when loom-bake cannot be asked (not installed yet); `loom-bake presets` is the truth.
# Same order as `loom-bake presets` (default, the weaves alphabetically, then the measured sample
# fabrics alphabetically): Blender stores a dynamic enum by index, so a different order would
# change a saved choice once loom-bake is found. New presets are only ever appended.
FALLBACK_PRESETS = (
    "default", "basket", "plain", "satin", "twill",
    "beige_silk_satin", "black_polyester_plain", "blue_cotton_satin", "cream_cotton_twill",
    "gray_wool_twill", "orange_polyester_satin", "white_silk_organza",
)
DEFAULT_CACHE_DIR = os.path.join("~", ".cache", "loom", "atlases")


class LoomBakeError(RuntimeError):
    """loom-bake could not be run or reported an error (message: its stderr, condensed)."""

    def __init__(self, message: str, returncode: int | None = None, stderr: str = ""):
        super().__init__(message)
        self.returncode = returncode
        self.stderr = stderr


# The baker the extension package carries (scripts/package.sh): bin/loom-bake beside the add-on.
BUNDLED_LOOM_BAKE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "bin", "loom-bake")


def bundled_loom_bake() -> str | None:
    """The package's own loom-bake, made executable if the installer dropped the bit (zip
    files do not always carry Unix permissions); None in a source checkout."""
    path = BUNDLED_LOOM_BAKE
    if not os.path.isfile(path):
        return None
    if not os.access(path, os.X_OK):
        try:
            os.chmod(path, os.stat(path).st_mode | 0o755)
        except OSError:
            return None
    return path if os.access(path, os.X_OK) else None


def find_loom_bake(preferred: str | None = None) -> str | None:
    """The loom-bake executable: ``preferred`` (the add-on preference) if set, else
    ``$LOOM_BAKE``, else the package's own, else ``loom-bake`` on PATH. None when nothing
    usable is found."""
    for cand in (preferred, os.environ.get("LOOM_BAKE")):
        if cand:
            path = os.path.abspath(os.path.expanduser(cand))
            if os.path.isfile(path) and os.access(path, os.X_OK):
                return path
            found = shutil.which(cand)
            if found:
                return found
    return bundled_loom_bake() or shutil.which("loom-bake")


def require_loom_bake(preferred: str | None = None) -> str:
    exe = find_loom_bake(preferred)
    if exe is None:
        raise LoomBakeError(
            "loom-bake not found: install the Loom package that carries it (loom-<version>-"
            "linux-x64.zip), set its path in the Loom add-on preferences, set $LOOM_BAKE, or put "
            "loom-bake on PATH"
        )
    return exe


def default_cache_dir() -> str:
    return os.path.expanduser(DEFAULT_CACHE_DIR)


def _condense_stderr(stderr: str, limit: int = 6) -> str:
    """The lines of loom-bake's stderr worth showing in a one-line report."""
    lines = [ln.strip() for ln in stderr.splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("error:") or ln.startswith("loom-bake:")]
    chosen = errors or lines
    return "; ".join(chosen[-limit:])


def run_loom_bake(exe: str, args: list[str], timeout: float = 60.0) -> str:
    """Run a short loom-bake command (presets, check, inspect) and return its stdout."""
    try:
        cp = subprocess.run(
            [exe, *args], capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL
        )
    except FileNotFoundError as exc:
        raise LoomBakeError(f"cannot run {exe}: {exc}") from exc
    except subprocess.TimeoutExpired as exc:
        raise LoomBakeError(f"{exe} {' '.join(args)} timed out after {timeout:.0f} s") from exc
    if cp.returncode != 0:
        detail = _condense_stderr(cp.stderr) or f"exit code {cp.returncode}"
        raise LoomBakeError(
            f"loom-bake {args[0]} failed ({cp.returncode}): {detail}", cp.returncode, cp.stderr
        )
    return cp.stdout


def spec_tier(exe: str, spec: str) -> str | None:
    """The model tier of a spec (preset name or file) by ``loom-bake check``; None when the spec
    does not validate (the bake itself then reports why)."""
    try:
        canon = json.loads(run_loom_bake(exe, ["check", _spec_arg(spec)], timeout=20))
    except (LoomBakeError, ValueError):
        return None
    return canon.get("model", {}).get("tier")


def spec_geometry(exe: str, spec: str) -> dict:
    """``loom-bake check --geometry``: {"spec": the canonical spec, "repeat_um": [x, y],
    "warp_yarns", "weft_yarns"}; raises LoomBakeError when the spec does not validate."""
    out = run_loom_bake(exe, ["check", _spec_arg(spec), "--geometry"], timeout=20)
    try:
        return json.loads(out)
    except ValueError as exc:
        raise LoomBakeError(f"loom-bake check --geometry printed no JSON: {exc}") from exc


def list_presets(exe: str) -> list[str]:
    """Names printed by ``loom-bake presets`` (one a line)."""
    out = run_loom_bake(exe, ["presets"], timeout=20)
    return [ln.strip() for ln in out.splitlines() if ln.strip()]


def _spec_arg(spec: str) -> str:
    """loom-bake takes a preset name or a file; make files absolute (the process may run in
    another working directory, e.g. through the chroot wrapper)."""
    path = os.path.expanduser(spec)
    if os.path.sep in spec or spec.endswith(".json") or os.path.exists(path):
        if not os.path.isfile(path):
            raise LoomBakeError(f"spec file not found: {spec}")
        return os.path.abspath(path)
    return spec


_NAME_SAFE = re.compile(r"[^A-Za-z0-9_.-]+")


def cache_entry(canonical_json: str, quality: str) -> tuple[str, str]:
    """(directory name, key) of the cache entry for a canonical spec: the key is the SHA-256 of
    the canonical JSON (which already holds model.quality) and of the quality, to be explicit."""
    h = hashlib.sha256()
    h.update(canonical_json.strip().encode("utf-8"))
    h.update(b"\0quality=" + quality.encode("utf-8"))
    key = h.hexdigest()
    try:
        name = str(json.loads(canonical_json).get("name") or "fabric")
    except (ValueError, AttributeError):
        name = "fabric"
    name = _NAME_SAFE.sub("_", name)[:40] or "fabric"
    return f"{name}-{quality}-{key[:20]}", key


def read_manifest(atlas_dir: str) -> dict:
    path = os.path.join(atlas_dir, "manifest.json")
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except OSError as exc:
        raise LoomBakeError(
            f"{atlas_dir} is not an atlas (no readable manifest.json: {exc})") from exc
    except ValueError as exc:
        raise LoomBakeError(f"{path} is not valid JSON: {exc}") from exc


# --------------------------------------------------------------------------------- processes


class AsyncProcess:
    """A subprocess whose stdout lines and stderr are collected by reader threads."""

    def __init__(self, argv: list[str]):
        self.argv = argv
        self._lines: queue.Queue[str] = queue.Queue()
        self._stderr_chunks: list[str] = []
        self.proc: subprocess.Popen | None = None
        self._threads: list[threading.Thread] = []

    def start(self) -> None:
        try:
            self.proc = subprocess.Popen(
                self.argv,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
                bufsize=1,
            )
        except OSError as exc:
            raise LoomBakeError(f"cannot run {self.argv[0]}: {exc}") from exc
        out = threading.Thread(target=self._pump_lines, args=(self.proc.stdout,), daemon=True)
        err = threading.Thread(target=self._pump_stderr, args=(self.proc.stderr,), daemon=True)
        self._threads = [out, err]
        for t in self._threads:
            t.start()

    def _pump_lines(self, stream) -> None:
        for line in stream:
            self._lines.put(line)
        stream.close()

    def _pump_stderr(self, stream) -> None:
        for chunk in stream:
            self._stderr_chunks.append(chunk)
        stream.close()

    def lines(self) -> list[str]:
        """stdout lines received since the last call (never blocks)."""
        got = []
        while True:
            try:
                got.append(self._lines.get_nowait())
            except queue.Empty:
                return got

    def returncode(self) -> int | None:
        """None while running; once it has exited, waits for the readers so that every line
        is in the queue before the caller sees the exit code."""
        if self.proc is None:
            return None
        rc = self.proc.poll()
        if rc is not None:
            for t in self._threads:
                t.join(timeout=5)
        return rc

    @property
    def stderr(self) -> str:
        return "".join(self._stderr_chunks)

    def kill(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                pass


@dataclass
class BakeRequest:
    spec: str  # preset name or spec file path
    quality: str = "preview"
    loom_bake: str | None = None  # None: find_loom_bake()
    cache_dir: str | None = None  # None: default_cache_dir()
    force: bool = False
    # OpenColorIO config for the spec's colours (Blender's, staged by colour_config.staged());
    # None: loom-bake's built-in sRGB -> linear Rec.709, which equals Blender's default.
    ocio_config: str | None = None
    # Optional check of a finished atlas: returns None if this add-on can use it, else why not.
    # loom-bake reuses an atlas of the same spec even if an older loom-bake wrote it in another
    # layout; an incompatible atlas is therefore re-baked once with --force.
    validate: object = None


@dataclass
class BakeStatus:
    state: str = "idle"  # idle | checking | baking | done | failed | cancelled
    stage: str = ""
    fraction: float = 0.0
    message: str = ""
    atlas_dir: str = ""
    reused: bool = False
    seconds: float = 0.0
    log: list[str] = field(default_factory=list)
    peak: float = 0.0  # the furthest the bake got (overall never goes back)

    @property
    def finished(self) -> bool:
        return self.state in ("done", "failed", "cancelled")

    @property
    def overall(self) -> float:
        """A monotone 0..1 progress for a progress bar: check is instant, the bake's stages are
        weighted evenly in the order loom-bake runs them (the ray-wave tier's stages between
        write and average hold the bar where write left it)."""
        if self.state == "done":
            return 1.0
        if self.state != "baking":
            return 0.0
        order = ("ply maps", "horizon", "closure lut", "write", "fitted closures", "swatch",
                 "average")
        if self.stage in order:
            at = (order.index(self.stage) + max(0.0, min(1.0, self.fraction))) / len(order)
            self.peak = max(self.peak, at)
        return self.peak


class BakeJob:
    """check -> bake, driven by ``poll()``; see the module docstring."""

    def __init__(self, request: BakeRequest):
        self.request = request
        self.status = BakeStatus()
        self._proc: AsyncProcess | None = None
        self._exe = ""
        self._spec = ""
        self._out_dir = ""
        self._check_output = ""
        self._forced = request.force
        self._error = ""  # the failure loom-bake reported on stdout (--progress=json)
        self._t0 = 0.0

    # -- public
    def start(self) -> BakeStatus:
        r = self.request
        if r.quality not in QUALITIES:
            return self._fail(f"unknown quality {r.quality!r} (one of {', '.join(QUALITIES)})")
        try:
            self._exe = require_loom_bake(r.loom_bake)
            self._spec = _spec_arg(r.spec)
        except LoomBakeError as exc:
            return self._fail(str(exc))
        self._t0 = time.monotonic()
        self.status.state = "checking"
        self.status.message = f"checking {r.spec}"
        return self._launch([self._exe, "check", self._spec, "--quality", r.quality])

    def poll(self) -> BakeStatus:
        if self.status.finished or self._proc is None:
            return self.status
        lines = self._proc.lines()
        if self.status.state == "checking":
            self._check_output += "".join(lines)
        else:
            for ln in lines:
                self._bake_line(ln)
        rc = self._proc.returncode()
        if rc is None:
            return self.status
        # The process has exited and its readers are joined: drain what is left.
        rest = self._proc.lines()
        if self.status.state == "checking":
            self._check_output += "".join(rest)
        else:
            for ln in rest:
                self._bake_line(ln)
        if rc != 0:
            what = "check" if self.status.state == "checking" else "bake"
            detail = (self._error or _condense_stderr(self._proc.stderr)
                      or f"exit code {rc}")
            return self._fail(f"loom-bake {what} failed ({rc}): {detail}")
        if self.status.state == "checking":
            return self._start_bake()
        if not self.status.atlas_dir:
            return self._fail("loom-bake bake finished without reporting an atlas")
        problem = self.request.validate(self.status.atlas_dir) if self.request.validate else None
        if problem:
            if self._forced:
                return self._fail(f"loom-bake wrote an atlas this add-on cannot use: {problem}")
            self.status.log.append(f"re-baking with --force: {problem}")
            self._forced = True
            return self._start_bake()
        self.status.state = "done"
        self.status.seconds = time.monotonic() - self._t0
        verb = "reused" if self.status.reused else "baked"
        self.status.message = f"{verb} {self.status.atlas_dir}"
        return self.status

    def cancel(self) -> BakeStatus:
        if self._proc is not None:
            self._proc.kill()
        if not self.status.finished:
            self.status.state = "cancelled"
            self.status.message = "bake cancelled"
        return self.status

    def wait(self, timeout: float | None = None, interval: float = 0.05) -> BakeStatus:
        """Block until finished (the blocking API); cancels on timeout."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while not self.poll().finished:
            if deadline is not None and time.monotonic() > deadline:
                self.cancel()
                self.status.message = f"bake timed out after {timeout:.0f} s"
                break
            time.sleep(interval)
        return self.status

    # -- internals
    def _fail(self, message: str) -> BakeStatus:
        self.status.state = "failed"
        self.status.message = message
        return self.status

    def _launch(self, argv: list[str]) -> BakeStatus:
        self.status.log.append(" ".join(argv))
        self._proc = AsyncProcess(argv)
        try:
            self._proc.start()
        except LoomBakeError as exc:
            return self._fail(str(exc))
        return self.status

    def _start_bake(self) -> BakeStatus:
        r = self.request
        canonical = self._check_output
        dirname, _key = cache_entry(canonical, r.quality)
        cache = os.path.abspath(os.path.expanduser(r.cache_dir or default_cache_dir()))
        try:
            os.makedirs(cache, exist_ok=True)
        except OSError as exc:
            return self._fail(f"cannot create the atlas cache {cache}: {exc}")
        self._out_dir = os.path.join(cache, dirname)
        self.status.state = "baking"
        self.status.message = f"baking {r.spec} ({r.quality})"
        argv = [self._exe, "bake", self._spec, "-o", self._out_dir, "--quality", r.quality,
                "--progress=json"]
        if self._forced:
            argv.append("--force")
        if r.ocio_config:
            argv += ["--ocio-config", r.ocio_config]
        return self._launch(argv)

    def _bake_line(self, line: str) -> None:
        line = line.strip()
        if not line:
            return
        try:
            msg = json.loads(line)
        except ValueError:
            self.status.log.append(line)
            return
        if not isinstance(msg, dict):
            return
        if "stage" in msg:
            self.status.stage = str(msg["stage"])
            self.status.fraction = float(msg.get("fraction", 0.0))
            self.status.message = f"{self.status.stage} {100 * self.status.fraction:.0f}%"
        if "error" in msg:  # loom-bake's own account of its failure (--progress=json)
            self._error = "; ".join(str(e) for e in msg.get("errors") or [msg["error"]])
        if "atlas" in msg:
            self.status.atlas_dir = os.path.abspath(str(msg["atlas"]))
            self.status.reused = bool(msg.get("reused", False))


def bake_blocking(request: BakeRequest, timeout: float | None = None) -> BakeStatus:
    job = BakeJob(request)
    job.start()
    return job.wait(timeout=timeout)
