"""Universal File Format (UFF) data set 58, "function at nodal DOF": the format, written with pyuff.

The bench's channels as UFF nodes and directions (:data:`CHANNEL_DOFS`), one data set
(:func:`uff58`) and the file writer (:func:`write_uff`), shared by the run's time records
(:mod:`daq.uff`) and the analyzer's frequency responses (:mod:`processing.uff`):

* node 1 is the stage (the accelerometer), node 2 the mirror; the global frame has x along the
  stage's travel (SPEC section 5's +x), z up and y = z x x (right-handed);
* channel ``a`` (stage acceleration) is node 1, +X translation, acceleration [m/s^2];
* channel ``x`` (mirror translation *relative to the stage*, SPEC section 5) is node 2,
  +X translation, displacement [m];
* channel ``y`` (mirror rotation theta: positive moves the body's lower part toward +x, i.e. a
  rotation about -y) is node 2, -Y rotation, (angular) displacement [rad].

UFF's unit exponents count length and force only; the unit labels carry the full SI unit. ASCII
UFF 58 keeps 12 significant digits of each value and 6 of the abscissa's start and increment
(pyuff's ``%20.11e`` and ``%13.5e`` fields).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rig.output_files import atomic_output, check_writable
from rig.errors import ConfigError, import_extra

#: UFF 58 function types used here (record 6, field 1).
TIME_RESPONSE, FRF, COHERENCE = 1, 4, 6
#: UFF specific data types (records 8-11, field 1).
UNKNOWN, DISPLACEMENT, ACCELERATION, TIME, FREQUENCY = 0, 8, 12, 17, 18


@dataclass(frozen=True)
class Dof:
    """A channel's place in UFF terms: entity name (<= 10 characters), node, direction code
    (1 = +X translation, -5 = -Y rotation, ...), specific data type, length-unit exponent, unit
    label and axis label (<= 20 characters)."""

    entity: str
    node: int
    direction: int
    data_type: int
    length_exp: int
    unit: str
    label: str = "NONE"


#: The bench's channels as UFF degrees of freedom (see the module docstring).
CHANNEL_DOFS = {
    "a": Dof("stage", 1, 1, ACCELERATION, 1, "m/s^2", "stage acceleration"),
    "x": Dof("mirror", 2, 1, DISPLACEMENT, 1, "m", "mirror translation"),
    "y": Dof("mirror", 2, -5, DISPLACEMENT, 0, "rad", "mirror rotation"),
}


def _id(text: str) -> str:
    """An ID line: at most 80 characters, ASCII."""
    return text.encode("ascii", "replace").decode()[:80]


def uff58(*, func_type: int, response: Dof, reference: Dof | None, x: np.ndarray,
          data: np.ndarray, abscissa: str, ids: tuple[str, ...], load_case: int = 0,
          ordinate_type: int | None = None, ordinate_unit: str | None = None,
          ordinate_label: str | None = None, even: bool = True) -> dict:
    """One UFF 58 data set (a pyuff dict) on the evenly spaced abscissa ``x`` ("time" [s] or
    "frequency" [Hz]; ``even=False``: any increasing abscissa, written as (x, value) pairs, e.g.
    a stepped sine's points); ``data`` real or complex. A ratio's ordinate is the response's quantity
    over the reference's; ``ordinate_type``/``ordinate_unit`` replace the response's (e.g. for a
    coherence, unit "1")."""
    pyuff = import_extra("pyuff", "uff", "writing UFF files")

    x = np.asarray(x, dtype=float)
    if x.size < 2:
        raise ConfigError(f"a UFF 58 set needs at least 2 abscissa values, got {x.size}")
    ref = reference or Dof("NONE", 0, 0, UNKNOWN, 0, "NONE")
    ids = tuple(_id(t) for t in ids) + ("NONE",) * (5 - len(ids))
    d = pyuff.prepare_58(
        binary=0, id1=ids[0], id2=ids[1], id3=ids[2], id4=ids[3], id5=ids[4],
        func_type=func_type, ver_num=0, load_case_id=int(load_case),
        rsp_ent_name=response.entity, rsp_node=response.node, rsp_dir=response.direction,
        ref_ent_name=ref.entity, ref_node=ref.node, ref_dir=ref.direction,
        abscissa_spacing=1 if even else 0, abscissa_spec_data_type=TIME if abscissa == "time" else FREQUENCY,
        abscissa_axis_units_lab="s" if abscissa == "time" else "Hz",
        ordinate_spec_data_type=response.data_type if ordinate_type is None else ordinate_type,
        ordinate_len_unit_exp=response.length_exp if ordinate_type is None else 0,
        ordinate_axis_units_lab=response.unit if ordinate_unit is None else ordinate_unit,
        orddenom_spec_data_type=ref.data_type if ordinate_type is None else UNKNOWN,
        orddenom_len_unit_exp=ref.length_exp if ordinate_type is None else 0,
        orddenom_axis_units_lab=ref.unit if ordinate_type is None and reference else "NONE",
        data=np.asarray(data), x=x)
    d["abscissa_axis_lab"] = abscissa
    d["ordinate_axis_lab"] = (ordinate_label or response.label)[:20]
    d["orddenom_axis_lab"] = ref.label[:20] if ordinate_type is None else "NONE"
    return d


def write_uff(datasets: list[dict], path: str | Path, *, force: bool = False) -> Path:
    """Write UFF data sets to a new file ``path`` (``.uff`` or ``.unv``), complete or not at
    all, never over an existing file without ``force``."""
    pyuff = import_extra("pyuff", "uff", "writing UFF files")

    path = Path(path)
    if path.suffix.lower() not in (".uff", ".unv"):
        raise ConfigError(f"output {str(path)!r} is invalid: expected a .uff or .unv file")
    check_writable(path, force=force)
    with atomic_output(path, force=force) as tmp:
        try:
            pyuff.UFF(str(tmp)).write_sets(datasets, mode="overwrite")
        except Exception as exc:  # pyuff turns any error, Ctrl-C included, into an Exception
            cause = exc.__context__
            if isinstance(cause, KeyboardInterrupt):
                raise cause from None
            raise
    return path
