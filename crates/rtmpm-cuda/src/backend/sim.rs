//! [`CudaBackend`] as the simulation's [`Backend`]: a step, the health check, particles in and
//! out, rigid-body poses, frame export.

use super::*;

impl Backend for CudaBackend {
    fn name(&self) -> String {
        if self.options.f64 {
            format!("cuda ({}, f64)", self.device_name)
        } else {
            format!("cuda ({})", self.device_name)
        }
    }

    fn num_particles(&self) -> usize {
        self.n
    }

    fn step(&mut self, dt: f32, t: f32) -> Result<(), SimError> {
        self.upload_params(dt, t)?;
        self.run_step(dt, &mut NoHooks, true)
    }

    fn max_speed(&mut self) -> Result<f32, SimError> {
        let c = self.ctl_words()?;
        self.error_check(&c)?;
        Ok(f32::from_bits(c[crate::contract::CTL_MAX_SPEED]))
    }

    fn check(&mut self) -> Result<Option<BadParticle>, SimError> {
        use crate::contract::{CTL_BAD_INDEX, CTL_BAD_REASON};
        let c = self.ctl_words()?;
        self.error_check(&c)?;
        if c[CTL_BAD_INDEX] == u32::MAX {
            return Ok(None);
        }
        let reset = [u32::MAX, 0];
        let mut view = self.buffers.ctl.slice_mut(CTL_BAD_INDEX..CTL_BAD_INDEX + 2);
        self.stream
            .memcpy_htod(&reset, &mut view)
            .map_err(err("reset bad particle"))?;
        let reason = if c[CTL_BAD_REASON] == 1 {
            BadReason::NonFinite
        } else {
            BadReason::TooFast
        };
        Ok(Some(BadParticle {
            index: c[CTL_BAD_INDEX] as usize,
            reason,
        }))
    }

    fn add_particles(&mut self, particles: &Particles) -> Result<(), SimError> {
        self.append_particles(particles)
    }

    fn read_particles(&mut self, out: &mut Particles) -> Result<(), SimError> {
        let host = self
            .stream
            .clone_dtoh(&self.buffers.state)
            .map_err(err("read particles"))?;
        crate::state::unpack(
            &host,
            self.n,
            self.ctx.cap as usize,
            self.layout,
            self.options.f64,
            out,
        )
        .map_err(SimError::Backend)
    }

    fn memory_bytes(&self) -> Option<(u64, u64)> {
        Some((0, self.device_bytes() as u64))
    }

    fn rigid_bodies(&self) -> Vec<rtmpm_core::rigid::BodyState> {
        self.bodies
            .as_ref()
            .map_or_else(Vec::new, |b| b.states().to_vec())
    }

    fn rigid_poses(&self) -> Vec<rtmpm_core::rigid::BodyPose> {
        self.bodies.as_ref().map_or_else(Vec::new, |b| b.poses())
    }

    fn flush_rigid(&mut self) -> Result<(), SimError> {
        match self.bodies.as_mut() {
            Some(b) => b.flush(),
            None => Ok(()),
        }
    }

    fn set_rigid_poses(&mut self, poses: &[rtmpm_core::rigid::BodyPose]) -> Result<(), SimError> {
        match self.bodies.as_mut() {
            Some(b) => b.set_poses(poses),
            None if poses.is_empty() => Ok(()),
            None => Err(SimError::Backend(format!(
                "{} rigid-body states for a scene without rigid bodies",
                poses.len()
            ))),
        }
    }

    /// The bodies take the impulses of the frame's last step (with `rigid_overlap` they are
    /// a step behind): at a frame's end they are where the CPU backend's would be.
    fn end_of_frame(&mut self) -> Result<(), SimError> {
        self.flush_rigid()
    }

    fn export_frame(&mut self, sink: &mut dyn rtmpm_core::sim::ChunkSink) -> Result<(), SimError> {
        self.export_chunks(sink)
    }

    fn setup_details(&self) -> Option<String> {
        Some(self.setup.to_string())
    }

    fn chunk_memory(&self, words: usize) -> Result<Box<dyn rtmpm_core::sim::HostBuffer>, SimError> {
        Ok(Box::new(self.chunk_host_memory(words)?))
    }
}
