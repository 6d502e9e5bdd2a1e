//! The host's decisions of a multi-GPU run: what several GPUs support, which particles go to
//! which GPU, how many shared blocks the reduction holds, and what to do at the end of a frame
//! (grow the reduction, re-partition drifted particles); the combination of every GPU's
//! control words.

use super::partition::{Partition, shared_blocks};
use super::reduce_shared::dense_dims;
use crate::backend::CudaBackend;
use crate::contract::{CTL_BAD_INDEX, CTL_MAX_SPEED, bad_particle};
use crate::options::{CudaOptions, P2gMode};
use rtmpm_physics::Particles;
use rtmpm_physics::transfer::Transfer;
use rtmpm_scene::Scene;
use rtmpm_sim::{BadParticle, SimError};

/// The particles of `idx`, in that order.
pub fn subset(p: &Particles, idx: &[u32]) -> Particles {
    let pick = |i: &u32| *i as usize;
    Particles {
        x: idx.iter().map(|i| p.x[pick(i)]).collect(),
        v: idx.iter().map(|i| p.v[pick(i)]).collect(),
        c: idx.iter().map(|i| p.c[pick(i)]).collect(),
        f: idx.iter().map(|i| p.f[pick(i)]).collect(),
        plastic: idx.iter().map(|i| p.plastic[pick(i)]).collect(),
        mass: idx.iter().map(|i| p.mass[pick(i)]).collect(),
        vol0: idx.iter().map(|i| p.vol0[pick(i)]).collect(),
        material: idx.iter().map(|i| p.material[pick(i)]).collect(),
    }
}

/// Shared-block capacity for a partition: twice the shared blocks with a margin, at most every
/// block of the domain (which can never overflow).
pub(crate) fn shared_capacity(
    scene: &Scene,
    p: &Particles,
    part: &Partition,
    o: &CudaOptions,
) -> (usize, usize) {
    let d = dense_count(scene);
    let s = shared_blocks(scene, &p.x, part);
    let cap = o.shared_capacity.unwrap_or(2 * s + 1024).clamp(1, d);
    (cap, s)
}

pub(crate) fn dense_count(scene: &Scene) -> usize {
    dense_dims(scene.n_cells())
        .iter()
        .map(|&x| x as usize)
        .product()
}

/// What several GPUs support, checked before any GPU work: the warp P2G, MLS-MPM and single
/// precision (clear errors otherwise).
pub fn check_supported(scene: &Scene, options: &CudaOptions) -> Result<(), SimError> {
    if options.p2g != P2gMode::Warp {
        return Err(SimError::Backend(
            "several GPUs need the warp P2G (p2g=warp)".into(),
        ));
    }
    if scene.solver.transfer != Transfer::Mls {
        let what = if scene.solver.transfer == Transfer::CkMpm {
            "its second grid is"
        } else {
            "its per-node force and FLIP velocity are"
        };
        return Err(SimError::Backend(format!(
            "several GPUs run MLS-MPM only: the scene's [solver] transfer is \"{}\" ({what} \
             not summed across GPUs yet); run it on one GPU (--gpus 1) or on the CPU",
            scene.solver.transfer.name()
        )));
    }
    if !scene.emitters.is_empty() {
        return Err(SimError::Backend(
            "several GPUs cannot take the particles of the scene's [[emitter]] tables yet (the \
             partition is fixed at the start); run it on one GPU (--gpus 1) or on the CPU"
                .into(),
        ));
    }
    if options.f64 || scene.precision == rtmpm_scene::Precision::F64 {
        return Err(SimError::Backend(
            "several GPUs run in single precision only (the particle exchange at \
             rebalancing moves f32 state); run f64 scenes on one GPU (--gpus 1)"
                .into(),
        ));
    }
    Ok(())
}
/// Combine the control words of every GPU: (max speed, first bad particle by original index).
/// Errors (capacity) of any GPU are reported.
pub(crate) fn combine(
    b: &CudaBackend,
    ctls: &[Vec<u32>],
) -> Result<(f32, Option<BadParticle>), SimError> {
    let mut speed = 0f32;
    let mut bad: Option<BadParticle> = None;
    for c in ctls {
        b.error_check(c)?;
        speed = speed.max(f32::from_bits(c[CTL_MAX_SPEED]));
        if let Some(b) = bad_particle(c[CTL_BAD_INDEX])
            && bad.is_none_or(|first| b.index < first.index)
        {
            bad = Some(b);
        }
    }
    Ok((speed, bad))
}

/// What to do at the end of a frame, from the shared-block count (the same on every GPU).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct FramePlan {
    pub grow_to: Option<usize>,
    pub rebalance: bool,
}

pub(crate) fn plan(
    shared: usize,
    cap: usize,
    d: usize,
    at_partition: usize,
    ranks: usize,
    o: &CudaOptions,
) -> FramePlan {
    let grow_to = (o.shared_capacity.is_none() && shared * 2 > cap && cap < d)
        .then(|| (2 * shared + 1024).min(d));
    let rebalance = ranks > 1 && o.rebalance && shared > 2 * at_partition + 256;
    FramePlan { grow_to, rebalance }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unsupported_scenes_are_clear_errors_before_any_gpu_work() {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/dam_break.toml");
        let scene = Scene::from_file(&path).expect("dam_break scene");
        let o = CudaOptions::default();
        assert!(check_supported(&scene, &o).is_ok());
        let msg = |r: Result<(), SimError>| r.err().map(|e| e.to_string()).unwrap_or_default();
        let shared = CudaOptions {
            p2g: P2gMode::Shared,
            ..o.clone()
        };
        assert!(msg(check_supported(&scene, &shared)).contains("p2g=warp"));
        let f64 = CudaOptions {
            f64: true,
            ..o.clone()
        };
        assert!(msg(check_supported(&scene, &f64)).contains("single precision"));
        let mut gimp = scene.clone();
        gimp.solver.transfer = Transfer::Gimp;
        assert!(msg(check_supported(&gimp, &o)).contains("\"gimp\""));
        let mut ck = scene.clone();
        ck.solver.transfer = Transfer::CkMpm;
        let m = msg(check_supported(&ck, &o));
        assert!(
            m.contains("\"ck-mpm\"") && m.contains("second grid") && m.contains("--gpus 1"),
            "{m}"
        );
        let mut double = scene;
        double.precision = rtmpm_scene::Precision::F64;
        assert!(msg(check_supported(&double, &o)).contains("--gpus 1"));
    }

    #[test]
    fn frame_plan_grows_the_reduction_and_rebalances_after_drift() {
        let o = CudaOptions::default();
        let p = plan(100, 1000, 5000, 100, 2, &o);
        assert_eq!(
            p,
            FramePlan {
                grow_to: None,
                rebalance: false
            }
        );
        let p = plan(600, 1000, 5000, 500, 2, &o);
        assert_eq!(p.grow_to, Some(2224));
        assert!(!p.rebalance);
        // Never beyond every block of the domain.
        assert_eq!(plan(600, 1000, 1500, 500, 2, &o).grow_to, Some(1500));
        assert_eq!(plan(1400, 1500, 1500, 500, 2, &o).grow_to, None);
        assert!(plan(1300, 3000, 5000, 500, 2, &o).rebalance);
        assert!(!plan(1300, 3000, 5000, 500, 1, &o).rebalance);
        let fixed = CudaOptions {
            shared_capacity: Some(1000),
            rebalance: false,
            ..o
        };
        assert_eq!(
            plan(900, 1000, 5000, 100, 2, &fixed),
            FramePlan {
                grow_to: None,
                rebalance: false
            }
        );
    }

    #[test]
    fn subset_picks_particles_in_order() {
        let mut p = Particles::default();
        for i in 0..5 {
            p.push(
                rtmpm_physics::math::Vec3::splat(i as f32),
                rtmpm_physics::math::Vec3::ZERO,
                i as f32,
                1.0,
                i,
                0.0,
            );
        }
        let s = subset(&p, &[4, 1]);
        assert_eq!(s.mass, vec![4.0, 1.0]);
        assert_eq!(s.material, vec![4, 1]);
    }
}
