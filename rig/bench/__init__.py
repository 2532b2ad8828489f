"""The whole bench, run continuously: source -> amplifier/coil -> stage -> pendulum -> sensors.

The input is the source voltage, a DAC sample held for one sample interval ``h = 1 /
simulation_rate_hz`` (SPEC section 8): that held staircase is, by definition, the true DAC
output; the source's analog reconstruction filter smooths it (:mod:`rig.devices.source`) and the
stage acceleration ``x0''`` is whatever the continuous amplifier, coil and stage make of that.

Models (``acquisition.model``, ``acquisition.error_budget``)
------------------------------------------------------------
``linear``
    The coil, stage, linearised pendulum (with its reaction on the stage if ``stage.reaction``)
    and the accelerometer's high-pass form one linear system ``z' = A z + B V``, discretised
    exactly for the held input (``z_{k+1} = Phi z_k + Gamma V_k``) and stepped by a compiled
    loop: exact at the DAC instants up to round-off. The sensors read the states at the
    instants. Its error is the linearisation (a model error, predicted by
    :func:`predict_linearisation_error`).
``nonlinear``
    ``method="etdab"`` (default) or ``"lawson4"``: the whole bench, nonlinear pendulum and its
    reaction, as one system (:mod:`rig.solvers.coupled`): the linear bench propagated exactly,
    only the nonlinear remainder integrated, ``substeps`` steps per DAC interval.
    ``method="rk4" | "gauss4" | "dop853"`` (``stage.reaction = false`` only): the pendulum's
    equations through :func:`rig.solvers.integrate` on the exactly discretised stage's
    acceleration, linear between ``h / oversample`` sub-instants. The methods: docs/bench_model.md.
``auto`` (default)
    The cheapest model that meets ``acquisition.error_budget`` (:func:`select_model`).

Error estimates: :func:`model_info` (:mod:`rig.bench.estimates`). Measured accuracies, costs and
levels for the defaults: docs/bench_model.md; the sensors' levels: docs/devices.md.

Rooms
-----
``model``       :class:`BenchModel`, :func:`build_model`, :func:`linear_scene` (the exact step)
``run``         :class:`BenchState`, :func:`start`, :func:`advance` (one block), the stage kernel
``fused``       the bench fused with its sensors and anti-alias filter, at the output rate
``simulation``  :class:`BenchSimulation` (the stateful wrapper: blocks, calibrations, model info)
``response``    :func:`calibrations`, :func:`expected_response`, :class:`BenchResponse`,
                :func:`stationary_levels`, :func:`signal_to_noise`
``sampled``     :func:`sampled_response`: the same response in modal form, built once per analysis
``selection``   :func:`predict_linearisation_error`, :func:`select_model`
``estimates``   :func:`model_info` and the error estimates (Richardson)
"""

from rig.bench.selection import (FIRST_ORDER_LIMIT, PREDICTOR_BATCHES, PREDICTOR_ENTROPY,
                                 SPREAD_CALIBRATION, predict_linearisation_error, select_model)
from rig.bench.model import (COUPLED_METHODS, DEFAULT_METHOD, MODELS, NONLINEAR_METHODS,
                             PRESCRIBED_STAGE_METHODS, BenchModel, build_model, linear_scene)
from rig.bench.run import (STREAMS, BenchState, advance, stage_fine_kernel, start)
from rig.bench.response import (BenchResponse, calibrations, expected_response,
                                signal_to_noise, stationary_levels)
from rig.bench.sampled import SampledResponse, sampled_response
from rig.bench.estimates import linear_method, model_info, model_seed
from rig.bench.fused import fused_model_info
from rig.model_info import ModelInfo
from rig.bench.simulation import BenchSimulation

__all__ = ["BenchSimulation", "BenchModel", "BenchState", "BenchResponse", "build_model", "start",
           "advance", "calibrations", "expected_response", "stationary_levels", "signal_to_noise",
           "linear_scene", "sampled_response", "SampledResponse",
           "model_info", "ModelInfo", "linear_method", "fused_model_info", "select_model",
           "predict_linearisation_error", "MODELS", "NONLINEAR_METHODS", "STREAMS"]


from rig.lazy_exports import submodule_getattr  # noqa: E402

__getattr__ = submodule_getattr('rig.bench')  # a public submodule is an attribute on first use
