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

from ._rtmpm import (
    BackendError,
    BackendInfo,
    DeviceArray,
    FrameIterator,
    Particles,
    RtmpmError,
    Scene,
    SceneError,
    Simulation,
    SimulationError,
    __version__,
    cuda_available,
    features,
    frame_formats,
    read_ply,
)

__all__ = [
    "BackendError",
    "BackendInfo",
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
]
