#!/usr/bin/env python3
"""Open a Rerun recording in the real Rerun viewer, headless, and screenshot it.

The viewer is the native one shipped in the ``rerun-sdk`` wheel, started with ``--headless``: no
window and no X server, it paints offscreen through wgpu. On a machine without a GPU that needs a
software Vulkan driver, Debian's ``mesa-vulkan-drivers`` (lavapipe, which pulls in ``libvulkan1``).
The viewer is driven over its gRPC control API (``rerun.experimental.ViewerClient``): open the
file, wait until it has loaded, move the time cursor to the end of ``sim_time``, wait until three
consecutive frames are identical, then take the screenshot and collect what went wrong: the
reports of every view (what failed to visualize), the viewer's own ERROR and unexpected WARN log
entries, and any error, panic or failure printed on its stderr.

Needs: pip's rerun-sdk (the viewer binary, and Pillow and numpy), and Debian's
mesa-vulkan-drivers. No X server, no browser.

Regenerate the README's screenshot from a sample run::

    .venv/bin/python scripts/screenshot.py                     # -> docs/screenshot.png
    .venv/bin/python scripts/screenshot.py run.rrd -o out.png  # any recording
    .venv/bin/python scripts/screenshot.py --docs              # every screenshot in docs/

The viewer process is bounded in time (a watchdog kills its process group) and always killed.
"""

from __future__ import annotations

import argparse
import ctypes
import glob
import io
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
DEFAULT_SCENE = REPO / "samples" / "spinning_bodies.toml"
DEFAULT_OUT = REPO / "docs" / "screenshot.png"
#: logical points; the headless viewer renders at 1 pixel per point
DEFAULT_SIZE = (1600, 900)

#: where Debian's Vulkan ICD manifests live (lavapipe's is lvp_icd.x86_64.json)
_ICD_DIRS = ("/usr/share/vulkan/icd.d", "/etc/vulkan/icd.d", "/usr/local/share/vulkan/icd.d")

#: warnings that are expected on a GPU-less machine, in a container or on a bare X server; any
#: other WARN (e.g. "Component ... matched semantic type ... but none of the expected physical
#: arrow types", "Failed to load mesh") means the viewer could not show something it was given
BENIGN = (
    re.compile(r"Software rasterizer detected", re.I),
    re.compile(r"running the Rerun Viewer inside a Docker container", re.I),
    re.compile(r"Failed to parse locale", re.I),
    re.compile(r"XSETTINGS|XRandR reported", re.I),
)
#: what counts as a viewer error on stderr (ANSI colour codes are stripped first)
_BAD_LINE = re.compile(r"\bERROR\b|panic|\bfailed\b|\bfailure\b", re.I)
_ANSI = re.compile(r"\x1b\[[0-9;]*m")


class ViewerUnavailable(RuntimeError):
    """A system piece the headless viewer needs is missing (the message says which)."""


# ------------------------------------------------------------------------------------ discovery

def rerun_executable() -> str:
    """The native ``rerun`` binary inside the rerun-sdk wheel (not the Python shim that wraps it)."""
    try:
        import rerun_cli

        exe = Path(rerun_cli.__file__).resolve().parent / "rerun"
        if exe.is_file() and os.access(exe, os.X_OK):
            return str(exe)
    except ImportError:
        pass
    found = shutil.which("rerun")
    if found:
        return found
    raise ViewerUnavailable("the `rerun` executable (pip package rerun-sdk) is not installed")


def software_vulkan_missing() -> str | None:
    """Why the viewer cannot render here, or None if a Vulkan loader and a driver are present."""
    try:
        ctypes.CDLL("libvulkan.so.1")
    except OSError:
        return ("no Vulkan loader (libvulkan.so.1): install Debian's mesa-vulkan-drivers "
                "(software Vulkan, lavapipe; it pulls in libvulkan1)")
    icds = [p for d in _ICD_DIRS for p in glob.glob(os.path.join(d, "*.json"))]
    if os.environ.get("VK_ICD_FILENAMES") or os.environ.get("VK_DRIVER_FILES"):
        return None
    if not icds:
        return ("no Vulkan driver (no ICD manifest in /usr/share/vulkan/icd.d): install Debian's "
                "mesa-vulkan-drivers (software Vulkan, lavapipe)")
    return None


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# ---------------------------------------------------------------------------------- the viewer

@dataclass
class Capture:
    """What one headless viewing of a recording gave."""

    png: Path
    seconds: float                      # wall time from viewer start to saved screenshot
    views: list = field(default_factory=list)            # rerun.experimental.View
    view_pngs: dict = field(default_factory=dict)        # view_id -> PNG of that view alone
    state: object = None                                 # the final rerun.experimental.ViewerState
    blueprint: dict = field(default_factory=dict)        # the active blueprint, as the viewer reads it
    view_problems: list[str] = field(default_factory=list)   # "view 'x' error: ..." lines
    log_errors: list[str] = field(default_factory=list)      # ERROR entries of the viewer's log
    stderr_errors: list[str] = field(default_factory=list)   # bad lines on the viewer's stderr
    log: list[str] = field(default_factory=list)             # the viewer's whole log, as text
    stderr: str = ""

    @property
    def problems(self) -> list[str]:
        return self.view_problems + self.log_errors + self.stderr_errors


class HeadlessViewer:
    """A ``rerun --headless`` process on a free localhost port, killed on exit (or by a watchdog).

    Use as a context manager; ``client`` is a connected ``rerun.experimental.ViewerClient``.
    """

    def __init__(self, size=DEFAULT_SIZE, max_lifetime: float = 180.0, startup_timeout: float = 30.0):
        self.size = size
        self.max_lifetime = max_lifetime
        self.startup_timeout = startup_timeout
        self.proc: subprocess.Popen | None = None
        self.client = None
        self._tmp = None
        self._watchdog: threading.Timer | None = None
        self.stderr_path: Path | None = None

    # -- process
    def __enter__(self) -> "HeadlessViewer":
        missing = software_vulkan_missing()
        if missing:
            raise ViewerUnavailable(missing)
        exe = rerun_executable()
        self._tmp = tempfile.TemporaryDirectory(prefix="rblog-viewer-")
        tmp = Path(self._tmp.name)
        runtime = tmp / "xdg-runtime"
        runtime.mkdir(mode=0o700)
        env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
        env.update(
            RERUN_APP_ONLY="true",          # what rerun.spawn sets: no analytics prompt
            XDG_RUNTIME_DIR=str(runtime),   # else winit/wayland print "error: XDG_RUNTIME_DIR ..."
            HOME=env.get("HOME") or str(tmp),
            RUST_BACKTRACE="1",
        )
        self.port = _free_port()
        self.stderr_path = tmp / "viewer.stderr"
        cmd = [exe, "--headless", "--port", str(self.port), "--hide-welcome-screen",
               "--window-size", f"{self.size[0]}x{self.size[1]}", "--memory-limit", "2GB"]
        with open(self.stderr_path, "wb") as err:
            self.proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                         stderr=err, env=env, cwd=tmp, start_new_session=True)
        self._watchdog = threading.Timer(self.max_lifetime, self._kill)
        self._watchdog.daemon = True
        self._watchdog.start()
        try:
            self._connect()
        except BaseException:
            self.__exit__(None, None, None)
            raise
        return self

    def _connect(self):
        from rerun.experimental import ViewerClient

        url = f"rerun+http://127.0.0.1:{self.port}/proxy"
        deadline = time.monotonic() + self.startup_timeout
        last = None
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"the headless viewer exited at start (code {self.proc.returncode}):"
                                   f"\n{self.stderr_text()[-3000:]}")
            try:
                client = ViewerClient.connect(url)
                client.get_state()
                self.client = client
                return
            except Exception as e:  # not listening yet
                last = e
                time.sleep(0.1)
        raise TimeoutError(f"the headless viewer did not answer on {url} within "
                           f"{self.startup_timeout:.0f} s ({last}):\n{self.stderr_text()[-3000:]}")

    def _kill(self):
        p = self.proc
        if p is None or p.poll() is not None:
            return
        for sig, wait in ((signal.SIGTERM, 5.0), (signal.SIGKILL, 5.0)):
            try:
                os.killpg(p.pid, sig)
            except ProcessLookupError:
                return
            try:
                p.wait(wait)
                return
            except subprocess.TimeoutExpired:
                continue

    def __exit__(self, *exc):
        if self._watchdog is not None:
            self._watchdog.cancel()
        self.client = None
        self._kill()
        self._stderr_cache = self.stderr_text()
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None
        return False

    def stderr_text(self) -> str:
        if self.stderr_path is not None and self.stderr_path.exists():
            return _ANSI.sub("", self.stderr_path.read_text("utf-8", "replace"))
        return getattr(self, "_stderr_cache", "")

    # -- driving
    def load(self, rrd: Path, timeout: float = 60.0, timeline: str | None = "sim_time",
             overlays=(), at_ns: int | None = None):
        """Open ``rrd`` (then each of ``overlays``: recordings with the same recording id, e.g.
        `rblog check --rrd` findings, merge into it), wait until it has loaded, and park the time
        cursor at the end of ``timeline`` (or at ``at_ns`` on it, if given; if the recording has
        it), paused. Returns the recording's ViewerState."""
        c = self.client
        for extra in overlays:  # first, so that their blueprint is the one the viewer keeps
            c.open(str(Path(extra).resolve()))
        c.open(str(Path(rrd).resolve()))
        deadline = time.monotonic() + timeout
        while True:
            st = c.get_state()
            rec = next((r for r in st.recordings if r.store_id == st.active_recording), None)
            ready = (not st.loading and rec is not None and st.views
                     and rec.timelines and all(t.end is not None for t in rec.timelines))
            if ready:
                break
            if not st.loading and any(e.level == "ERROR" for e in c.get_logs()):
                return st  # e.g. "Data source failed": nothing more will arrive; capture reports it
            if time.monotonic() > deadline:
                raise TimeoutError(f"the viewer had not loaded {rrd} after {timeout:.0f} s: "
                                   f"loading={st.loading}, views={len(st.views)}")
            time.sleep(0.1)
        if overlays:  # the overlays' data and blueprint arrive after the run's: let them land
            n_views = len(st.views)
            until = min(deadline, time.monotonic() + 10.0)
            while time.monotonic() < until:
                st = c.get_state()
                if st.loading or len(st.views) == n_views:
                    time.sleep(0.2)
                    continue
                break
            rec = next((r for r in st.recordings if r.store_id == st.active_recording), rec)
        names = {t.name: t for t in rec.timelines if t.end is not None}
        if timeline in names:
            t = names[timeline]
            import numpy as np

            end = t.end if at_ns is None else int(at_ns)
            if t.time_type == "duration":
                where = {"duration": np.timedelta64(end, "ns")}
            elif t.time_type == "timestamp":
                where = {"timestamp": np.datetime64(t.end, "ns")}
            else:
                where = {"sequence": t.end}
            c.set_time(timeline, play_state="paused", **where)
        else:
            c.set_time(play_state="paused")
        return st

    def settle(self, timeout: float = 30.0, interval: float = 0.4, stable: int = 3) -> bytes:
        """Screenshots until ``stable`` consecutive ones are pixel-identical (chunks fetched,
        notifications faded); returns the last PNG. Raises TimeoutError past ``timeout``."""
        import numpy as np
        from PIL import Image

        deadline = time.monotonic() + timeout
        prev, same = None, 0
        while True:
            png = self.client.take_screenshot()
            img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))
            same = same + 1 if prev is not None and np.array_equal(img, prev) else 0
            if same >= stable - 1:
                return png
            if time.monotonic() > deadline:
                raise TimeoutError(f"the viewer's frames were still changing after {timeout:.0f} s")
            prev = img
            time.sleep(interval)

    def problems(self):
        """(views, their reports, the viewer's ERROR and unexpected WARN log entries, its whole
        log) -- all but the views as text lines."""
        st = self.client.get_state()
        views = st.views
        view_problems = [f"view {v.name!r} ({v.view_class}) {r.severity}: {r.summary}"
                         + (f" -- {r.details}" if r.details else "")
                         for v in views for r in v.reports]
        log = [f"{e.level} {e.target}: {e.message}" for e in self.client.get_logs()]
        log_errors = [line for line in log if not _benign(line)
                      and (line.startswith(("ERROR", "WARN")) or _BAD_LINE.search(line))]
        return views, view_problems, log_errors, log


def _benign(line: str) -> bool:
    return any(p.search(line) for p in BENIGN)


def stderr_problems(text: str) -> list[str]:
    """Lines of the viewer's stderr that report an error, a panic or a failure."""
    return [line for line in text.splitlines() if _BAD_LINE.search(line) and not _benign(line)]


def capture(rrd: Path, png: Path, size=DEFAULT_SIZE, timeout: float = 120.0,
            timeline: str | None = "sim_time", per_view: bool = False, overlays=(),
            at_ns: int | None = None) -> Capture:
    """Open ``rrd`` (and ``overlays`` merged into it) in a headless viewer, save a settled
    screenshot to ``png``, and report. ``at_ns``: park the cursor there on ``timeline``.

    With ``per_view``, also save each view alone next to it (``STEM-view-N.png``)."""
    t0 = time.monotonic()
    png = Path(png)
    png.parent.mkdir(parents=True, exist_ok=True)
    viewer = HeadlessViewer(size=size, max_lifetime=timeout + 30.0)
    with viewer:
        viewer.load(rrd, timeout=timeout / 2, timeline=timeline, overlays=overlays, at_ns=at_ns)
        data = viewer.settle(timeout=timeout / 2)
        png.write_bytes(data)
        seconds = time.monotonic() - t0
        view_pngs = {}
        if per_view:
            for i, v in enumerate(viewer.client.get_state().views):
                path = png.with_name(f"{png.stem}-view-{i}.png")
                path.write_bytes(viewer.client.take_screenshot(v.view_id))
                view_pngs[v.view_id] = path
        state = viewer.client.get_state()
        blueprint = viewer.client.get_blueprint().blueprint
        views, view_problems, log_errors, log = viewer.problems()
    stderr = viewer.stderr_text()
    return Capture(png=png, seconds=seconds, views=views, view_pngs=view_pngs, state=state,
                   blueprint=blueprint,
                   view_problems=view_problems, log_errors=log_errors,
                   stderr_errors=stderr_problems(stderr), log=log, stderr=stderr)


def image_stats(png: Path, region=None) -> dict:
    """Non-triviality measures of a screenshot (optionally of a (x0, y0, x1, y1) region)."""
    import numpy as np
    from PIL import Image

    img = np.asarray(Image.open(png).convert("RGB")).astype(np.int32)
    if region is not None:
        x0, y0, x1, y1 = (int(v) for v in region)
        img = img[y0:y1, x0:x1]
    flat = img.reshape(-1, 3)
    colours, counts = np.unique(flat, axis=0, return_counts=True)
    background = colours[np.argmax(counts)]
    far = np.abs(flat - background).sum(axis=1) > 60
    saturated = (flat.max(axis=1) - flat.min(axis=1)) > 60   # not grey: a body, a plotted line
    return {"shape": img.shape, "std": float(img.std()), "colours": int(len(colours)),
            "background": tuple(int(v) for v in background),
            "non_background_fraction": float(far.mean()),
            "colourful_fraction": float(saturated.mean())}


def text_lines(png, region=None, min_gap: int = 3) -> list[tuple[int, int]]:
    """(top, bottom) pixel rows of each line of text in a screenshot of a table (optionally of
    a (x0, y0, x1, y1) region): runs of pixel rows that hold text-coloured pixels (light on the
    viewer's dark background), separated by at least ``min_gap`` empty rows. A table with a
    header and k rows gives k + 1 lines; a header alone gives 1."""
    import numpy as np
    from PIL import Image

    img = np.asarray(Image.open(png).convert("L")).astype(np.int32)
    if region is not None:
        x0, y0, x1, y1 = (int(v) for v in region)
        img = img[y0:y1, x0:x1]
    ink = (img > 120).sum(axis=1) >= 2
    lines, start, gap = [], None, 0
    for y, on in enumerate(ink):
        if on:
            if start is None:
                start = y
            gap, end = 0, y
        elif start is not None:
            gap += 1
            if gap >= min_gap:
                lines.append((start, end + 1))
                start = None
    if start is not None:
        lines.append((start, end + 1))
    return [(a, b) for a, b in lines if b - a >= 5]   # glyphs, not rules or specks


def view_properties(cap: Capture, view) -> dict:
    """The blueprint properties of ``view`` (archetype -> fields), as the viewer holds them."""
    pre = f"/view/{view.view_id}"
    out = {}
    for key, val in cap.blueprint.items():
        if key == pre:
            out.update(val)
        elif key.startswith(pre + "/"):
            out.update(val)
    return out


def colour_mask(png, rgb, tol: int = 40):
    """Boolean image: pixels within ``tol`` (per channel) of colour ``rgb``."""
    import numpy as np
    from PIL import Image

    img = np.asarray(Image.open(png).convert("RGB")).astype(np.int32)
    return np.all(np.abs(img - np.asarray(rgb)) <= tol, axis=-1)


# ------------------------------------------------------------------------------------ the CLI

def rblog_command() -> list[str]:
    exe = Path(sys.executable).with_name("rblog")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "rblog_cli.main"]


def record_sample(scene: Path, out: Path, *extra: str) -> None:
    """Run a sample scene with rblog's CLI into ``out`` (.rrd or .mcap; ``extra``: more options
    of `rblog run`, e.g. --duration 1)."""
    flag = "--mcap" if str(out).endswith(".mcap") else "--rrd"
    subprocess.run([*rblog_command(), "run", str(scene), flag, str(out), *extra], check=True,
                   cwd=REPO, timeout=900, stdout=subprocess.DEVNULL)


def check_to_rrd(log: Path, out: Path) -> tuple[list[str], str]:
    """`rblog check LOG --rrd OUT`, as a user types it: returns the command it prints to open the
    findings (split into words) and its whole output."""
    p = subprocess.run([*rblog_command(), "check", str(log), "--rrd", str(out)], cwd=REPO,
                       capture_output=True, text=True, timeout=900)
    text = p.stdout + p.stderr
    if p.returncode not in (0, 1):
        raise RuntimeError(f"rblog check exited {p.returncode}:\n{text}")
    m = re.search(r"open with: ((?:\S*/)?rerun [^)]*)\)", text)
    if not m:
        raise RuntimeError(f"rblog check printed no command to open the findings:\n{text}")
    return m.group(1).split(), text


#: the screenshots in docs/ (name -> scene, options of `rblog run`, log format checked)
DOC_SHOTS = {
    "viewer-tumbling_box.png": ("samples/tumbling_box.toml", (), ".mcap"),
    "viewer-pile.png": ("samples/pile.toml", ("--duration", "1.5"), ".rrd"),
    "findings-overlay.png": ("samples/tumbling_box.toml",
                             ("--integrator", "seed", "--orthonormalize", "none"), ".mcap"),
}


def small_png(png: Path) -> None:
    """Rewrite ``png`` with a 256-colour palette (a screenshot of the viewer is mostly flat
    colour: ~4x smaller, no visible loss)."""
    from PIL import Image

    img = Image.open(png).convert("RGB")
    img.quantize(256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).save(
        png, optimize=True)


def shoot_checked(scene: Path, run_args, kind: str, png: Path, tmp: Path, size=DEFAULT_SIZE,
                  timeout: float = 180.0, per_view: bool = False) -> Capture:
    """Run ``scene`` into a ``kind`` log, check it with `rblog check LOG --rrd`, open what that
    prints in the headless viewer and screenshot it."""
    log = tmp / (Path(scene).stem + kind)
    record_sample(Path(scene), log, *run_args)
    cmd, _ = check_to_rrd(log, tmp / (Path(scene).stem + "-checked.rrd"))
    files = [Path(w) for w in cmd[1:]]
    return capture(files[0], png, size=size, timeout=timeout, overlays=files[1:],
                   per_view=per_view)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rrd", nargs="?", type=Path,
                    help=f"recording to show (default: a fresh run of {DEFAULT_SCENE.relative_to(REPO)})")
    ap.add_argument("-o", "--out", type=Path, default=DEFAULT_OUT, help="PNG to write (%(default)s)")
    ap.add_argument("--scene", type=Path, default=DEFAULT_SCENE, help="scene to run when no RRD is given")
    ap.add_argument("--size", default=f"{DEFAULT_SIZE[0]}x{DEFAULT_SIZE[1]}", help="viewer size WxH")
    ap.add_argument("--timeout", type=float, default=120.0)
    ap.add_argument("--docs", action="store_true",
                    help="regenerate docs/'s viewer screenshots: " + ", ".join(DOC_SHOTS)
                    + " (each a run checked with `rblog check LOG --rrd`) and docs/screenshot.png")
    args = ap.parse_args(argv)
    size = tuple(int(v) for v in args.size.lower().split("x"))
    if args.docs:
        bad = 0
        with tempfile.TemporaryDirectory(prefix="rblog-shot-") as tmp:
            for name, (scene, run_args, kind) in DOC_SHOTS.items():
                out = REPO / "docs" / name
                sub = Path(tmp) / Path(name).stem
                sub.mkdir()
                cap = shoot_checked(REPO / scene, run_args, kind, out, sub, size=size,
                                    timeout=args.timeout)
                small_png(out)
                print(f"wrote {out} ({out.stat().st_size // 1024} KB) in {cap.seconds:.1f} s")
                for p in cap.problems:
                    print("PROBLEM:", p, file=sys.stderr)
                bad += bool(cap.problems)
            rrd = Path(tmp) / (DEFAULT_SCENE.stem + ".rrd")
            record_sample(DEFAULT_SCENE, rrd)
            cap = capture(rrd, DEFAULT_OUT, size=size, timeout=args.timeout)
            small_png(DEFAULT_OUT)
            print(f"wrote {DEFAULT_OUT} ({DEFAULT_OUT.stat().st_size // 1024} KB)")
            bad += bool(cap.problems)
        return 1 if bad else 0
    with tempfile.TemporaryDirectory(prefix="rblog-shot-") as tmp:
        rrd = args.rrd
        if rrd is None:
            rrd = Path(tmp) / (args.scene.stem + ".rrd")
            record_sample(args.scene, rrd)
        cap = capture(rrd, args.out, size=size, timeout=args.timeout)
    print(f"wrote {args.out} in {cap.seconds:.1f} s; views: "
          + ", ".join(f"{v.name} ({v.view_class})" for v in cap.views))
    for p in cap.problems:
        print("PROBLEM:", p, file=sys.stderr)
    return 1 if cap.problems else 0


if __name__ == "__main__":
    sys.exit(main())
