"""A recording rendered into a PNG without a window (``rerun --headless`` on Vulkan, or
``xvfb-run``), and the rows of a recording's entities (for checks and tests)."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

from rig.output_files import atomic_output
from processing.live_view.stream import LiveViewError, viewer_executable


def screenshot_command(rrd: Path, png: Path, size: str = "1600x900") -> tuple[list, dict]:
    """The command rendering ``rrd`` into ``png`` without a display, and its environment:
    ``rerun --headless`` on Vulkan (Mesa's software rasteriser works), else ``xvfb-run``.
    Raises LiveViewError when neither is available."""
    exe = viewer_executable()
    if exe is None:
        raise LiveViewError("no rerun viewer executable (pip install rerun-sdk)")
    env = dict(os.environ, WGPU_BACKEND="vulkan", RUST_LOG="error")
    # a port of its own on this machine: on rerun's default port, every SDK streaming to a
    # viewer there (another run's --connect) would draw into the screenshot
    cmd = [exe, str(rrd), "--screenshot-to", str(png), "--window-size", size, "--bind",
           "127.0.0.1", "--port", str(_free_port())]
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        return cmd, env
    if not _has_vulkan():
        raise LiveViewError("no Vulkan driver to render with (Debian: apt-get install xvfb "
                            "xauth mesa-vulkan-drivers libvulkan1)")
    xvfb = shutil.which("xvfb-run")
    if xvfb is not None:
        return [xvfb, "-a", "-s", f"-screen 0 {size}x24", *cmd], env
    return [exe, "--headless", *cmd[1:]], env


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _has_vulkan() -> bool:
    for d in ("/usr/share/vulkan/icd.d", "/etc/vulkan/icd.d"):
        if Path(d).is_dir() and any(Path(d).glob("*.json")):
            return True
    return False


def screenshot(rrd, png, *, size: str = "1600x900", force: bool = False,
               timeout_s: float = 300.0) -> Path:
    """Render the layout of ``rrd`` (at its end) into the image ``png`` without a window (see
    :func:`screenshot_command`); its format follows its extension (PNG, or JPEG converted from
    the viewer's PNG with Pillow: :func:`processing.figure_files.image_format`)."""
    from processing.figure_files import image_format

    png = Path(png)
    fmt = image_format(png)
    with atomic_output(png, force=force, suffix=".part.png") as tmp:
        # absolute: the viewer does not write a relative path where this process would
        tmp = Path(os.path.abspath(tmp))
        cmd, env = screenshot_command(Path(rrd), tmp, size)
        try:
            p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout_s)
        except subprocess.TimeoutExpired:
            raise LiveViewError(f"the viewer did not render within {timeout_s:g} s") from None
        if p.returncode != 0 or tmp.stat().st_size == 0:
            tail = (p.stderr or p.stdout).strip().splitlines()[-3:]
            raise LiveViewError(f"the viewer could not render a screenshot (exit "
                                f"{p.returncode}): " + " | ".join(tail))
        _to_size(tmp, size)
        if fmt == "jpeg":
            _to_jpeg(tmp)
    return png


def _to_jpeg(path: Path) -> None:
    """Rewrite the PNG ``path`` as a JPEG in place (quality 92; Pillow, matplotlib's
    dependency)."""
    from PIL import Image

    with Image.open(path) as im:
        rgb = im.convert("RGB")
    rgb.save(path, format="JPEG", quality=92)


def _to_size(png: Path, size: str) -> None:
    """Scale the rendered PNG to exactly ``size`` (W x H pixels): the viewer renders its
    logical points at two pixels each (a HiDPI screenshot), which is resampled (Lanczos)."""
    from PIL import Image  # matplotlib's dependency

    w, h = (int(v) for v in size.lower().split("x"))
    with Image.open(png) as im:
        if im.size == (w, h):
            return
        out = im.convert("RGB").resize((w, h), Image.Resampling.LANCZOS)
    out.save(png, format="PNG")


def recording_summary(rrd) -> dict:
    """Entities of an ``.rrd`` file and their rows (for checks and tests)."""
    from rerun.chunk import RrdReader

    rows: dict = {}
    for ch in RrdReader(str(rrd)).stream().to_chunks():
        rows[str(ch.entity_path)] = rows.get(str(ch.entity_path), 0) + ch.num_rows
    return rows
