"""Figure files whose format follows their extension.

:func:`figure_format` reads a figure path's extension (``.png``, ``.pdf``, ``.svg``: the formats
matplotlib writes without extra libraries) and refuses any other, or none, with a sentence naming
the valid ones -- before anything is computed. :func:`save_figure` writes a matplotlib Figure in
that format, whole or not at all (:func:`rig.output_files.atomic_output`). :func:`image_format` does the
same for raster images (``.png``, ``.jpg``/``.jpeg``: the live view's screenshots).
"""

from __future__ import annotations

from pathlib import Path

from processing.errors import SettingsError
from rig.output_files import atomic_output

__all__ = ["FIGURE_FORMATS", "IMAGE_FORMATS", "figure_format", "image_format", "save_figure"]

#: extension -> matplotlib ``savefig`` format of the figures (Bode diagrams, views)
FIGURE_FORMATS = {".png": "png", ".pdf": "pdf", ".svg": "svg"}
#: extension -> format of raster images (screenshots)
IMAGE_FORMATS = {".png": "png", ".jpg": "jpeg", ".jpeg": "jpeg"}


def _format(path, formats: dict, what: str) -> str:
    suffix = Path(path).suffix.lower()
    if suffix in formats:
        return formats[suffix]
    valid = ", ".join(formats)
    said = f"has the extension {suffix!r}" if suffix else "has no extension"
    raise SettingsError(f"{what} {str(path)!r} {said}: its format follows the extension, one "
                        f"of {valid}")


def figure_format(path) -> str:
    """The matplotlib format of the figure file ``path`` ("png", "pdf" or "svg"), from its
    extension (case-insensitive); a SettingsError naming the valid extensions otherwise."""
    return _format(path, FIGURE_FORMATS, "figure file")


def image_format(path) -> str:
    """The raster format of the image file ``path`` ("png" or "jpeg"), from its extension; a
    SettingsError naming the valid extensions otherwise."""
    return _format(path, IMAGE_FORMATS, "image file")


def save_figure(fig, path, *, force: bool = False, dpi: int = 120) -> Path:
    """Write ``fig`` to ``path`` in the format of its extension (:func:`figure_format`), under a
    temporary name renamed when complete; never over an existing file without ``force``."""
    import matplotlib

    fmt = figure_format(path)
    with atomic_output(path, force=force) as tmp, \
            matplotlib.rc_context({"svg.fonttype": "none"}):  # SVG text stays text
        fig.savefig(tmp, dpi=dpi, format=fmt)
    return Path(path)
