"""The compiled cycle: the signal path of `service.pipeline.Compensator` compiled by numba.

Why numba: the effects' laws are plain Python numeric functions in their own files
(`stiffness.effects.terms`), and numba compiles exactly those functions into the cycle, so an effect
stays one file and the Python path (the reference) and the compiled one run the same equation. It comes
from the package index as a wheel (no compiler on the machine), and caches what it compiles on disk.

Nothing here is imported until a service compiles its cycle (`Compensator.compile`): a tool, the I/O
process or a Python-path test never loads numba.

* `chain`: frames, adjoints, Jacobian, static torque, damped pseudo-inverse, Newton refinement;
* `signal`: spike rejection, low-pass, limiter;
* `template` and `build`: the per-model part (the laws the model's terms use), generated and cached;
* `predictor`: a `FastPredictor`'s arrays and calls.
"""

from __future__ import annotations

import atexit
import gc

from .build import NotCompilable
from .predictor import CompiledPredictor

# numba leaves some hundred thousand objects behind; the interpreter's last collection at exit would walk
# them all (half a second per process, and `make test` starts the service well over a hundred times)
atexit.register(gc.freeze)

__all__ = ["CompiledPredictor", "NotCompilable"]
