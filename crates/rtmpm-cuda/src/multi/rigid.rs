//! Rigid bodies (`[[rigid_body]]`) on several GPUs: one rapier world on the host
//! ([`SharedBodies`]), the coupling on every GPU. Each GPU's grid update couples the bodies to
//! the nodes of its own pblocks and sums their reactions (`kernels/grid_update.cu`:
//! `couple_bodies`); a pblock that k GPUs hold has the same summed nodes on each of them after
//! the shared-block reduction, so each adds 1/k of its reaction and the sum over the GPUs
//! ([`sum_over_ranks`]) counts every node once. The host advances the world once with that sum,
//! and every GPU gets the same poses before its next step. With
//! [`crate::options::CudaOptions::rigid_overlap`] the world advances by a step's sums while the
//! GPUs run the next one, as on one GPU (`crate::step::rigid`). The sums the world takes are
//! also every body's load, kinematic and fixed bodies' too (their reactions are summed like a
//! dynamic body's, in the same buffer): [`SharedBodies::advance`] keeps them for
//! `Backend::rigid_loads` ([`LastLoads`]).
//!
//! One process per GPU ([`RankBodies`], `crate::multi::process`): every process holds the same
//! rapier world (the same scene, built and advanced in the same order) and its GPU's sums are
//! summed across the processes on the device (an NCCL all-reduce of the impulse buffer after
//! each step, `crate::multi::rank::GpuRank::set_body_check`), so every process advances its
//! world by the same sums and the worlds stay identical. The check of that goes with the sums:
//! each process puts a hash of the body states its GPU coupled in the step ([`state_hash`]) in
//! the words after them ([`check_words`]); from their sum alone every process decides whether
//! all hashes were equal ([`ranks_agree`]), so every process stops at the same step with the
//! same error when the worlds differ. Every process reports the same loads: those of the
//! summed buffer.

use crate::contract::BODY_EXCHANGE_SLOTS;
use crate::options::CudaOptions;
use crate::step::rigid::{CHECK_WORDS, HeldBodies, LastLoads, exchange_sums};
use rtmpm_rigid::{BodyLoad, BodyPose, BodyState, Exchange, RigidWorld};
use rtmpm_scene::Scene;
use rtmpm_sim::SimError;

/// The bodies of a multi-GPU run: their world and the step whose sums it has not taken yet.
pub(crate) struct SharedBodies {
    world: RigidWorld,
    /// A step queued on every GPU whose sums the bodies have not taken yet: its host copy and
    /// its dt.
    pending: Option<(usize, f32)>,
    overlap: bool,
    /// The sums of the last step the world took, over every GPU (the loads).
    last: LastLoads,
}

impl SharedBodies {
    /// The bodies of `scene` (`None` without any; the same refusals as on one GPU).
    pub(crate) fn new(scene: &Scene, o: &CudaOptions) -> Result<Option<SharedBodies>, SimError> {
        Ok(crate::step::rigid::world(scene)?.map(|world| SharedBodies {
            world,
            pending: None,
            overlap: o.rigid_overlap,
            last: LastLoads::default(),
        }))
    }

    /// Gravity from the next advance on.
    pub(crate) fn set_gravity(&mut self, g: rtmpm_physics::math::Vec3) {
        self.world.set_gravity(g);
    }

    /// A step of `dt` was queued on every GPU, its sums going to host copy `k`: the step whose
    /// sums the bodies take now (this one without overlap, the one before with it), if any.
    pub(crate) fn queued(&mut self, k: usize, dt: f32) -> Option<(usize, f32)> {
        if self.overlap {
            self.pending.replace((k, dt))
        } else {
            Some((k, dt))
        }
    }

    /// The step whose sums are still to be taken (flushing), if any.
    pub(crate) fn take_pending(&mut self) -> Option<(usize, f32)> {
        self.pending.take()
    }

    /// Advance the world by `dt` with every GPU's sums of one step (in rank order); their
    /// total is every body's load over that step.
    pub(crate) fn advance(&mut self, per_rank: &[Vec<Exchange>], dt: f32) {
        let total = sum_over_ranks(per_rank, self.world.states().len());
        self.world.advance(&total, dt);
        self.last.record(total, dt);
    }
}

impl HeldBodies for SharedBodies {
    /// The states every GPU couples in the coming step.
    fn states(&self) -> &[BodyState] {
        self.world.states()
    }

    fn poses(&self) -> Vec<BodyPose> {
        self.world.poses()
    }

    fn loads(&self) -> Vec<BodyLoad> {
        self.last.loads(self.world.states().len())
    }

    /// Sums not yet taken are dropped.
    fn set_poses(&mut self, poses: &[BodyPose]) -> Result<(), SimError> {
        self.pending = None;
        self.world.set_poses(poses).map_err(SimError::Backend)
    }
}

/// The bits of a hash each pair of check words carries: 16, so that the check's sums stay
/// exact integers in f64 up to [`MAX_CHECK_RANKS`] processes.
const CHECK_BITS: u32 = 16;

/// The most processes [`ranks_agree`] decides exactly: n^2 x 2^32 < 2^53 (the largest of its
/// sums times n) holds up to n = 1448; the run refuses more.
pub(crate) const MAX_CHECK_RANKS: usize = 1024;

/// A 64-bit hash (FNV-1a) of the bit patterns of every body's state that the GPUs couple:
/// centre, rotation, velocity, angular velocity and whether it moves, in body order. Equal
/// states give equal hashes on every machine.
pub(crate) fn state_hash(states: &[BodyState]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bits: u32| {
        for b in bits.to_le_bytes() {
            h ^= b as u64;
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    for s in states {
        let floats = s
            .center
            .to_array()
            .into_iter()
            .chain(s.rotation.to_cols_array())
            .chain(s.velocity.to_array())
            .chain(s.angular_velocity.to_array());
        for f in floats {
            eat(f.to_bits());
        }
        eat(s.dynamic as u32);
    }
    h
}

/// The check words of a process whose state hash is `hash`: for each 16-bit part x of the
/// hash, x and x^2 (exact in f64). Summed over n processes they give S1 = sum x and
/// S2 = sum x^2 for each part, from which [`ranks_agree`] decides.
pub(crate) fn check_words(hash: u64) -> [f64; CHECK_WORDS] {
    let mut w = [0.0; CHECK_WORDS];
    for (i, pair) in w.chunks_exact_mut(2).enumerate() {
        let x = ((hash >> (CHECK_BITS * i as u32)) & 0xffff) as f64;
        pair[0] = x;
        pair[1] = x * x;
    }
    w
}

/// True when the check words summed over `ranks` processes ([`check_words`]) come from one
/// hash: for each part, n S2 = S1^2, which by the Cauchy-Schwarz inequality
/// ((sum x)^2 <= n sum x^2, equal only when every x is the same) holds exactly when all n
/// parts are equal. Every term is an integer below 2^53 (n <= [`MAX_CHECK_RANKS`]), so the sums
/// are exact in any order and every process reaches the same answer from the same sums.
pub(crate) fn ranks_agree(summed: &[f64], ranks: usize) -> bool {
    summed.len() == CHECK_WORDS
        && summed
            .chunks_exact(2)
            .all(|p| ranks as f64 * p[1] == p[0] * p[0])
}

/// The bodies of one process of a run of several (one GPU each): the same world in every
/// process, advanced by the sums of every process's GPU ([`RankBodies::take`]).
pub(crate) struct RankBodies {
    bodies: SharedBodies,
    ranks: usize,
    /// Steps queued so far.
    steps: u64,
    /// The hash of the states of the coming step ([`RankBodies::coming`]).
    hash: u64,
    /// For each host copy: the step whose sums it holds (counted from this backend's start)
    /// and the hash of the states of that step.
    copies: [(u64, u64); 2],
}

impl RankBodies {
    /// The bodies of `scene` for a run of `ranks` processes (`None` without any; the same
    /// refusals as on one GPU, and more processes than the check decides).
    pub(crate) fn new(
        scene: &Scene,
        o: &CudaOptions,
        ranks: usize,
    ) -> Result<Option<RankBodies>, SimError> {
        let Some(bodies) = SharedBodies::new(scene, o)? else {
            return Ok(None);
        };
        if ranks > MAX_CHECK_RANKS {
            return Err(SimError::Backend(format!(
                "rigid bodies in a run of {ranks} processes: at most {MAX_CHECK_RANKS} processes \
                 check that their rapier worlds agree; run with fewer processes"
            )));
        }
        Ok(Some(RankBodies {
            bodies,
            ranks,
            steps: 0,
            hash: 0,
            copies: [(0, 0); 2],
        }))
    }

    /// The bodies' world (to set poses or gravity: every process the same).
    pub(crate) fn shared(&mut self) -> &mut SharedBodies {
        &mut self.bodies
    }

    /// The states the GPU couples in the coming step and the check words of them.
    pub(crate) fn coming(&mut self) -> (&[BodyState], [f64; CHECK_WORDS]) {
        let states = self.bodies.states();
        self.hash = state_hash(states);
        (states, check_words(self.hash))
    }

    /// The coming step was queued, its sums (summed over the processes) going to host copy
    /// `k`: the step whose sums the bodies take now, if any ([`SharedBodies::queued`]).
    pub(crate) fn queued(&mut self, k: usize, dt: f32) -> Option<(usize, f32)> {
        self.copies[k & 1] = (self.steps, self.hash);
        self.steps += 1;
        self.bodies.queued(k, dt)
    }

    /// The step whose sums are still to be taken (flushing), if any.
    pub(crate) fn take_pending(&mut self) -> Option<(usize, f32)> {
        self.bodies.take_pending()
    }

    /// Host copy `k` (`copy`: its words, summed over the processes: the sums' slots, then the
    /// check): when every process coupled the same states in its step, advance the world by
    /// `dt` with its sums; otherwise the error every process gives at this point.
    pub(crate) fn take(&mut self, k: usize, dt: f32, copy: &[f64]) -> Result<(), SimError> {
        let n = self.bodies.states().len();
        let at = BODY_EXCHANGE_SLOTS * n * 6;
        let (step, hash) = self.copies[k & 1];
        let check = copy.get(at..at + CHECK_WORDS).ok_or_else(|| {
            SimError::Backend(format!(
                "rigid bodies: {} words of impulse sums for {n} bodies",
                copy.len()
            ))
        })?;
        if !ranks_agree(check, self.ranks) {
            return Err(SimError::Backend(format!(
                "rigid bodies: the rapier worlds of the {} processes differ: the body states \
                 their GPUs coupled in step {} (counted from the start or resume of this run) \
                 are not the same (this process's state hash {hash:016x}). Every process must \
                 run the same rtmpm build, on the same kind of machine, with the same scene, \
                 checkpoint and options; otherwise run the scene in one process (--gpus N), on \
                 one GPU or on the CPU",
                self.ranks,
                step + 1
            )));
        }
        let sums = exchange_sums(&copy[..at], n);
        self.bodies.advance(&[sums], dt);
        Ok(())
    }
}

/// The run's one world, as every process holds it.
impl HeldBodies for RankBodies {
    fn states(&self) -> &[BodyState] {
        self.bodies.states()
    }

    fn poses(&self) -> Vec<BodyPose> {
        self.bodies.poses()
    }

    /// The loads of the sums summed over the processes: the same in every process.
    fn loads(&self) -> Vec<BodyLoad> {
        self.bodies.loads()
    }

    /// Every process is given the same (a checkpoint every one reads); sums not yet taken are
    /// dropped.
    fn set_poses(&mut self, poses: &[BodyPose]) -> Result<(), SimError> {
        self.bodies.set_poses(poses)
    }
}

/// Each body's impulse sums added over the GPUs, in rank order (the same sum for the same
/// sums).
pub(crate) fn sum_over_ranks(per_rank: &[Vec<Exchange>], bodies: usize) -> Vec<Exchange> {
    let mut out = vec![Exchange::default(); bodies];
    for rank in per_rank {
        for (o, e) in out.iter_mut().zip(rank) {
            *o = o.plus(e);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn body(center: glam::Vec3) -> BodyState {
        BodyState {
            shape: rtmpm_geometry::Shape::Box(rtmpm_geometry::shape::Cuboid::centred(
                glam::Vec3::ZERO,
                glam::Vec3::splat(0.1),
            )),
            rotation: glam::Mat3::from_rotation_y(0.3),
            center,
            velocity: glam::Vec3::new(0.0, -1.0, 0.5),
            angular_velocity: glam::Vec3::new(0.1, 0.0, 0.0),
            dynamic: true,
            condition: rtmpm_physics::boundary::Condition::Slip,
            friction: 0.0,
        }
    }

    /// The next float above `x` (one unit in the last place).
    fn ulp(x: f32) -> f32 {
        f32::from_bits(x.to_bits() + 1)
    }

    /// Equal states hash equally; one unit in the last place of any coupled field of any body,
    /// or the order of the bodies, changes the hash.
    #[test]
    fn the_state_hash_sees_every_coupled_field() {
        let a = vec![body(glam::Vec3::new(0.5, 0.4, 0.3)), body(glam::Vec3::ONE)];
        let h = state_hash(&a);
        assert_eq!(h, state_hash(&a.clone()));
        let changes: [fn(&mut BodyState); 5] = [
            |b| b.center.y = ulp(b.center.y),
            |b| b.rotation.z_axis.x = ulp(b.rotation.z_axis.x),
            |b| b.velocity.z = ulp(b.velocity.z),
            |b| b.angular_velocity.x = ulp(b.angular_velocity.x),
            |b| b.dynamic = false,
        ];
        for (i, change) in changes.iter().enumerate() {
            for k in 0..a.len() {
                let mut b = a.clone();
                change(&mut b[k]);
                assert_ne!(state_hash(&b), h, "change {i} of body {k}");
            }
        }
        let swapped = vec![a[1].clone(), a[0].clone()];
        assert_ne!(state_hash(&swapped), h);
    }

    /// The check words of the processes, summed as the all-reduce sums them (in f64, in any
    /// order).
    fn summed(hashes: &[u64]) -> Vec<f64> {
        let mut s = vec![0.0; CHECK_WORDS];
        for &h in hashes.iter().rev() {
            for (o, w) in s.iter_mut().zip(check_words(h)) {
                *o += w;
            }
        }
        s
    }

    /// From the summed check words alone: equal hashes agree, any difference does not, with
    /// 2 to MAX_CHECK_RANKS processes, including parts whose sum equals n times one of them
    /// (1, 2, 3: the mean is a part) and the largest parts at the most processes (exact).
    #[test]
    fn the_summed_check_words_tell_whether_every_hash_was_the_same() {
        let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        for ranks in [2, 3, 4, 7, 64, MAX_CHECK_RANKS] {
            for _ in 0..20 {
                let h = next();
                let mut all = vec![h; ranks];
                assert!(ranks_agree(&summed(&all), ranks), "{ranks}: {h:016x}");
                // One process differs, in one part or in one bit.
                let r = (next() as usize) % ranks;
                all[r] = next();
                assert!(!ranks_agree(&summed(&all), ranks), "{ranks}");
                all[r] = h ^ (1 << (next() % 64));
                assert!(!ranks_agree(&summed(&all), ranks), "{ranks}");
            }
        }
        // The mean of the parts is one of them: a sum alone would not tell.
        assert!(!ranks_agree(&summed(&[1, 2, 3]), 3));
        assert!(!ranks_agree(
            &summed(&[0x0001_0000, 0x0002_0000, 0x0003_0000]),
            3
        ));
        // The largest parts at the most processes stay exact.
        let max = u64::MAX;
        let mut all = vec![max; MAX_CHECK_RANKS];
        assert!(ranks_agree(&summed(&all), MAX_CHECK_RANKS));
        all[0] = max - 1;
        assert!(!ranks_agree(&summed(&all), MAX_CHECK_RANKS));
        all[0] = max ^ (1 << 63);
        assert!(!ranks_agree(&summed(&all), MAX_CHECK_RANKS));
        // The wrong number of words never agrees.
        assert!(!ranks_agree(&summed(&[7, 7])[..6], 2));
    }

    /// A scene with two bodies falling (a box and a ball).
    #[cfg(feature = "rigid")]
    fn scene() -> Scene {
        Scene::from_toml(
            "[domain]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\ndx = 0.05\n[time]\nduration = 1\n\
             [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000.0\n\
             bulk_modulus = 1e4\n[[body]]\nmaterial = \"w\"\nshape = \"box\"\n\
             min = [0.2, 0.2, 0.2]\nmax = [0.4, 0.4, 0.4]\n\
             [[rigid_body]]\nname = \"a\"\nshape = \"box\"\nmin = [0.4, 0.5, 0.4]\n\
             max = [0.6, 0.6, 0.6]\ndensity = 500\n\
             [[rigid_body]]\nname = \"b\"\nshape = \"sphere\"\ncenter = [0.25, 0.7, 0.7]\n\
             radius = 0.1\ndensity = 800\n",
            "ranks",
        )
        .unwrap_or_else(|e| panic!("{e}"))
    }

    /// One step of the processes `procs` as `NcclRankBackend::step` and the GPUs' all-reduce
    /// run it: each process's states and check, each GPU's partial sums (`partial(rank, word)`
    /// for every word of the slots) and the checks summed over the processes into host copy
    /// `k` (`copies`: the host copies, the same in every process after the all-reduce), then
    /// each process queues the step and takes what is due from its copy. Returns each
    /// process's result of taking.
    #[cfg(feature = "rigid")]
    fn step(
        procs: &mut [RankBodies],
        copies: &mut [Vec<f64>; 2],
        k: usize,
        partial: impl Fn(usize, usize) -> f64,
    ) -> Vec<Result<(), String>> {
        let n = procs[0].states().len();
        let at = BODY_EXCHANGE_SLOTS * n * 6;
        let mut sum = vec![0.0; at + CHECK_WORDS];
        for (r, p) in procs.iter_mut().enumerate() {
            let (_, check) = p.coming();
            for (i, w) in sum[..at].iter_mut().enumerate() {
                *w += partial(r, i);
            }
            for (o, w) in sum[at..].iter_mut().zip(check) {
                *o += w;
            }
        }
        copies[k] = sum;
        procs
            .iter_mut()
            .map(|p| match p.queued(k, 1e-3) {
                Some((q, dt)) => p.take(q, dt, &copies[q]).map_err(|e| e.to_string()),
                None => Ok(()),
            })
            .collect()
    }

    /// Processes that take the same summed copies keep identical worlds (bit for bit), with
    /// and without rigid_overlap; when one process's world differs, every process refuses the
    /// step's sums with the same error, at the same step.
    #[cfg(feature = "rigid")]
    #[test]
    fn processes_given_the_same_sums_keep_one_world_and_stop_together_when_not() {
        let scene = scene();
        for options in ["", "rigid_overlap=off"] {
            let o: CudaOptions = options.parse().expect("options");
            let mut procs: Vec<RankBodies> = (0..3)
                .map(|_| {
                    RankBodies::new(&scene, &o, 3)
                        .expect("bodies")
                        .expect("some")
                })
                .collect();
            let mut copies = [Vec::new(), Vec::new()];
            let start = procs[0].poses();
            // Each GPU pushes the bodies a little, differently (upwards: against gravity).
            let push = |r: usize, i: usize| {
                if i % 6 == 1 {
                    1e-5 * (r + 1) as f64
                } else {
                    0.0
                }
            };
            for s in 0..40 {
                let res = step(&mut procs, &mut copies, s % 2, push);
                assert!(res.iter().all(Result::is_ok), "{options} step {s}: {res:?}");
                let h = state_hash(procs[0].states());
                assert!(
                    procs.iter().all(|p| state_hash(p.states()) == h),
                    "{options}"
                );
            }
            // A frame end: the sums still pending (the last step's, with overlap) are taken.
            for p in procs.iter_mut() {
                if let Some((k, dt)) = p.take_pending() {
                    assert!(o.rigid_overlap, "nothing pends without overlap");
                    assert_eq!(p.copies[k].0, 39, "the last step pends");
                    p.take(k, dt, &copies[k]).expect("flush");
                }
            }
            let poses: Vec<_> = procs.iter().map(RankBodies::poses).collect();
            assert!(poses.iter().all(|p| p == &poses[0]), "{options}");
            // The bodies moved: the box fell.
            assert!(
                poses[0][0].position.y < start[0].position.y - 1e-3,
                "{options}"
            );
            // Process 2's world moves by a hair: every process refuses the next sums.
            let mut moved = procs[2].poses();
            moved[1].position.x = ulp(moved[1].position.x);
            procs[2].shared().set_poses(&moved).expect("poses");
            let mut res = step(&mut procs, &mut copies, 0, push);
            if o.rigid_overlap {
                // Nothing due yet: the step's sums are taken at the next step.
                assert!(res.iter().all(Result::is_ok), "{res:?}");
                res = step(&mut procs, &mut copies, 1, push);
            }
            for r in &res {
                let e = r.as_ref().expect_err("the worlds differ");
                assert!(
                    e.contains("the rapier worlds of the 3 processes differ")
                        && e.contains("in step 41"),
                    "{options}: {e}"
                );
            }
        }
    }

    /// A kinematic tool and a dynamic ball above water.
    #[cfg(feature = "rigid")]
    fn tool_scene() -> Scene {
        Scene::from_toml(
            "[domain]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\ndx = 0.05\n[time]\nduration = 1\n\
             [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000.0\n\
             bulk_modulus = 1e4\n[[body]]\nmaterial = \"w\"\nshape = \"box\"\n\
             min = [0.2, 0.2, 0.2]\nmax = [0.4, 0.4, 0.4]\n\
             [[rigid_body]]\nname = \"tool\"\nshape = \"box\"\nmin = [0.4, 0.5, 0.4]\n\
             max = [0.6, 0.6, 0.6]\ndensity = 500\ntype = \"kinematic\"\n\
             velocity = [0.0, -0.5, 0.0]\n\
             [[rigid_body]]\nname = \"ball\"\nshape = \"sphere\"\ncenter = [0.25, 0.7, 0.7]\n\
             radius = 0.1\ndensity = 800\n",
            "tool",
        )
        .unwrap_or_else(|e| panic!("{e}"))
    }

    /// Several GPUs of one process: the world takes the sum of every GPU's sums, and that sum
    /// over the step's dt is every body's load, the kinematic tool's too, which the sums do
    /// not move (it goes where a world given no sums puts it); zeros before the first step;
    /// the ball, dynamic, is moved by them.
    #[cfg(feature = "rigid")]
    #[test]
    fn the_gpus_summed_sums_are_every_bodys_load() {
        use crate::step::rigid::HeldBodies;
        let scene = tool_scene();
        let o = CudaOptions::default();
        let mut b = SharedBodies::new(&scene, &o)
            .expect("bodies")
            .expect("some");
        let mut alone = SharedBodies::new(&scene, &o)
            .expect("bodies")
            .expect("some");
        assert_eq!(b.loads(), vec![BodyLoad::default(); 2]);
        let e = |i: f64, t: f64| Exchange {
            impulse: [0.0, i, 0.5 * i],
            torque: [t, 0.0, 0.0],
        };
        let dt = 1e-3_f32;
        // Two GPUs, each with a share of both bodies' reactions.
        let per_rank = vec![
            vec![e(0.25, 0.01), e(0.5, 0.0)],
            vec![e(0.75, 0.03), e(0.25, 0.0)],
        ];
        b.advance(&per_rank, dt);
        alone.advance(&[vec![Exchange::default(); 2]], dt);
        let l = b.loads();
        let dt = dt as f64;
        let near = |a: [f64; 3], w: [f64; 3]| a.iter().zip(w).all(|(x, y)| (x - y).abs() < 1e-9);
        assert!(near(l[0].force, [0.0, 1.0 / dt, 0.5 / dt]), "{l:?}");
        assert!(near(l[0].torque, [0.04 / dt, 0.0, 0.0]), "{l:?}");
        assert!(near(l[1].force, [0.0, 0.75 / dt, 0.375 / dt]), "{l:?}");
        assert_eq!(
            b.poses()[0],
            alone.poses()[0],
            "the tool is not moved by its load"
        );
        assert!(
            b.poses()[1].velocity.y > alone.poses()[1].velocity.y,
            "the ball is pushed up by its impulse"
        );
    }

    /// One process per GPU: every process reports the same loads, those of the copy summed
    /// over the processes (the kinematic tool's with the ball's).
    #[cfg(feature = "rigid")]
    #[test]
    fn every_process_reports_the_loads_of_the_summed_sums() {
        use crate::step::rigid::HeldBodies;
        let scene = tool_scene();
        let o: CudaOptions = "rigid_overlap=off".parse().expect("options");
        let mut procs: Vec<RankBodies> = (0..2)
            .map(|_| {
                RankBodies::new(&scene, &o, 2)
                    .expect("bodies")
                    .expect("some")
            })
            .collect();
        let mut copies = [Vec::new(), Vec::new()];
        // Each GPU pushes the tool (body 0) up: word 1 of body 0 in every slot.
        let push = |r: usize, i: usize| {
            if i % 12 == 1 {
                1e-6 * (r + 1) as f64
            } else {
                0.0
            }
        };
        let res = step(&mut procs, &mut copies, 0, push);
        assert!(res.iter().all(Result::is_ok), "{res:?}");
        let (a, b) = (procs[0].loads(), procs[1].loads());
        assert_eq!(a, b, "the processes' loads");
        // The step's dt, 1e-3 in f32.
        let want = 3e-6 * BODY_EXCHANGE_SLOTS as f64 / (1e-3_f32 as f64);
        assert!((a[0].force[1] - want).abs() < 1e-9 * want, "{a:?}");
        assert_eq!(a[1], BodyLoad::default(), "{a:?}");
    }

    #[test]
    fn the_ranks_sums_add_up_body_by_body() {
        let e = |i: f64, t: f64| Exchange {
            impulse: [i, 0.0, -i],
            torque: [0.0, t, 0.0],
        };
        // Two bodies, three GPUs; the third GPU holds none of body 1's nodes.
        let per_rank = vec![
            vec![e(1.0, 0.5), e(2.0, 0.0)],
            vec![e(0.25, 0.5), e(-1.0, 1.0)],
            vec![e(0.0, 0.0), e(0.0, 0.0)],
        ];
        let s = sum_over_ranks(&per_rank, 2);
        assert_eq!(s[0], e(1.25, 1.0));
        assert_eq!(s[1], e(1.0, 1.0));
        // A shared node's reaction r split 1/k on each of its k GPUs adds up to r once.
        let r = 0.3_f64;
        for k in 2..=8 {
            let per_rank: Vec<Vec<Exchange>> = (0..k).map(|_| vec![e(r / k as f64, 0.0)]).collect();
            let s = sum_over_ranks(&per_rank, 1);
            assert!((s[0].impulse[0] - r).abs() < 1e-15, "{k}: {:?}", s[0]);
        }
    }
}
