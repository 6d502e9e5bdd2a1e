//! One step of the CPU backend: the four stages in order (MUSL adds a re-map), the rigid
//! bodies advanced with the grid's impulses, the stage times.

use crate::state::CpuBackend;
use crate::{g2p, grid_update, p2g, rebuild};
use physics::math::Real;
use physics::real;
use physics::transfer::{Transfer, Update};

impl CpuBackend {
    /// Give the rigid bodies the step's impulses and advance them by `dt` (their new pose is
    /// the next step's boundary).
    fn advance_bodies(&mut self, exchange: Vec<rtmpm_rigid::Exchange>, dt: Real) {
        if let Some(w) = self.rigid.as_mut() {
            w.advance(&exchange, real::to_f32(dt));
        }
        self.last_exchange = (exchange, real::to_f32(dt) as f64);
    }

    pub(crate) fn step_inner(&mut self, dt: Real, t: f32) {
        let t0 = std::time::Instant::now();
        rebuild::rebuild(self);
        let t1 = std::time::Instant::now();
        let solver = self.consts.solver;
        let (max_speed, bad, t2, t3);
        if solver.transfer == Transfer::CkMpm {
            p2g::p2g_ck(self, dt);
            t2 = std::time::Instant::now();
            let exchange = grid_update::grid_update(self, dt, t);
            self.advance_bodies(exchange, dt);
            t3 = std::time::Instant::now();
            (max_speed, bad) = g2p::g2p_ck(self, dt);
        } else if solver.transfer == Transfer::Mls {
            p2g::p2g(self, dt);
            t2 = std::time::Instant::now();
            let exchange = grid_update::grid_update(self, dt, t);
            self.advance_bodies(exchange, dt);
            t3 = std::time::Instant::now();
            (max_speed, bad) = g2p::g2p(self, dt);
        } else {
            p2g::p2g_mpm(self, dt);
            t2 = std::time::Instant::now();
            let exchange = grid_update::grid_update(self, dt, t);
            self.advance_bodies(exchange, dt);
            t3 = std::time::Instant::now();
            let musl = solver.update == Update::Musl;
            if musl {
                // MUSL (Sulsky et al. 1995): new particle velocities, their momenta mapped to
                // the grid again, then the velocity gradient from that grid.
                g2p::g2p_mpm_velocity(self);
                p2g::p2g_musl(self);
                grid_update::grid_update_musl(self, t);
            }
            (max_speed, bad) = g2p::g2p_mpm(self, dt, musl);
        }
        let t4 = std::time::Instant::now();
        for (acc, (a, b)) in
            self.stage_seconds
                .iter_mut()
                .zip([(t0, t1), (t1, t2), (t2, t3), (t3, t4)])
        {
            *acc += (b - a).as_secs_f64();
        }
        self.max_speed = max_speed;
        if self.bad.is_none() {
            self.bad = bad;
        }
    }
}
