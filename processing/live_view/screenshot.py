"""A recording rendered into a PNG without a window (``rerun --headless`` on Vulkan, or
``xvfb-run``), and the rows of a recording's entities (for checks and tests)."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

from rig._io import check_writable
from processing.live_view.stream import LiveViewError, viewer_executable


def screenshot_command(rrd: Path, png: Path, size: str = "1600x900") -> tuple[list, dict]:
    """The command rendering ``rrd`` into ``png`` without a display, and its environment:
    ``rerun --headless`` on Vulkan (Mesa's software rasteriser works), else ``xvfb-run``.
    Raises LiveViewError when neither is available."""
    exe = viewer_executable()
    if exe is None:
        raise LiveViewError("no rerun viewer executable (pip install rerun-sdk)")
    env = dict(os.environ, WGPU_BACKEND="vulkan", RUST_LOG="error")
    cmd = [exe, str(rrd), "--screenshot-to", str(png), "--window-size", size]
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        return cmd, env
    if not _has_vulkan():
        raise LiveViewError("no Vulkan driver to render with (Debian: apt-get install xvfb "
                            "xauth mesa-vulkan-drivers libvulkan1)")
    xvfb = shutil.which("xvfb-run")
    if xvfb is not None:
        return [xvfb, "-a", "-s", f"-screen 0 {size}x24", *cmd], env
    return [exe, "--headless", *cmd[1:]], env


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
    check_writable(png, force=force)
    # absolute: the viewer does not write a relative path where this process would
    tmp = Path(os.path.abspath(png.with_name(png.name + ".part.png")))
    cmd, env = screenshot_command(Path(rrd), tmp, size)
    try:
        p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        raise LiveViewError(f"the viewer did not render within {timeout_s:g} s") from None
    if p.returncode != 0 or not tmp.exists():
        tail = (p.stderr or p.stdout).strip().splitlines()[-3:]
        tmp.unlink(missing_ok=True)
        raise LiveViewError(f"the viewer could not render a screenshot (exit {p.returncode}): "
                            + " | ".join(tail))
    if fmt == "jpeg":
        from PIL import Image

        jpg = png.with_name(png.name + ".part.jpg")
        try:
            with Image.open(tmp) as im:
                im.convert("RGB").save(jpg, format="JPEG", quality=92)
            os.replace(jpg, png)
        finally:
            tmp.unlink(missing_ok=True)
            jpg.unlink(missing_ok=True)
        return png
    os.replace(tmp, png)
    return png


def recording_summary(rrd) -> dict:
    """Entities of an ``.rrd`` file and their rows (for checks and tests)."""
    from rerun.chunk import RrdReader

    rows: dict = {}
    for ch in RrdReader(str(rrd)).stream().to_chunks():
        rows[str(ch.entity_path)] = rows.get(str(ch.entity_path), 0) + ch.num_rows
    return rows
