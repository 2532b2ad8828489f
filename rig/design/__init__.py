"""The designer's tool: from targets to a double physical pendulum (Ishizaki et al. 2009).

Pure physics, no I/O: :func:`parse_targets` (a targets file's text) -> :func:`design` (the paper's
relations solved exactly where they determine the design, the rest optimised on the exact linear
model) -> :class:`Design`, written as a scene by :func:`design_scene_toml`, described by
:func:`design_dict` and :func:`design_markdown`. :mod:`rig.design.tradeoffs` sweeps the
trade-offs, :mod:`rig.design.tolerance` runs the Monte Carlo over manufacturing tolerances, both on
the batched exact model :class:`Pendulums`.
"""

from __future__ import annotations

from rig.design.model import Pendulums
from rig.design.report import design_dict, design_markdown, design_scene_toml, paper_comparison
from rig.design.solve import Design, PerformanceCheck, TargetCheck, design
from rig.design.targets import (
    SuppressionTarget, Targets, TranslationTarget, VariableTarget, parse_targets,
    targets_from_data)

__all__ = ["Pendulums", "Design", "PerformanceCheck", "TargetCheck", "design", "design_dict",
           "design_markdown", "design_scene_toml", "paper_comparison", "parse_targets",
           "targets_from_data", "Targets", "VariableTarget", "SuppressionTarget",
           "TranslationTarget"]
