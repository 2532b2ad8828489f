"""rig: the emulated bench -- a pendulum chain on a shaken stage, its source and sensors,
simulated in blocks. Imports nothing from ``daq`` or ``processing``.

The public names below are imported on first use (PEP 562), so ``import rig`` costs no more
than the package directory::

    import rig

    scene = rig.load_scene("ishizaki2009", ["acquisition.records=4"])
    resp = rig.expected_response(scene, freqs_hz)        # exact H_t, Theta_2, channels ...
    run = rig.simulate_pendulum(scene.chain, 10.0, theta0=[0.01, 0.0])  # the chain alone
    rig.SOLVERS                                          # every integrator, by name
"""

from __future__ import annotations

from rig.lazy_exports import lazy_exports

#: public name -> (module, attribute)
_EXPORTS = {
    "Scene": ("rig.scene", "Scene"),
    "load_scene": ("rig.scene", "load_scene"),
    "preset_names": ("rig.scene", "preset_names"),
    "scene_from_settings": ("rig.scene", "scene_from_settings"),
    "Chain": ("rig.chain", "Chain"),
    "ModelInfo": ("rig.model_info", "ModelInfo"),
    "simulate_pendulum": ("rig.simulate", "simulate"),
    "SOLVERS": ("rig.solvers", "SOLVERS"),
    "solver_named": ("rig.solvers", "solver_named"),
    "integrate": ("rig.solvers", "integrate"),
    "Source": ("rig.devices", "Source"),
    "Stage": ("rig.devices", "Stage"),
    "Accelerometer": ("rig.devices", "Accelerometer"),
    "OpticalLever": ("rig.devices", "OpticalLever"),
    "LinearSystem": ("rig.linear", "LinearSystem"),
    "FrequencyResponse": ("rig.linear", "FrequencyResponse"),
    "BenchSimulation": ("rig.bench", "BenchSimulation"),
    "build_model": ("rig.bench", "build_model"),
    "expected_response": ("rig.bench", "expected_response"),
    "AnalogBlock": ("rig.blocks", "AnalogBlock"),
    "Calibration": ("rig.blocks", "Calibration"),
    "RigError": ("rig.errors", "RigError"),
    "ConfigError": ("rig.errors", "ConfigError"),
    "DivergenceError": ("rig.errors", "DivergenceError"),
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports('rig', _EXPORTS, globals())
