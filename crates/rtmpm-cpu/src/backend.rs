//! The CPU backend behind the backend interface ([`Backend`]).

use crate::state::CpuBackend;
use physics::math::Real;
use physics::real;
use rtmpm_sim as sim;
use rtmpm_sim::{Backend, BadParticle, SimError};

impl Backend for CpuBackend {
    fn name(&self) -> String {
        match real::PRECISION {
            "f32" => format!("cpu ({} threads)", self.threads()),
            p => format!("cpu ({} threads, {p})", self.threads()),
        }
    }

    fn num_particles(&self) -> usize {
        self.particles.len()
    }

    fn step(&mut self, dt: f32, t: f32) -> Result<(), SimError> {
        let dt = real::real(dt);
        match self.pool.take() {
            Some(pool) => {
                pool.install(|| self.step_inner(dt, t));
                self.pool = Some(pool);
            }
            None => self.step_inner(dt, t),
        }
        Ok(())
    }

    fn max_speed(&mut self) -> Result<f32, SimError> {
        Ok(real::to_f32(self.max_speed))
    }

    fn check(&mut self) -> Result<Option<BadParticle>, SimError> {
        Ok(self.bad)
    }

    fn read_particles(&mut self, out: &mut sim::Particles) -> Result<(), SimError> {
        // Back to the original order, and to the interface's f32.
        let p = &self.particles;
        let n = p.len();
        out.x.resize(n, Default::default());
        out.v.resize(n, Default::default());
        out.c.resize(n, Default::default());
        out.f.resize(n, Default::default());
        out.plastic.resize(n, 0.0);
        out.mass.resize(n, 0.0);
        out.vol0.resize(n, 0.0);
        out.material.resize(n, 0);
        for (i, &id) in self.ids.iter().enumerate() {
            let id = id as usize;
            out.x[id] = real::vec3_to_f32(p.x[i]);
            out.v[id] = real::vec3_to_f32(p.v[i]);
            out.c[id] = real::mat3_to_f32(p.c[i]);
            out.f[id] = real::mat3_to_f32(p.f[i]);
            out.plastic[id] = real::to_f32(p.plastic[i]);
            out.mass[id] = real::to_f32(p.mass[i]);
            out.vol0[id] = real::to_f32(p.vol0[i]);
            out.material[id] = p.material[i];
        }
        Ok(())
    }

    fn export_frame(&mut self, sink: &mut dyn sim::ChunkSink) -> Result<(), SimError> {
        // Gathered chunk by chunk through the inverse of the storage order (4 bytes a particle)
        // rather than a copy of every particle.
        let slot = sim::invert_ids(&self.ids)?;
        let p = &self.particles;
        sim::fill_chunks(slot.len(), sink, |id, cols| {
            let i = slot[id] as usize;
            let mut r = rtmpm_io::chunks::ParticleRow {
                x: real::vec3_to_f32(p.x[i]).to_array(),
                ..Default::default()
            };
            if cols.v {
                r.v = real::vec3_to_f32(p.v[i]).to_array();
            }
            if cols.material {
                r.material = p.material[i];
            }
            if cols.plastic {
                r.plastic = real::to_f32(p.plastic[i]);
            }
            if cols.mass {
                r.mass = real::to_f32(p.mass[i]);
            }
            if cols.vol0 {
                r.vol0 = real::to_f32(p.vol0[i]);
            }
            if cols.f {
                r.f = real::mat3_to_f32(p.f[i]).to_cols_array();
            }
            if cols.c {
                r.c = real::mat3_to_f32(p.c[i]).to_cols_array();
            }
            r
        })
    }

    fn cheap_check(&self) -> bool {
        true
    }

    fn memory_bytes(&self) -> Option<(u64, u64)> {
        fn cap<T>(v: &Vec<T>) -> usize {
            v.capacity() * std::mem::size_of::<T>()
        }
        let (p, s) = (&self.particles, &self.scratch);
        let bytes = cap(&p.x)
            + cap(&p.v)
            + cap(&p.c)
            + cap(&p.f)
            + cap(&p.plastic)
            + cap(&p.mass)
            + cap(&p.vol0)
            + cap(&p.material)
            + cap(&self.ids)
            + cap(&s.vec3)
            + cap(&s.mat3)
            + cap(&s.real)
            + cap(&s.word)
            + cap(&self.bases)
            + cap(&self.grid)
            + cap(&self.grid_dual)
            + cap(&self.grid_aux)
            + self.colours.iter().map(cap).sum::<usize>()
            + self.layout.memory_bytes();
        Some((bytes as u64, 0))
    }

    fn rigid_bodies(&self) -> Vec<rtmpm_rigid::BodyState> {
        self.rigid
            .as_ref()
            .map_or_else(Vec::new, |w| w.states().to_vec())
    }

    fn rigid_poses(&self) -> Vec<rtmpm_rigid::BodyPose> {
        self.rigid.as_ref().map_or_else(Vec::new, |w| w.poses())
    }

    fn rigid_loads(&self) -> Option<Vec<rtmpm_rigid::BodyLoad>> {
        let n = self.rigid.as_ref().map_or(0, |w| w.states().len());
        let (exchange, dt) = &self.last_exchange;
        if exchange.len() != n {
            // Before the first step: no load yet.
            return Some(vec![rtmpm_rigid::BodyLoad::default(); n]);
        }
        Some(exchange.iter().map(|e| e.load(*dt)).collect())
    }

    fn set_rigid_poses(&mut self, poses: &[rtmpm_rigid::BodyPose]) -> Result<(), SimError> {
        match self.rigid.as_mut() {
            Some(w) => w.set_poses(poses).map_err(SimError::Backend),
            None if poses.is_empty() => Ok(()),
            None => Err(SimError::Backend(format!(
                "{} rigid-body states for a scene without rigid bodies",
                poses.len()
            ))),
        }
    }

    fn add_particles(&mut self, p: &sim::Particles) -> Result<(), SimError> {
        // The next original indices; the next step's rebuild sorts them in.
        let first = self.ids.len();
        if first + p.len() > u32::MAX as usize {
            return Err(SimError::Backend(format!(
                "{} particles exceed the CPU backend's 2^32 - 1 (emitters): lower their rates",
                first + p.len()
            )));
        }
        let add = physics::convert::particles(p.clone());
        let fastest = add.v.iter().map(|v| v.length()).fold(0.0, Real::max);
        self.max_speed = self.max_speed.max(fastest);
        self.particles.extend(&add);
        self.ids.extend(first as u32..(first + p.len()) as u32);
        // Stored at the end: re-sort the storage at the next step (locality only; P2G's sum
        // order comes from the layout, whatever the storage order).
        self.since_sort = u32::MAX;
        Ok(())
    }

    fn set_gravity(&mut self, gravity: glam::Vec3) -> Result<(), SimError> {
        if !gravity.is_finite() {
            return Err(SimError::Backend(format!(
                "gravity must be finite, got {gravity}"
            )));
        }
        self.consts.gravity = real::vec3(gravity);
        if let Some(w) = self.rigid.as_mut() {
            w.set_gravity(gravity);
        }
        Ok(())
    }

    fn set_tool(&mut self, tool: Option<rtmpm_geometry::Tool>) -> Result<(), SimError> {
        if let Some(t) = &tool {
            t.check().map_err(SimError::Backend)?;
        }
        self.consts.tool = tool;
        Ok(())
    }

    fn stage_times(&self) -> Vec<(&'static str, f64)> {
        ["rebuild", "p2g", "grid_update", "g2p"]
            .into_iter()
            .zip(self.stage_seconds)
            .collect()
    }
}
