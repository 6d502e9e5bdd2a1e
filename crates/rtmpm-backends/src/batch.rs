//! Where a batch of worlds runs: on the CPU backend (each world its own simulation) or on one GPU
//! (every world in the same kernels, `rtmpm_cuda::batch::CudaBatch`). `auto` picks the GPU when
//! one is usable (the probe a single scene's `auto` uses) and the batch uses only what the GPU
//! batch supports, else the CPU, saying why. Shared by `rtmpm run` and Python's
//! `BatchSimulation`.

use crate::BackendKind;
use rtmpm_cuda::CudaOptions;
use rtmpm_scene::Scene;

/// The backend chosen for a batch and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BatchChoice {
    /// [`BackendKind::Cpu`] or [`BackendKind::Cuda`].
    pub kind: BackendKind,
    /// What was asked and what was picked, e.g. "auto -> cpu (CUDA not usable: libcuda.so not
    /// found)".
    pub reason: String,
}

/// The backend for a batch asked to run on `kind`, from what the probe found (`gpu`: the GPU's
/// name, or why none is usable) and whether the GPU batch can run it (`support`: `None`, or
/// what it lacks). A pure function: `auto` picks the GPU only when both allow it; `cuda` is
/// refused (the error says why and names the CPU backend) when either does not.
pub fn choose(
    kind: BackendKind,
    gpu: Result<&str, &str>,
    support: Option<&str>,
) -> Result<BatchChoice, String> {
    let pick = |kind, reason| Ok(BatchChoice { kind, reason });
    match (kind, gpu, support) {
        (BackendKind::Cpu, _, _) => pick(BackendKind::Cpu, "cpu (asked for)".into()),
        (BackendKind::Cuda, Err(why), _) => Err(format!(
            "the CUDA backend is not usable here: {why}\n  hint: use the CPU backend \
             (`--backend cpu`; in Python `backend=\"cpu\"`)"
        )),
        (BackendKind::Cuda, Ok(_), Some(why)) => Err(format!(
            "this batch cannot run on the GPU: {why}\n  hint: use the CPU backend \
             (`--backend cpu`; in Python `backend=\"cpu\"`), which runs every batch"
        )),
        (BackendKind::Cuda, Ok(name), None) => pick(
            BackendKind::Cuda,
            format!("cuda -> {name}, every world in the same kernels (asked for)"),
        ),
        (BackendKind::Auto, Err(why), _) => pick(
            BackendKind::Cpu,
            format!("auto -> cpu (CUDA not usable: {why})"),
        ),
        (BackendKind::Auto, Ok(_), Some(why)) => pick(
            BackendKind::Cpu,
            format!("auto -> cpu (the GPU batch cannot run it: {why})"),
        ),
        (BackendKind::Auto, Ok(name), None) => pick(
            BackendKind::Cuda,
            format!("auto -> {name}, every world in the same kernels (a usable GPU was found)"),
        ),
    }
}

/// [`choose`] for the worlds `worlds` with the CUDA options `cuda`: the GPU probed (unless the
/// CPU is asked for), the batch checked against what the GPU batch supports
/// (`rtmpm_cuda::batch::unsupported`).
pub fn choose_for(
    kind: BackendKind,
    worlds: &[Scene],
    cuda: &CudaOptions,
) -> Result<BatchChoice, String> {
    if kind == BackendKind::Cpu {
        return choose(kind, Err("not probed"), None);
    }
    let gpu = rtmpm_cuda::probe()
        .map(|i| i.name)
        .map_err(|e| e.to_string());
    let support = rtmpm_cuda::batch::unsupported(worlds, cuda);
    choose(
        kind,
        gpu.as_deref().map_err(String::as_str),
        support.as_deref(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    const GPU: Result<&str, &str> = Ok("NVIDIA H200");
    const NO_GPU: Result<&str, &str> = Err("libcuda.so not found");

    #[test]
    fn auto_picks_the_gpu_only_when_it_is_usable_and_supports_the_batch() {
        let c = choose(BackendKind::Auto, GPU, None).unwrap();
        assert_eq!(c.kind, BackendKind::Cuda);
        assert!(c.reason.contains("NVIDIA H200") && c.reason.contains("usable GPU"));
        let c = choose(BackendKind::Auto, NO_GPU, None).unwrap();
        assert_eq!(c.kind, BackendKind::Cpu);
        assert_eq!(
            c.reason,
            "auto -> cpu (CUDA not usable: libcuda.so not found)"
        );
        let c = choose(BackendKind::Auto, GPU, Some("world 0 has rigid bodies")).unwrap();
        assert_eq!(c.kind, BackendKind::Cpu);
        assert_eq!(
            c.reason,
            "auto -> cpu (the GPU batch cannot run it: world 0 has rigid bodies)"
        );
        // Without a GPU the probe's reason is the one given, whatever the batch is.
        let c = choose(BackendKind::Auto, NO_GPU, Some("rigid bodies")).unwrap();
        assert!(c.reason.contains("libcuda"), "{}", c.reason);
    }

    #[test]
    fn cpu_is_always_the_cpu_and_cuda_is_refused_with_the_reason() {
        for gpu in [GPU, NO_GPU] {
            for support in [None, Some("emitters")] {
                let c = choose(BackendKind::Cpu, gpu, support).unwrap();
                assert_eq!(
                    (c.kind, c.reason.as_str()),
                    (BackendKind::Cpu, "cpu (asked for)")
                );
            }
        }
        assert_eq!(
            choose(BackendKind::Cuda, GPU, None).unwrap().kind,
            BackendKind::Cuda
        );
        let e = choose(BackendKind::Cuda, NO_GPU, None).unwrap_err();
        assert!(
            e.contains("libcuda.so not found") && e.contains("backend=\"cpu\""),
            "{e}"
        );
        let e = choose(BackendKind::Cuda, GPU, Some("world 2 differs")).unwrap_err();
        assert!(e.contains("cannot run on the GPU: world 2 differs"), "{e}");
        assert!(e.contains("--backend cpu"), "{e}");
    }

    fn scene(extra: &str) -> Scene {
        Scene::from_toml(
            &format!(
                "[domain]\nmin = [0,0,0]\nmax = [1,1,1]\ndx = 0.1\n[time]\nduration = 0.1\n\
                 [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000.0\n\
                 bulk_modulus = 1e4\n[[body]]\nmaterial = \"w\"\nshape = \"box\"\n\
                 min = [0.3,0.3,0.3]\nmax = [0.5,0.5,0.5]\n{extra}"
            ),
            "<test>",
        )
        .unwrap()
    }

    #[test]
    fn what_the_gpu_batch_lacks_is_found_from_the_scenes() {
        let plain = scene("");
        let opts = CudaOptions::default();
        assert_eq!(
            rtmpm_cuda::batch::unsupported(&[plain.clone(), plain.clone()], &opts),
            None
        );
        let mut other = plain.clone();
        other.dx = 0.05;
        let why = rtmpm_cuda::batch::unsupported(&[plain.clone(), other], &opts).unwrap();
        assert!(why.starts_with("world 1 differs from world 0"), "{why}");
        let mut gravity = plain.clone();
        gravity.gravity = rtmpm_physics::math::Vec3::new(0.0, -1.0, 0.0);
        assert_eq!(
            rtmpm_cuda::batch::unsupported(&[plain.clone(), gravity], &opts),
            None
        );
        let sort: CudaOptions = "p2g=sort".parse().unwrap();
        let why = rtmpm_cuda::batch::unsupported(std::slice::from_ref(&plain), &sort).unwrap();
        assert!(why.contains("p2g=sort"), "{why}");
        // The probe decides between them for a batch the GPU runs.
        let c = choose_for(BackendKind::Auto, &[plain], &opts).unwrap();
        let want = match rtmpm_cuda::probe() {
            Ok(_) => BackendKind::Cuda,
            Err(_) => BackendKind::Cpu,
        };
        assert_eq!(c.kind, want, "{}", c.reason);
    }

    /// A pusher's motion swept over the worlds (`[batch.sweep]` of a collider's velocity, or of
    /// a key of its keyframes) is a batch the GPU runs, so `auto` takes it to the GPU when one
    /// is usable; worlds with different numbers of colliders still go to the CPU, saying why.
    #[test]
    fn a_sweep_of_a_pushers_motion_runs_on_the_gpu_batch() {
        let pusher = "[[collider]]\nshape = \"box\"\nmin = [0.0, 0.0, 0.0]\n\
                      max = [0.2, 0.8, 1.0]\n";
        let sweeps = [
            format!(
                "{pusher}velocity = [0.1, 0.0, 0.0]\n[batch]\ncount = 4\n[batch.sweep]\n\
                 \"collider[0].velocity[0]\" = {{ from = 0.1, to = 1.0 }}\n"
            ),
            format!(
                "{pusher}keyframes = [{{ t = 0.0, position = [0.1, 0.4, 0.5] }}, \
                 {{ t = 0.05, position = [0.2, 0.4, 0.5] }}]\n[batch]\ncount = 3\n\
                 [batch.sweep]\n\"collider[0].keyframes[1].t\" = [0.02, 0.05, 0.08]\n"
            ),
        ];
        let opts = CudaOptions::default();
        for extra in sweeps {
            let text = format!(
                "[domain]\nmin = [0,0,0]\nmax = [1,1,1]\ndx = 0.1\n[time]\nduration = 0.1\n\
                 [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000.0\n\
                 bulk_modulus = 1e4\n[[body]]\nmaterial = \"w\"\nshape = \"box\"\n\
                 min = [0.3,0.3,0.3]\nmax = [0.5,0.5,0.5]\n{extra}"
            );
            let b = rtmpm_scene::BatchScene::from_toml(&text, "<test>")
                .unwrap_or_else(|e| panic!("{e}"));
            let (first, last) = (
                &b.worlds[0].colliders[0],
                &b.worlds[b.count() - 1].colliders[0],
            );
            assert_ne!(
                format!("{first:?}"),
                format!("{last:?}"),
                "the worlds differ"
            );
            let support = rtmpm_cuda::batch::unsupported(&b.worlds, &opts);
            assert_eq!(support, None);
            let c = choose(BackendKind::Auto, GPU, support.as_deref()).unwrap();
            assert_eq!(c.kind, BackendKind::Cuda, "{}", c.reason);
        }
        let one =
            scene("[[collider]]\nshape = \"sphere\"\ncenter = [0.7, 0.2, 0.5]\nradius = 0.1\n");
        let why = rtmpm_cuda::batch::unsupported(&[one, scene("")], &opts).expect("refused");
        let c = choose(BackendKind::Auto, GPU, Some(&why)).unwrap();
        assert_eq!(c.kind, BackendKind::Cpu);
        assert!(
            c.reason
                .contains("world 1 has 0 colliders and world 0 has 1"),
            "{}",
            c.reason
        );
    }
}
