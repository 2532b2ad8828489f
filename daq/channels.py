"""Channels that describe themselves: what each measures, in which unit, calibration and ADC.

A channel turns a sensor's volts into codes; its :class:`rig.blocks.Calibration` turns volts back
into the physical quantity (SPEC section 5)::

    volts = code * lsb_v + offset_v,        quantity [unit] = volts / volts_per_unit

``volts_per_unit`` is signed: it carries the sensor's polarity/orientation, which processing must
undo. The calibration is the sensor's gain in its pass band; the exact frequency response of the
whole chain (sensor dynamics, anti-alias filter) is stored separately as the model response.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from daq.adc import ADC
from rig.blocks import Calibration
from rig.errors import ConfigError

#: Descriptions of the bench's channels (SPEC section 1); others fall back to their name.
LONG_NAMES = {
    "a": "stage acceleration (accelerometer on the X stage)",
    "x": "mirror translation (PSD horizontal, optical lever)",
    "y": "mirror rotation (PSD vertical, optical lever)",
}


@dataclass(frozen=True)
class Channel:
    """One acquired channel.

    Attributes
    ----------
    name : short key, e.g. "a"; data is keyed by it.
    long_name : what it is.
    quantity, unit : the physical quantity measured and its SI unit.
    volts_per_unit : signed calibration [V per unit].
    range_v, bits : the ADC (+-range_v [V], resolution).
    """

    name: str
    long_name: str
    quantity: str
    unit: str
    volts_per_unit: float
    range_v: float
    bits: int = 16

    def __post_init__(self):
        if not self.name or not self.name.isidentifier():
            raise ConfigError(f"channel name {self.name!r} is invalid: expected an identifier")
        v = self.volts_per_unit
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v != 0):
            raise ConfigError(f"channel {self.name}: volts_per_unit = {v!r} is invalid: expected a "
                              "finite non-zero number")
        ADC(self.range_v, self.bits)  # validates range and bits

    @property
    def adc(self) -> ADC:
        return ADC(self.range_v, self.bits)

    @property
    def calibration(self) -> Calibration:
        return Calibration(self.quantity, self.unit, self.volts_per_unit)

    @property
    def units_per_volt(self) -> float:
        """1 / volts_per_unit [unit per V]."""
        return 1.0 / self.volts_per_unit

    def describe(self) -> dict:
        """Everything about the channel as plain data (the HDF5 attributes of its dataset)."""
        adc = self.adc
        return {"name": self.name, "long_name": self.long_name, "quantity": self.quantity,
                "unit": self.unit, "volts_per_unit": float(self.volts_per_unit),
                "range_v": float(self.range_v), "bits": int(self.bits), "lsb_v": adc.lsb_v,
                "offset_v": adc.offset_v, "code_min": adc.code_min, "code_max": adc.code_max}

    @classmethod
    def from_description(cls, d: dict) -> "Channel":
        return cls(name=str(d["name"]), long_name=str(d["long_name"]), quantity=str(d["quantity"]),
                   unit=str(d["unit"]), volts_per_unit=float(d["volts_per_unit"]),
                   range_v=float(d["range_v"]), bits=int(d["bits"]))

    @classmethod
    def from_attrs(cls, name: str, attrs) -> "Channel":
        """The channel ``name`` of a run file from its dataset's attributes
        (:meth:`description` as HDF5 attributes, the unit as ``engineering_unit``)."""
        a = {k: (v.decode("utf-8", "replace") if isinstance(v, bytes) else v)
             for k, v in attrs.items()}
        return cls.from_description({**a, "name": name, "unit": a["engineering_unit"]})


def channels_for(acquisition: dict, calibrations: dict[str, Calibration]) -> tuple[Channel, ...]:
    """The channels of a run, in the order of ``calibrations``.

    Parameters
    ----------
    acquisition : ``Scene.settings["acquisition"]`` (``adc_bits``, ``range_<name>_v`` per channel).
    calibrations : the bench's calibration per channel name.
    """
    out = []
    for name, cal in calibrations.items():
        key = f"range_{name}_v"
        if key not in acquisition:
            ranged = ", ".join(_ranged(acquisition)) or "none"
            raise ConfigError(f"channel {name!r} has no ADC range: acquisition.{key} is missing "
                              f"(channels with a range: {ranged})")
        rng = acquisition[key]
        if not (isinstance(rng, (int, float)) and math.isfinite(rng) and rng > 0):
            raise ConfigError(f"acquisition.{key} = {rng!r} is invalid: expected a range > 0 V")
        out.append(Channel(name=name, long_name=LONG_NAMES.get(name, name),
                           quantity=cal.quantity, unit=cal.unit,
                           volts_per_unit=float(cal.volts_per_unit), range_v=float(rng),
                           bits=int(acquisition["adc_bits"])))
    if not out:
        raise ConfigError("the bench has no channels")
    return tuple(out)


def _ranged(acquisition: dict) -> list[str]:
    return [k[6:-2] for k in acquisition if k.startswith("range_") and k.endswith("_v")]
