"""rtmpm: a real-time Material Point Method simulator (water, sand, snow, jelly).

Scenes are the TOML files of the command line (``docs/scene-format.md``), or the same
structure as a dict::

    import rtmpm
    scene = rtmpm.Scene.load("scenes/dam_break.toml")
    sim = rtmpm.Simulation(scene, backend="auto")   # CUDA when a GPU is usable, else the CPU
    print(sim.backend)                              # what was picked and why
    for frame in sim.frames(10):
        x = sim.particles.x                         # (n, 3) float32 NumPy array
        ke = 0.5 * (sim.particles.mass * (sim.particles.v ** 2).sum(1)).sum()

On the CUDA backend ``torch.from_dlpack(sim.particles.x_device)`` sees the simulation's GPU
memory without a copy. Full documentation: ``docs/python.md``.
"""

import os as _os

from . import _rtmpm
from ._rtmpm import (
    BackendError,
    BackendInfo,
    BatchSimulation,
    DeviceArray,
    FrameIterator,
    Particles,
    RtmpmError,
    Scene,
    SceneError,
    SimulationError,
    __version__,
    cuda_available,
    features,
    frame_formats,
    read_ply,
    validate,
    validation_cases,
)



class Simulation(_rtmpm.Simulation):
    __doc__ = _rtmpm.Simulation.__doc__
    __slots__ = ()

    def __new__(cls, scene, *args, batch=None, **kwargs):
        # A batch of worlds: `batch=N`, or a scene with [batch] (docs/batch.md).
        if isinstance(scene, dict):
            scene = Scene.from_dict(scene)
        elif isinstance(scene, (str, _os.PathLike)):
            scene = Scene.load(scene)
        if batch is not None or (isinstance(scene, Scene) and scene.batch is not None):
            return BatchSimulation(scene, *args, batch=batch, **kwargs)
        return super().__new__(cls, scene, *args, **kwargs)

    @staticmethod
    def resume(path, *args, **kwargs):
        sim = _rtmpm.Simulation.resume(path, *args, **kwargs)
        sim.__class__ = Simulation
        return sim

    resume.__doc__ = _rtmpm.Simulation.resume.__doc__


__all__ = [
    "BackendError",
    "BackendInfo",
    "BatchSimulation",
    "DeviceArray",
    "FrameIterator",
    "Particles",
    "RtmpmError",
    "Scene",
    "SceneError",
    "Simulation",
    "SimulationError",
    "__version__",
    "cuda_available",
    "features",
    "frame_formats",
    "read_ply",
    "validate",
    "validation_cases",
]
