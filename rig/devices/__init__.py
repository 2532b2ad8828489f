"""The bench's devices, one module per physical thing (parameters, stepping, transfer function).

- :mod:`rig.devices.source`: the analyzer's source, a DAC held between samples (``[source]``);
- :mod:`rig.devices.stage`: amplifier, voice coil and X stage (``[stage]``);
- :mod:`rig.devices.accelerometer`: piezoelectric accelerometer + charge amplifier
  (``[accelerometer]``);
- :mod:`rig.devices.optical_lever`: laser, optical lever and PSD (``[psd]``).

Each device is a frozen dataclass whose fields are the keys of its scene section: name, unit,
default, valid range and doc are written once, in the field's metadata (:mod:`rig.params`), and
:mod:`rig.scene` generates its key tables from them.
"""

from rig.devices.accelerometer import Accelerometer
from rig.devices.optical_lever import OpticalLever
from rig.devices.source import Source
from rig.devices.stage import Stage

__all__ = ["Accelerometer", "OpticalLever", "Source", "Stage"]


from rig.lazy_exports import submodule_getattr  # noqa: E402

__getattr__ = submodule_getattr('rig.devices')  # a public submodule is an attribute on first use
