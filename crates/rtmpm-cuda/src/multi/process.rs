//! One process per GPU, on any number of machines ([`NcclRankBackend`]), meeting through a
//! [`super::rendezvous::Rendezvous`]; the GPUs sum their shared blocks through NCCL. Rigid
//! bodies: the same rapier world in every process, advanced by the impulse sums of every
//! process's GPU, summed through NCCL with a check that the worlds agree ([`super::rigid`]).

use super::nccl::UniqueId;
use super::partition::split;
use super::plan::{check_supported, combine, dense_count, plan, shared_capacity, subset};
use super::rank::{CommSource, GpuRank};
use super::rigid::RankBodies;
use crate::backend::Part;
use crate::backend::readback::{resize_particles, scatter_state};
use crate::contract::{CTL_BAD_INDEX, CTL_MAX_SPEED, CTL_SHARED};
use crate::options::{CudaOptions, ExchangeMode, Transport};
use crate::step::rigid::{loads_of, poses_of, set_poses_of, states_of};
use rtmpm_physics::Particles;
use rtmpm_scene::Scene;
use rtmpm_sim::{Backend, BadParticle, SimError};

fn nccl_err(e: String) -> SimError {
    SimError::Backend(e)
}

fn rank(r: &mut Option<GpuRank>) -> Result<&mut GpuRank, SimError> {
    r.as_mut()
        .ok_or_else(|| SimError::Backend("GPU rank missing".into()))
}

/// This process's GPU in a run of several processes (one per GPU, any number of machines).
/// Every process runs the same driver loop; max speed, bad particles and particle read-back are
/// NCCL collectives, so every process calls them at the same points (they do: the same scene and
/// the same time steps everywhere).
pub struct NcclRankBackend {
    rank: Option<GpuRank>,
    scene: Scene,
    options: CudaOptions,
    me: usize,
    ranks: usize,
    device: usize,
    counts: Vec<usize>,
    n: usize,
    name: String,
    shared_cap: usize,
    shared_at_partition: usize,
    d: usize,
    /// Rebalances done so far.
    pub rebalances: u32,
    /// The user's tool (given again to a rank rebuilt by a rebalance).
    tool: Option<rtmpm_geometry::Tool>,
    /// Rigid bodies (`[[rigid_body]]`): this process's copy of the run's one world.
    bodies: Option<RankBodies>,
}

impl NcclRankBackend {
    /// Join the run as rank `me` of `ranks` on CUDA device `device`; `particles` are all the
    /// particles of the scene (every process samples the same ones).
    pub fn new(
        scene: &Scene,
        particles: &Particles,
        me: usize,
        ranks: usize,
        device: usize,
        rendezvous: &super::rendezvous::Rendezvous,
        options: CudaOptions,
    ) -> Result<NcclRankBackend, SimError> {
        check_supported(scene, &options)?;
        if me >= ranks {
            return Err(SimError::Backend(format!(
                "--nccl-rank {me} must be below --nccl-ranks {ranks}"
            )));
        }
        if options.transport == Some(Transport::P2p)
            || options.barrier.is_some()
            || options.devices.is_some()
        {
            return Err(SimError::Backend(
                "transport=p2p, barrier= and devices= need the GPUs in one process (--gpus N); runs \
                 of several processes use NCCL, one device each"
                    .into(),
            ));
        }
        if let Some(mode) = options.exchange.filter(|&m| m != ExchangeMode::Kernels) {
            return Err(SimError::Backend(format!(
                "exchange={} needs the GPUs in one process (--gpus N) with transport=p2p; runs \
                 of several processes use NCCL: use exchange=kernels",
                super::exchange::mode_name(mode)
            )));
        }
        // The bodies' world before any GPU work (its refusals are clear errors).
        let bodies = RankBodies::new(scene, &options, ranks)?;
        let nccl = super::nccl::library()
            .map_err(|e| SimError::Backend(format!("multi-process runs need NCCL: {e}")))?;
        let info = crate::probe::probe_device(device)
            .map_err(|e| SimError::Backend(format!("rank {me}: CUDA device {device}: {e}")))?;
        let id = if me == 0 {
            Some(nccl.unique_id().map_err(nccl_err)?.to_bytes())
        } else {
            None
        };
        let id = rendezvous.exchange(me, ranks, id).map_err(nccl_err)?;
        let mut b = NcclRankBackend {
            rank: None,
            scene: scene.clone(),
            options,
            me,
            ranks,
            device,
            counts: Vec::new(),
            n: particles.len(),
            name: format!(
                "cuda rank {me}/{ranks} on device {device} ({}, NCCL {})",
                info.name, nccl.version
            ),
            shared_cap: 0,
            shared_at_partition: 0,
            d: dense_count(scene),
            rebalances: 0,
            tool: None,
            bodies,
        };
        b.load(
            particles,
            CommSource::New {
                id: UniqueId::from_bytes(&id),
                rank: me,
                ranks,
            },
        )?;
        Ok(b)
    }

    /// Partition every particle (the same on every rank) and build this rank's share; every rank
    /// gets the capacity of the largest share, so that the state arrays can be all-gathered.
    fn load(&mut self, particles: &Particles, comm: CommSource) -> Result<(), SimError> {
        let part = split(&particles.x, self.ranks, self.options.partition);
        let (cap, s) = shared_capacity(&self.scene, particles, &part, &self.options);
        self.shared_cap = cap.max(self.shared_cap.min(self.d));
        self.shared_at_partition = s;
        self.counts = part.parts.iter().map(Vec::len).collect();
        let ids = &part.parts[self.me];
        let p = Part {
            device: self.device,
            ids: Some(ids.clone()),
            capacity: part.max_len(),
        };
        let mut rank = GpuRank::new(
            &self.scene,
            &subset(particles, ids),
            &p,
            self.options.clone(),
            self.shared_cap,
            comm,
        )?;
        if self.tool.is_some() {
            rank.b.set_tool(self.tool)?;
        }
        self.rank = Some(rank);
        Ok(())
    }

    fn r(&mut self) -> Result<&mut GpuRank, SimError> {
        rank(&mut self.rank)
    }

    /// This process's rank.
    pub fn rank(&self) -> usize {
        self.me
    }

    /// Re-partition the particles now (collective: every process calls it at the same point;
    /// gathers every particle, re-splits them and rebuilds this process's rank; synchronises).
    /// The bodies first take the sums the old rank holds.
    pub fn rebalance_now(&mut self) -> Result<(), SimError> {
        self.flush_rigid()?;
        let c = self.r()?.ctl()?;
        let speed = f32::from_bits(c[CTL_MAX_SPEED]);
        let speed = self.max_speed()?.max(speed);
        let mut all = Particles::default();
        self.read_particles(&mut all)?;
        let old = self.rank.take();
        let comm = old
            .and_then(GpuRank::into_comm)
            .ok_or_else(|| SimError::Backend("no communicator".into()))?;
        self.load(&all, CommSource::Existing(comm))?;
        self.r()?.b.set_ctl_word(CTL_MAX_SPEED, speed.to_bits())?;
        self.rebalances += 1;
        Ok(())
    }

    /// Give the bodies the run's sums of host copy `k` (summed over the processes) and advance
    /// them by `dt`, after the check that every process coupled the same states.
    fn take_bodies(&mut self, k: usize, dt: f32) -> Result<(), SimError> {
        let copy = rank(&mut self.rank)?.body_copy_words(k)?;
        match self.bodies.as_mut() {
            Some(b) => b.take(k, dt, &copy),
            None => Ok(()),
        }
    }
}

impl Backend for NcclRankBackend {
    fn name(&self) -> String {
        self.name.clone()
    }

    fn num_particles(&self) -> usize {
        self.n
    }

    /// One step; with rigid bodies, the world's states of now go up with it and its impulse
    /// sums (summed over the processes on the device) are taken now or, with
    /// `rigid_overlap`, at the next step ([`super::rigid::RankBodies`]).
    fn step(&mut self, dt: f32, t: f32) -> Result<(), SimError> {
        let r = rank(&mut self.rank)?;
        let Some(bodies) = self.bodies.as_mut() else {
            return r.step(dt, t);
        };
        let (states, check) = bodies.coming();
        r.set_body_states(states);
        r.set_body_check(check);
        r.step(dt, t)?;
        let due = r.body_copy().and_then(|k| bodies.queued(k, dt));
        match due {
            Some((k, dt)) => self.take_bodies(k, dt),
            None => Ok(()),
        }
    }

    fn max_speed(&mut self) -> Result<f32, SimError> {
        let r = self.r()?;
        let c = r.gather_ctl()?;
        Ok(combine(&r.b, &c)?.0)
    }

    fn check(&mut self) -> Result<Option<BadParticle>, SimError> {
        let r = self.r()?;
        let c = r.gather_ctl()?;
        let (_, bad) = combine(&r.b, &c)?;
        let me = r.x.comm()?.rank;
        if c[me][CTL_BAD_INDEX] != u32::MAX {
            r.b.check()?;
        }
        Ok(bad)
    }

    /// Gravity of this rank's GPU and of the bodies (every rank of the run is given the same).
    fn set_gravity(&mut self, gravity: rtmpm_physics::math::Vec3) -> Result<(), SimError> {
        self.r()?.b.set_gravity(gravity)?;
        if let Some(b) = self.bodies.as_mut() {
            b.shared().set_gravity(gravity);
        }
        self.scene.gravity = gravity;
        Ok(())
    }

    fn rigid_bodies(&self) -> Vec<rtmpm_rigid::BodyState> {
        states_of(self.bodies.as_ref())
    }

    fn rigid_poses(&self) -> Vec<rtmpm_rigid::BodyPose> {
        poses_of(self.bodies.as_ref())
    }

    /// Every body's load over the last step the bodies took, summed over the GPUs (kinematic
    /// and fixed bodies too; with `rigid_overlap`, the last step's after
    /// [`Backend::flush_rigid`]), as on one GPU.
    fn rigid_loads(&self) -> Option<Vec<rtmpm_rigid::BodyLoad>> {
        loads_of(self.bodies.as_ref())
    }

    /// The sums still pending (`rigid_overlap`): already summed over the processes on the
    /// device, so this only waits for this process's copy (every process must still call it at
    /// the same points, as the driver does: their worlds must take the same steps).
    fn flush_rigid(&mut self) -> Result<(), SimError> {
        match self.bodies.as_mut().and_then(RankBodies::take_pending) {
            Some((k, dt)) => self.take_bodies(k, dt),
            None => Ok(()),
        }
    }

    /// The bodies at `poses` (every process is given the same: a checkpoint every one reads).
    fn set_rigid_poses(&mut self, poses: &[rtmpm_rigid::BodyPose]) -> Result<(), SimError> {
        set_poses_of(self.bodies.as_mut(), poses)
    }

    /// The tool on this rank's GPU (every rank of the run is given the same).
    fn set_tool(&mut self, tool: Option<rtmpm_geometry::Tool>) -> Result<(), SimError> {
        self.r()?.b.set_tool(tool)?;
        self.tool = tool;
        Ok(())
    }

    fn read_particles(&mut self, out: &mut Particles) -> Result<(), SimError> {
        let counts = self.counts.clone();
        let n = self.n;
        let r = self.r()?;
        let cap = r.b.ctx.cap as usize;
        let layout = r.b.state_layout();
        let all = r.gather_state()?;
        *out = Particles::default();
        resize_particles(out, n);
        let per = layout.words() * cap;
        for (k, &count) in counts.iter().enumerate() {
            scatter_state(&all[k * per..(k + 1) * per], count, cap, layout, out)?;
        }
        Ok(())
    }

    /// The bodies take the impulses of the frame's last step (as on one GPU), then the
    /// reduction grows or the particles are re-partitioned where the plan says so.
    fn end_of_frame(&mut self) -> Result<(), SimError> {
        self.flush_rigid()?;
        let c = self.r()?.ctl()?;
        let shared = c[CTL_SHARED] as usize;
        let p = plan(
            shared,
            self.shared_cap,
            self.d,
            self.shared_at_partition,
            self.ranks,
            &self.options,
        );
        if p.rebalance {
            self.rebalance_now()?;
        } else if let Some(cap) = p.grow_to {
            self.shared_cap = cap;
            self.r()?.set_shared_capacity(cap)?;
        }
        Ok(())
    }
}
