"""A resolved scene written back as a complete, editable TOML scene file.

:func:`scene_toml` gives every key of every section (the pendulum's of its kind), each value as the
scene resolved it, with the key's documentation as a comment; :func:`rig.scene.load_scene` of the
text gives the same scene (same settings, same chain). A key whose resolved value is "not set"
(e.g. ``pendulum.l_m`` of an Ishizaki design, meaning l = r1) is written commented out, since TOML
has no null.
"""

from __future__ import annotations

import tomli_w

from rig.scene import SECTIONS, Scene, section_keys


def toml_value(value) -> str:
    """One value as TOML text (numbers exactly as Python's repr, strings escaped)."""
    return tomli_w.dumps({"v": value})[len("v = "):].rstrip("\n")


def scene_toml(scene: Scene, *, header: str = "") -> str:
    """The complete TOML scene file of ``scene`` (see the module docstring).

    ``header`` is written first as comment lines (e.g. where the scene came from).
    """
    settings = scene.settings
    lines = [f"# {line}".rstrip() for line in header.splitlines()]
    for section in SECTIONS:
        keys = section_keys(section, scene.pendulum_kind)
        if lines:
            lines.append("")
        lines.append(f"[{section}]")
        values = settings[section]
        for key, spec in keys.items():
            value = values.get(key)
            doc = spec.doc + (f" (one of {', '.join(map(str, spec.choices))})"
                              if spec.choices and spec.doc.find("|") < 0 else "")
            if value is None:
                lines.append(f"# {key} =  # not set: {doc}")
            else:
                lines.append(f"{key} = {toml_value(value)}  # {doc}")
    return "\n".join(lines) + "\n"
