//! Choosing and constructing a compute backend, shared by the command line (`rtmpm run`,
//! `validate`, `bench`) and the Python package (`rtmpm.Simulation`).
//!
//! [`create`] builds the backend a [`BackendKind`] asks for, in the scene's precision, and says
//! which one `auto` picked and why. The result is an [`AnyBackend`]: a concrete enum rather than a
//! `Box<dyn Backend>`, so that a caller can reach the backend's own methods (the CUDA backend's
//! device pointers, the CPU backend's state setters) and move it across threads (it is `Send`).

pub mod batch;

use rtmpm_cuda::CudaOptions;
use rtmpm_io::limits::human_bytes;
use rtmpm_physics::Particles;
use rtmpm_scene::sampling::SampledBody;
use rtmpm_scene::{Precision, Scene, sampling};
use rtmpm_sim::{Backend, BadParticle, SimError};

/// Which backend to run on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BackendKind {
    /// CUDA when a GPU is usable, else the CPU.
    #[default]
    Auto,
    /// The CPU reference backend.
    Cpu,
    /// The CUDA backend (fails with the reason when no GPU is usable).
    Cuda,
}

impl BackendKind {
    /// The name used on the command line and in Python: "auto", "cpu" or "cuda".
    pub fn name(self) -> &'static str {
        match self {
            BackendKind::Auto => "auto",
            BackendKind::Cpu => "cpu",
            BackendKind::Cuda => "cuda",
        }
    }
}

impl std::str::FromStr for BackendKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(BackendKind::Auto),
            "cpu" => Ok(BackendKind::Cpu),
            "cuda" => Ok(BackendKind::Cuda),
            _ => Err(format!(
                "unknown backend `{s}`: expected \"auto\", \"cpu\" or \"cuda\""
            )),
        }
    }
}

/// Every backend [`create`] can build.
pub enum AnyBackend {
    /// The CPU reference backend in f32.
    Cpu(rtmpm_cpu::CpuBackend),
    /// The CPU backend in f64 (`precision = "f64"`).
    CpuF64(rtmpm_cpu_f64::CpuBackend),
    /// One GPU.
    Cuda(CudaSend),
    /// Several GPUs of this process.
    MultiGpu(Box<rtmpm_cuda::MultiGpuBackend>),
}

/// A [`rtmpm_cuda::CudaBackend`] that may move to another thread (the Python package steps it
/// with the interpreter lock released, possibly from another Python thread).
pub struct CudaSend(pub Box<rtmpm_cuda::CudaBackend>);

// SAFETY: the only part of the CUDA backend that is not `Send` is cudarc's `CudaGraph` (raw
// CUgraph/CUgraphExec handles, for which cudarc declares no `Send`). CUDA driver handles are
// not tied to a thread: cudarc binds the graph's context to the calling thread before every
// launch (`CudaGraph::launch`) and destroys the handles through that context on drop, as it
// does for its streams, modules and functions, which it declares `Send`. The backend is used
// by one thread at a time (`&mut self`).
unsafe impl Send for CudaSend {}

/// A backend and why it was picked.
pub struct Created {
    pub backend: AnyBackend,
    /// What was asked and what was picked, e.g. "auto -> cpu (2 threads) (CUDA not usable:
    /// libcuda.so not found)".
    pub reason: String,
}

/// How to build a backend: everything [`create`] needs besides the scene and the particles.
#[derive(Clone, Debug, Default)]
pub struct BackendRequest {
    pub kind: BackendKind,
    /// CPU worker threads (None: one per core).
    pub threads: Option<usize>,
    /// GPUs of this process (0 or 1: one).
    pub gpus: usize,
    /// CUDA backend switches.
    pub cuda: CudaOptions,
}

/// Construct the backend `request` asks for, in the scene's precision; the reason says which one
/// `auto` picked and why. Errors are messages for the user (with a hint).
pub fn create(
    request: &BackendRequest,
    scene: &Scene,
    particles: Particles,
) -> Result<Created, String> {
    let gpus = request.gpus.max(1);
    if gpus > 1 {
        if request.kind == BackendKind::Cpu {
            return Err(format!(
                "{gpus} GPUs asked for with the CPU backend: several GPUs need the CUDA backend"
            ));
        }
        let b = rtmpm_cuda::MultiGpuBackend::new(scene, &particles, gpus, request.cuda.clone())
            .map_err(|e| e.to_string())?;
        let backend = AnyBackend::MultiGpu(Box::new(b));
        let reason = format!(
            "{} -> {} ({gpus} GPUs)",
            request.kind.name(),
            backend.name()
        );
        return Ok(Created { backend, reason });
    }
    match request.kind {
        BackendKind::Cpu => {
            let backend = cpu_backend(scene, particles, request.threads)?;
            let reason = format!("cpu -> {} (asked for)", backend.name());
            Ok(Created { backend, reason })
        }
        BackendKind::Cuda => match cuda_backend(scene, &particles, &request.cuda) {
            Ok(backend) => {
                let reason = format!("cuda -> {} (asked for)", backend.name());
                Ok(Created { backend, reason })
            }
            Err(why) => Err(format!(
                "the CUDA backend is not usable here: {why}\n  hint: use the CPU backend \
                 (`--backend cpu`; in Python `backend=\"cpu\"`)"
            )),
        },
        BackendKind::Auto => match cuda_backend(scene, &particles, &request.cuda) {
            Ok(backend) => {
                let reason = format!("auto -> {} (a usable GPU was found)", backend.name());
                Ok(Created { backend, reason })
            }
            Err(why) => {
                let backend = cpu_backend(scene, particles, request.threads)?;
                let reason = format!("auto -> {} (CUDA not usable: {why})", backend.name());
                Ok(Created { backend, reason })
            }
        },
    }
}

/// [`create`] from sampled bodies ([`rtmpm_scene::sampling::sample_bodies`]): one GPU
/// packs them straight from their positions, so the host never holds the particles (about 129
/// instead of 254 bytes a particle at the host's peak); the CPU, several GPUs, and an `auto` that
/// falls back to the CPU get the particles written from them (those of `scene.sample_particles()`).
pub fn create_from_bodies(
    request: &BackendRequest,
    scene: &Scene,
    bodies: Vec<SampledBody>,
) -> Result<Created, String> {
    if request.gpus > 1 || request.kind == BackendKind::Cpu {
        return create(request, scene, sampling::particles_of(bodies));
    }
    let n = bodies.iter().map(|b| b.len()).sum();
    let made = cuda_backend_with(scene, n, || {
        rtmpm_cuda::CudaBackend::from_bodies(scene, &bodies, request.cuda.clone())
    });
    match (made, request.kind) {
        (Ok(backend), BackendKind::Cuda) => {
            let reason = format!("cuda -> {} (asked for)", backend.name());
            Ok(Created { backend, reason })
        }
        (Ok(backend), _) => {
            let reason = format!("auto -> {} (a usable GPU was found)", backend.name());
            Ok(Created { backend, reason })
        }
        (Err(why), BackendKind::Cuda) => Err(format!(
            "the CUDA backend is not usable here: {why}\n  hint: use the CPU backend \
             (`--backend cpu`; in Python `backend=\"cpu\"`)"
        )),
        (Err(why), _) => {
            let particles = sampling::particles_of(bodies);
            let backend = cpu_backend(scene, particles, request.threads)?;
            let reason = format!("auto -> {} (CUDA not usable: {why})", backend.name());
            Ok(Created { backend, reason })
        }
    }
}

/// The CPU backend in the scene's precision (`[solver] precision`).
fn cpu_backend(
    scene: &Scene,
    particles: Particles,
    threads: Option<usize>,
) -> Result<AnyBackend, String> {
    Ok(match scene.precision {
        Precision::F32 => AnyBackend::Cpu(
            rtmpm_cpu::CpuBackend::new(scene, particles, threads).map_err(|e| e.to_string())?,
        ),
        Precision::F64 => AnyBackend::CpuF64(
            rtmpm_cpu_f64::CpuBackend::new(scene, particles, threads).map_err(|e| e.to_string())?,
        ),
    })
}

/// The CUDA backend, or why it cannot run.
fn cuda_backend(
    scene: &Scene,
    particles: &Particles,
    options: &CudaOptions,
) -> Result<AnyBackend, String> {
    cuda_backend_with(scene, particles.len(), || {
        rtmpm_cuda::CudaBackend::new(scene, particles, options.clone())
    })
}

/// The CUDA backend `make` builds for `n` particles, or why it cannot run (the GPU's memory
/// checked first).
fn cuda_backend_with(
    scene: &Scene,
    n: usize,
    make: impl FnOnce() -> Result<rtmpm_cuda::CudaBackend, SimError>,
) -> Result<AnyBackend, String> {
    let info = rtmpm_cuda::probe().map_err(|e| e.to_string())?;
    // The budget's device estimate (rtmpm_scene::budget) against the GPU's memory,
    // before anything is allocated: a clear error with the sizes.
    let need = rtmpm_scene::Budget::estimate(scene, Some(1)).gpu_bytes;
    let emitted = scene.emitters.iter().map(|e| e.total()).sum::<u64>();
    let have = info.memory as u64;
    if need > have {
        return Err(format!(
            "the scene needs about {} of GPU memory for {} particles (with the {} its emitters \
             add) and its grid (an estimate), more than the {} of the {}; use fewer particles \
             or a coarser dx, lower emitter rates, several GPUs (--gpus N), or --backend cpu",
            human_bytes(need),
            n as u64 + emitted,
            emitted,
            human_bytes(have),
            info.name
        ));
    }
    let b = make().map_err(|e| {
        format!(
            "{e} (estimated need {} of the GPU's {})",
            human_bytes(need),
            human_bytes(have)
        )
    })?;
    Ok(AnyBackend::Cuda(CudaSend(Box::new(b))))
}

impl AnyBackend {
    /// The backend as a trait object.
    pub fn as_dyn(&mut self) -> &mut dyn Backend {
        match self {
            AnyBackend::Cpu(b) => b,
            AnyBackend::CpuF64(b) => b,
            AnyBackend::Cuda(b) => b.0.as_mut(),
            AnyBackend::MultiGpu(b) => b.as_mut(),
        }
    }

    fn as_dyn_ref(&self) -> &dyn Backend {
        match self {
            AnyBackend::Cpu(b) => b,
            AnyBackend::CpuF64(b) => b,
            AnyBackend::Cuda(b) => b.0.as_ref(),
            AnyBackend::MultiGpu(b) => b.as_ref(),
        }
    }

    /// "cpu" or "cuda".
    pub fn kind(&self) -> BackendKind {
        match self {
            AnyBackend::Cpu(_) | AnyBackend::CpuF64(_) => BackendKind::Cpu,
            AnyBackend::Cuda(_) | AnyBackend::MultiGpu(_) => BackendKind::Cuda,
        }
    }
}

/// Every call goes to the backend inside.
impl Backend for AnyBackend {
    fn name(&self) -> String {
        self.as_dyn_ref().name()
    }
    fn num_particles(&self) -> usize {
        self.as_dyn_ref().num_particles()
    }
    fn step(&mut self, dt: f32, t: f32) -> Result<(), SimError> {
        self.as_dyn().step(dt, t)
    }
    fn max_speed(&mut self) -> Result<f32, SimError> {
        self.as_dyn().max_speed()
    }
    fn check(&mut self) -> Result<Option<BadParticle>, SimError> {
        self.as_dyn().check()
    }
    fn read_particles(&mut self, out: &mut Particles) -> Result<(), SimError> {
        self.as_dyn().read_particles(out)
    }
    fn export_frame(&mut self, sink: &mut dyn rtmpm_sim::ChunkSink) -> Result<(), SimError> {
        self.as_dyn().export_frame(sink)
    }
    fn chunk_memory(
        &self,
        words: usize,
    ) -> Result<Box<dyn rtmpm_io::chunks::HostBuffer>, SimError> {
        self.as_dyn_ref().chunk_memory(words)
    }
    fn cheap_check(&self) -> bool {
        self.as_dyn_ref().cheap_check()
    }
    fn stage_times(&self) -> Vec<(&'static str, f64)> {
        self.as_dyn_ref().stage_times()
    }
    fn end_of_frame(&mut self) -> Result<(), SimError> {
        self.as_dyn().end_of_frame()
    }
    fn memory_bytes(&self) -> Option<(u64, u64)> {
        self.as_dyn_ref().memory_bytes()
    }
    fn add_particles(&mut self, particles: &Particles) -> Result<(), SimError> {
        self.as_dyn().add_particles(particles)
    }
    fn rigid_bodies(&self) -> Vec<rtmpm_rigid::BodyState> {
        self.as_dyn_ref().rigid_bodies()
    }
    fn rigid_poses(&self) -> Vec<rtmpm_rigid::BodyPose> {
        self.as_dyn_ref().rigid_poses()
    }
    fn flush_rigid(&mut self) -> Result<(), SimError> {
        self.as_dyn().flush_rigid()
    }
    fn rigid_loads(&self) -> Option<Vec<rtmpm_rigid::BodyLoad>> {
        self.as_dyn_ref().rigid_loads()
    }
    fn set_rigid_poses(&mut self, poses: &[rtmpm_rigid::BodyPose]) -> Result<(), SimError> {
        self.as_dyn().set_rigid_poses(poses)
    }
    fn render_view(
        &mut self,
        req: &rtmpm_render::ViewRequest,
        out: &mut rtmpm_render::Image,
    ) -> Result<bool, SimError> {
        self.as_dyn().render_view(req, out)
    }
    fn begin_view(&mut self, req: &rtmpm_render::ViewRequest) -> Result<bool, SimError> {
        self.as_dyn().begin_view(req)
    }
    fn finish_view(&mut self, out: &mut rtmpm_render::Image) -> Result<(), SimError> {
        self.as_dyn().finish_view(out)
    }
    fn set_gravity(&mut self, gravity: rtmpm_physics::math::Vec3) -> Result<(), SimError> {
        self.as_dyn().set_gravity(gravity)
    }
    fn set_tool(&mut self, tool: Option<rtmpm_geometry::Tool>) -> Result<(), SimError> {
        self.as_dyn().set_tool(tool)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Python package steps a backend with the interpreter's lock released: it must be Send.
    #[test]
    fn backends_can_move_between_threads() {
        fn send<T: Send>() {}
        send::<AnyBackend>();
    }

    /// A block of water in a unit box, and its particles.
    fn water_block() -> (Scene, Particles) {
        let scene = Scene::from_toml(
            "[domain]\nmin = [0,0,0]\nmax = [1,1,1]\ndx = 0.1\n[time]\nduration = 0.1\n\
             [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000.0\nbulk_modulus = 1e4\n\
             [[body]]\nmaterial = \"w\"\nshape = \"box\"\nmin = [0.3,0.3,0.3]\nmax = [0.5,0.5,0.5]\n",
            "<test>",
        )
        .unwrap();
        let p = scene.sample_particles().unwrap();
        (scene, p)
    }

    #[test]
    fn steering_reaches_the_cpu_backend_inside() {
        use rtmpm_driver::Simulation;
        use rtmpm_geometry::{Tool, ToolShape};
        let (scene, p) = water_block();
        let req = BackendRequest {
            kind: BackendKind::Cpu,
            threads: Some(1),
            ..Default::default()
        };
        let c = create(&req, &scene, p).unwrap();
        let mut sim = Simulation::with_backend(scene.clone(), Box::new(c.backend));
        let g = rtmpm_physics::math::Vec3::new(0.0, 0.0, -3.0);
        sim.set_gravity(g).unwrap();
        assert_eq!(sim.scene.gravity, g);
        assert!(sim.set_gravity(rtmpm_physics::math::Vec3::NAN).is_err());
        assert_eq!(sim.scene.gravity, g, "a refused gravity changes nothing");
        let AnyBackend::Cpu(cpu) = sim.backend.as_ref() else {
            panic!("a CPU backend");
        };
        assert_eq!(cpu.consts.gravity, g);
        let tool = Tool {
            shape: ToolShape::Sphere { radius: 0.1 },
            center: rtmpm_physics::math::Vec3::splat(0.5),
            velocity: rtmpm_physics::math::Vec3::X,
        };
        sim.backend.set_tool(Some(tool)).unwrap();
        let AnyBackend::Cpu(cpu) = sim.backend.as_ref() else {
            panic!("a CPU backend");
        };
        assert_eq!(cpu.consts.tool, Some(tool));
        // The CPU backend does not draw: the caller uses the CPU renderer.
        let req = rtmpm_render::ViewRequest::framing(&scene, 32, 32, 0.01);
        let mut img = rtmpm_render::Image::new(1, 1, [0; 3]);
        assert!(!sim.backend.render_view(&req, &mut img).unwrap());
    }

    #[test]
    fn kinds_parse_and_cpu_is_built_with_its_reason() {
        assert_eq!("cuda".parse::<BackendKind>(), Ok(BackendKind::Cuda));
        assert!("gpu".parse::<BackendKind>().unwrap_err().contains("cpu"));
        let (scene, p) = water_block();
        let n = p.len();
        let req = BackendRequest {
            kind: BackendKind::Cpu,
            threads: Some(1),
            ..Default::default()
        };
        let c = create(&req, &scene, p).unwrap();
        assert_eq!(c.backend.kind(), BackendKind::Cpu);
        assert_eq!(c.backend.num_particles(), n);
        assert!(
            c.reason.starts_with("cpu -> cpu (1 threads)"),
            "{}",
            c.reason
        );
    }
}
